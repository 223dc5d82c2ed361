//! Bad input never panics: thousands of seeded mutations (bit flips, byte replacement,
//! truncation, duplicated and deleted spans, hostile numbers) of valid inputs go through every
//! reader and decoder of the crate. Each must return an error or a value, never panic, and the
//! unmutated input must still decode (so the harness is known to reach the real parsers).
//!
//! The generator is a fixed-seed xorshift, so a failure reproduces; the failing case's index and
//! bytes are printed. `RIGCAST_FUZZ_CASES=50000 cargo test -p rigcast-sources --test
//! fuzz_inputs` searches longer.

#![allow(clippy::unwrap_used)]

use std::panic::{catch_unwind, AssertUnwindSafe};

use glam::Quat;
use rigcast_sources::bvh::{read_bvh, write_bvh, BvhReadOptions, BvhWriteOptions};
use rigcast_sources::demo;
use rigcast_sources::gltf::{read_gltf, write_glb, GltfReadOptions};
use rigcast_sources::recording::{read_recording, write_clip_recording, RecordingReader};
use rigcast_sources::serial::{teapot_packet, witmotion_frame, ImuFormat, ImuParser};
use rigcast_sources::vmc_in::{OscMapping, VmcDecoder};

/// Mutated cases per input kind; `RIGCAST_FUZZ_CASES` raises it for a longer hunt.
fn cases() -> usize {
    std::env::var("RIGCAST_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
}

/// Tiny xorshift64*: deterministic, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

/// Text fragments that stress number and keyword parsing.
const HOSTILE: [&[u8]; 12] = [
    b"NaN",
    b"inf",
    b"-1e39",
    b"1e308",
    b"99999999999999999999",
    b"-0",
    b"{",
    b"}",
    b"\xff\xfe",
    b"\0",
    b"\n",
    b"\xff\xff\xff\xff",
];

/// One random mutation of `base` (1–4 edits).
fn mutate(rng: &mut Rng, base: &[u8]) -> Vec<u8> {
    let mut v = base.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = v.len();
        match rng.below(7) {
            0 if len > 0 => {
                let i = rng.below(len);
                v[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                v[i] = rng.next() as u8;
            }
            2 => v.truncate(rng.below(len + 1)),
            3 if len > 0 => {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(64)).min(len);
                v.drain(a..b);
            }
            4 if len > 0 => {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(64)).min(len);
                let span = v[a..b].to_vec();
                let at = rng.below(v.len() + 1);
                v.splice(at..at, span);
            }
            5 => {
                let at = rng.below(len + 1);
                let h = HOSTILE[rng.below(HOSTILE.len())];
                v.splice(at..at, h.iter().copied());
            }
            _ if len >= 4 => {
                // Overwrite a 32-bit word: corrupts length prefixes and counts in binary formats.
                let i = rng.below(len - 3);
                let w = match rng.below(4) {
                    0 => u32::MAX,
                    1 => 0,
                    2 => 0x8000_0000,
                    _ => rng.next() as u32,
                };
                v[i..i + 4].copy_from_slice(&w.to_le_bytes());
            }
            _ => {}
        }
    }
    v
}

/// Runs `decode` on `base` (must return true) and on [`cases`] mutations (must not panic).
fn fuzz(what: &str, seed: u64, base: &[u8], mut decode: impl FnMut(&[u8]) -> bool) {
    assert!(decode(base), "{what}: the unmutated input must decode");
    let mut rng = Rng(seed);
    let mut rejected = 0;
    let cases = cases();
    for case in 0..cases {
        let input = mutate(&mut rng, base);
        match catch_unwind(AssertUnwindSafe(|| decode(&input))) {
            Ok(true) => {}
            Ok(false) => rejected += 1,
            Err(_) => panic!(
                "{what}: case {case} (seed {seed}) panicked on {} bytes: {:?}",
                input.len(),
                String::from_utf8_lossy(&input[..input.len().min(400)])
            ),
        }
    }
    // The mutations must actually hurt sometimes, or they are not reaching the parser.
    assert!(rejected > 0, "{what}: no mutation was rejected");
    println!("{what}: {rejected}/{cases} mutations rejected, none panicked");
}

#[test]
fn bvh_reader_survives_mutations() {
    let text = write_bvh(&demo::generate(), &BvhWriteOptions::default()).unwrap();
    // Keep the file small so thousands of parses stay quick: the header and a few frames.
    let lines: Vec<&str> = text.lines().collect();
    let motion = lines.iter().position(|l| l.starts_with("MOTION")).unwrap();
    let mut small = lines[..motion + 1].join("\n");
    small.push_str("\nFrames: 4\n");
    small.push_str(lines[motion + 2]);
    for l in &lines[motion + 3..motion + 7] {
        small.push('\n');
        small.push_str(l);
    }
    small.push('\n');
    fuzz("bvh", 0x9e37_79b9_7f4a_7c15, small.as_bytes(), |b| {
        read_bvh(b, "fuzz", &BvhReadOptions::default()).is_ok()
    });
}

#[test]
fn glb_reader_survives_mutations() {
    let clip = demo::generate();
    let clip = clip.resampled(clip.frame_time_secs * 8.0).unwrap();
    let glb = write_glb(&clip).unwrap();
    fuzz("glb", 0x2545_f491_4f6c_dd1d, &glb, |b| {
        read_gltf(b, None, "fuzz", &GltfReadOptions::default()).is_ok()
    });
}

