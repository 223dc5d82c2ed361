//! Fuzz targets, one per reader or decoder that takes untrusted bytes: BVH, glTF/GLB,
//! recordings, config files, VMC/OSC datagrams and the binary pose frame. Each mutates a seed
//! corpus (the shared test data and `recordings/` when present, plus valid inputs made here)
//! for `RIGCAST_FUZZ_SECS` seconds (default 10; CI runs the default). A panic fails the test and
//! saves the input (see `rigcast_tests::fuzz`); crashes found become regression tests in
//! `server/tests/hostile_files.rs` and `tests/tests/hostile_*.rs`.
//!
//! A longer hunt: `RIGCAST_FUZZ_SECS=600 nice -n 19 cargo test --release -p rigcast-tests
//! --test fuzz_targets -- --nocapture --test-threads 1`.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use rigcast_tests::fuzz::{budget, corpus, run};

fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn outcome<T, E: std::fmt::Display>(r: Result<T, E>) -> String {
    match r {
        Ok(_) => "ok".into(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn fuzz_bvh_reader() {
    let mut seeds = corpus(&shared(), &[".bvh"], 24, 256 * 1024);
    let clip = rigcast_server::demo::procedural_clip(8, 30.0).unwrap();
    let opts = rigcast_sources::bvh::BvhWriteOptions::default();
    seeds.push(
        rigcast_sources::bvh::write_bvh(&clip, &opts)
            .unwrap()
            .into_bytes(),
    );
    let read = rigcast_sources::bvh::BvhReadOptions::default();
    run("bvh", &seeds, budget(), true, |b| {
        outcome(rigcast_sources::bvh::read_bvh(b, "fuzz", &read))
    });
}

#[test]
fn fuzz_gltf_reader() {
    // GLB only: a .gltf's buffers are files beside it, which mutations would only miss.
    let mut seeds = corpus(&shared(), &[".glb", ".vrm"], 8, 1024 * 1024);
    let clip = rigcast_server::demo::procedural_clip(4, 30.0).unwrap();
    seeds.push(rigcast_sources::gltf::write_glb(&clip).unwrap());
    let opts = rigcast_sources::gltf::GltfReadOptions::default();
    run("gltf", &seeds, budget(), true, |b| {
        outcome(rigcast_sources::gltf::read_gltf(b, None, "fuzz", &opts))
    });
}

#[test]
fn fuzz_recording_reader() {
    let seeds = corpus(&repo().join("recordings"), &[".rcr"], 12, 2 * 1024 * 1024);
    run("recording", &seeds, budget(), true, |b| {
        outcome(rigcast_sources::recording::read_recording(b))
    });
}

#[test]
fn fuzz_config_reader() {
    let mut seeds = vec![std::fs::read(repo().join("server/rigcast.example.toml")).unwrap()];
    seeds.push(
        b"rate_hz = 60\n[[sources]]\nkind = \"vmc\"\nport = 0\n[[performers]]\nsource = \"vmc\"\ntarget = \"builtin:mannequin\"\n"
            .to_vec(),
    );
    // Parsing and validation (paths are not opened here: the config names them only).
    run("config", &seeds, budget(), false, |b| {
        let Ok(text) = std::str::from_utf8(b) else {
            return "not utf-8".into();
        };
        match toml::from_str::<rigcast_server::config::FileConfig>(text) {
            Ok(file) => outcome(rigcast_server::ServerConfig::from_file(file)),
            Err(e) => e.to_string(),
        }
    });
}

#[test]
fn fuzz_vmc_decoder() {
    let clip = rigcast_server::demo::procedural_clip(4, 30.0).unwrap();
    let names = clip.skeleton.names().to_vec();
    let mut enc = rigcast_protocol::vmc::VmcEncoder::new();
    let mut seeds = Vec::new();
    for (k, pose) in clip.poses.iter().enumerate() {
        let bones = rigcast_tests::vmc_bones(&names, pose);
        seeds.extend(enc.encode(k as f32 / 30.0, bones).iter().cloned());
    }
    // One decoder for the whole run: its learnt skeleton and state are part of what is fuzzed.
    let mut decoder =
        rigcast_sources::vmc_in::VmcDecoder::new(rigcast_sources::vmc_in::OscMapping::vmc())
            .unwrap();
    run("vmc", &seeds, budget(), false, |b| {
        let r = decoder.feed(b);
        let pose_ok = decoder.pose().clone().check_values().is_ok();
        format!(
            "frame {} dropped {} pose {}",
            r.frame_ready, r.dropped, pose_ok
        )
    });
}

#[test]
fn fuzz_frame_decoder() {
    use rigcast_protocol::frame::{append_frame_v2, decode_frame, encode_frame, FrameHeader};
    let clip = rigcast_server::demo::procedural_clip(2, 30.0).unwrap();
    let pose = &clip.poses[1];
    let header = FrameHeader {
        flags: 0,
        subject: 3,
        seq: 7,
        capture_nanos: 1,
        send_nanos: 2,
        missed_frames: 0,
    };
    let mut v1 = Vec::new();
    encode_frame(&mut v1, &header, pose.root_translation(), &pose.rotations);
    let mut v2 = Vec::new();
    append_frame_v2(
        &mut v2,
        &header,
        &pose.rotations,
        &pose.translations,
        &[0, 1],
    );
    run("frame", &[v1, v2], budget(), true, |b| {
        outcome(decode_frame(b))
    });
}
