//! Serial IMU input through pseudo-terminals (no hardware): CSV and binary frames drive bone
//! rotations, calibration removes mounting angles, and unplugging (closing the pty) makes the
//! source Lost until a new pty appears behind the same path, when it reconnects by itself.
//!
//! The hardware-free replays `recordings/serial/*.rcr` (raw serial chunks + expected frames,
//! configs beside them as `.toml`) are regenerated with
//! `cargo test -p rigcast-sources --test live_serial -- --ignored write_serial_recordings`.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_retarget::{Pose, Skeleton};
use rigcast_sources::live::humanoid::default_humanoid;
use rigcast_sources::live::{LiveSource, SourceState};
use rigcast_sources::recording::{read_recording, RawKind, RecordingWriter};
use rigcast_sources::serial::{
    teapot_packet, witmotion_frame, ImuFormat, SensorAssignment, SerialImuConfig, SerialImuSource,
};

mod common {
    pub mod pty;
}
use common::pty::{angle, Pty};

fn point_link(link: &Path, target: &Path) {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link).unwrap();
}

/// CSV lines `id,w,x,y,z`, one per sensor, the ids in order from 0.
fn csv(readings: &[Quat]) -> Vec<u8> {
    let mut s = String::new();
    for (id, q) in readings.iter().enumerate() {
        s.push_str(&format!("{id},{},{},{},{}\r\n", q.w, q.x, q.y, q.z));
    }
    s.into_bytes()
}

/// Calls next_frame until `pred` holds for the pose (or fails after `secs`), optionally
/// re-sending `resend` every 50 ms.
fn wait_for(
    source: &mut SerialImuSource,
    pose: &mut Pose,
    secs: f32,
    mut resend: impl FnMut(),
    pred: impl Fn(&Skeleton, &Pose) -> bool,
) {
    let skeleton = source.skeleton().unwrap();
    let start = Instant::now();
    let mut last_send = Instant::now() - Duration::from_secs(1);
    loop {
        if last_send.elapsed() > Duration::from_millis(50) {
            resend();
            last_send = Instant::now();
        }
        if source
            .next_frame(Duration::from_millis(20), pose)
            .unwrap()
            .is_some()
            && pred(&skeleton, pose)
        {
            return;
        }
        assert!(
            start.elapsed().as_secs_f32() < secs,
            "timed out; status {:?}",
            source.status()
        );
    }
}

fn local(skeleton: &Skeleton, pose: &Pose, bone: &str) -> Quat {
    pose.rotations[skeleton.bone(bone).unwrap().index()]
}

fn arm_sensors() -> Vec<SensorAssignment> {
    [(0, "Hips"), (1, "LeftUpperArm"), (2, "LeftLowerArm")]
        .into_iter()
        .map(|(sensor, bone)| SensorAssignment {
            sensor,
            bone: bone.into(),
        })
        .collect()
}

/// Expected locals when the sensors' world rotations are `d` (bones between them at rest).
fn arm_matches(d: [Quat; 3]) -> impl Fn(&Skeleton, &Pose) -> bool {
    move |s, p| {
        angle(local(s, p, "Hips"), d[0]) < 1e-4
            && angle(local(s, p, "LeftUpperArm"), d[0].inverse() * d[1]) < 1e-4
            && angle(local(s, p, "LeftLowerArm"), d[1].inverse() * d[2]) < 1e-4
            && angle(local(s, p, "Spine"), Quat::IDENTITY) < 1e-4
    }
}

