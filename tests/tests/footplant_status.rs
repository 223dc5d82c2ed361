//! Footplant state reaches clients (issue 13): the real server replays the CMU 131_01 walk
//! into the built-in mannequin (foot lock on by default for a humanoid), and `/v1/status`
//! lists the mannequin's two locked feet with their state, which changes as the performer
//! steps: over the clip's first 1.6 s (left foot swinging then planted from ~0.3 s to ~0.7 s,
//! right foot planted until ~1 s, then swinging) each foot is seen both planted and lifted.
//! With `foot_lock = false` the field is `null` (on the first labelled walk, found by its
//! motion). Skips when the shared data is absent.
#![allow(clippy::unwrap_used)]

use std::collections::HashSet;
use std::time::{Duration, Instant};

use rigcast_server::{PerformerSpec, ServerConfig};
use rigcast_tests::*;

/// The CMU 131_01 walk: the tests that watch its first seconds for both feet planting and
/// lifting depend on its timing (a walk that starts standing still shows no lift there), so
/// they name it until they watch for as long as the clip's own gait needs.
fn cmu_walk() -> Option<rigcast_retarget::Clip> {
    shared_clip(CMU_WALK)
}

/// The first labelled walk (found by its motion), for tests that need only a walker with legs.
fn a_walk() -> Option<rigcast_retarget::Clip> {
    Some(first_walk()?.1)
}

async fn start(
    clip: Option<rigcast_retarget::Clip>,
    foot_lock: Option<bool>,
) -> Option<rigcast_server::ServerHandle> {
    let clip = clip?;
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: 60.0,
        sources: vec![clip_source(clip)],
        performers: vec![PerformerSpec {
            foot_lock,
            ..PerformerSpec::target_file("builtin:mannequin")
        }],
        ..ServerConfig::default()
    };
    Some(rigcast_server::start(config).await.unwrap())
}

