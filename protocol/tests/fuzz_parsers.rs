//! Seeded random and garbled input for every public parser of the wire formats: each must
//! answer with an error (or a value that is itself well formed), never panic.
//!
//! The inputs are mutations of valid messages (byte flips, cuts, splices, lying length fields)
//! plus plain noise, so the parsers are driven past their first check. The generator is a fixed
//! xorshift, so a failure reproduces with the printed case number.
#![allow(clippy::unwrap_used)] // tests may unwrap

use glam::{Quat, Vec3};
use rigcast_protocol::control::parse_client_message;
use rigcast_protocol::frame::{decode_frame, encode_frame, frame_len, FrameHeader};
use rigcast_protocol::vmc::{decode_packet, VmcBone, VmcEncoder};
use rigcast_protocol::FrameError;

const CASES: usize = 4000;

#[path = "../../retarget/tests/common/xorshift.rs"]
mod xorshift;
use xorshift::Rng;

/// One to four random edits of `seed`: flip, overwrite with a boundary byte, cut, duplicate a
/// span, insert noise.
fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(b.len() + 1);
        match rng.below(5) {
            0 if !b.is_empty() => {
                let i = at.min(b.len() - 1);
                b[i] ^= 1 << rng.below(8);
            }
            1 if !b.is_empty() => {
                let i = at.min(b.len() - 1);
                b[i] = *rng.pick(&[0x00, 0x7f, 0x80, 0xff, b'"', b'{', b'[', b'#', b'/', b',']);
            }
            2 => b.truncate(at),
            3 if at < b.len() => {
                let end = (at + 1 + rng.below(24)).min(b.len());
                let span = b[at..end].to_vec();
                let to = rng.below(b.len() + 1);
                b.splice(to..to, span);
            }
            _ => {
                let noise: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
                b.splice(at..at, noise);
            }
        }
    }
    b
}

#[test]
fn parse_client_message_never_panics() {
    let seeds = [
        r#"{"type":"subscribe","subjects":[1,2,3]}"#,
        r#"{"type":"subscribe","subjects":null}"#,
        r#"{"type":"ping","nonce":18446744073709551615}"#,
        r#"{"type":"set_mapping","subject":2,"overrides":{"LeftArm":"mixamorig:LeftArm","Tail":null}}"#,
        r#"{"type":"calibrate","subject":4,"pose":"n","delay_secs":2.5}"#,
    ];
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut ok, mut err) = (0, 0);
    for case in 0..CASES {
        let seed = *rng.pick(&seeds);
        let bytes = mutate(&mut rng, seed.as_bytes());
        // The server hands over WebSocket text, which is always UTF-8.
        let text = String::from_utf8_lossy(&bytes);
        match parse_client_message(&text) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(
                    !e.message.is_empty(),
                    "case {case}: empty message for {text:?}"
                );
                err += 1;
            }
        }
    }
    // Both outcomes must be exercised, or the mutations are too mild / too wild to test much.
    println!("accepted {ok}, refused {err}");
    assert!(ok > 0 && err > CASES / 2, "ok {ok}, err {err}");
}

#[test]
fn decode_frame_never_panics_and_accepts_only_consistent_frames() {
    let header = FrameHeader {
        flags: 0,
        subject: 3,
        seq: 77,
        capture_nanos: 1_700_000_000_000_000_000,
        send_nanos: 1_700_000_000_000_500_000,
        missed_frames: 0,
    };
    let rots: Vec<Quat> = (0..6)
        .map(|i| Quat::from_rotation_z(0.2 * i as f32))
        .collect();
    let mut good = Vec::new();
    encode_frame(&mut good, &header, Vec3::new(0.1, 0.9, -0.2), &rots);

    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let (mut ok, mut err) = (0, 0);
    for case in 0..CASES {
        let mut bytes = mutate(&mut rng, &good);
        if case % 4 == 0 && bytes.len() >= 16 {
            // A lying bone count, including values whose byte length would overflow 32 bits.
            let n = *rng.pick(&[0u32, 1, 5, 7, 0x1000_0000, u32::MAX]);
            bytes[12..16].copy_from_slice(&n.to_le_bytes());
        }
        match decode_frame(&bytes) {
            Ok(d) => {
                // Whatever is accepted is self-consistent: length, count and finite values.
                assert_eq!(bytes.len(), frame_len(d.rotations.len()), "case {case}");
                assert!(d.root.is_finite(), "case {case}");
                assert!(d.rotations.iter().all(|q| q.is_finite()), "case {case}");
                ok += 1;
            }
            Err(
                FrameError::ShortBuffer { .. }
                | FrameError::BadMagic { .. }
                | FrameError::UnsupportedVersion { .. }
                | FrameError::CountMismatch { .. }
                | FrameError::NonFinite { .. },
            ) => err += 1,
        }
    }
    println!("accepted {ok}, refused {err}");
    assert!(ok > 0 && err > CASES / 2, "ok {ok}, err {err}");
}

#[test]
fn decode_packet_never_panics() {
    let names: Vec<String> = (0..12).map(|i| format!("Bone{i}")).collect();
    let mut enc = VmcEncoder::with_max_bundle_bytes(512);
    let bundles: Vec<Vec<u8>> = enc
        .encode(
            0.5,
            names.iter().enumerate().map(|(i, n)| VmcBone {
                name: n,
                translation: Vec3::new(0.0, 0.1 * i as f32, 0.0),
                rotation: Quat::from_rotation_y(0.1 * i as f32),
            }),
        )
        .to_vec();
    assert!(bundles.len() > 1, "the cap should split the pose");
    // A bundle nested in a bundle, to reach the recursive framing check.
    let inner = &bundles[0];
    let mut nested = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
    nested.extend_from_slice(&(inner.len() as i32).to_be_bytes());
    nested.extend_from_slice(inner);
    let mut seeds = bundles.clone();
    seeds.push(nested);
    seeds.push(b"/VMC/Ext/T\0\0,f\0\0\x3f\x00\x00\x00".to_vec());

    let mut rng = Rng(0xdead_beef_cafe_f00d);
    let (mut ok, mut err) = (0, 0);
    for _ in 0..CASES {
        let seed = rng.pick(&seeds);
        let bytes = mutate(&mut rng, seed);
        match decode_packet(&bytes) {
            Ok(_) => ok += 1,
            Err(_) => err += 1,
        }
    }
    println!("accepted {ok}, refused {err}");
    assert!(ok > 0 && err > CASES / 2, "ok {ok}, err {err}");
}

/// The deepest nesting a UDP datagram can hold (each level costs a 16-byte bundle header and a
/// 4-byte size): decoding it must not exhaust a worker thread's stack.
#[test]
fn deeply_nested_bundles_are_refused_not_a_stack_overflow() {
    let mut packet = b"/VMC/Ext/T\0\0,f\0\0\x3f\x00\x00\x00".to_vec();
    while packet.len() + 20 <= 65_507 {
        let mut outer = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
        outer.extend_from_slice(&(packet.len() as i32).to_be_bytes());
        outer.extend_from_slice(&packet);
        packet = outer;
    }
    let r = std::thread::Builder::new()
        .stack_size(2 * 1024 * 1024) // the default of spawned and tokio worker threads
        .spawn(move || decode_packet(&packet).map(|m| m.len()))
        .unwrap()
        .join()
        .unwrap();
    match r {
        Err(e) => assert!(e.to_string().contains("nested deeper than 8"), "{e}"),
        Ok(n) => panic!("a {n}-message datagram nested thousands deep was accepted"),
    }
}
