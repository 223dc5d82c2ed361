//! VMC input end to end: a recorded VMC stream replayed over a real UDP socket decodes to the
//! poses it was made from; malformed packets are counted and dropped; silence → Lost → Live.
//!
//! The recording `recordings/vmc/humanoid_wave.rcr` holds the raw datagrams (raw-packet
//! records, made by the protocol crate's VMC encoder, bones split over several bundles with
//! `/VMC/Ext/T` first) plus the expected poses as frame records. Regenerate it with
//! `cargo test -p rigcast-sources --test live_vmc -- --ignored write_vmc_recording`.

#![allow(clippy::unwrap_used)]

use std::net::UdpSocket;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_protocol::vmc::{VmcBone, VmcEncoder};
use rigcast_retarget::{Pose, RawSkeleton, Skeleton, Transform};
use rigcast_sources::live::humanoid::{human_bone_index, HUMAN_BONES};
use rigcast_sources::live::{LiveSource, SourceState};
use rigcast_sources::recording::{read_recording, RawKind, RecordingWriter};
use rigcast_sources::vmc_in::{OscMapping, VmcConfig, VmcDecoder, VmcSource};
use rosc::{OscBundle, OscMessage, OscPacket, OscTime, OscType};

const BODY: [&str; 22] = [
    "Hips",
    "Spine",
    "Chest",
    "UpperChest",
    "Neck",
    "Head",
    "LeftShoulder",
    "LeftUpperArm",
    "LeftLowerArm",
    "LeftHand",
    "RightShoulder",
    "RightUpperArm",
    "RightLowerArm",
    "RightHand",
    "LeftUpperLeg",
    "LeftLowerLeg",
    "LeftFoot",
    "LeftToes",
    "RightUpperLeg",
    "RightLowerLeg",
    "RightFoot",
    "RightToes",
];
const NUM_FRAMES: usize = 48;

/// Angle between rotations, accurate for tiny angles (acos of a dot product in f32 bottoms out
/// near 7e-4 rad).
fn quat_angle(a: Quat, b: Quat) -> f32 {
    let d = a.inverse() * b;
    2.0 * d.xyz().length().atan2(d.w.abs())
}

fn recording_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/vmc/humanoid_wave.rcr")
}

/// A known clip: the body bones with offsets unlike the decoder's defaults (so learning them
/// is tested), waving rotations and a moving hips translation.
fn known_clip() -> (Arc<Skeleton>, Vec<Pose>) {
    let mut raw = RawSkeleton::default();
    let mut index = Vec::new();
    for name in BODY {
        let h = human_bone_index(name).unwrap();
        let parent = HUMAN_BONES[h]
            .parent
            .map(|p| BODY.iter().position(|b| *b == HUMAN_BONES[p].name).unwrap())
            .map(|i| index[i]);
        let o = Vec3::from_array(HUMAN_BONES[h].default_offset) * 1.1 + Vec3::new(0.0, 0.0, 0.01);
        index.push(raw.add(name, parent, Transform::from_translation(o)));
    }
    let skeleton = Arc::new(Skeleton::build(&raw).unwrap());
    let poses = (0..NUM_FRAMES)
        .map(|f| {
            let t = f as f32 / 30.0;
            let mut pose = skeleton.rest_pose();
            for b in 0..skeleton.num_bones() {
                let k = b as f32;
                let axis = Vec3::new((k * 0.7).sin(), 1.0, (k * 1.3).cos()).normalize_or_zero();
                pose.rotations[b] = Quat::from_axis_angle(axis, 0.8 * (t * 2.0 + k).sin());
            }
            pose.translations[0] = Vec3::new(0.3 * t, 1.0 + 0.05 * (t * 3.0).sin(), -0.2 * t);
            pose
        })
        .collect();
    (skeleton, poses)
}

/// The datagrams of one frame, as the server's VMC output would send them.
fn encode_frame(
    encoder: &mut VmcEncoder,
    skeleton: &Skeleton,
    pose: &Pose,
    time: f32,
) -> Vec<Vec<u8>> {
    let bones = skeleton.bone_ids().map(|b| VmcBone {
        name: skeleton.name(b),
        translation: pose.translations[b.index()],
        rotation: pose.rotations[b.index()],
    });
    encoder.encode(time, bones).to_vec()
}

