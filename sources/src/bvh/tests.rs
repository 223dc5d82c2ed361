#![allow(clippy::unwrap_used)]
use glam::{Quat, Vec3};
use rigcast_retarget::approx::{quat_close_precise as quat_close, vec_close};

use super::*;
use crate::error::SourceError;

/// Two joints in centimetres; the child has only two rotation channels and a position channel,
/// CRLF line ends and tabs.
const SMALL: &str = "HIERARCHY\r\nROOT Hips\r\n{\r\n\tOFFSET 0 90 0\r\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\r\n\tJOINT Upper Arm\r\n\t{\r\n\t\tOFFSET 10 0 0\r\n\t\tCHANNELS 3 Yrotation Xposition Xrotation\r\n\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 20 0\r\n\t\t}\r\n\t}\r\n}\r\nMOTION\r\nFrames: 2\r\nFrame Time: 0.5\r\n1 2 3 90 0 0 0 10 0\r\n0 100 0 0 0 0 90 15 45\r\n";

fn read(text: &str) -> Result<BvhRead, SourceError> {
    read_bvh(text.as_bytes(), "t", &BvhReadOptions { scale: Some(0.01) })
}

#[test]
fn reads_small_file_with_known_values() {
    let r = read(SMALL).unwrap();
    let s = &r.clip.skeleton;
    assert_eq!(s.names(), &["Hips", "Upper Arm", "Upper Arm_end"]);
    assert_eq!((r.num_joints, r.num_end_sites), (2, 1));
    assert!(vec_close(
        s.rest()[0].translation,
        Vec3::new(0.0, 0.9, 0.0),
        1e-7
    ));
    assert!(vec_close(
        s.rest()[2].translation,
        Vec3::new(0.0, 0.2, 0.0),
        1e-7
    ));
    assert_eq!(r.clip.num_frames(), 2);
    assert!((r.clip.frame_time_secs - 0.5).abs() < 1e-12);
    let f0 = &r.clip.poses[0];
    assert!(vec_close(
        f0.translations[0],
        Vec3::new(0.01, 0.02, 0.03),
        1e-7
    ));
    assert!(quat_close(
        f0.rotations[0],
        Quat::from_rotation_z(90f32.to_radians()),
        1e-6
    ));
    // Position channel on a non-root joint replaces only its own component.
    assert!(vec_close(
        f0.translations[1],
        Vec3::new(0.10, 0.0, 0.0),
        1e-7
    ));
    let f1 = &r.clip.poses[1];
    assert!(vec_close(
        f1.translations[1],
        Vec3::new(0.15, 0.0, 0.0),
        1e-7
    ));
    let expect =
        Quat::from_rotation_y(90f32.to_radians()) * Quat::from_rotation_x(45f32.to_radians());
    assert!(quat_close(f1.rotations[1], expect, 1e-6));
    assert!(quat_close(f1.rotations[2], Quat::IDENTITY, 0.0));
}

#[test]
fn round_trip_is_exact_within_tolerance() {
    let a = read(SMALL).unwrap();
    let text = write_bvh(&a.clip, &BvhWriteOptions::default()).unwrap();
    let b = read(&text).unwrap();
    assert_clips_equal(&a.clip, &b.clip);
    // The non-root position channel survived as a position channel.
    assert_eq!(b.channels[1].len(), 6);
    assert!(text.contains("End Site"));
}

pub(crate) fn assert_clips_equal(a: &rigcast_retarget::Clip, b: &rigcast_retarget::Clip) {
    assert_eq!(a.skeleton.names(), b.skeleton.names());
    assert_eq!(a.skeleton.parents(), b.skeleton.parents());
    for (x, y) in a.skeleton.rest().iter().zip(b.skeleton.rest()) {
        assert!(vec_close(x.translation, y.translation, 1e-6), "{x:?} {y:?}");
    }
    assert_eq!(a.num_frames(), b.num_frames());
    assert!((a.frame_time_secs - b.frame_time_secs).abs() < 1e-9);
    for (pa, pb) in a.poses.iter().zip(&b.poses) {
        for i in 0..pa.num_bones() {
            assert!(
                quat_close(pa.rotations[i], pb.rotations[i], 1e-5),
                "bone {i}"
            );
            assert!(
                vec_close(pa.translations[i], pb.translations[i], 1e-6),
                "bone {i}"
            );
        }
    }
}

#[test]
fn guesses_units_from_height() {
    let r = read_bvh(SMALL.as_bytes(), "t", &BvhReadOptions::default()).unwrap();
    // The rest stands 20 units tall along Y (hips to the arm's end): 2.0 m in decimetres, the
    // unit nearest a person's height. A hips-and-arm figure has no feet and head to read as a
    // two-legged body, so the guess claims no confidence (units.rs tests the graded one).
    assert!(r.scale_guessed);
    assert_eq!(r.scale, 0.1);
    assert_eq!(r.scale_confidence, 0.0);
    let given = read(SMALL).unwrap();
    assert!(!given.scale_guessed);
    assert_eq!(given.scale_confidence, 1.0);
}

fn expect_err(text: &[u8]) -> SourceError {
    match read_bvh(text, "bad", &BvhReadOptions { scale: Some(1.0) }) {
        Ok(_) => panic!("accepted malformed input"),
        Err(e) => {
            // Messages must be printable and non-empty.
            assert!(!e.to_string().is_empty());
            e
        }
    }
}

