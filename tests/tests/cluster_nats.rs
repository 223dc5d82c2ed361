//! Cluster mode through real NATS: a 3-server `nats-server` cluster (JetStream on) on
//! loopback and three `rigcast serve` nodes.
//!
//! - Node A has a replay source (the bundled walk) and a VMC source fed by this test.
//! - Node B retargets A's walk onto the built-in mannequin (its performer runs where its
//!   character is, driven by A's source through NATS).
//! - Node C has nothing of its own and relays everything.
//!
//! Clients on B and C must get A's subjects with the rotations a direct client on A gets
//! (1e-6, matched by seq) and in order; C must get B's character like B's own clients; killing
//! A must make B and C report A's sources lost within 1 s, restarting it live again within
//! 2 s; killing one NATS server must not stop the streams.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigcast_protocol::vmc::VmcEncoder;
use rigcast_protocol::SourceState;
use rigcast_tests::nats::{
    client, config_file, frames_equal, nats_server, spawn_node, wait_state, NatsCluster,
};
use rigcast_tests::{free_port, next, temp_path, Incoming, Ws};

/// Sends a gently moving humanoid over VMC until stopped.
fn vmc_sender(port: u16, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let skeleton = rigcast_sources::live::humanoid::default_humanoid().unwrap();
        let names: Vec<String> = skeleton.names().to_vec();
        let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut enc = VmcEncoder::new();
        let start = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let t = start.elapsed().as_secs_f32();
            let mut pose = skeleton.rest_pose();
            for r in pose.rotations.iter_mut().skip(1) {
                *r = glam::Quat::from_rotation_x(0.3 * (2.0 * t).sin());
            }
            let to = std::net::SocketAddr::from(([127, 0, 0, 1], port));
            rigcast_tests::send_vmc_pose(&socket, to, &mut enc, &names, &pose, t);
            std::thread::sleep(Duration::from_millis(16));
        }
    })
}

/// Per subject id: (seq, rotations) of every frame received for `secs`.
type Frames = HashMap<u32, Vec<(u64, Vec<glam::Quat>)>>;

async fn collect(ws: &mut Ws, secs: f64) -> Frames {
    let mut out: Frames = HashMap::new();
    let end = Instant::now() + Duration::from_secs_f64(secs);
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match next(ws, left).await {
            Some(Incoming::Frame(f, _)) => out
                .entry(f.header.subject)
                .or_default()
                .push((f.header.seq, f.rotations)),
            Some(Incoming::Json(_)) => {}
            None => break,
        }
    }
    out
}

/// Asserts that B and C (in that order) both got there within `limit`.
fn all_within(after: [Option<Duration>; 2], limit: Duration) {
    for (node, after) in ["B", "C"].iter().zip(after) {
        assert!(after.is_some_and(|d| d <= limit), "{node}: {after:?}");
    }
}