fn assert_pose_matches(skeleton: &Skeleton, expected: &Pose, got_skel: &Skeleton, got: &Pose) {
    for b in skeleton.bone_ids() {
        let id = got_skel.bone(skeleton.name(b)).unwrap();
        let angle = quat_angle(expected.rotations[b.index()], got.rotations[id.index()]);
        assert!(angle < 1e-4, "{}: {angle} rad", skeleton.name(b));
    }
    let dt = (expected.translations[0] - got.translations[0]).length();
    assert!(dt < 1e-5, "hips translation off by {dt}");
}

#[test]
#[ignore = "writes recordings/vmc/humanoid_wave.rcr"]
fn write_vmc_recording() {
    let (skeleton, poses) = known_clip();
    let file = std::fs::File::create(recording_path()).unwrap();
    let mut w = RecordingWriter::new(file).unwrap();
    w.write_skeleton(1, "expected", &skeleton).unwrap();
    // Small bundles so a frame spans several datagrams, as with a full VRM avatar.
    let mut encoder = VmcEncoder::with_max_bundle_bytes(512);
    for (f, pose) in poses.iter().enumerate() {
        let nanos = f as u64 * 33_333_333;
        for d in encode_frame(&mut encoder, &skeleton, pose, f as f32 / 30.0) {
            w.write_raw(0, RawKind::Osc, nanos, &d).unwrap();
        }
        w.write_frame(1, f as u64, nanos, pose).unwrap();
    }
    w.finish().unwrap();
}

/// What a collector thread hands back: the source and each received (skeleton, pose).
type Collected = (VmcSource, Vec<(Arc<Skeleton>, Pose)>);

/// Collects `want` frames (10 s at most); `progress` counts them as they come, so a sender can
/// wait for the receiver instead of guessing how long a loaded machine takes to schedule it.
fn spawn_collector(
    mut source: VmcSource,
    want: usize,
    progress: Arc<AtomicUsize>,
) -> std::thread::JoinHandle<Collected> {
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut pose = Pose {
            rotations: vec![],
            translations: vec![],
        };
        let start = Instant::now();
        while out.len() < want && start.elapsed() < Duration::from_secs(10) {
            if let Some(meta) = source
                .next_frame(Duration::from_millis(50), &mut pose)
                .unwrap()
            {
                assert_eq!(meta.seq as usize, out.len() + 1);
                assert_eq!(meta.skeleton_changed, out.is_empty());
                out.push((source.skeleton().unwrap(), pose.clone()));
                progress.store(out.len(), Ordering::Release);
            }
        }
        (source, out)
    })
}

