//! End to end: a server replays a file; a WebSocket client and a VMC (UDP) receiver get the
//! file's rotations.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_protocol::coords::{internal_from_unity_position, internal_from_unity_rotation};
use rigcast_protocol::vmc::{decode_packet, VmcMessage};
use rigcast_protocol::ServerMessage;
use rigcast_server::{ReplaySettings, SourceSpec};
use rigcast_tests::*;

const TOLERANCE_RAD: f32 = 1e-4;

async fn check_file_streams_its_rotations(path: &Path) {
    let clip = rigcast_sources::load_clip(path).unwrap();
    let udp = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let vmc_addr = udp.local_addr().unwrap().to_string();
    // Bone names as in the file (humanoid role names are the default; see live_vmc/engine tests).
    let server = rigcast_server::start(rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![SourceSpec::ReplayFile(
            rigcast_server::config::ReplayFileSpec {
                path: path.to_path_buf(),
                name: None,
                settings: ReplaySettings::default(),
            },
        )],
        vmc_out: vec![rigcast_server::VmcOut::to(vmc_addr)],
        vmc_bone_names: rigcast_engine::settings::VmcBoneNames::Skeleton,
        ..rigcast_server::ServerConfig::default()
    })
    .await
    .unwrap();

    // WebSocket side.
    let mut ws = connect(&server.stream_url()).await;
    let (hello, skeletons) = handshake(&mut ws).await;
    let ServerMessage::Hello {
        protocol_version,
        subjects,
        ..
    } = hello
    else {
        unreachable!()
    };
    assert_eq!(protocol_version, 1);
    assert_eq!(subjects.len(), 1);
    assert_eq!(subjects[0].num_bones as usize, clip.skeleton.num_bones());
    assert_eq!(subjects[0].fingerprint, clip.skeleton.fingerprint_hex());
    let ServerMessage::Skeleton { bones, .. } = &skeletons[0] else {
        unreachable!()
    };
    let names: Vec<&str> = bones.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, clip.skeleton.names());

    // A count, not a time: under load the replay's frames come late but all come.
    let frames = collect_n_frames(&mut ws, 20, Duration::from_secs(20)).await;
    assert!(frames.len() >= 20, "only {} frames", frames.len());
    let mut last_seq = 0;
    for (f, _) in &frames {
        assert_eq!(f.rotations.len(), clip.skeleton.num_bones());
        assert!(f.header.seq >= last_seq, "seq went backwards");
        last_seq = f.header.seq;
        let (index, angle) = best_matching_frame(&clip, &f.rotations);
        assert!(
            angle <= TOLERANCE_RAD,
            "frame seq {} differs from every clip frame (best {index}: {angle} rad)",
            f.header.seq
        );
        let root = clip.poses[index].translations[0];
        assert!((f.root - root).length() < 1e-5);
    }

    // VMC side: bundles of one tick start with /VMC/Ext/T; gather each tick's bones.
    let mut buf = vec![0u8; 65536];
    let mut poses: Vec<HashMap<String, (Vec3, Quat)>> = Vec::new();
    // Until 21 ticks are complete (a count, not a time, as above), at most 20 s.
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut bundles = 0;
    let whole = |p: &HashMap<String, (Vec3, Quat)>| p.len() == clip.skeleton.num_bones();
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        if poses.iter().filter(|p| whole(p)).count() > 20 {
            break;
        }
        let Ok(Ok(n)) = tokio::time::timeout(left, udp.recv(&mut buf)).await else {
            break;
        };
        assert!(n <= 1500, "VMC bundle of {n} bytes");
        bundles += 1;
        for m in decode_packet(&buf[..n]).unwrap() {
            match m.unwrap() {
                VmcMessage::Time { .. } => poses.push(HashMap::new()),
                VmcMessage::BonePos {
                    name,
                    position,
                    rotation,
                } => {
                    if let Some(p) = poses.last_mut() {
                        p.insert(name, (position, rotation));
                    }
                }
                _ => {}
            }
        }
    }
    assert!(bundles > 0, "no VMC bundle received");
    // The last tick may be cut off by the deadline.
    let complete: Vec<_> = poses.iter().filter(|p| whole(p)).collect();
    assert!(
        complete.len() >= 20,
        "only {} complete VMC poses",
        complete.len()
    );
    for pose in complete {
        let rotations: Vec<Quat> = clip
            .skeleton
            .names()
            .iter()
            .map(|n| internal_from_unity_rotation(pose[n].1))
            .collect();
        let (index, angle) = best_matching_frame(&clip, &rotations);
        assert!(angle <= TOLERANCE_RAD, "VMC pose off by {angle} rad");
        for (i, n) in clip.skeleton.names().iter().enumerate() {
            let t = internal_from_unity_position(pose[n].0);
            assert!((t - clip.poses[index].translations[i]).length() < 1e-5);
        }
    }
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_walk_bvh_streams_file_rotations() {
    // The first labelled walk (found by its motion; a server per file, so one).
    let Some((walk, _, _)) = first_walk() else {
        return;
    };
    let path = walk.path;
    check_file_streams_its_rotations(&path).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fixture_bvh_streams_file_rotations() {
    let path = temp_path("fixture.bvh");
    let clip = fixture_clip();
    rigcast_sources::save_clip(&path, &clip).unwrap();
    // The file must carry the motion we built (BVH stores Euler degrees as text: loose bound).
    let back = rigcast_sources::load_clip(&path).unwrap();
    assert_eq!(back.num_frames(), clip.num_frames());
    for (a, b) in clip.poses.iter().zip(&back.poses) {
        let names = back.skeleton.names();
        for (i, n) in names.iter().enumerate() {
            if let Some(j) = clip.skeleton.bone(n) {
                assert!(rotation_angle(a.rotations[j.index()], b.rotations[i]) < 1e-3);
            }
        }
    }
    check_file_streams_its_rotations(&path).await;
}