#[test]
fn recording_reader_survives_mutations() {
    let clip = demo::generate();
    let clip = clip.resampled(clip.frame_time_secs * 8.0).unwrap();
    let rcr = write_clip_recording(Vec::new(), &clip).unwrap();
    fuzz("rcr read_recording", 0x1234_5678_9abc_def1, &rcr, |b| {
        read_recording(b).is_ok()
    });
    // The streaming reader, record by record, must also stop on its first error.
    fuzz("rcr RecordingReader", 0x0fed_cba9_8765_4321, &rcr, |b| {
        let Ok(reader) = RecordingReader::new(b) else {
            return false;
        };
        let mut ok = true;
        for (i, r) in reader.enumerate() {
            ok &= r.is_ok();
            assert!(i < 100_000, "reader does not terminate");
        }
        ok
    });
}

#[test]
fn vmc_decoder_survives_mutations() {
    use rigcast_protocol::vmc::{VmcBone, VmcEncoder};
    use rigcast_sources::live::humanoid::HUMAN_BONES;
    let mut encoder = VmcEncoder::with_max_bundle_bytes(512);
    let bones = HUMAN_BONES.iter().map(|h| VmcBone {
        name: h.name,
        translation: glam::Vec3::from_array(h.default_offset),
        rotation: Quat::from_rotation_x(0.1),
    });
    let datagrams = encoder.encode(0.5, bones).to_vec();
    let mut decoder = VmcDecoder::new(OscMapping::vmc()).unwrap();
    // One decoder for all cases: garbage must not poison its state into a later panic. Each
    // datagram is mutated on its own, as a network would deliver it.
    for (i, d) in datagrams.iter().enumerate() {
        fuzz(
            &format!("vmc datagram {i}"),
            0x5555_aaaa_3333_cccc + i as u64,
            d,
            |b| {
                let r = decoder.feed(b);
                r.good_input && r.dropped == 0
            },
        );
    }
    assert!(decoder.stats().dropped() > 0);
}

#[test]
fn serial_parsers_survive_mutations() {
    let q = Quat::from_rotation_y(0.7);
    let csv = b"0,1,0,0,0\n1,0.7071,0,0.7071,0\r\n# comment\n\n2,0.5,0.5,0.5,0.5\n".to_vec();
    let mut wit = Vec::new();
    let mut teapot = Vec::new();
    for i in 0..4u8 {
        wit.extend_from_slice(&witmotion_frame(q));
        teapot.extend_from_slice(&teapot_packet(q, i));
    }
    for (format, base, seed) in [
        (ImuFormat::Csv, csv, 11u64),
        (ImuFormat::WitMotion, wit, 12),
        (ImuFormat::Teapot, teapot, 13),
    ] {
        let mut parser = ImuParser::new(format);
        let expected = if format == ImuFormat::Csv { 3 } else { 4 };
        fuzz(&format!("serial {format:?}"), seed, &base, |b| {
            parser.reset();
            let mut samples = 0;
            let mut finite = true;
            let dropped = parser.feed(b, |s| {
                samples += 1;
                finite &= s.rotation.is_finite() && s.rotation.is_normalized();
            });
            assert!(finite, "{format:?} produced a non-unit rotation");
            samples == expected && dropped == 0
        });
    }
}

#[cfg(feature = "vision")]
#[test]
fn landmark_records_survive_mutations() {
    use rigcast_sources::vision::source::{decode_landmarks, encode_landmarks};
    use rigcast_sources::vision::{LandmarkStages, SolverConfig};
    let mut lm = rigcast_sources::vision::Landmarks {
        presence: 0.9,
        ..Default::default()
    };
    for (i, v) in lm.world.iter_mut().enumerate() {
        *v = glam::Vec3::new(i as f32 * 0.01, 1.0 - i as f32 * 0.02, 0.1);
    }
    for (i, v) in lm.image.iter_mut().enumerate() {
        *v = glam::Vec4::new(100.0 + i as f32, 200.0 - i as f32, 0.0, 0.9);
    }
    let mut base = Vec::new();
    encode_landmarks(&lm, &mut base);
    let mut stages = LandmarkStages::new(SolverConfig::default(), true, true).unwrap();
    let mut pose = stages.skeleton().rest_pose();
    let mut t = 0.0;
    // Decoded garbage (NaN, infinities, huge values) is also fed through smoothing, constant
    // lengths and the solver, as a replayed recording would be.
    fuzz("landmarks", 0x7777_1111_2222_3333, &base, |b| {
        let Some(lm) = decode_landmarks(b) else {
            return false;
        };
        t += 1.0 / 30.0;
        stages.process(&lm, t, &mut pose);
        true
    });
}

/// Replaces the first `from` in `bytes` by `to` (same length, so GLB chunk lengths stay right).
fn patch(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    assert_eq!(from.len(), to.len());
    let at = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap();
    let mut out = bytes.to_vec();
    out[at..at + to.len()].copy_from_slice(to.as_bytes());
    out
}

#[test]
fn glb_with_bad_channel_target_is_an_error() {
    // The gltf crate does not validate channel targets and panics on them; found by the
    // mutations above.
    let glb = write_glb(&demo::generate()).unwrap();
    let opts = GltfReadOptions::default();
    let bad_path = patch(&glb, "\"path\":\"rotation\"", "\"path\":\"rotatiom\"");
    let err = read_gltf(&bad_path, None, "t", &opts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("channels[") && err.contains("path"), "{err}");
    // A two-digit channel target node becomes 99 (the demo has fewer nodes).
    let key = b"\"node\":";
    let at = glb
        .windows(key.len() + 2)
        .position(|w| w.starts_with(key) && w[key.len()..].iter().all(u8::is_ascii_digit))
        .unwrap()
        + key.len();
    let mut bad_node = glb.clone();
    bad_node[at..at + 2].copy_from_slice(b"99");
    let err = read_gltf(&bad_node, None, "t", &opts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("node 99 does not exist"), "{err}");
}