#[test]
fn recorded_vmc_stream_over_udp_matches_expected_pose() {
    let path = recording_path();
    let rec = read_recording(std::fs::File::open(&path).unwrap()).unwrap();
    assert!(rec.ended_cleanly);
    let expected_skeleton = rec.skeletons[0].skeleton.clone();
    assert_eq!(rec.frames.len(), NUM_FRAMES);
    // The recording is what the generator makes (independent check of the expected poses).
    let (clip_skeleton, clip_poses) = known_clip();
    assert_eq!(expected_skeleton.names(), clip_skeleton.names());
    for (r, p) in rec.frames.iter().zip(&clip_poses) {
        assert_pose_matches(&clip_skeleton, p, &expected_skeleton, &r.pose);
    }

    let source = VmcSource::bind(VmcConfig {
        bind: "127.0.0.1".parse().unwrap(),
        port: 0,
        ..VmcConfig::default()
    })
    .unwrap();
    let addr = source.local_addr().unwrap();
    let progress = Arc::new(AtomicUsize::new(0));
    let collector = spawn_collector(source, NUM_FRAMES, Arc::clone(&progress));
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    std::thread::sleep(Duration::from_millis(50));
    let (mut last, mut frame) = (0, 0);
    for p in &rec.raw {
        assert_eq!(p.kind, RawKind::Osc);
        if p.capture_nanos != last {
            // Pace frames on the receiver: on a loaded machine its thread can sleep long enough
            // for the kernel's socket buffer to overflow, a loss this test is not about. The
            // first frame closes only at the second's `/VMC/Ext/T`, so frame f + 1 goes out once
            // f - 1 frames are in.
            frame += 1;
            let start = Instant::now();
            while progress.load(Ordering::Acquire) + 1 < frame.max(1)
                && start.elapsed() < Duration::from_secs(2)
            {
                std::thread::sleep(Duration::from_millis(1));
            }
            last = p.capture_nanos;
        }
        sender.send_to(&p.bytes, addr).unwrap();
    }
    let (source, frames) = collector.join().unwrap();
    // `/VMC/Ext/T` comes first in each frame: the first frame (while the skeleton is learnt)
    // closes at the second frame's T, every later one as soon as its last bone arrives, so all
    // frames come out whole and in order.
    assert_eq!(frames.len(), NUM_FRAMES, "{:?}", source.stats());
    let learnt = &frames[0].0;
    assert_eq!(learnt.num_bones(), BODY.len());
    for b in clip_skeleton.bone_ids() {
        let id = learnt.bone(clip_skeleton.name(b)).unwrap();
        let parent = clip_skeleton.parent(b).map(|p| clip_skeleton.name(p));
        assert_eq!(learnt.parent(id).map(|p| learnt.name(p)), parent);
        if b.index() > 0 {
            let d =
                clip_skeleton.rest()[b.index()].translation - learnt.rest()[id.index()].translation;
            assert!(
                d.length() < 1e-5,
                "{} offset off by {d}",
                clip_skeleton.name(b)
            );
        }
    }
    for (i, (skel, pose)) in frames.iter().enumerate() {
        assert_pose_matches(&expected_skeleton, &rec.frames[i].pose, skel, pose);
    }
    let status = source.status();
    assert_eq!(status.state, SourceState::Live);
    assert_eq!(status.dropped, 0);
    assert_eq!(status.frames as usize, NUM_FRAMES);
}

#[test]
fn replay_from_recording_goes_through_the_same_decoder() {
    let rec = read_recording(std::fs::File::open(recording_path()).unwrap()).unwrap();
    let mut source = VmcSource::replay(rec.raw.clone(), VmcConfig::default(), false).unwrap();
    let mut pose = Pose {
        rotations: vec![],
        translations: vec![],
    };
    let mut n = 0;
    while !source.replay_finished() {
        if source
            .next_frame(Duration::from_millis(10), &mut pose)
            .unwrap()
            .is_some()
        {
            let skel = source.skeleton().unwrap();
            assert_pose_matches(
                &rec.skeletons[0].skeleton,
                &rec.frames[n].pose,
                &skel,
                &pose,
            );
            n += 1;
        }
    }
    assert_eq!(n, NUM_FRAMES);
}

fn msg(addr: &str, args: Vec<OscType>) -> OscPacket {
    OscPacket::Message(OscMessage {
        addr: addr.into(),
        args,
    })
}

fn bone(name: &str, p: [f32; 3], q: [f32; 4]) -> OscPacket {
    let mut args = vec![OscType::String(name.into())];
    args.extend(p.iter().chain(q.iter()).map(|v| OscType::Float(*v)));
    msg("/VMC/Ext/Bone/Pos", args)
}

fn bundle(content: Vec<OscPacket>) -> OscPacket {
    OscPacket::Bundle(OscBundle {
        timetag: OscTime {
            seconds: 0,
            fractional: 1,
        },
        content,
    })
}

fn enc(p: &OscPacket) -> Vec<u8> {
    rosc::encoder::encode(p).unwrap()
}

