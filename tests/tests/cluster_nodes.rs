//! Cluster mode between nodes, through a real `nats-server`: control requests about another
//! node's subject are carried out by that node (with the deployment's control token checked
//! there too); nodes that start later are found by the ones already running, and a node that
//! stops cleanly makes its subjects lost elsewhere at once.
//!
//! - Node A has the bundled walk; node B retargets it onto the built-in mannequin; node C
//!   relays both (and has a walk of its own); all three hold the same token file. Node D relays too but holds another
//!   token.
//! - A `set_mapping` sent to C about `mannequin@b` must change B's mapping (seen by a client
//!   on B), be acknowledged with C's subject id, and B's own refusals (an unknown bone) must
//!   come back to the client on C. Without a token C refuses; D's token is refused by B.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use rigcast_protocol::control::MappingEntry;
use rigcast_protocol::{ErrorCode, ServerMessage, SourceState};
use rigcast_tests::nats::{
    client_with, frames_equal, frames_of, one_nats_server, spawn_node_with_token, wait_state,
    wait_subject,
};
use rigcast_tests::{next_json, send_text, Ws};

const TOKEN: &str = "deployment-token-0123456789abcdef";
const OTHER_TOKEN: &str = "another-deployment-0123456789abc";

/// The next `mapping` message about `subject` within `timeout`.
async fn next_mapping(ws: &mut Ws, subject: u32, timeout: Duration) -> Option<Vec<MappingEntry>> {
    let end = tokio::time::Instant::now() + timeout;
    while let Some(left) = end.checked_duration_since(tokio::time::Instant::now()) {
        match next_json(ws, left).await? {
            ServerMessage::Mapping {
                subject: s,
                entries,
                ..
            } if s == subject => return Some(entries),
            _ => {}
        }
    }
    None
}

/// The next `ack` or `error` (the answer to a request) within `timeout`.
async fn answer(ws: &mut Ws, timeout: Duration) -> Option<ServerMessage> {
    let end = tokio::time::Instant::now() + timeout;
    while let Some(left) = end.checked_duration_since(tokio::time::Instant::now()) {
        let m = next_json(ws, left).await?;
        if matches!(m, ServerMessage::Ack { .. } | ServerMessage::Error { .. }) {
            return Some(m);
        }
    }
    None
}

fn set_mapping(subject: u32, bone: &str) -> String {
    serde_json::json!({"type": "set_mapping", "subject": subject, "overrides": {bone: null}})
        .to_string()
}

