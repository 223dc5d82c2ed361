//! A VRM character's own humanoid map is ground truth for the server's mapping: a VRM whose
//! bones have meaningless names and whose body gives no facing cue (no toes, symmetric) is
//! driven from the demo walk, and its `mapping` message follows the VRM's humanoid map — also
//! where geometry alone would pick the other side.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use futures_util::StreamExt;
use rigcast_protocol::ServerMessage;
use rigcast_retarget::analysis::{analyze, humanoid_roles, HumanBone, SkeletonView};
use rigcast_server::{PerformerSpec, ServerConfig, SourceSpec};
use serde_json::json;
use tokio_tungstenite::tungstenite::Message;

/// Meaningless node names, so only structure or the VRM map can tell the roles.
fn name(i: usize) -> String {
    format!("n{:02}", (i * 7 + 3) % 23)
}

/// A GLB with a skin-less humanoid node tree and a `VRMC_vrm` humanoid map. The character's
/// left (per the map) is at −X; feet point straight down, so nothing but the map says which
/// way it faces.
fn vrm_bytes() -> (Vec<u8>, Vec<(&'static str, usize)>) {
    // (translation, children)
    let tree: Vec<([f32; 3], Vec<usize>)> = vec![
        ([0.0, 1.0, 0.0], vec![1, 5, 8]),   // 0 hips
        ([0.0, 0.15, 0.0], vec![2]),        // 1 spine
        ([0.0, 0.2, 0.0], vec![3, 11, 15]), // 2 chest
        ([0.0, 0.2, 0.0], vec![4]),         // 3 neck
        ([0.0, 0.1, 0.0], vec![]),          // 4 head
        ([-0.1, -0.05, 0.0], vec![6]),      // 5 left upper leg
        ([0.0, -0.45, 0.0], vec![7]),       // 6 left lower leg
        ([0.0, -0.45, 0.0], vec![]),        // 7 left foot
        ([0.1, -0.05, 0.0], vec![9]),       // 8 right upper leg
        ([0.0, -0.45, 0.0], vec![10]),      // 9 right lower leg
        ([0.0, -0.45, 0.0], vec![]),        // 10 right foot
        ([-0.05, 0.15, 0.0], vec![12]),     // 11 left shoulder
        ([-0.1, 0.0, 0.0], vec![13]),       // 12 left upper arm
        ([-0.28, 0.0, 0.0], vec![14]),      // 13 left lower arm
        ([-0.25, 0.0, 0.0], vec![]),        // 14 left hand
        ([0.05, 0.15, 0.0], vec![16]),      // 15 right shoulder
        ([0.1, 0.0, 0.0], vec![17]),        // 16 right upper arm
        ([0.28, 0.0, 0.0], vec![18]),       // 17 right lower arm
        ([0.25, 0.0, 0.0], vec![]),         // 18 right hand
    ];
    let roles: Vec<(&'static str, usize)> = vec![
        ("hips", 0),
        ("spine", 1),
        ("chest", 2),
        ("neck", 3),
        ("head", 4),
        ("leftUpperLeg", 5),
        ("leftLowerLeg", 6),
        ("leftFoot", 7),
        ("rightUpperLeg", 8),
        ("rightLowerLeg", 9),
        ("rightFoot", 10),
        ("leftShoulder", 11),
        ("leftUpperArm", 12),
        ("leftLowerArm", 13),
        ("leftHand", 14),
        ("rightShoulder", 15),
        ("rightUpperArm", 16),
        ("rightLowerArm", 17),
        ("rightHand", 18),
    ];
    let nodes: Vec<_> = tree
        .iter()
        .enumerate()
        .map(|(i, (t, c))| {
            if c.is_empty() {
                json!({"name": name(i), "translation": t})
            } else {
                json!({"name": name(i), "translation": t, "children": c})
            }
        })
        .collect();
    let mut human = serde_json::Map::new();
    for (h, n) in &roles {
        human.insert(h.to_string(), json!({ "node": n }));
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["VRMC_vrm"],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
        "nodes": nodes,
        "extensions": {"VRMC_vrm": {"specVersion": "1.0", "humanoid": {"humanBones": human}}},
    });
    let mut text = serde_json::to_vec(&doc).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    // GLB: 12-byte header, then one JSON chunk (length, "JSON", data).
    let total = 12 + 8 + text.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(text.len() as u32).to_le_bytes());
    glb.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    glb.extend_from_slice(&text);
    (glb, roles)
}

fn temp_dir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("rigcast-vrm-truth-{}", std::process::id()));
    // A folder left by an earlier process with the same id is stale.
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vrm_humanoid_map_decides_the_servers_mapping() {
    let dir = temp_dir();
    let path = dir.join("figure.vrm");
    let (bytes, roles) = vrm_bytes();
    std::fs::write(&path, bytes).unwrap();
    let node = |role: &str| name(roles.iter().find(|(h, _)| *h == role).unwrap().1);

    // The file reads as a VRM with its map.
    let info = rigcast_sources::describe(&path).unwrap();
    assert_eq!(
        info.vrm_roles.unwrap()["leftUpperLeg"],
        node("leftUpperLeg")
    );

    // Control: structure alone puts the left leg on the other side (else this test could not
    // tell whether the truth was used).
    let clip = rigcast_sources::load_clip(&path).unwrap();
    let guessed = humanoid_roles(
        &clip.skeleton,
        &analyze(&SkeletonView::rest(&clip.skeleton)),
        None,
    );
    let guessed_left_leg = guessed
        .iter()
        .find(|(h, _)| *h == HumanBone::parse("leftUpperLeg").unwrap())
        .map(|(_, b)| clip.skeleton.name(*b).to_string());
    assert!(guessed_left_leg.is_some());
    assert_ne!(guessed_left_leg, Some(node("leftUpperLeg")));

    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![SourceSpec::demo()],
        performers: vec![PerformerSpec::target_file(path.clone())],
        mapping_cache_dir: Some(dir.join("cache")),
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let (mut ws, _) = tokio_tungstenite::connect_async(server.stream_url())
        .await
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    let entries = loop {
        let left = deadline
            .checked_duration_since(Instant::now())
            .expect("no mapping message");
        let msg = tokio::time::timeout(left, ws.next())
            .await
            .expect("no mapping message")
            .unwrap()
            .unwrap();
        if let Message::Text(t) = msg {
            if let ServerMessage::Mapping {
                subject: 1,
                entries,
                ..
            } = serde_json::from_str(t.as_str()).unwrap()
            {
                break entries;
            }
        }
    };
    let source_of = |target: String| {
        entries
            .iter()
            .find(|e| e.target == target)
            .unwrap_or_else(|| panic!("no entry for {target}"))
            .source
            .clone()
    };
    for (role, demo) in [
        ("hips", "pelvis"),
        ("leftUpperArm", "arm_upper_l"),
        ("rightUpperArm", "arm_upper_r"),
        ("leftUpperLeg", "leg_upper_l"),
        ("rightUpperLeg", "leg_upper_r"),
    ] {
        assert_eq!(
            source_of(node(role)).as_deref(),
            Some(demo),
            "VRM {role} ({})",
            node(role)
        );
    }
    // The truth-driven table bypasses the cache (its key does not cover the truth).
    assert!(std::fs::read_dir(dir.join("cache"))
        .map(|d| d.count() == 0)
        .unwrap_or(true));
    server.shutdown().await;
    let _ = std::fs::remove_dir_all(&dir);
}
