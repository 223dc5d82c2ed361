//! Cluster liveness through a real `nats-server`, for the cases a clean stop does not cover:
//!
//! - A node killed with SIGKILL removes nothing: its entries must age out. The node relaying
//!   its subject says the source is lost at once (no frames), then that "its node stopped
//!   answering" once the entry is past its age; a node started after that does not list the
//!   dead node's subject at all; the dead node started again is live again on both.
//! - A performer may name another node's subject before that node publishes it: it waits,
//!   saying for what, and starts driving its character when the subject appears.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use rigcast_protocol::SourceState;
use rigcast_tests::nats::{
    client, config_file, frames_of, one_nats_server, spawn_node, wait_state, wait_subject,
};
use rigcast_tests::{ServeProcess, Ws};

/// How long an entry lives without a re-put (the server's bucket max age is 5 s), plus slack
/// for the heartbeat period and scheduling.
const AGE_OUT: Duration = Duration::from_secs(9);

/// Sequence numbers of subject `id`'s frames received for `secs`.
async fn seqs_of(ws: &mut Ws, id: u32, secs: f64) -> Vec<u64> {
    let frames = frames_of(ws, id, secs).await;
    frames.into_iter().map(|(seq, _)| seq).collect()
}

/// The largest difference of any rotation component between the first frame and any other.
fn motion(frames: &[(u64, Vec<glam::Quat>)]) -> f32 {
    let Some((_, first)) = frames.first() else {
        return 0.0;
    };
    let diff = |r: &Vec<glam::Quat>| {
        first
            .iter()
            .zip(r)
            .map(|(a, b)| {
                (glam::Vec4::from(*a) - glam::Vec4::from(*b))
                    .abs()
                    .max_element()
            })
            .fold(0.0, f32::max)
    };
    frames.iter().map(|(_, r)| diff(r)).fold(0.0, f32::max)
}

/// A node's `/v1/status` as JSON.
async fn status(p: &ServeProcess) -> serde_json::Value {
    let (_, body) = rigcast_tests::http_get(p.addr, "/v1/status").await;
    serde_json::from_str(&body).unwrap()
}

/// The source health in `status` of subject `name`.
fn source_entry<'a>(status: &'a serde_json::Value, name: &str) -> Option<&'a serde_json::Value> {
    let subject = status["subjects"]
        .as_array()?
        .iter()
        .find(|s| s["name"] == name)?;
    Some(&subject["source"])
}