async fn target_status(server: &rigcast_server::ServerHandle) -> serde_json::Value {
    let (_, body) = http_get(server.local_addr(), "/v1/status").await;
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    v["subjects"][1].clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_shows_the_feet_planting_in_turn() {
    let Some(server) = start(cmu_walk(), None).await else {
        return;
    };
    let mut seen: HashSet<(String, bool)> = HashSet::new();
    let t0 = Instant::now();
    let mut bones = Vec::new();
    while t0.elapsed() < Duration::from_millis(1600) {
        let s = target_status(&server).await;
        assert_eq!(s["kind"], "target");
        if let Some(feet) = s["footplants"].as_array() {
            bones = feet
                .iter()
                .map(|f| f["bone"].as_str().unwrap().to_string())
                .collect();
            for f in feet {
                seen.insert((
                    f["bone"].as_str().unwrap().into(),
                    f["planted"].as_bool().unwrap(),
                ));
            }
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    println!("feet {bones:?}, states seen {seen:?}");
    assert_eq!(bones, vec!["foot_l".to_string(), "foot_r".to_string()]);
    for bone in &bones {
        for planted in [true, false] {
            assert!(
                seen.contains(&(bone.clone(), planted)),
                "{bone} planted={planted} never seen"
            );
        }
    }
    server.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_the_foot_lock_there_is_no_footplant_state() {
    let Some(server) = start(a_walk(), Some(false)).await else {
        return;
    };
    tokio::time::sleep(Duration::from_millis(500)).await;
    let s = target_status(&server).await;
    assert_eq!(s["kind"], "target");
    assert!(s["footplants"].is_null(), "{s}");
    server.shutdown().await;
}

/// `set_performer` turns the lock off and on at run time (control access).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn set_performer_switches_the_foot_lock() {
    let Some(server) = start(a_walk(), None).await else {
        return;
    };
    let (mut control, _) = tokio_tungstenite::connect_async(server.control_stream_url())
        .await
        .unwrap();
    handshake(&mut control).await;
    for (on, expect_null) in [(false, true), (true, false)] {
        send_text(
            &mut control,
            &format!(r#"{{"type":"set_performer","subject":1,"foot_lock":{on}}}"#),
        )
        .await;
        loop {
            match next_json(&mut control, Duration::from_secs(5))
                .await
                .expect("ack")
            {
                rigcast_protocol::ServerMessage::Ack {
                    request,
                    subject: 1,
                } => {
                    assert_eq!(request, "set_performer");
                    break;
                }
                rigcast_protocol::ServerMessage::Error { code, message, .. } => {
                    panic!("{code:?}: {message}")
                }
                _ => {}
            }
        }
        // The rebuild happens off the tick; the status follows.
        let t0 = Instant::now();
        loop {
            let s = target_status(&server).await;
            if s["footplants"].is_null() == expect_null {
                break;
            }
            assert!(t0.elapsed() < Duration::from_secs(5), "foot_lock {on}: {s}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    // A source subject is refused.
    send_text(
        &mut control,
        r#"{"type":"set_performer","subject":0,"foot_lock":true}"#,
    )
    .await;
    loop {
        match next_json(&mut control, Duration::from_secs(5))
            .await
            .expect("error")
        {
            rigcast_protocol::ServerMessage::Error { code, .. } => {
                assert_eq!(code, rigcast_protocol::control::ErrorCode::Unsupported);
                break;
            }
            rigcast_protocol::ServerMessage::Ack { .. } => panic!("a source was accepted"),
            _ => {}
        }
    }
    server.shutdown().await;
}

/// The `footplants` side message: pushed when a foot plants or lifts, each foot's position is
/// forward kinematics of the frame it names (checked with the client's own FK), a planted foot
/// stays where it is until the next message while a lifted one travels, and both feet plant
/// in turn over the walk.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn footplants_message_follows_the_feet() {
    use rigcast_protocol::ServerMessage;
    let Some(server) = start(cmu_walk(), None).await else {
        return;
    };
    let mut ws = connect(&format!("ws://{}/v1/stream", server.local_addr())).await;
    let seen = watch_v2(&mut ws, 1, Duration::from_millis(2500)).await;
    let bones = seen.bones.clone().expect("the mannequin's skeleton");
    let w = judge_footplants(1, &bones, &seen.frames, &seen.messages);
    println!(
        "{} footplants messages over 2.5 s, {} checked against FK, {} plants judged; planted feet moved ≤ {:.3} m ({:.3} cm per frame at most), lifted ones up to {:.3} m",
        w.messages,
        w.checked,
        w.planted_judged,
        w.planted_travel,
        100.0 * w.planted_drift,
        w.lifted_travel
    );
    assert!(w.messages >= 3, "only {} footplants messages", w.messages);
    let (checked, seen) = (w.checked, w.seen.clone());
    let (planted_travel, planted_drift, lifted_travel) =
        (w.planted_travel, w.planted_drift, w.lifted_travel);
    assert!(checked >= 3, "only {checked} messages matched a frame");
    assert!(w.planted_judged >= 2, "{} plants judged", w.planted_judged);
    for bone in ["foot_l", "foot_r"] {
        for planted in [true, false] {
            assert!(
                seen.contains(&(bone.to_string(), planted)),
                "{bone} never {planted}: {seen:?}"
            );
        }
    }
    assert!(
        planted_drift <= 0.0005,
        "a planted foot slid {planted_travel} m, {planted_drift} m per frame"
    );
    assert!(
        lifted_travel > 0.1,
        "lifted feet never travelled ({lifted_travel} m)"
    );
    // A client connecting now gets the current state at once.
    let mut late = connect(&format!("ws://{}/v1/stream", server.local_addr())).await;
    let mut got = false;
    let t1 = Instant::now();
    while t1.elapsed() < Duration::from_secs(2) {
        if let Some(Incoming::Json(ServerMessage::Footplants { .. })) =
            next(&mut late, Duration::from_secs(2)).await
        {
            got = true;
            break;
        }
    }
    assert!(got, "a late client got no footplants state");
    server.shutdown().await;
}
