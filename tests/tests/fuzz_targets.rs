//! Fuzz targets, one per reader or decoder that takes untrusted bytes: BVH, glTF/GLB,
//! recordings, config files, VMC/OSC datagrams, the binary pose frame, HTTP request heads (with
//! the access rules) and a client's WebSocket byte stream (frames and the control messages in
//! them). Each mutates a seed
//! corpus (the shared test data and `recordings/` when present, plus valid inputs made here)
//! for `RIGCAST_FUZZ_SECS` seconds (default 10; CI runs the default). A panic fails the test and
//! saves the input (see `rigcast_tests::fuzz`); crashes found become regression tests in
//! `server/tests/hostile_files.rs` and `tests/tests/hostile_*.rs`.
//!
//! A longer, coverage-guided hunt with a coverage report per target:
//! `scripts/fuzz-coverage.sh SECONDS_PER_TARGET`.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use rigcast_tests::fuzz::{budget, corpus, run};

// Inert unless the build is instrumented (see `rigcast_tests::coverage`).
rigcast_tests::sancov_hooks!();

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
            Ok(file) => {
                let config = rigcast_server::ServerConfig::from_file(file);
                if let Ok(c) = &config {
                    // What a valid config sets, the server must be able to start with.
                    let stall = c.limits.stalled_client_timeout_secs;
                    std::time::Duration::try_from_secs_f64(stall).unwrap();
                    if let Some(cluster) = &c.cluster {
                        cluster.lost_after();
                    }
                }
                outcome(config)
            }
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

/// Request heads as clients send them: the WebSocket upgrade (with a token, an origin), the
/// status, a model and a viewer file.
fn head_seeds() -> Vec<Vec<u8>> {
    [
        "GET /v1/stream HTTP/1.1\r\nHost: 127.0.0.1:9000\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        "GET /v1/stream?token=0123456789abcdef0123 HTTP/1.1\r\nHost: localhost:9000\r\nOrigin: http://localhost:9000\r\nUpgrade: websocket\r\nSec-WebSocket-Key: x3JJHMbDL1EzLkh9GBhXDw==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        "GET /v1/status HTTP/1.1\r\nHost: studio.lan:9000\r\nAuthorization: Bearer 0123456789abcdef0123\r\nAccept: */*\r\n\r\n",
        "GET /v1/subjects/2/model.glb HTTP/1.1\r\nHost: [::1]:9000\r\nOrigin: http://localhost:3000\r\n\r\n",
        "GET /app.js?v=3#x HTTP/1.1\r\nHost: a.localhost\r\n\r\n",
    ]
    .iter()
    .map(|h| h.as_bytes().to_vec())
    .collect()
}

#[test]
fn fuzz_http_head() {
    use rigcast_server::access::{AccessPolicy, BindScope};
    let token = rigcast_server::token::ControlToken::from_text("0123456789abcdef0123").unwrap();
    let policies = [BindScope::Loopback, BindScope::Network].map(|scope| {
        AccessPolicy::new(
            token.clone(),
            scope,
            &["http://localhost:3000/".to_string()],
            &["studio.lan".to_string()],
        )
    });
    run("http_head", &head_seeds(), budget(), false, |b| {
        // As the listener reads: the head ends at the first blank line.
        let Some(end) = b.windows(4).position(|w| w == b"\r\n\r\n") else {
            return "no blank line".into();
        };
        policies
            .iter()
            .map(
                |p| match rigcast_server::http::route_head(&b[..end + 4], p) {
                    Ok(r) => format!("{:?} {:?}", r.route, r.access),
                    Err((status, body)) => {
                        assert!(body.len() <= 512, "a {status} body of {} bytes", body.len());
                        format!("{status} {}", body.split(':').next().unwrap_or(""))
                    }
                },
            )
            .collect::<Vec<_>>()
            .join(" / ")
    });
}

/// A byte stream read from `input`; what the server writes back is kept aside.
struct Wire {
    input: std::io::Cursor<Vec<u8>>,
    output: Vec<u8>,
}

impl std::io::Read for Wire {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.input.read(buf)
    }
}

impl std::io::Write for Wire {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.output.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn fuzz_websocket_client_stream() {
    use tokio_tungstenite::tungstenite::protocol::{Role, WebSocket};
    use tokio_tungstenite::tungstenite::Message;
    // What a client sends after the upgrade: masked frames (a client's), control messages of
    // every kind, a ping, a binary message and a close.
    let mut client = WebSocket::from_raw_socket(
        Wire {
            input: std::io::Cursor::new(Vec::new()),
            output: Vec::new(),
        },
        Role::Client,
        None,
    );
    let texts = [
        r#"{"type":"subscribe","subjects":[0,3]}"#,
        r#"{"type":"ping","nonce":7}"#,
        r#"{"type":"set_protocol","version":2}"#,
        r#"{"type":"set_mapping","subject":1,"overrides":{"Hips":"hips","LeftFoot":null}}"#,
        r#"{"type":"calibrate","subject":2,"pose":"n","delay_secs":3}"#,
        r#"{"type":"set_performer","subject":1,"foot_lock":true}"#,
    ];
    let mut seeds = Vec::new();
    for text in texts {
        client.send(Message::text(text)).unwrap();
        seeds.push(std::mem::take(&mut client.get_mut().output));
    }
    client.send(Message::Ping(vec![1, 2, 3].into())).unwrap();
    client.send(Message::Binary(vec![0; 40].into())).unwrap();
    client.send(Message::text(texts[1])).unwrap();
    client.close(None).unwrap();
    client.flush().unwrap_or(());
    seeds.push(std::mem::take(&mut client.get_mut().output));
    let config = rigcast_server::http::websocket_config();
    run("websocket", &seeds, budget(), false, |b| {
        let wire = Wire {
            input: std::io::Cursor::new(b.to_vec()),
            output: Vec::new(),
        };
        let mut server = WebSocket::from_raw_socket(wire, Role::Server, Some(config));
        let mut outcome = Vec::new();
        // Bounded: a stream of many tiny frames could otherwise take long.
        for _ in 0..64 {
            match server.read() {
                Ok(Message::Text(t)) => {
                    outcome.push(match rigcast_protocol::control::parse_client_message(&t) {
                        Ok(_) => "message".to_string(),
                        Err(e) => format!("{:?}", e.code),
                    })
                }
                Ok(m) => outcome.push(format!("{:?}", std::mem::discriminant(&m))),
                Err(e) => {
                    outcome.push(e.to_string());
                    break;
                }
            }
        }
        assert!(
            server.get_ref().output.len() <= b.len() + 1024,
            "the server wrote {} bytes for {} read",
            server.get_ref().output.len(),
            b.len()
        );
        outcome.join(" ")
    });
}