/// The error of [`SMALL`] with `from` replaced by `to`.
fn small_err(from: &str, to: &str) -> SourceError {
    expect_err(SMALL.replace(from, to).as_bytes())
}

#[test]
fn malformed_inputs_give_clear_errors() {
    // Truncated inside the hierarchy.
    let cut = &SMALL[..SMALL.find("End Site").unwrap()];
    assert!(matches!(
        expect_err(cut.as_bytes()),
        SourceError::MissingMotion { .. } | SourceError::UnexpectedEof { .. }
    ));
    // Garbled number in OFFSET, reported on line 4.
    let e = small_err("OFFSET 0 90 0", "OFFSET 0 9x0 0");
    assert!(matches!(e, SourceError::BadNumber { line: 4, .. }), "{e}");
    // Wrong channel count.
    let e = small_err("CHANNELS 3 Yrot", "CHANNELS 4 Yrot");
    assert!(
        matches!(
            e,
            SourceError::ChannelCount {
                line: 9,
                declared: 4,
                found: 3
            }
        ),
        "{e}"
    );
    // Unknown channel name.
    let e = small_err("Xposition Xrotation", "Wposition Xrotation");
    assert!(
        matches!(e, SourceError::UnknownChannel { line: 9, .. }),
        "{e}"
    );
    // Missing MOTION.
    let e = expect_err(&SMALL.as_bytes()[..SMALL.find("MOTION").unwrap()]);
    assert!(matches!(e, SourceError::MissingMotion { .. }), "{e}");
    // Frames count mismatch.
    let e = small_err("Frames: 2", "Frames: 3");
    assert!(
        matches!(
            e,
            SourceError::FrameCountMismatch {
                declared: 3,
                found: 2
            }
        ),
        "{e}"
    );
    // A frame line with too few values.
    let e = small_err("0 100 0 0 0 0 90 15 45", "0 100 0 0 0 0 90 15");
    assert!(
        matches!(
            e,
            SourceError::FrameValues {
                line: 20,
                expected: 9,
                found: 8
            }
        ),
        "{e}"
    );
    // Garbled number in the motion data.
    let e = small_err("0 100 0 0", "0 1,0 0 0");
    assert!(matches!(e, SourceError::BadNumber { line: 20, .. }), "{e}");
    // NaN is not a number we accept.
    let e = small_err("0 100 0 0", "0 NaN 0 0");
    assert!(matches!(e, SourceError::BadNumber { .. }), "{e}");
    // Non-UTF-8 bytes.
    let mut bytes = SMALL.as_bytes().to_vec();
    bytes[20] = 0xff;
    assert!(matches!(
        expect_err(&bytes),
        SourceError::NotUtf8 { offset: 20 }
    ));
    // Not a BVH at all / empty.
    assert!(matches!(expect_err(b""), SourceError::UnexpectedEof { .. }));
    assert!(matches!(
        expect_err(b"{\"json\": 1}"),
        SourceError::Syntax { line: 1, .. }
    ));
    // Zero frame time.
    let e = small_err("Frame Time: 0.5", "Frame Time: 0");
    assert!(matches!(e, SourceError::BadNumber { line: 18, .. }), "{e}");
    // Duplicate joint names are a skeleton error, not a panic.
    let dup = SMALL.replace("JOINT Upper Arm", "JOINT Hips");
    assert!(matches!(
        expect_err(dup.as_bytes()),
        SourceError::Skeleton(_)
    ));
    // Unbalanced braces.
    let e = small_err("\t}\r\n}\r\nMOTION", "\t}\r\nMOTION");
    assert!(matches!(e, SourceError::UnexpectedEof { .. }), "{e}");
}

#[test]
fn every_prefix_fails_cleanly_or_parses() {
    // Truncation at any byte must never panic, and must be reported as an error up to the
    // last value of the last frame (a file cut inside that number cannot be told from one
    // without a final newline, so from there on it parses).
    let last_value = SMALL.rfind("45").unwrap();
    for cut in 0..SMALL.len() {
        let r = read_bvh(&SMALL.as_bytes()[..cut], "t", &BvhReadOptions::default());
        if cut <= last_value {
            assert!(r.is_err(), "prefix of {cut} bytes parsed");
        } else {
            assert_eq!(r.unwrap().clip.num_frames(), 2, "prefix of {cut} bytes");
        }
    }
}

#[test]
fn degenerate_rest_guesses_scale_from_first_frame() {
    // Rest: four 45-unit bones in a line along X (180 units: "centimetres" if trusted). Frame
    // 0 zigzags them into a 90×90 figure, which reads as inches.
    let text = "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n\
JOINT b\n{\nOFFSET 45 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n\
JOINT c\n{\nOFFSET 45 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n\
JOINT d\n{\nOFFSET 45 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n\
End Site\n{\nOFFSET 45 0 0\n}\n}\n}\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n\
0 0 0 90 0 0 -90 0 0 90 0 0\n";
    let r = read_bvh(text.as_bytes(), "z", &BvhReadOptions::default()).unwrap();
    assert_eq!(r.scale, 0.0254);
    // The rest data itself is kept exactly (no re-posing).
    assert!(vec_close(
        r.clip.skeleton.rest()[1].translation,
        Vec3::new(45.0 * 0.0254, 0.0, 0.0),
        1e-6
    ));
}