/// A valid VMC frame written with rosc, bones after the root and `/VMC/Ext/T` last.
fn good_frame(time: f32, angle: f32) -> Vec<u8> {
    let q = Quat::from_rotation_y(angle);
    enc(&bundle(vec![
        msg("/VMC/Ext/Root/Pos", {
            let mut a = vec![OscType::String("root".into())];
            a.extend([0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0].map(OscType::Float));
            a
        }),
        bone("Hips", [0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
        bone("Spine", [0.0, 0.1, 0.0], [q.x, q.y, q.z, q.w]),
        bone("Head", [0.0, 0.5, 0.0], [0.0, 0.0, 0.0, 1.0]),
        msg(
            "/VMC/Ext/Blend/Val",
            vec![OscType::String("A".into()), OscType::Float(0.5)],
        ),
        msg("/VMC/Ext/Blend/Apply", vec![]),
        msg("/VMC/Ext/OK", vec![OscType::Int(1)]),
        msg("/VMC/Ext/T", vec![OscType::Float(time)]),
    ]))
}

/// 22 distinct kinds of malformed OSC/VMC datagrams; each must count exactly one drop.
fn malformed_packets() -> Vec<(&'static str, Vec<u8>)> {
    let good = good_frame(1.0, 0.0);
    let single = enc(&bone("Spine", [0.0, 0.1, 0.0], [0.0, 0.0, 0.0, 1.0]));
    let f = |v: f32| OscType::Float(v);
    let mut nested = b"#bundle\0".to_vec();
    nested.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]);
    let garbage = [0xde, 0xad, 0xbe, 0xef, 1, 2, 3, 4];
    nested.extend_from_slice(&(garbage.len() as u32).to_be_bytes());
    nested.extend_from_slice(&garbage);
    let mut deep = single.clone();
    for _ in 0..40 {
        let mut b = b"#bundle\0".to_vec();
        b.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]);
        b.extend_from_slice(&(deep.len() as u32).to_be_bytes());
        b.extend_from_slice(&deep);
        deep = b;
    }
    let mut bad_len = good.clone();
    bad_len[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    let mut zero_len = b"#bundle\0".to_vec();
    zero_len.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0]);
    let mut bad_utf8 = single.clone();
    bad_utf8[1] = 0xff;
    let mut unpadded = b"/VMC".to_vec();
    unpadded.extend_from_slice(b",f\0\0");
    let mut trailing = single.clone();
    trailing.extend_from_slice(&[0, 0, 0, 1]);
    let mut unknown_tag = b"/VMC/Ext/T\0\0,X\0\0".to_vec();
    unknown_tag.extend_from_slice(&[0, 0, 0, 0]);
    let close_array = b"/VMC/Ext/T\0\0,]\0\0".to_vec();
    let mut root_few = vec![OscType::String("root".into())];
    root_few.extend([0.0, 0.0].map(f));
    vec![
        ("empty datagram", vec![]),
        ("truncated message", single[..single.len() - 8].to_vec()),
        ("truncated bundle", good[..good.len() / 2 / 4 * 4].to_vec()),
        (
            "length not a multiple of 4",
            single[..single.len() - 1].to_vec(),
        ),
        (
            "address without leading slash",
            enc(&msg("VMC/Ext/T", vec![f(1.0)])),
        ),
        ("address not null-terminated", unpadded),
        ("address not UTF-8", bad_utf8),
        ("unknown type tag", unknown_tag),
        ("array close without open", close_array),
        ("trailing bytes after a message", trailing),
        ("bundle element length too large", bad_len),
        ("bundle element length zero", zero_len),
        ("nested garbage in a bundle", nested),
        ("bundles nested 40 deep", deep),
        (
            "wrong type tags (ints for floats)",
            enc(&msg(
                "/VMC/Ext/Bone/Pos",
                vec![
                    OscType::String("Spine".into()),
                    OscType::Int(0),
                    OscType::Int(0),
                    OscType::Int(0),
                    OscType::Int(0),
                    OscType::Int(0),
                    OscType::Int(0),
                    OscType::Int(1),
                ],
            )),
        ),
        (
            "too few arguments",
            enc(&msg(
                "/VMC/Ext/Bone/Pos",
                vec![OscType::String("Spine".into()), f(0.0), f(0.1)],
            )),
        ),
        (
            "root with too few arguments",
            enc(&msg("/VMC/Ext/Root/Pos", root_few)),
        ),
        (
            "NaN rotation",
            enc(&bone("Spine", [0.0, 0.1, 0.0], [f32::NAN, 0.0, 0.0, 1.0])),
        ),
        (
            "infinite position",
            enc(&bone(
                "Spine",
                [f32::INFINITY, 0.1, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            )),
        ),
        (
            "zero quaternion",
            enc(&bone("Spine", [0.0, 0.1, 0.0], [0.0, 0.0, 0.0, 0.0])),
        ),
        (
            "huge bone name",
            enc(&bone(&"X".repeat(4000), [0.0; 3], [0.0, 0.0, 0.0, 1.0])),
        ),
        (
            "unknown bone",
            enc(&bone("Tail", [0.0; 3], [0.0, 0.0, 0.0, 1.0])),
        ),
        (
            "bone name sent as a blob",
            enc(&msg(
                "/VMC/Ext/Bone/Pos",
                vec![
                    OscType::Blob(b"Spine".to_vec()),
                    f(0.0),
                    f(0.1),
                    f(0.0),
                    f(0.0),
                    f(0.0),
                    f(0.0),
                    f(1.0),
                ],
            )),
        ),
        (
            "time is a string",
            enc(&msg("/VMC/Ext/T", vec![OscType::String("now".into())])),
        ),
        (
            "blend value NaN",
            enc(&msg(
                "/VMC/Ext/Blend/Val",
                vec![OscType::String("A".into()), f(f32::NAN)],
            )),
        ),
    ]
}