#[test]
fn csv_calibration_unplug_and_reconnect_through_pty() {
    let dir = std::env::temp_dir().join(format!("rigcast-live-serial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("imu");
    let pty = Pty::new();
    point_link(&link, &pty.path);

    let mut config = SerialImuConfig::csv(&link, arm_sensors());
    config.reconnect_secs = 0.1;
    config.lost_after_secs = 0.3;
    let mut source = SerialImuSource::open(config, default_humanoid().unwrap()).unwrap();
    let mut pose = Pose {
        rotations: vec![],
        translations: vec![],
    };
    assert_eq!(source.status().state, SourceState::Connecting);

    // Uncalibrated: sensors read their bones' world rotations directly.
    let s = [
        Quat::from_rotation_y(0.4),
        Quat::from_rotation_z(-1.2),
        Quat::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize_or_zero(), 0.7),
    ];
    let data = csv(&s);
    wait_for(
        &mut source,
        &mut pose,
        3.0,
        || pty.write(&data),
        arm_matches(s),
    );
    assert_eq!(source.status().state, SourceState::Live);

    // Calibration in the rest T-pose with sensors strapped on at arbitrary angles.
    let mount = [
        Quat::from_rotation_x(1.0),
        Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.8, 2.0),
        Quat::from_rotation_z(2.5),
    ];
    let cal = csv(&mount);
    wait_for(
        &mut source,
        &mut pose,
        3.0,
        || pty.write(&cal),
        arm_matches(mount),
    );
    source.calibrate().unwrap();
    // Bones rotate by d in the world: sensors then read d · mount.
    let d = [
        Quat::from_rotation_y(0.5),
        Quat::from_rotation_x(-0.9),
        Quat::from_rotation_z(1.1),
    ];
    let moved = csv(&[d[0] * mount[0], d[1] * mount[1], d[2] * mount[2]]);
    wait_for(
        &mut source,
        &mut pose,
        3.0,
        || pty.write(&moved),
        arm_matches(d),
    );
    let frames_before = source.status().frames;

    // Unplug: the pty disappears.
    drop(pty);
    let start = Instant::now();
    while source.status().state != SourceState::Lost {
        assert!(source
            .next_frame(Duration::from_millis(20), &mut pose)
            .unwrap()
            .is_none());
        assert!(
            start.elapsed() < Duration::from_secs(3),
            "{:?}",
            source.status()
        );
    }
    assert!(!source.is_connected());

    // Plug back in: a new pty behind the same path. Calibration survives.
    let pty2 = Pty::new();
    point_link(&link, &pty2.path);
    let d2 = [
        Quat::from_rotation_y(-0.3),
        Quat::from_rotation_x(0.6),
        Quat::from_rotation_y(1.4),
    ];
    let moved2 = csv(&[d2[0] * mount[0], d2[1] * mount[1], d2[2] * mount[2]]);
    wait_for(
        &mut source,
        &mut pose,
        5.0,
        || pty2.write(&moved2),
        arm_matches(d2),
    );
    assert!(source.is_connected());
    let status = source.status();
    assert_eq!(status.state, SourceState::Live);
    assert!(status.frames > frames_before);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn witmotion_and_teapot_binary_frames_through_pty() {
    for format in [ImuFormat::WitMotion, ImuFormat::Teapot] {
        let pty = Pty::new();
        let mut config = SerialImuConfig::csv(
            &pty.path,
            vec![SensorAssignment {
                sensor: 0,
                bone: "LeftLowerArm".into(),
            }],
        );
        config.format = format;
        let mut source = SerialImuSource::open(config, default_humanoid().unwrap()).unwrap();
        let mut pose = Pose {
            rotations: vec![],
            translations: vec![],
        };
        for target in [Quat::from_rotation_z(0.8), Quat::from_rotation_x(-0.5)] {
            let mut bytes = vec![0x00, 0x55, 0x24, 0x13]; // line noise, including start bytes
            match format {
                ImuFormat::WitMotion => {
                    let mut corrupt = witmotion_frame(Quat::from_rotation_y(3.0));
                    corrupt[10] ^= 0xff;
                    bytes.extend_from_slice(&corrupt);
                    bytes.extend_from_slice(&witmotion_frame(target));
                }
                _ => bytes.extend_from_slice(&teapot_packet(target, 1)),
            }
            // Quantised to 1/32768 (WitMotion) or 1/16384 (teapot): a few 1e-4 rad.
            wait_for(
                &mut source,
                &mut pose,
                3.0,
                || pty.write(&bytes),
                move |s, p| angle(local(s, p, "LeftLowerArm"), target) < 2e-3,
            );
        }
        assert_eq!(source.status().state, SourceState::Live);
        if format == ImuFormat::WitMotion {
            assert!(source.status().dropped >= 1, "{:?}", source.status());
        }
    }
}

fn recordings_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/serial")
}