fn error_code(m: &ServerMessage) -> Option<(ErrorCode, String)> {
    match m {
        ServerMessage::Error { code, message, .. } => Some((*code, message.clone())),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn control_requests_are_carried_out_by_the_owning_node() {
    let Some(nats) = one_nats_server().await else {
        return;
    };
    let args = |site: &str, extra: &[&str]| -> Vec<String> {
        let mut v = vec!["--nats".into(), nats.urls(), "--site".into(), site.into()];
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let a = spawn_node_with_token(args("a", &["--source", "demo"]), "ctl-a", Some(TOKEN)).await;
    let b_args = args("b", &["--target", "builtin:mannequin"]);
    let b = spawn_node_with_token(b_args, "ctl-b", Some(TOKEN)).await;
    // A source of its own shifts C's ids away from B's.
    let c_args = args("c", &["--source", "demo"]);
    let c = spawn_node_with_token(c_args, "ctl-c", Some(TOKEN)).await;
    let d = spawn_node_with_token(args("d", &[]), "ctl-d", Some(OTHER_TOKEN)).await;

    let (mut wb, sb) = client_with(&b, Some(TOKEN)).await;
    let (mut wc, sc) = client_with(&c, Some(TOKEN)).await;
    let on_b = sb["mannequin"].id;
    let on_c = sc["mannequin@b"].id;
    assert_ne!(on_b, on_c, "the test needs ids that differ between nodes");
    let before = next_mapping(&mut wb, on_b, Duration::from_secs(5))
        .await
        .expect("B's mapping of its mannequin");
    let bone = before
        .iter()
        .find(|e| e.source.is_some())
        .expect("a mapped bone")
        .target
        .clone();

    // Through C: acknowledged with C's id, carried out on B.
    send_text(&mut wc, &set_mapping(on_c, &bone)).await;
    let ack = answer(&mut wc, Duration::from_secs(3)).await;
    println!("set_mapping via C: {ack:?}");
    assert_eq!(
        ack,
        Some(ServerMessage::Ack {
            request: "set_mapping".into(),
            subject: on_c
        })
    );
    let after = next_mapping(&mut wb, on_b, Duration::from_secs(5))
        .await
        .expect("B re-maps");
    let entry = after.iter().find(|e| e.target == bone).unwrap();
    assert_eq!(entry.source, None, "{bone} still mapped on B: {entry:?}");

    // B's own checks answer the client on C.
    send_text(&mut wc, &set_mapping(on_c, "no_such_bone")).await;
    let refused = answer(&mut wc, Duration::from_secs(3)).await.unwrap();
    let (code, message) = error_code(&refused).expect("an error");
    println!("unknown bone via C: {message}");
    assert_eq!(code, ErrorCode::Unsupported);
    assert!(message.contains("no_such_bone"), "{message}");

    // A source's owner answers too (forwarded to A, not B).
    let demo_c = sc["demo@a"].id;
    let foot_lock =
        serde_json::json!({"type": "set_performer", "subject": demo_c, "foot_lock": true});
    send_text(&mut wc, &foot_lock.to_string()).await;
    let (code, message) =
        error_code(&answer(&mut wc, Duration::from_secs(3)).await.unwrap()).expect("an error");
    println!("set_performer on A's source via C: {message}");
    assert_eq!(code, ErrorCode::Unsupported);
    assert!(message.contains("is a source"), "{message}");

    // Without the token C itself refuses.
    let (mut anon, _) = client_with(&c, None).await;
    send_text(&mut anon, &set_mapping(on_c, &bone)).await;
    let (code, _) =
        error_code(&answer(&mut anon, Duration::from_secs(3)).await.unwrap()).expect("an error");
    assert_eq!(code, ErrorCode::Unauthorized);

    // D holds another deployment's token: D accepts its client, B refuses D.
    let (mut wd, sd) = client_with(&d, Some(OTHER_TOKEN)).await;
    send_text(&mut wd, &set_mapping(sd["mannequin@b"].id, &bone)).await;
    let (code, message) =
        error_code(&answer(&mut wd, Duration::from_secs(3)).await.unwrap()).expect("an error");
    println!("via D (other token): {message}");
    assert_eq!(code, ErrorCode::Unauthorized);
    assert!(message.contains("node b refused"), "{message}");
    // And B did not re-map for it.
    assert!(
        next_mapping(&mut wb, on_b, Duration::from_millis(700))
            .await
            .is_none(),
        "B re-mapped for a refused request"
    );
    // Each node counted its part: C forwarded 2 requests to B, B served them and refused D's.
    let (on_b_status, on_c_status) = (cluster_status(&b).await, cluster_status(&c).await);
    println!("B: {on_b_status}\nC: {on_c_status}");
    assert_eq!(on_b_status["control_served"], 2);
    assert_eq!(on_b_status["control_refused"], 1);
    assert_eq!(on_c_status["control_forwarded"], 3);

    // The owner gone: a short error, not a hang.
    drop(a);
    let started = std::time::Instant::now();
    send_text(&mut wc, &foot_lock.to_string()).await;
    let (code, message) =
        error_code(&answer(&mut wc, Duration::from_secs(5)).await.unwrap()).expect("an error");
    println!("A gone: {message} after {:?}", started.elapsed());
    assert_eq!(code, ErrorCode::Internal);
    assert!(message.contains("node a"), "{message}");
    assert!(started.elapsed() <= Duration::from_secs(3));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn nodes_that_start_later_are_found_and_a_clean_stop_is_a_loss() {
    let Some(nats) = one_nats_server().await else {
        return;
    };
    let args = |site: &str| -> Vec<String> {
        ["--nats", &nats.urls(), "--site", site, "--source", "demo"]
            .map(String::from)
            .to_vec()
    };
    // W runs first and knows nothing of A.
    let w = spawn_node_with_token(args("w"), "disc-w", None).await;
    let (mut ww, sw) = client_with(&w, None).await;
    assert!(!sw.contains_key("demo@a"), "{:?}", sw.keys());

    // A starts later: W finds its subject while running and streams it as A does.
    let a = spawn_node_with_token(args("a"), "disc-a", None).await;
    let id = wait_subject(&mut ww, "demo@a", Duration::from_secs(5))
        .await
        .expect("W announces A's subject");
    let (mut wa, sa) = client_with(&a, None).await;
    let (on_w, on_a) = tokio::join!(
        frames_of(&mut ww, id, 2.0),
        frames_of(&mut wa, sa["demo"].id, 2.0)
    );
    let matched = frames_equal(&on_a, &on_w, "demo@a on W");
    println!(
        "demo@a found on W: {matched} of {} frames equal to A's",
        on_w.len()
    );
    assert!(matched >= 30, "only {matched} frames matched A's");
    let (_, status) = rigcast_tests::http_get(w.addr, "/v1/status").await;
    let status: serde_json::Value = serde_json::from_str(&status).unwrap();
    assert_eq!(
        status["cluster"]["subjects_discovered"], 1,
        "{}",
        status["cluster"]
    );

    // A stops cleanly (Ctrl-C): it removes its entries, and W says so at once.
    // SAFETY: kill(2) on a child process id this test started.
    assert_eq!(unsafe { libc::kill(a.pid() as i32, libc::SIGINT) }, 0);
    let lost = wait_state(&mut ww, id, SourceState::Lost, "", Duration::from_secs(3)).await;
    println!("A stopped: {lost:?}");
    let (detail, after) = lost.expect("lost on W");
    assert!(detail.contains("removed"), "{detail}");
    assert!(after <= Duration::from_secs(2), "{after:?}");
    drop(a);

    // A again: the same subject on W is live again, not a second one.
    let a = spawn_node_with_token(args("a"), "disc-a", None).await;
    let live = wait_state(&mut ww, id, SourceState::Live, "", Duration::from_secs(5)).await;
    println!("A restarted: {live:?}");
    assert!(live.is_some());
    let (_, sw) = client_with(&w, None).await;
    let relayed: Vec<&String> = sw.keys().filter(|n| n.ends_with("@a")).collect();
    assert_eq!(relayed, vec!["demo@a"]);
    drop(a);
}

/// The `cluster` part of a node's `/v1/status`.
async fn cluster_status(p: &rigcast_tests::ServeProcess) -> serde_json::Value {
    let (_, body) = rigcast_tests::http_get(p.addr, "/v1/status").await;
    let status: serde_json::Value = serde_json::from_str(&body).unwrap();
    status["cluster"].clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_mapping_computed_on_one_node_is_taken_by_the_next() {
    let Some(nats) = one_nats_server().await else {
        return;
    };
    // Same walk onto the same character on both nodes; no disk cache, so only the
    // cluster's cache can spare B the computation.
    let args = |site: &str| -> Vec<String> {
        let mut v: Vec<String> = ["--nats", &nats.urls(), "--site", site]
            .map(String::from)
            .to_vec();
        v.extend(
            [
                "--source",
                "demo",
                "--target",
                "builtin:mannequin",
                "--no-mapping-cache",
            ]
            .map(String::from),
        );
        v
    };
    let a = spawn_node_with_token(args("a"), "map-a", None).await;
    let on_a = cluster_status(&a).await;
    println!("A: {on_a}");
    assert_eq!(on_a["mappings_shared"], 1);
    assert_eq!(on_a["mappings_from_cluster"], 0);

    let b = spawn_node_with_token(args("b"), "map-b", None).await;
    let on_b = cluster_status(&b).await;
    println!("B: {on_b}");
    assert_eq!(on_b["mappings_from_cluster"], 1);
    assert_eq!(on_b["mappings_shared"], 0);

    // And B's performer runs on A's table.
    let (mut wa, sa) = client_with(&a, None).await;
    let (mut wb, sb) = client_with(&b, None).await;
    let ma = next_mapping(&mut wa, sa["mannequin"].id, Duration::from_secs(5)).await;
    let mb = next_mapping(&mut wb, sb["mannequin"].id, Duration::from_secs(5)).await;
    let pairs = |m: Option<Vec<MappingEntry>>| -> Vec<(String, Option<String>)> {
        m.expect("a mapping")
            .into_iter()
            .map(|e| (e.target, e.source))
            .collect()
    };
    assert_eq!(pairs(ma), pairs(mb));
}