#[test]
fn each_malformed_kind_is_counted_and_dropped() {
    let mut dec = VmcDecoder::new(OscMapping::vmc()).unwrap();
    let r = dec.feed(&good_frame(1.0, 0.3));
    assert!(
        r.frame_ready && r.skeleton_changed && r.dropped == 0,
        "{r:?}"
    );
    let before = dec.pose().clone();
    let kinds = malformed_packets();
    assert!(kinds.len() >= 20);
    for (i, (what, bytes)) in kinds.iter().enumerate() {
        let r = dec.feed(bytes);
        assert_eq!(r.dropped, 1, "{what}: {r:?}");
        assert!(!r.frame_ready && !r.good_input, "{what}: {r:?}");
        assert_eq!(dec.stats().dropped(), i as u64 + 1, "{what}");
        assert_eq!(dec.pose(), &before, "{what} changed the pose");
    }
    // Still decoding afterwards.
    let r = dec.feed(&good_frame(1.1, 0.6));
    assert!(r.frame_ready && !r.skeleton_changed, "{r:?}");
    let spine = dec.skeleton().unwrap().bone("Spine").unwrap();
    assert!(
        quat_angle(
            dec.pose().rotations[spine.index()],
            Quat::from_rotation_y(-0.6)
        ) < 1e-5
            || quat_angle(
                dec.pose().rotations[spine.index()],
                Quat::from_rotation_y(0.6)
            ) < 1e-5
    );
}

#[test]
fn unity_to_internal_conversion_and_root_folding() {
    let mut dec = VmcDecoder::new(OscMapping::vmc()).unwrap();
    assert!(dec.feed(&good_frame(1.0, 0.3)).frame_ready);
    let skel = dec.skeleton().unwrap().clone();
    assert_eq!(skel.names(), &["Hips", "Spine", "Head"]);
    // Head's parent is Spine: Chest/UpperChest/Neck were not sent.
    assert_eq!(skel.parent(skel.bone("Head").unwrap()), skel.bone("Spine"));
    // Unity rotation of +0.3 rad about Y is -0.3 rad about Y in an X-mirrored frame.
    let spine = skel.bone("Spine").unwrap();
    let got = dec.pose().rotations[spine.index()];
    assert!(
        quat_angle(got, Quat::from_rotation_y(-0.3)) < 1e-5,
        "{got:?}"
    );
    // Root (0.5, 0, 1) in Unity is (-0.5, 0, 1) internally; the hips sit 1 m above it.
    let hips = dec.pose().translations[0];
    assert!((hips - Vec3::new(-0.5, 1.0, 1.0)).length() < 1e-6, "{hips}");
    // The mirrored position of a bone offset.
    let head_rest = skel.rest()[skel.bone("Head").unwrap().index()].translation;
    assert!((head_rest - Vec3::new(0.0, 0.5, 0.0)).length() < 1e-6);
}

