//! VMC input through the real server: it listens on loopback unless configured otherwise,
//! decodes only allowed senders when given a list, and rate-limits skeleton changes so a
//! sender churning skeletons cannot force a re-map per packet.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use rigcast_protocol::vmc::VmcEncoder;
use rigcast_protocol::ServerMessage;
use rigcast_server::config::FileConfig;
use rigcast_server::{PerformerSpec, ServerConfig, SourceSpec};
use rigcast_tests::*;

/// Sends the procedural humanoid's frames from `from` to `to` for `secs` at ~100 Hz;
/// with `churn`, every other frame moves one bone's offset by 2 cm (a new skeleton).
fn send_for(from: &str, to: SocketAddr, secs: f32, churn: bool) {
    let clip = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let names = clip.skeleton.names().to_vec();
    let socket = UdpSocket::bind(from).unwrap();
    let mut enc = VmcEncoder::new();
    let t0 = Instant::now();
    let mut k = 0usize;
    while t0.elapsed().as_secs_f32() < secs {
        let mut pose = clip.poses[k % clip.poses.len()].clone();
        if churn && k % 2 == 1 {
            pose.translations[3].x += 0.02;
        }
        rigcast_tests::send_vmc_pose(
            &socket,
            to,
            &mut enc,
            &names,
            &pose,
            t0.elapsed().as_secs_f32(),
        );
        k += 1;
        std::thread::sleep(Duration::from_millis(10));
    }
}

async fn status(addr: SocketAddr) -> serde_json::Value {
    let (_, body) = http_get(addr, "/v1/status").await;
    serde_json::from_str(&body).unwrap()
}

fn vmc(port: u16, allowed: &[&str], name: &str) -> SourceSpec {
    SourceSpec::Vmc(rigcast_server::config::VmcSpec {
        allowed_senders: allowed.iter().map(|a| a.parse().unwrap()).collect(),
        lost_after_secs: Some(5.0),
        name: Some(name.into()),
        ..rigcast_server::config::VmcSpec::loopback(port)
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vmc_input_listens_on_loopback_by_default() {
    // As written in a config file without a `bind`, and as `--source vmc:0`.
    let file: FileConfig = toml_config("[[sources]]\nkind = \"vmc\"\nport = 0\n");
    let mut config = ServerConfig::from_file(file).unwrap();
    config
        .sources
        .push("vmc:0".parse::<rigcast_server::SourceSpec>().unwrap());
    config.listen = "127.0.0.1:0".parse().unwrap();
    config.mapping_cache_dir = None;
    let server = rigcast_server::start(config).await.unwrap();
    let s = status(server.local_addr()).await;
    for subject in s["subjects"].as_array().unwrap() {
        let listen: SocketAddr = subject["listen"].as_str().unwrap().parse().unwrap();
        assert_eq!(listen.ip().to_string(), "127.0.0.1", "{subject}");
    }
    assert_eq!(s["subjects"].as_array().unwrap().len(), 2);
    server.shutdown().await;
}

fn toml_config(text: &str) -> FileConfig {
    let path = temp_path("rigcast.toml");
    std::fs::write(&path, text).unwrap();
    FileConfig::load(&path).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_allowed_senders_drive_a_source() {
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![vmc(0, &["127.0.0.2"], "guarded")],
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr = server.local_addr();
    let to = server.state().subjects()[0].listen_addr.unwrap();
    // 127.0.0.1 is not on the list: counted and dropped, the source stays connecting.
    tokio::task::spawn_blocking(move || send_for("127.0.0.1:0", to, 0.6, false))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let s = status(addr).await;
    let health = &s["subjects"][0]["source"];
    assert_eq!(health["state"], "connecting", "{health}");
    assert!(health["dropped"].as_u64().unwrap() >= 20, "{health}");
    assert!(
        health["detail"]
            .as_str()
            .unwrap()
            .contains("allowed_senders"),
        "{health}"
    );
    assert_eq!(s["subjects"][0]["input_frames"], 0);
    // From 127.0.0.2 (also loopback, but the listed address) it is decoded.
    tokio::task::spawn_blocking(move || send_for("127.0.0.2:0", to, 0.6, false))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let s = status(addr).await;
    assert_eq!(
        s["subjects"][0]["source"]["state"], "live",
        "{}",
        s["subjects"][0]
    );
    assert!(s["subjects"][0]["input_frames"].as_u64().unwrap() >= 20);
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_skeleton_changes_is_rate_limited() {
    let server = rigcast_server::start(ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![vmc(0, &[], "churn")],
        performers: vec![PerformerSpec::target_file("builtin:mannequin")],
        ..ServerConfig::default()
    })
    .await
    .unwrap();
    let addr = server.local_addr();
    let to = server.state().subjects()[0].listen_addr.unwrap();
    let mut ws = connect(&server.stream_url()).await;
    handshake(&mut ws).await;
    // A new skeleton every other frame, ~50 changes a second, for 3 s.
    let sender = tokio::task::spawn_blocking(move || send_for("127.0.0.1:0", to, 3.0, true));
    let mut skeleton_messages = 0;
    let mut mapping_messages = 0;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(3500) {
        match next(&mut ws, Duration::from_secs(1)).await {
            Some(Incoming::Json(ServerMessage::Skeleton { subject: 0, .. })) => {
                skeleton_messages += 1
            }
            Some(Incoming::Json(ServerMessage::Mapping { .. })) => mapping_messages += 1,
            Some(_) => {}
            None => break,
        }
    }
    sender.await.unwrap();
    let s = status(addr).await;
    let changes = s["subjects"][0]["skeleton_changes"].as_u64().unwrap();
    let limited = s["subjects"][0]["skeleton_frames_limited"]
        .as_u64()
        .unwrap();
    eprintln!(
        "3 s of skeleton churn: {changes} changes applied, {limited} frames held back, \
         {skeleton_messages} skeleton and {mapping_messages} mapping messages"
    );
    // At most one change a second (plus the first), instead of ~150.
    assert!(
        (2..=5).contains(&changes),
        "{changes} skeleton changes applied"
    );
    assert!(limited >= 50, "only {limited} frames held back");
    assert!(
        skeleton_messages <= 5 && mapping_messages <= 6,
        "{skeleton_messages} / {mapping_messages}"
    );
    server.shutdown().await;
}
