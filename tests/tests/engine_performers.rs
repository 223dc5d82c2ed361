//! The default demo as performers: the bundled walk (source) and the built-in mannequin
//! (target) stream together; `set_mapping` rebuilds the target's mapping, updates the on-disk
//! cache and broadcasts the new `mapping`; `record` writes both subjects into one recording.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use rigcast_protocol::control::{ErrorCode, SubjectKind};
use rigcast_protocol::ServerMessage;
use rigcast_server::ServerConfig;
use rigcast_sources::recording::read_recording;
use rigcast_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_target_set_mapping_cache_and_record() {
    let rec_path = temp_path("session.rcr");
    let cache_dir = temp_path("cache").with_file_name("mappings");
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        record: Some(rec_path.clone()),
        mapping_cache_dir: Some(cache_dir.clone()),
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    // set_mapping changes the server: this client holds the control token.
    let mut ws = connect(&server.control_stream_url()).await;
    let (hello, skeletons) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        unreachable!()
    };
    assert_eq!(subjects.len(), 2);
    assert_eq!(subjects[1].kind, SubjectKind::Target);
    let ServerMessage::Skeleton { bones, .. } = &skeletons[1] else {
        unreachable!()
    };
    let Some(ServerMessage::Mapping {
        subject: 1,
        entries,
        ..
    }) = next_json(&mut ws, Duration::from_secs(3)).await
    else {
        panic!("expected the mannequin's mapping after the skeletons")
    };
    assert_eq!(entries.len(), bones.len());
    let thigh = entries.iter().find(|e| e.target == "thigh_l").unwrap();
    let thigh_source = thigh.source.clone().expect("thigh_l is mapped");
    // Both subjects stream.
    let frames = collect_frames(&mut ws, Duration::from_millis(500)).await;
    for id in [0, 1] {
        let n = frames
            .iter()
            .filter(|(f, _)| f.header.subject == id)
            .count();
        assert!(n >= 15, "subject {id}: only {n} frames");
    }
    let files = std::fs::read_dir(&cache_dir).unwrap().count();
    assert_eq!(files, 1, "one cached mapping");

    // Unknown bones are refused at once.
    send_text(
        &mut ws,
        r#"{"type":"set_mapping","subject":1,"overrides":{"no_such_bone":null}}"#,
    )
    .await;
    expect_unsupported(&mut ws).await;
    send_text(
        &mut ws,
        r#"{"type":"set_mapping","subject":0,"overrides":{}}"#,
    )
    .await;
    expect_unsupported(&mut ws).await;

    // Unmap the left thigh and drive the right thigh from the left source thigh.
    let text = format!(
        r#"{{"type":"set_mapping","subject":1,"overrides":{{"thigh_l":null,"thigh_r":"{thigh_source}"}}}}"#
    );
    send_text(&mut ws, &text).await;
    let ack = wait_for(&mut ws, |m| matches!(m, ServerMessage::Ack { .. })).await;
    assert!(matches!(ack, ServerMessage::Ack { subject: 1, .. }));
    let ServerMessage::Mapping { entries, .. } =
        wait_for(&mut ws, |m| matches!(m, ServerMessage::Mapping { .. })).await
    else {
        unreachable!()
    };
    let get = |n: &str| entries.iter().find(|e| e.target == n).unwrap().clone();
    assert_eq!(get("thigh_l").source, None);
    assert_eq!(
        get("thigh_r").source.as_deref(),
        Some(thigh_source.as_str())
    );
    assert_eq!(get("thigh_r").score, 0.0);
    // The cache entry now holds the edited table.
    let cached: Vec<_> = std::fs::read_dir(&cache_dir).unwrap().collect();
    assert_eq!(cached.len(), 1);
    let text = std::fs::read_to_string(cached[0].as_ref().unwrap().path()).unwrap();
    assert!(text.contains("set_mapping"), "cache not updated");

    server.shutdown().await;
    let rec = read_recording(std::fs::File::open(&rec_path).unwrap()).unwrap();
    assert!(rec.ended_cleanly, "no end marker");
    let skeleton_subjects: Vec<u32> = rec.skeletons.iter().map(|s| s.subject_id).collect();
    let mut frames = [0usize; 2];
    for f in &rec.frames {
        frames[f.subject_id as usize] += 1;
    }
    assert!(skeleton_subjects.contains(&0) && skeleton_subjects.contains(&1));
    // Both subjects' frames are in the recording. (How many depends on how fast this machine
    // got through the test; rates are measured elsewhere, so only require a steady stream.)
    assert!(frames[0] >= 10 && frames[1] >= 10, "{frames:?}");
}

/// The next error reply is `unsupported`.
async fn expect_unsupported(ws: &mut Ws) {
    let reply = wait_for(ws, |m| matches!(m, ServerMessage::Error { .. })).await;
    assert!(
        matches!(
            reply,
            ServerMessage::Error {
                code: ErrorCode::Unsupported,
                ..
            }
        ),
        "{reply:?}"
    );
}

async fn wait_for(ws: &mut Ws, f: impl Fn(&ServerMessage) -> bool) -> ServerMessage {
    loop {
        let m = next_json(ws, Duration::from_secs(3))
            .await
            .expect("message");
        if f(&m) {
            return m;
        }
    }
}

/// A target whose names mark the sides the other way round from its body (the label files
/// say so: today the Godot platformer robot, which names its left side `r-*`): the live
/// `mapping` message drives its labelled left thigh from the performer's left thigh and
/// carries the warning. The first labelled human rig with mirrored names (a server each).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mapping_message_warns_when_names_lie_about_sides() {
    let rigs = labelled_where("human rig with mirrored side names", |l| {
        l.kind() == "human" && l.has_legs() && !l.is_bvh() && l.names_mirrored()
    });
    let Some(rig) = rigs.first() else {
        return;
    };
    let robot = rig.path.clone();
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        mapping_cache_dir: Some(temp_path("cache-lying").with_file_name("mappings-lying")),
        performers: vec![rigcast_server::config::PerformerSpec::target_file(robot)],
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let mut ws = connect(&server.stream_url()).await;
    let _ = handshake(&mut ws).await;
    let ServerMessage::Mapping {
        entries, warnings, ..
    } = wait_for(&mut ws, |m| matches!(m, ServerMessage::Mapping { .. })).await
    else {
        unreachable!()
    };
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("target:") && w.contains("geometry")),
        "{warnings:?}"
    );
    let source_of = |t: &str| {
        entries
            .iter()
            .find(|e| e.target == t)
            .and_then(|e| e.source.clone())
    };
    // The bundled demo walk's thighs are `leg_upper_l` / `leg_upper_r`.
    let (left, right) = (
        rig.bone("upperLeg.L").unwrap(),
        rig.bone("upperLeg.R").unwrap(),
    );
    assert_eq!(
        source_of(left).as_deref(),
        Some("leg_upper_l"),
        "{}",
        rig.rel
    );
    assert_eq!(
        source_of(right).as_deref(),
        Some("leg_upper_r"),
        "{}",
        rig.rel
    );
    server.shutdown().await;
}