#[test]
fn reordered_datagrams_are_dropped() {
    let mut dec = VmcDecoder::new(OscMapping::vmc()).unwrap();
    assert!(dec.feed(&good_frame(2.0, 0.1)).frame_ready);
    assert!(dec.feed(&good_frame(2.1, 0.2)).frame_ready);
    let r = dec.feed(&good_frame(2.05, 0.9));
    assert_eq!((r.frame_ready, r.dropped), (false, 1));
    assert_eq!(dec.stats().reordered_datagrams, 1);
    // A big step back is a restarted sender, not reordering.
    assert!(dec.feed(&good_frame(0.0, 0.3)).frame_ready);
}

#[test]
fn generic_osc_mapping_drives_bones() {
    let mapping = OscMapping::from_toml(
        r#"
[[rules]]
address = "/tracker/{bone}/quat"
args = ["qw", "qx", "qy", "qz"]
space = "internal"

[[rules]]
address = "/frame"
frame_end = true

[bone_names]
pelvis = "Hips"
chest = "Chest"
"#,
    )
    .unwrap();
    let mut dec = VmcDecoder::new(mapping).unwrap();
    let q = Quat::from_rotation_x(0.4);
    let datagram = |q: Quat| {
        enc(&bundle(vec![
            msg(
                "/tracker/pelvis/quat",
                [q.w, q.x, q.y, q.z].map(OscType::Float).to_vec(),
            ),
            msg(
                "/tracker/chest/quat",
                [1.0, 0.0, 0.0, 0.0].map(OscType::Float).to_vec(),
            ),
            msg("/frame", vec![]),
        ]))
    };
    let r = dec.feed(&datagram(q));
    assert!(r.frame_ready, "{r:?} {:?}", dec.stats());
    let skel = dec.skeleton().unwrap().clone();
    assert_eq!(skel.names(), &["Hips", "Chest"]);
    assert!(quat_angle(dec.pose().rotations[0], q) < 1e-6);
    // No positions sent: default offsets (chest above the hips).
    assert!(skel.rest()[1].translation.y > 0.1);
}

#[test]
fn malformed_over_udp_then_lost_then_live() {
    let mut source = VmcSource::bind(VmcConfig {
        bind: "127.0.0.1".parse().unwrap(),
        port: 0,
        lost_after_secs: 0.2,
        ..VmcConfig::default()
    })
    .unwrap();
    let addr = source.local_addr().unwrap();
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut pose = Pose {
        rotations: vec![],
        translations: vec![],
    };
    assert_eq!(source.status().state, SourceState::Connecting);
    sender.send_to(&good_frame(1.0, 0.1), addr).unwrap();
    let meta = source
        .next_frame(Duration::from_secs(2), &mut pose)
        .unwrap()
        .unwrap();
    assert!(meta.skeleton_changed);
    assert_eq!(pose.num_bones(), 3);
    assert_eq!(source.status().state, SourceState::Live);

    let kinds = malformed_packets();
    for (_, bytes) in &kinds {
        sender.send_to(bytes, addr).unwrap();
    }
    // Drain: none of them makes a frame.
    let start = Instant::now();
    while source.stats().datagrams < 1 + kinds.len() as u64
        && start.elapsed() < Duration::from_secs(3)
    {
        assert!(source
            .next_frame(Duration::from_millis(20), &mut pose)
            .unwrap()
            .is_none());
    }
    assert_eq!(source.stats().datagrams, 1 + kinds.len() as u64);
    assert_eq!(source.status().dropped, kinds.len() as u64);

    // Silence beyond 0.2 s: Lost.
    let start = Instant::now();
    while source.status().state != SourceState::Lost && start.elapsed() < Duration::from_secs(2) {
        assert!(source
            .next_frame(Duration::from_millis(50), &mut pose)
            .unwrap()
            .is_none());
    }
    assert_eq!(source.status().state, SourceState::Lost);
    assert!(start.elapsed() >= Duration::from_millis(150));

    // Resume (sender restarted: its clock went back to 0): Live again, frames flow.
    sender.send_to(&good_frame(0.0, 0.2), addr).unwrap();
    let meta = source
        .next_frame(Duration::from_secs(2), &mut pose)
        .unwrap()
        .unwrap();
    assert!(!meta.skeleton_changed);
    assert_eq!(meta.seq, 2);
    assert_eq!(source.status().state, SourceState::Live);
}