/// Waits on two clients at once (5 s at most) for their subject to reach `state`; how long
/// each took.
async fn on_both(
    wb: &mut Ws,
    b: u32,
    wc: &mut Ws,
    c: u32,
    state: SourceState,
) -> [Option<Duration>; 2] {
    let limit = Duration::from_secs(5);
    let (on_b, on_c) = tokio::join!(
        wait_state(wb, b, state, "", limit),
        wait_state(wc, c, state, "", limit)
    );
    [on_b.map(|(_, d)| d), on_c.map(|(_, d)| d)]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn three_nodes_share_subjects_through_a_nats_cluster() {
    let Some(bin) = nats_server() else { return };
    let mut nats = tokio::task::spawn_blocking(move || NatsCluster::start(&bin))
        .await
        .unwrap();
    let urls = nats.urls();
    let vmc_port = free_port();
    let stop = Arc::new(AtomicBool::new(false));
    let sender = vmc_sender(vmc_port, stop.clone());
    let cluster_args = |site: &str| -> Vec<String> {
        vec!["--nats".into(), urls.clone(), "--site".into(), site.into()]
    };
    let mut a_args = cluster_args("a");
    a_args.extend(["--source", "demo", "--source"].map(String::from));
    a_args.push(format!("vmc:{vmc_port}"));
    let a = spawn_node(a_args.clone(), "a").await;
    let vmc_name = format!("vmc:{vmc_port}");
    // A's VMC source goes live before B and C start, so its skeleton is the sender's.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut b_args = cluster_args("b");
    b_args.extend(["--target", "builtin:mannequin"].map(String::from));
    let b = spawn_node(b_args, "b").await;
    let c = spawn_node(cluster_args("c"), "c").await;

    let (mut wa, sa) = client(&a).await;
    let (mut wb, sb) = client(&b).await;
    let (mut wc, sc) = client(&c).await;
    println!("A: {:?}\nB: {:?}\nC: {:?}", sa.keys(), sb.keys(), sc.keys());
    for name in ["demo", vmc_name.as_str()] {
        let relayed = format!("{name}@a");
        assert!(
            sb.contains_key(&relayed),
            "B lacks {relayed}: {:?}",
            sb.keys()
        );
        assert!(
            sc.contains_key(&relayed),
            "C lacks {relayed}: {:?}",
            sc.keys()
        );
    }
    assert!(
        sc.contains_key("mannequin@b"),
        "C lacks B's character: {:?}",
        sc.keys()
    );

    // Same rotations as a direct client on the origin node, in order.
    let (fa, fb, fc) = tokio::join!(
        collect(&mut wa, 2.5),
        collect(&mut wb, 2.5),
        collect(&mut wc, 2.5)
    );
    for name in ["demo", vmc_name.as_str()] {
        let relayed = format!("{name}@a");
        let origin = &fa[&sa[name].id];
        for (label, frames, subjects) in [("B", &fb, &sb), ("C", &fc, &sc)] {
            let got = &frames[&subjects[&relayed].id];
            let n = frames_equal(origin, got, &format!("{relayed} on {label}"));
            println!(
                "{relayed} on {label}: {n} frames equal to A's (of {})",
                got.len()
            );
            assert!(n >= 30, "{relayed} on {label}: only {n} frames matched A's");
        }
    }
    let n = frames_equal(
        &fb[&sb["mannequin"].id],
        &fc[&sc["mannequin@b"].id],
        "mannequin@b on C",
    );
    println!("mannequin@b on C: {n} frames equal to B's");
    assert!(n >= 30, "mannequin@b on C: only {n} frames matched B's");

    // Node A goes away: its sources are lost on B and C within 1 s.
    let demo_b = sb["demo@a"].id;
    let demo_c = sc["demo@a"].id;
    drop(a);
    let lost = on_both(&mut wb, demo_b, &mut wc, demo_c, SourceState::Lost).await;
    println!("A killed: lost on B and C after {lost:?}");
    all_within(lost, Duration::from_secs(1));

    // A comes back: live again on B and C within 2 s of it serving.
    let a = spawn_node(a_args, "a").await;
    let live = on_both(&mut wb, demo_b, &mut wc, demo_c, SourceState::Live).await;
    println!("A restarted: live on B and C after {live:?}");
    all_within(live, Duration::from_secs(2));

    // One NATS server dies: the streams go on (clients fail over to the others).
    nats.kill(0);
    // Reading on meanwhile: a client that stops reading is sent its backlog later.
    tokio::join!(collect(&mut wb, 3.0), collect(&mut wc, 3.0));
    let (fb, fc) = tokio::join!(collect(&mut wb, 1.0), collect(&mut wc, 1.0));
    let count = |f: &Frames, id: u32| f.get(&id).map_or(0, Vec::len);

    println!(
        "after losing a NATS server: {} frames of demo@a on B, {} on C in 1 s",
        count(&fb, demo_b),
        count(&fc, demo_c)
    );
    // The tick rate (60 Hz), give or take scheduling.
    for n in [count(&fb, demo_b), count(&fc, demo_c)] {
        assert!((30..=90).contains(&n), "{n} frames in 1 s");
    }
    stop.store(true, Ordering::Relaxed);
    sender.join().unwrap();
    drop(a);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn credentials_are_required_and_namespaces_keep_deployments_apart() {
    let Some(bin) = nats_server() else { return };
    let port = free_port();
    let store = temp_path("nats-auth");
    std::fs::create_dir_all(&store).unwrap();
    let server = Command::new(&bin)
        .args(["-a", "127.0.0.1", "-p", &port.to_string(), "--user", "rig"])
        .args(["--pass", "s3cret", "-js", "-sd"])
        .arg(&store)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _server = rigcast_tests::KillOnDrop(server);
    let config = |ns: &str, site: &str, password: &str| {
        format!(
            "[cluster]\nservers = [\"nats://127.0.0.1:{port}\"]\nsite = \"{site}\"\n\
             namespace = \"{ns}\"\nuser = \"rig\"\npassword = \"{password}\"\n"
        )
    };
    // JetStream takes a moment after the port opens.
    tokio::time::sleep(Duration::from_secs(1)).await;

    // Wrong password: a short, clear refusal, not a hang.
    let bad = config_file("bad", &config("one", "a", "wrong"));
    let rigcast = tokio::task::spawn_blocking(rigcast_tests::rigcast_binary)
        .await
        .unwrap();
    let started = Instant::now();
    let out = tokio::task::spawn_blocking(move || {
        Command::new(rigcast)
            .args(["serve", "--listen", "127.0.0.1:0", "--config"])
            .arg(&bad)
            .output()
            .unwrap()
    })
    .await
    .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    println!("wrong password: {err}");
    assert!(!out.status.success());
    assert!(err.contains("cannot connect to NATS"), "{err}");
    assert!(err.len() < 600, "error too long: {err}");
    assert!(
        started.elapsed() < Duration::from_secs(15),
        "refused only after {:?}",
        started.elapsed()
    );

    // Right password, two namespaces on one NATS system: B does not see A's subjects.
    let one = config_file("one", &config("one", "a", "s3cret"));
    let two = config_file("two", &config("two", "b", "s3cret"));
    let a_args = vec!["--config".to_string(), one.display().to_string()];
    let a = spawn_node(a_args, "auth-a").await;
    let b_args = vec!["--config".to_string(), two.display().to_string()];
    let b = spawn_node(b_args, "auth-b").await;
    let (_wa, sa) = client(&a).await;
    let (_wb, sb) = client(&b).await;
    println!(
        "namespace one: {:?}; namespace two: {:?}",
        sa.keys(),
        sb.keys()
    );
    assert!(sa.contains_key("demo"));
    assert!(
        sb.keys().all(|n| !n.ends_with("@a")),
        "namespace two sees namespace one: {:?}",
        sb.keys()
    );
    // The same namespace does.
    let c_conf = config_file("one-c", &config("one", "c", "s3cret"));
    let c = spawn_node(
        vec!["--config".into(), c_conf.display().to_string()],
        "auth-c",
    )
    .await;
    let (_wc, sc) = client(&c).await;
    assert!(sc.contains_key("demo@a"), "{:?}", sc.keys());
}