/// (file stem, config, chunks of bytes with the expected pose after each chunk).
fn serial_cases() -> Vec<(&'static str, SerialImuConfig, Vec<Vec<u8>>)> {
    let mut cases = Vec::new();
    let mut csv_chunks = Vec::new();
    let mut wit_chunks = Vec::new();
    for f in 0..30 {
        let t = f as f32 / 30.0;
        let q = [
            Quat::from_rotation_y(0.3 * t),
            Quat::from_rotation_z(-1.2 * (t * 3.0).sin()),
            Quat::from_rotation_x(0.8 * (t * 5.0).sin()),
        ];
        csv_chunks.push(csv(&q));
        wit_chunks.push(witmotion_frame(q[2]).to_vec());
    }
    cases.push((
        "csv_left_arm",
        SerialImuConfig::csv("/dev/ttyUSB0", arm_sensors()),
        csv_chunks,
    ));
    let mut wit = SerialImuConfig::csv(
        "/dev/ttyUSB0",
        vec![SensorAssignment {
            sensor: 0,
            bone: "LeftLowerArm".into(),
        }],
    );
    wit.format = ImuFormat::WitMotion;
    cases.push(("witmotion_forearm", wit, wit_chunks));
    cases
}

#[test]
#[ignore = "writes recordings/serial/*.rcr and *.toml"]
fn write_serial_recordings() {
    let skeleton = default_humanoid().unwrap();
    for (stem, config, chunks) in serial_cases() {
        let dir = recordings_dir();
        std::fs::write(
            dir.join(format!("{stem}.toml")),
            toml::to_string(&config).unwrap(),
        )
        .unwrap();
        // Expected poses from a replay of the same bytes, checked independently below.
        let packets: Vec<_> = chunks
            .iter()
            .enumerate()
            .map(|(i, c)| rigcast_sources::recording::RawPacket {
                source_id: 0,
                kind: RawKind::Serial,
                capture_nanos: i as u64 * 33_333_333,
                bytes: c.clone(),
            })
            .collect();
        let mut source =
            SerialImuSource::replay(packets.clone(), config.clone(), skeleton.clone()).unwrap();
        let mut w =
            RecordingWriter::new(std::fs::File::create(dir.join(format!("{stem}.rcr"))).unwrap())
                .unwrap();
        w.write_skeleton(1, "expected", &skeleton).unwrap();
        let mut pose = skeleton.rest_pose();
        for (i, p) in packets.iter().enumerate() {
            w.write_raw(0, RawKind::Serial, p.capture_nanos, &p.bytes)
                .unwrap();
            source
                .next_frame(Duration::from_millis(1), &mut pose)
                .unwrap()
                .unwrap();
            w.write_frame(1, i as u64, p.capture_nanos, &pose).unwrap();
        }
        w.finish().unwrap();
    }
}

#[test]
fn serial_recordings_replay_to_expected_poses() {
    let skeleton: Arc<Skeleton> = default_humanoid().unwrap();
    for (stem, _, chunks) in serial_cases() {
        let dir = recordings_dir();
        let config = SerialImuConfig::from_toml(
            &std::fs::read_to_string(dir.join(format!("{stem}.toml"))).unwrap(),
        )
        .unwrap();
        let rec =
            read_recording(std::fs::File::open(dir.join(format!("{stem}.rcr"))).unwrap()).unwrap();
        assert_eq!(rec.raw.len(), chunks.len());
        let mut source =
            SerialImuSource::replay(rec.raw.clone(), config, skeleton.clone()).unwrap();
        let mut pose = skeleton.rest_pose();
        let mut n = 0;
        while !source.replay_finished() {
            if source
                .next_frame(Duration::from_millis(1), &mut pose)
                .unwrap()
                .is_some()
            {
                let expected = &rec.frames[n].pose;
                for b in 0..skeleton.num_bones() {
                    assert!(
                        angle(pose.rotations[b], expected.rotations[b]) < 1e-4,
                        "{stem} frame {n}"
                    );
                }
                n += 1;
            }
        }
        assert_eq!(n, chunks.len(), "{stem}");
        // Independent check of the last frame: the forearm's sensor reading drives its world
        // rotation (uncalibrated, rest world rotations are identity).
        let last = &rec.frames[n - 1].pose;
        let world = rigcast_retarget::world_transforms(&skeleton, last);
        let forearm = skeleton.bone("LeftLowerArm").unwrap().index();
        let t = 29.0 / 30.0;
        let q = Quat::from_rotation_x(0.8 * (t * 5.0_f32).sin());
        assert!(angle(world[forearm].rotation, q) < 2e-3, "{stem}");
    }
}
