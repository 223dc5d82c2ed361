//! Runs the real `rigcast` binary: with no subcommand it serves the bundled demo; a WebSocket
//! client gets hello, skeleton and frames at the configured rate; Ctrl-C stops it cleanly.
#![allow(clippy::unwrap_used)]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use rigcast_protocol::control::SubjectKind;
use rigcast_protocol::frame::decode_frame;
use rigcast_protocol::ServerMessage;
use tokio_tungstenite::tungstenite::Message;

struct Server {
    child: Child,
    url: String,
    stdout: BufReader<std::process::ChildStdout>,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The binary with `args` and its own config folder, so the control token it creates is not the
/// user's.
fn rigcast(args: &[&str]) -> Command {
    let config_home =
        std::env::temp_dir().join(format!("rigcast-binary-xdg-{}", std::process::id()));
    let mut command = Command::new(env!("CARGO_BIN_EXE_rigcast"));
    command.args(args).env("XDG_CONFIG_HOME", config_home);
    command
}

/// Starts the binary and reads the printed stream URL.
fn spawn(args: &[&str]) -> Server {
    let mut child = rigcast(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut url = None;
    let mut line = String::new();
    while url.is_none() {
        line.clear();
        assert!(
            stdout.read_line(&mut line).unwrap() > 0,
            "binary exited early"
        );
        if let Some(rest) = line.trim().strip_prefix("stream: ") {
            url = Some(rest.to_string());
        }
    }
    Server {
        child,
        url: url.unwrap(),
        stdout,
    }
}

async fn check_demo_stream(url: &str, rate_hz: f64) {
    let (mut ws, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    let mut text = Vec::new();
    let mut frame_times = Vec::new();
    // Bones per subject id, from `hello`.
    let mut num_bones: Option<Vec<u32>> = None;
    let start = Instant::now();
    let mut window_start = None;
    while start.elapsed() < Duration::from_secs(5) {
        let msg = tokio::time::timeout(Duration::from_secs(2), ws.next())
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        match msg {
            Message::Text(t) => {
                text.push(serde_json::from_str::<ServerMessage>(t.as_str()).unwrap())
            }
            Message::Binary(b) => {
                let f = decode_frame(&b).unwrap();
                let bones = num_bones.as_ref().unwrap();
                assert_eq!(f.rotations.len() as u32, bones[f.header.subject as usize]);
                // The rate is per subject: measure the demo source's frames.
                if f.header.subject != 0 {
                    continue;
                }
                // Skip the first 200 ms (connection warm-up), then measure for 1 s.
                let now = Instant::now();
                let ws0 = *window_start.get_or_insert(now + Duration::from_millis(200));
                if now >= ws0 {
                    frame_times.push(now);
                    if now - ws0 >= Duration::from_secs(1) {
                        break;
                    }
                }
            }
            _ => {}
        }
        if num_bones.is_none() {
            if let Some(ServerMessage::Hello {
                subjects,
                tick_hz,
                protocol_version,
                ..
            }) = text.first()
            {
                assert_eq!(*protocol_version, 1);
                assert_eq!(*tick_hz, rate_hz);
                // The bundled walk and the built-in mannequin retargeted from it.
                assert_eq!(subjects.len(), 2);
                assert_eq!(subjects[0].kind, SubjectKind::Source);
                assert_eq!(subjects[1].kind, SubjectKind::Target);
                assert_eq!(subjects[1].source, Some(0));
                assert_eq!(subjects[1].name, "mannequin");
                assert_ne!(subjects[0].fingerprint, subjects[1].fingerprint);
                num_bones = Some(subjects.iter().map(|s| s.num_bones).collect());
            }
        }
    }
    assert!(matches!(text.first(), Some(ServerMessage::Hello { .. })));
    assert!(
        matches!(text.get(1), Some(ServerMessage::Skeleton { .. })),
        "{text:?}"
    );
    assert!(
        matches!(
            text.get(2),
            Some(ServerMessage::Skeleton { subject: 1, .. })
        ),
        "{text:?}"
    );
    let mapping = text.iter().find_map(|m| match m {
        ServerMessage::Mapping {
            subject: 1,
            source_subject: 0,
            entries,
            ..
        } => Some(entries),
        _ => None,
    });
    let entries = mapping.expect("a mapping message for the mannequin");
    let mapped = entries.iter().filter(|e| e.source.is_some()).count();
    assert!(mapped >= 15, "only {mapped} mannequin bones mapped");
    let span = (*frame_times.last().unwrap() - frame_times[0]).as_secs_f64();
    let rate = (frame_times.len() - 1) as f64 / span;
    eprintln!("measured {rate:.1} Hz (configured {rate_hz})");
    // Never faster than configured (10% for timer jitter over 1 s); on a loaded shared machine
    // the tick skips missed ticks, so slower is allowed down to 60% (a halved rate still fails).
    assert!(
        rate <= rate_hz * 1.1 && rate >= rate_hz * 0.6,
        "rate {rate}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn binary_serves_demo_at_default_rate_and_stops_on_ctrl_c() {
    let mut server = spawn(&["--listen", "127.0.0.1:0"]);
    check_demo_stream(&server.url, 60.0).await;
    // Ctrl-C = SIGINT.
    let status = Command::new("kill")
        .args(["-INT", &server.child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        if let Some(code) = server.child.try_wait().unwrap() {
            assert!(code.success(), "exit status {code}");
            break;
        }
        assert!(Instant::now() < deadline, "no clean exit after SIGINT");
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut server.stdout, &mut rest).unwrap();
    assert!(rest.contains("shutting down"), "{rest}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn binary_serve_subcommand_honours_rate() {
    let server = spawn(&["serve", "--listen", "127.0.0.1:0", "--rate", "30"]);
    check_demo_stream(&server.url, 30.0).await;
}

/// Runs the binary with `args`, expecting it to refuse them: it must exit (not start serving)
/// within 20 s with a failure status. Returns stderr.
fn refused(args: &[&str]) -> String {
    let mut child = rigcast(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("rigcast {args:?} did not exit: it accepted the arguments");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!status.success(), "rigcast {args:?} succeeded: {err}");
    err
}

#[test]
fn binary_rejects_bad_flags_with_clear_errors() {
    let bad_toml = common::test_file(
        "badflags",
        "bad.toml",
        "rate_hz = 60\n[[sources]]\nkind = \"teleport\"\n",
    );
    let bad_toml = bad_toml.to_str().unwrap();
    // (arguments, what stderr must name)
    let cases: &[(&[&str], &str)] = &[
        (&["--rate", "1000"], "rate_hz"),
        (&["--rate", "NaN"], "rate_hz"),
        (&["--rate", "fast"], "--rate"),
        (&["--listen", "nope"], "listen"),
        (&["--listen", "127.0.0.1:99999"], "listen"),
        (&["--source", "teleport:x"], "unknown source"),
        (&["--source", "vmc:99999"], "vmc:PORT"),
        (&["--source", "replay:"], "unknown source"),
        (&["--on-lost", "drop"], "expected rest (ease), hold or idle"),
        (
            &["--config", "/no/such/rigcast.toml"],
            "/no/such/rigcast.toml",
        ),
        (&["--config", bad_toml], "line 3"),
        (&["--no-such-flag"], "--no-such-flag"),
        (&["serve", "--rate", "0"], "rate_hz"),
    ];
    for (args, needle) in cases {
        let mut all = args.to_vec();
        // Bad input must be refused before binding; a wrong acceptance binds a free port only.
        if !args.contains(&"--listen") {
            all.extend(["--listen", "127.0.0.1:0"]);
        }
        let err = refused(&all);
        assert!(err.contains(needle), "rigcast {all:?}: {err}");
    }
    let err = common::rigcast_fails(["info", "/no/such/file.bvh"]);
    assert!(err.contains("/no/such/file.bvh"), "{err}");
}

/// A reader that stops early (`rigcast info walk.bvh | head -1`) ends an offline command
/// quietly, as it ends any Unix tool: no panic message, killed by SIGPIPE. The pipe's read end
/// is closed before the command writes anything, so every write meets the closed pipe.
#[cfg(unix)]
#[test]
fn an_offline_command_whose_reader_went_away_ends_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let dir = common::test_dir("bin-pipe");
    let clip = rigcast_server::demo::procedural_clip(10, 30.0).unwrap();
    let bvh = dir.join("demo.bvh");
    rigcast_sources::save_clip(&bvh, &clip).unwrap();
    let mut child = rigcast(&["info", bvh.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        out.status.signal(),
        Some(libc::SIGPIPE),
        "{:?}: {stderr}",
        out.status
    );
}

#[test]
fn info_and_convert_commands() {
    let dir = common::test_dir("bin");
    let clip = rigcast_server::demo::procedural_clip(10, 30.0).unwrap();
    let bvh = dir.join("demo.bvh");
    rigcast_sources::save_clip(&bvh, &clip).unwrap();

    let text = common::rigcast_ok(["info", bvh.to_str().unwrap()]);
    assert!(text.contains("LeftUpperArm"), "{text}");
    assert!(text.contains("BVH"), "{text}");

    let rcr = dir.join("demo.rcr");
    common::rigcast_ok(["convert", bvh.to_str().unwrap(), rcr.to_str().unwrap()]);
    let back = rigcast_sources::load_clip(&rcr).unwrap();
    assert_eq!(back.num_frames(), 10);

    let err = common::rigcast_fails(["convert", "/no/such.bvh", rcr.to_str().unwrap()]);
    assert!(err.contains("/no/such.bvh"), "{err}");
}

/// `--unit` reads a BVH in the unit given instead of the guessed one: the demo's figure read at
/// a unit stands that unit's share of its height read in metres, and `info` says the unit was
/// given; the other commands reading a BVH take it too, and a unit that is none is refused with
/// what is accepted.
#[test]
fn a_given_bvh_unit_replaces_the_guess() {
    let dir = common::test_dir("bin-unit");
    let clip = rigcast_server::demo::procedural_clip(10, 30.0).unwrap();
    let bvh = dir.join("demo.bvh");
    rigcast_sources::save_clip(&bvh, &clip).unwrap();
    let path = bvh.to_str().unwrap();
    let height = |text: &str| -> f32 {
        let line = text.lines().find(|l| l.starts_with("height:")).unwrap();
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    let guessed = common::rigcast_ok(["info", path]);
    assert!(guessed.contains("guessed"), "{guessed}");
    let metres = height(&common::rigcast_ok(["info", path, "--unit", "m"]));
    for (unit, ratio) in [("cm", 0.01), ("0.01", 0.01), ("in", 0.0254), ("2.5", 2.5)] {
        let given = common::rigcast_ok(["info", path, "--unit", unit]);
        assert!(
            given.contains(&format!("{ratio} m per unit (given)")),
            "{given}"
        );
        let h = height(&given);
        assert!(
            (h / metres - ratio).abs() < 0.01 * ratio,
            "{unit}: {h} m against {metres} m in metres"
        );
    }
    // The same unit through the other commands that read a BVH.
    let rcr = dir.join("demo_mm.rcr");
    common::rigcast_ok(["convert", path, rcr.to_str().unwrap(), "--unit", "mm"]);
    let back = rigcast_sources::describe(&rcr).unwrap();
    assert!(
        (back.height_m / metres - 0.001).abs() < 1e-5,
        "{} m against {metres} m",
        back.height_m
    );
    let map = common::rigcast_ok(["map", path, path, "--json", "--no-cache", "--unit", "mm"]);
    assert!(map.contains("\"mapping\""), "{map}");
    let err = common::rigcast_fails(["info", path, "--unit", "furlong"]);
    assert!(err.contains("furlong") && err.contains("cm"), "{err}");
}