fn cluster_args(urls: &str, site: &str, rest: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = ["--nats", urls, "--site", site].map(String::from).to_vec();
    args.extend(rest.iter().map(|s| s.to_string()));
    args
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_node_ages_out_and_comes_back() {
    let Some(nats) = one_nats_server().await else {
        return;
    };
    let urls = nats.urls();
    let a_args = cluster_args(&urls, "a", &["--source", "demo"]);
    let a = spawn_node(a_args.clone(), "live-a").await;
    let w = spawn_node(cluster_args(&urls, "w", &[]), "live-w").await;
    let (mut ww, sw) = client(&w).await;
    let id = sw.get("demo@a").expect("W relays A's walk").id;
    assert!(
        seqs_of(&mut ww, id, 1.0).await.len() >= 30,
        "W streams demo@a"
    );

    // SIGKILL: A removes nothing. W sees the frames stop at once...
    drop(a);
    let lost = wait_state(&mut ww, id, SourceState::Lost, "", Duration::from_secs(3)).await;
    println!("A killed: lost on W {lost:?}");
    assert!(lost.is_some_and(|(_, after)| after <= Duration::from_secs(1)));
    // ...and, once A's entry is past its age, that A stopped answering.
    let expired = wait_state(&mut ww, id, SourceState::Lost, "stopped answering", AGE_OUT).await;
    println!("A's entry aged out on W: {expired:?}");
    assert!(expired.is_some(), "W never said A stopped answering");

    // A node started now does not list the dead node's subject.
    let f = spawn_node(cluster_args(&urls, "f", &[]), "live-f").await;
    let (mut wf, sf) = client(&f).await;
    println!("F, started after A died: {:?}", sf.keys());
    assert!(!sf.contains_key("demo@a"), "{:?}", sf.keys());
    assert_eq!(status(&f).await["cluster"]["subjects_discovered"], 0);

    // A again: live on W (the same subject) and found by F, streaming.
    let a = spawn_node(a_args, "live-a").await;
    let live = wait_state(&mut ww, id, SourceState::Live, "", Duration::from_secs(5)).await;
    println!("A restarted: live on W {live:?}");
    assert!(live.is_some_and(|(_, after)| after <= Duration::from_secs(2)));
    let on_f = wait_subject(&mut wf, "demo@a", Duration::from_secs(5))
        .await
        .expect("F finds A's subject");
    let (on_w, on_f) = tokio::join!(seqs_of(&mut ww, id, 1.5), seqs_of(&mut wf, on_f, 1.5));
    println!(
        "after the restart: {} frames on W, {} on F",
        on_w.len(),
        on_f.len()
    );
    for seqs in [&on_w, &on_f] {
        assert!(seqs.len() >= 30, "{} frames in 1.5 s", seqs.len());
        // Non-decreasing: a tick between two source frames sends the latest one again.
        assert!(
            seqs.windows(2).all(|p| p[0] <= p[1]),
            "out of order: {seqs:?}"
        );
    }
    drop(a);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_performer_waits_for_a_remote_subject_published_later() {
    let Some(nats) = one_nats_server().await else {
        return;
    };
    let urls = nats.urls();
    let servers: Vec<String> = urls.split(',').map(|u| format!("\"{u}\"")).collect();
    let body = format!(
        "[cluster]\nservers = [{}]\nsite = \"b\"\n\n\
         [[performers]]\nsource = \"demo@a\"\ntarget = \"builtin:mannequin\"\nname = \"puppet\"\n",
        servers.join(", ")
    );
    let config = config_file("liveness-b", &body);
    let b_args = vec!["--config".to_string(), config.display().to_string()];
    let b = spawn_node(b_args, "wait-b").await;

    // Before A exists: the performer's character is announced, its source waits, saying for
    // what, and the character does not move (it holds a rest pose, if it streams at all).
    let (mut wb, sb) = client(&b).await;
    println!("B before A: {:?}", sb.keys());
    let puppet = sb.get("puppet").expect("B announces its character").id;
    let st = status(&b).await;
    let waiting = source_entry(&st, "demo@a").expect("B lists the subject it waits for");
    println!("B waits: {waiting}");
    let detail = waiting["detail"].as_str().unwrap_or_default();
    assert!(detail.contains("waiting for node a"), "{detail}");
    assert_ne!(waiting["state"], "live");
    let before = frames_of(&mut wb, puppet, 1.0).await;
    println!(
        "puppet before A: {} frames, moving by {}",
        before.len(),
        motion(&before)
    );
    assert!(motion(&before) < 1e-4, "B's character moves with no source");

    // A starts: B's performer takes A's walk and its character moves.
    let started = Instant::now();
    let a = spawn_node(cluster_args(&urls, "a", &["--source", "demo"]), "wait-a").await;
    let mut after = Vec::new();
    while started.elapsed() < Duration::from_secs(10) && motion(&after) < 0.05 {
        after = frames_of(&mut wb, puppet, 1.0).await;
    }
    println!(
        "puppet on B: {} frames in the last second, moving by {}, {:?} after A started",
        after.len(),
        motion(&after),
        started.elapsed()
    );
    assert!(
        motion(&after) >= 0.05,
        "B's character did not move with A's walk"
    );
    assert!(after.len() >= 30, "{} frames in 1 s", after.len());
    let st = status(&b).await;
    let live = source_entry(&st, "demo@a").unwrap();
    assert_eq!(live["state"], "live", "{live}");
    drop(a);
}
