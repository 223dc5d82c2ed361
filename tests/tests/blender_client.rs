//! Real Blender runs the live-link add-on against the real server.
//!
//! Headless Blender (`clients/blender/tests/run_in_blender.py`) installs the add-on from a zip
//! built with the documented builder, enables it with default preferences and connects. Meanwhile
//! this test keeps its own WebSocket client on the same server, so it holds exactly what the
//! server sent and judges Blender against it:
//! - stream: the embedded demo, a twisted copy of it (every rest rotation non-identity) and the
//!   built-in mannequin retargeted from the demo stream in-process on 127.0.0.1:0; Blender
//!   creates an armature per subject, applies the stream for ~2 s while recording, and every
//!   applied pose is compared with forward kinematics of the frame with the same sequence
//!   number, converted to Blender axes ((x, y, z) → (x, -z, y)); rate, latency and the
//!   recorded Action are checked too.
//! - mapping: the default demo (`demo` + retargeted `mannequin`); the add-on's mapping list and
//!   bone colours must equal the server's `mapping` message, and an override picked in the list
//!   must come back from the server as a new `mapping` that the list then shows. With the
//!   shared data, a mapping with flagged bones (Meredith onto the mannequin): the list marks
//!   exactly the flagged rows.
//! - binary: the `rigcast` binary started with only `--listen`, the zip built by the documented
//!   command, the add-on's default settings apart from the address.
//!
//! Needs `blender` (scripts/install-apps.sh installs it). Missing Blender fails the test with
//! a clear message, unless RIGCAST_SKIP_APPS=1, which skips it with a printed reason.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use glam::{Quat, Vec3};
use rigcast_protocol::frame::{decode_frame, DecodedFrame};
use rigcast_retarget::{Clip, Pose, Skeleton};
use rigcast_server::config::PerformerSpec;
use rigcast_server::{ReplaySettings, ServerConfig, SourceSpec};
use rigcast_tests::{
    find_app, free_port, repo_root, rigcast_binary, start_demo_server, KillOnDrop,
};
use serde_json::Value;
use tokio_tungstenite::tungstenite::Message;

fn blender_from_ours(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.z, p.y)
}

fn ours_from_blender(p: Vec3) -> Vec3 {
    Vec3::new(p.x, p.z, -p.y)
}

/// The first `N` numbers of a JSON array.
fn floats<const N: usize>(v: &Value) -> [f32; N] {
    let a = rigcast_tests::f64s(v);
    std::array::from_fn(|i| a[i] as f32)
}

fn vec3(v: &Value) -> Vec3 {
    Vec3::from_array(floats(v))
}

/// `[x, y, z, w]`.
fn quat(v: &Value) -> Quat {
    Quat::from_array(floats(v))
}

/// A skeleton as the client sees it on the wire.
struct WireSkeleton {
    names: Vec<String>,
    parents: Vec<Option<usize>>,
    rest_translations: Vec<Vec3>,
    rest_rotations: Vec<Quat>,
    /// Per bone: its slot among a version 2 frame's translations.
    slots: Vec<Option<usize>>,
}

impl WireSkeleton {
    fn from_message(message: &Value) -> WireSkeleton {
        let bones = message["bones"].as_array().expect("bones");
        WireSkeleton {
            names: bones
                .iter()
                .map(|b| b["name"].as_str().expect("name").to_string())
                .collect(),
            parents: bones
                .iter()
                .map(|b| b["parent"].as_u64().map(|p| p as usize))
                .collect(),
            rest_translations: bones.iter().map(|b| vec3(&b["rest_translation"])).collect(),
            rest_rotations: bones.iter().map(|b| quat(&b["rest_rotation"])).collect(),
            slots: bones
                .iter()
                .scan(0, |next, b| {
                    Some(if b["translated"].as_bool() == Some(true) {
                        *next += 1;
                        Some(*next - 1)
                    } else {
                        None
                    })
                })
                .collect(),
        }
    }

    /// World (rotation, position) per bone; `frame` None means the rest pose.
    fn fk(&self, frame: Option<&DecodedFrame>) -> Vec<(Quat, Vec3)> {
        let mut out: Vec<(Quat, Vec3)> = Vec::with_capacity(self.names.len());
        for i in 0..self.names.len() {
            let (rotation, translation) = match frame {
                Some(f) if f.version == 2 => (
                    f.rotations[i],
                    self.slots[i].map_or(self.rest_translations[i], |k| f.translations[k]),
                ),
                Some(f) if i == 0 => (f.rotations[i], f.root),
                Some(f) => (f.rotations[i], self.rest_translations[i]),
                None => (self.rest_rotations[i], self.rest_translations[i]),
            };
            out.push(match self.parents[i] {
                None => (rotation, translation),
                Some(p) => {
                    let (pr, pp) = out[p];
                    (pr * rotation, pp + pr * translation)
                }
            });
        }
        out
    }
}

/// The same motion on a skeleton whose joint frames are rotated by a different arbitrary
/// rotation per bone: world positions are unchanged, every rest and pose local rotation is not
/// (q'_i = R_parent^-1 · q_i · R_i, t'_i = R_parent^-1 · t_i).
fn twisted(clip: &Clip) -> Clip {
    let n = clip.skeleton.num_bones();
    let offsets: Vec<Quat> = (0..n)
        .map(|i| {
            let axis = Vec3::new(1.0, 2.0, 0.5 + i as f32).normalize_or_zero();
            Quat::from_axis_angle(axis, 0.4 + 0.3 * i as f32)
        })
        .collect();
    let parents: Vec<Option<usize>> = clip
        .skeleton
        .parents()
        .iter()
        .map(|p| p.map(|b| b.index()))
        .collect();
    let parent_offset = |i: usize| parents[i].map_or(Quat::IDENTITY, |p| offsets[p]);
    let mut raw = clip.skeleton.to_raw();
    for (i, bone) in raw.bones.iter_mut().enumerate() {
        let rp = parent_offset(i).inverse();
        bone.rest.rotation = rp * bone.rest.rotation * offsets[i];
        bone.rest.translation = rp * bone.rest.translation;
    }
    let skeleton = Skeleton::build(&raw).expect("twisted skeleton builds");
    let poses: Vec<Pose> = clip
        .poses
        .iter()
        .map(|pose| {
            let mut out = pose.clone();
            for (i, offset) in offsets.iter().enumerate() {
                let rp = parent_offset(i).inverse();
                out.rotations[i] = rp * pose.rotations[i] * *offset;
                out.translations[i] = rp * pose.translations[i];
            }
            out
        })
        .collect();
    Clip::new("twisted", Arc::new(skeleton), poses, clip.frame_time_secs).expect("twisted clip")
}

#[derive(Default)]
struct Observed {
    hello: Option<Value>,
    skeletons: HashMap<u64, Value>,
    /// Every `mapping` message, in arrival order.
    mappings: Vec<Value>,
    /// Every `footplants` message, in arrival order.
    footplants: Vec<Value>,
    frames: HashMap<(u32, u64), DecodedFrame>,
}

/// Our own client on the same stream: records every frame by (subject, seq).
async fn watch_stream(addr: SocketAddr, observed: Arc<Mutex<Observed>>) {
    let url = format!("ws://{addr}/v1/stream");
    let (mut ws, _) = tokio_tungstenite::connect_async(url)
        .await
        .expect("test client connects");
    // Version 2, as the add-on asks for: the frames carry every moving bone's translation.
    ws.send(Message::text(r#"{"type":"set_protocol","version":2}"#))
        .await
        .expect("test client sends");
    while let Some(message) = ws.next().await {
        match message {
            Ok(Message::Binary(bytes)) => {
                let frame = decode_frame(&bytes).expect("server frames decode");
                if frame.version != 2 {
                    continue; // sent before the switch
                }
                let key = (frame.header.subject, frame.header.seq);
                observed.lock().unwrap().frames.insert(key, frame);
            }
            Ok(Message::Text(text)) => {
                let value: Value = serde_json::from_str(text.as_str()).expect("server JSON parses");
                let mut o = observed.lock().unwrap();
                match value["type"].as_str() {
                    Some("hello") => o.hello = Some(value),
                    Some("skeleton") => {
                        let id = value["subject"].as_u64().expect("subject id");
                        o.skeletons.insert(id, value);
                    }
                    Some("mapping") => o.mappings.push(value),
                    Some("footplants") => o.footplants.push(value),
                    _ => {}
                }
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
}

static BLENDER: Mutex<()> = Mutex::new(());

/// One Blender of the test matrix.
#[derive(Clone, Debug)]
enum Blender {
    /// A `blender` program on PATH (Debian 12's 3.4), run headless with `-b`.
    App(PathBuf),
    /// The official `bpy` wheel (Blender as a Python module) in the venv
    /// `scripts/setup-bpy.sh` makes for one release series; no event loop, so the in-Blender
    /// script drives the add-on's timer function itself.
    Module {
        series: &'static str,
        python: PathBuf,
    },
}

impl Blender {
    /// Debian's Blender, or None (skip) when absent and RIGCAST_SKIP_APPS=1.
    fn app() -> Option<Blender> {
        find_app("blender").map(Blender::App)
    }

    /// The `bpy` venv of `series` ("4.5", "5.0"). Skips with the printed reason when the setup
    /// script could not install that wheel on this machine (or RIGCAST_SKIP_APPS=1); panics
    /// when the setup script was simply not run, so a missing version never passes silently.
    fn module(series: &'static str) -> Option<Blender> {
        let home = std::env::var_os("RIGCAST_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/rigcast")))
            .expect("HOME or RIGCAST_HOME is set");
        let dir = home.join("bpy").join(series);
        let python = dir.join("venv/bin/python");
        if python.is_file() {
            return Some(Blender::Module { series, python });
        }
        if let Ok(reason) = std::fs::read_to_string(dir.join("failed")) {
            eprintln!("SKIP: Blender {series} (bpy wheel): {}", reason.trim());
            return None;
        }
        if std::env::var("RIGCAST_SKIP_APPS").as_deref() == Ok("1") {
            eprintln!("SKIP: Blender {series}: no bpy venv and RIGCAST_SKIP_APPS=1");
            return None;
        }
        panic!("{} missing: run scripts/setup-bpy.sh", python.display());
    }

    fn label(&self) -> String {
        match self {
            Blender::App(path) => format!("blender program {}", path.display()),
            Blender::Module { series, .. } => format!("bpy {series} module"),
        }
    }

    /// The command running `script` with `args`, its user folders inside `work`.
    fn command(&self, script: &Path, work: &Path) -> Command {
        let mut command = match self {
            Blender::App(blender) => {
                let mut c = Command::new(blender);
                c.args([
                    "-b",
                    "--factory-startup",
                    "--python-exit-code",
                    "1",
                    "--python",
                ]);
                c.arg(script);
                c
            }
            Blender::Module { python, .. } => {
                // sys.path[0] is the script's folder (clients/blender/tests), which holds no
                // add-on code; the add-on can only load from where it was installed.
                let mut c = Command::new(python);
                c.arg(script);
                c
            }
        };
        command
            .arg("--")
            // Install the add-on into throwaway user folders, never the user's own (3.4 reads
            // SCRIPTS/CONFIG; 4.2+ RESOURCES, where the extension repository lives).
            .env("BLENDER_USER_SCRIPTS", work.join("user_scripts"))
            .env("BLENDER_USER_CONFIG", work.join("user_config"))
            .env("BLENDER_USER_RESOURCES", work.join("user_resources"))
            // The working directory is on a module-mode sys.path (''): keep it away from the
            // source tree.
            .current_dir(work);
        command
    }

    /// How the add-on is installed for `mode` on this Blender: the extensions platform on
    /// 4.2+ where it is the documented route, the legacy add-on route otherwise (and on one
    /// mode per module version, so both routes stay tested there).
    fn install_for(&self, mode: &str) -> &'static str {
        match (self, mode) {
            (Blender::App(_), _) => "legacy",
            (Blender::Module { .. }, "mapping") => "legacy",
            (Blender::Module { series: "5.0", .. }, "connect") => "legacy",
            (Blender::Module { .. }, _) => "extension",
        }
    }
}

/// A fresh scratch directory (several tests of this file run at once).
fn work_dir() -> PathBuf {
    let dir = rigcast_tests::temp_path("blender");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// How the in-Blender script gets the add-on zip.
enum Zip {
    /// Build it inside Blender with clients/blender/build_zip.py's `build()`.
    Build,
    /// Install this zip (built beforehand by the documented command).
    Use(PathBuf),
}

/// [`run_blender`] on a blocking thread, so the test's runtime keeps serving the in-process
/// server and the stream watcher meanwhile.
async fn run_blender_off_runtime(
    blender: Blender,
    addr: SocketAddr,
    work: &Path,
    mode: &'static str,
    zip: Zip,
) -> Value {
    run_blender_with_token(blender, addr, work, mode, zip, None).await
}

/// [`run_blender_off_runtime`] with the server's control token typed into the add-on's
/// Token field.
async fn run_blender_with_token(
    blender: Blender,
    addr: SocketAddr,
    work: &Path,
    mode: &'static str,
    zip: Zip,
    token: Option<String>,
) -> Value {
    let work = work.to_path_buf();
    tokio::task::spawn_blocking(move || run_blender(&blender, addr, &work, mode, zip, token))
        .await
        .expect("blender task")
}

fn run_blender(
    blender: &Blender,
    addr: SocketAddr,
    work: &Path,
    mode: &str,
    zip: Zip,
    token: Option<String>,
) -> Value {
    let root = repo_root();
    let out_json = work.join("observations.json");
    let zip_args: Vec<std::ffi::OsString> = match zip {
        Zip::Build => vec![
            "--build-zip".into(),
            work.join("rigcast_livelink.zip").into(),
        ],
        Zip::Use(path) => vec!["--zip".into(), path.into()],
    };
    let install = blender.install_for(mode);
    // One Blender at a time: the rate assertions must not compete with another Blender for
    // the machine's cores.
    let _one_at_a_time = BLENDER.lock().unwrap_or_else(|e| e.into_inner());
    let mut child = blender
        .command(&root.join("clients/blender/tests/run_in_blender.py"), work)
        .args(&zip_args)
        .args(["--mode", mode, "--install", install])
        .args(["--address", &addr.to_string(), "--seconds", "2.0"])
        .args(
            token
                .map(|t| ["--token".to_string(), t])
                .into_iter()
                .flatten(),
        )
        .arg("--out")
        .arg(&out_json)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{} starts: {e}", blender.label()));
    // Drain both pipes while waiting: Blender's chatter must never fill a pipe and block it.
    let stdout = drain(child.stdout.take().unwrap());
    let stderr = drain(child.stderr.take().unwrap());
    let deadline = Instant::now() + Duration::from_secs(180);
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait on blender") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("{} did not finish within 180 s", blender.label());
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let log = format!(
        "--- {} stdout ---\n{}\n--- stderr ---\n{}",
        blender.label(),
        stdout.join().unwrap(),
        stderr.join().unwrap()
    );
    let text = std::fs::read_to_string(&out_json).unwrap_or_else(|e| {
        panic!(
            "no observations at {} (exit {status:?}): {e}\n{log}",
            out_json.display()
        )
    });
    let value: Value = serde_json::from_str(&text).expect("observations are JSON");
    assert!(
        value["ok"].as_bool() == Some(true) && status.success(),
        "in-Blender script failed (exit {:?}): {}\n{log}",
        status.code(),
        value["error"]
    );
    assert_installed_copy_ran(&value, work, install);
    value
}

fn drain(mut pipe: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut text = String::new();
        let _ = pipe.read_to_string(&mut text);
        text
    })
}

/// The add-on that ran is the copy installed from the zip, not the source tree.
fn assert_installed_copy_ran(value: &Value, work: &Path, install: &str) {
    let file = PathBuf::from(value["addon_file"].as_str().expect("addon_file"));
    assert!(
        file.starts_with(work) && !file.starts_with(repo_root()),
        "the add-on was loaded from {} (want the installed copy under {})",
        file.display(),
        work.display()
    );
    assert_eq!(
        value["source_dir_on_path"],
        serde_json::json!([]),
        "clients/blender is on sys.path"
    );
    let module = value["addon_module"].as_str().unwrap();
    match install {
        "extension" => assert!(
            module.starts_with("bl_ext.user_default."),
            "not installed as an extension: {module}"
        ),
        _ => assert_eq!(module, "rigcast_livelink.livelink"),
    }
}

/// One test per (scenario, Blender) pair of the matrix; a version whose wheel could not be
/// installed is skipped by [`Blender::module`] with the reason printed.
macro_rules! matrix {
    ($scenario:ident: $($name:ident => $blender:expr),+ $(,)?) => {
        $(
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn $name() {
                let Some(blender) = $blender else { return };
                $scenario(blender).await;
            }
        )+
    };
}

matrix!(applies_and_records_the_live_stream:
    blender_3_4_applies_and_records_the_live_stream => Blender::app(),
    blender_4_2_applies_and_records_the_live_stream => Blender::module("4.2"),
    blender_4_5_applies_and_records_the_live_stream => Blender::module("4.5"),
    blender_5_0_applies_and_records_the_live_stream => Blender::module("5.0"),
);
matrix!(survives_a_failing_take:
    blender_3_4_survives_a_failing_take => Blender::app(),
    blender_4_2_survives_a_failing_take => Blender::module("4.2"),
    blender_4_5_survives_a_failing_take => Blender::module("4.5"),
    blender_5_0_survives_a_failing_take => Blender::module("5.0"),
);
matrix!(exposes_the_footplants:
    blender_3_4_exposes_the_footplants => Blender::app(),
    blender_4_2_exposes_the_footplants => Blender::module("4.2"),
    blender_4_5_exposes_the_footplants => Blender::module("4.5"),
    blender_5_0_exposes_the_footplants => Blender::module("5.0"),
);
matrix!(shows_and_overrides_the_server_mapping:
    blender_3_4_shows_and_overrides_the_server_mapping => Blender::app(),
    blender_4_2_shows_and_overrides_the_server_mapping => Blender::module("4.2"),
    blender_4_5_shows_and_overrides_the_server_mapping => Blender::module("4.5"),
    blender_5_0_shows_and_overrides_the_server_mapping => Blender::module("5.0"),
);
matrix!(marks_the_bones_the_mapper_flagged:
    blender_3_4_marks_the_bones_the_mapper_flagged => Blender::app(),
    blender_4_2_marks_the_bones_the_mapper_flagged => Blender::module("4.2"),
    blender_4_5_marks_the_bones_the_mapper_flagged => Blender::module("4.5"),
    blender_5_0_marks_the_bones_the_mapper_flagged => Blender::module("5.0"),
);
matrix!(zip_connects_to_the_rigcast_binary:
    blender_3_4_zip_connects_to_the_rigcast_binary => Blender::app(),
    blender_4_2_zip_connects_to_the_rigcast_binary => Blender::module("4.2"),
    blender_4_5_zip_connects_to_the_rigcast_binary => Blender::module("4.5"),
    blender_5_0_zip_connects_to_the_rigcast_binary => Blender::module("5.0"),
);

async fn applies_and_records_the_live_stream(blender: Blender) {
    // The demo has identity rest rotations; the twisted copy has none, so the add-on's
    // rest-rotation and bone-axis handling is exercised too; the mannequin is the demo's
    // retargeted target (A-pose, different structure), as `rigcast serve` streams it.
    let demo = rigcast_sources::embedded_demo().expect("embedded demo");
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![
            SourceSpec::demo(),
            SourceSpec::ReplayClip(rigcast_server::config::ReplayClipSpec {
                clip: twisted(&demo),
                name: Some("twisted".into()),
                settings: ReplaySettings::default(),
            }),
        ],
        performers: vec![PerformerSpec {
            sources: vec!["demo".into()],
            ..PerformerSpec::target_file("builtin:mannequin")
        }],
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.expect("server starts");
    eprintln!("server on {}", server.local_addr());
    let addr = server.local_addr();
    let observed = Arc::new(Mutex::new(Observed::default()));
    let watcher = tokio::spawn(watch_stream(addr, observed.clone()));

    let work = work_dir();
    let result = run_blender_off_runtime(blender, addr, &work, "stream", Zip::Build).await;
    eprintln!("blender finished");
    watcher.abort();
    // Shutdown is not what this test judges; do not let a slow close hang it.
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let observed = observed.lock().unwrap();

    // The add-on's default address is the server's default listen address.
    assert_eq!(result["default_address"], "127.0.0.1:8717");
    // Recording never touches the scene's frame rate.
    assert_eq!(result["scene_fps_before"], result["scene_fps_after"]);
    let scene_fps = result["scene_fps_before"][0].as_f64().unwrap()
        / result["scene_fps_before"][1].as_f64().unwrap();

    let hello = observed.hello.as_ref().expect("test client got hello");
    let subjects = hello["subjects"].as_array().expect("subjects");
    assert!(!subjects.is_empty());
    assert_eq!(result["session"]["bad"], 0, "the add-on rejected frames");

    // Bones coloured by the server's mapping while streaming (values: the mapping test).
    assert!(
        !observed.mappings.is_empty(),
        "the server sent no mapping for the mannequin"
    );
    let colored = result["colored_bones"].as_object().expect("colored bones");
    assert!(
        colored.values().any(|n| n.as_u64() > Some(0)),
        "no bone coloured by the mapping"
    );
    let kinds: Vec<&str> = subjects
        .iter()
        .map(|s| s["kind"].as_str().unwrap())
        .collect();
    assert!(
        kinds.contains(&"target"),
        "no retargeted subject: {kinds:?}"
    );

    let label = format!(
        "Blender {}",
        result["blender_version"].as_str().unwrap_or("?")
    );
    assert_eq!(
        result["record_errors"],
        serde_json::json!({}),
        "{label}: recording failed"
    );
    let observations = result["observations"].as_array().expect("observations");
    let mut worst_pose = Vec::new();
    for subject in subjects {
        let id = subject["id"].as_u64().unwrap();
        let skeleton = WireSkeleton::from_message(&observed.skeletons[&id]);
        let rest = skeleton.fk(None);
        let rest_points = &result["rest_points"][id.to_string()];

        // 1. Pose: every applied frame matches forward kinematics of the frame the server sent.
        let mine: Vec<&Value> = observations
            .iter()
            .filter(|o| o["subject"].as_u64() == Some(id))
            .collect();
        assert!(
            mine.len() > 30,
            "subject {id}: only {} frames applied",
            mine.len()
        );
        let mut worst_m = 0.0f32;
        let mut worst_at = String::new();
        let mut checked = 0;
        for obs in mine.iter().filter(|o| o.get("heads").is_some()) {
            let seq = obs["seq"].as_u64().unwrap();
            let Some(frame) = observed.frames.get(&(id as u32, seq)) else {
                continue; // our own client may have joined a moment later
            };
            let world = skeleton.fk(Some(frame));
            for (i, name) in skeleton.names.iter().enumerate() {
                let got = &obs["heads"][name];
                let expected = posed_points(&rest_points[name], rest[i], world[i]);
                for (k, expected) in expected.into_iter().enumerate() {
                    let error = (vec3(&got[k]) - expected).length();
                    if error > worst_m {
                        worst_m = error;
                        worst_at = format!("seq {seq}, bone {name}, point {k}");
                    }
                }
            }
            checked += 1;
        }
        eprintln!("{label}: subject {id}: {checked} sampled poses matched a server frame");
        assert!(
            checked >= 15,
            "subject {id}: only {checked} sampled poses matched a server frame"
        );
        assert!(
            worst_m < POSE_TOLERANCE_M,
            "{label}: subject {id}: Blender pose differs from FK of the server frame by {worst_m} m at {worst_at}"
        );
        worst_pose.push((id, worst_m));
        // The hips bob: each translated bone below a root (the mannequin's pelvis under its
        // ground root) rises and falls in Blender as much as in FK of the server's frames.
        for (i, name) in skeleton.names.iter().enumerate() {
            if skeleton.slots[i].is_none() || skeleton.parents[i].is_none() {
                continue;
            }
            let (mut in_blender, mut in_server) = (Vec::new(), Vec::new());
            for obs in mine.iter().filter(|o| o.get("heads").is_some()) {
                let seq = obs["seq"].as_u64().unwrap();
                if let Some(frame) = observed.frames.get(&(id as u32, seq)) {
                    in_blender.push(vec3(&obs["heads"][name][0]).z);
                    in_server.push(skeleton.fk(Some(frame))[i].1.y);
                }
            }
            let range = |v: &[f32]| {
                v.iter().cloned().fold(f32::MIN, f32::max)
                    - v.iter().cloned().fold(f32::MAX, f32::min)
            };
            let (rb, rs) = (range(&in_blender), range(&in_server));
            println!("subject {id}: {name} height varies over {rb:.4} m in Blender, {rs:.4} m in server FK");
            assert!(
                (rb - rs).abs() < 1e-3,
                "subject {id}: {name} height range {rb} vs {rs}"
            );
            if subject["kind"] == "target" {
                assert!(
                    rs > 0.01,
                    "subject {id}: {name} height does not vary ({rs} m)"
                );
            }
        }

        // 2. Rate: distinct frames applied per second over the recorded run.
        let applied: Vec<f64> = mine
            .iter()
            .map(|o| o["applied_nanos"].as_f64().unwrap() * 1e-9)
            .collect();
        let span = applied.last().unwrap() - applied.first().unwrap();
        let rate = (applied.len() - 1) as f64 / span;
        let seqs: Vec<u64> = mine.iter().map(|o| o["seq"].as_u64().unwrap()).collect();
        // The add-on applies the newest frame on each of Blender's ticks, so it can apply no
        // faster than it ticks or than the server produces (seq counts produced frames). The
        // two are not in phase, so half the slower of them is the bound: 30 frames/s on an
        // idle machine (60 Hz ticks, the 60 fps demo), less when a loaded machine slows Blender
        // or the server. A fixed 30 failed at load 20 (15.1/s), judging the machine's speed,
        // which is a benchmark's figure (printed below), not the add-on's behaviour.
        let tick_rate =
            result["record_ticks"].as_f64().unwrap() / result["record_secs"].as_f64().unwrap();
        let produced_rate = (seqs.last().unwrap() - seqs.first().unwrap()) as f64 / span;
        let bound = 0.5 * tick_rate.min(produced_rate);
        assert!(
            rate >= bound,
            "subject {id}: applied {rate:.1} frames/s, want ≥ {bound:.1} (Blender ticked {tick_rate:.1}/s, the server produced {produced_rate:.1}/s)"
        );
        assert!(
            seqs.windows(2).all(|w| w[1] > w[0]),
            "subject {id}: seq went backwards"
        );

        // 3. Latency from capture time stays bounded: no backlog growing over the run.
        let latency_ms: Vec<(f64, f64)> = mine
            .iter()
            .map(|o| {
                let applied = o["applied_nanos"].as_f64().unwrap();
                let capture = o["capture_nanos"].as_f64().unwrap();
                (
                    (applied - applied_first(&mine)) * 1e-9,
                    (applied - capture) * 1e-6,
                )
            })
            .collect();
        let mean = |from: f64, to: f64| {
            let v: Vec<f64> = latency_ms
                .iter()
                .filter(|(t, _)| *t >= from && *t < to)
                .map(|(_, l)| *l)
                .collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        };
        let first_second = mean(0.0, 1.0);
        let last_second = mean(span - 1.0, span + 1.0);
        let max_latency = latency_ms.iter().map(|(_, l)| *l).fold(0.0, f64::max);
        // Counted over the frames, not the single worst: a loaded machine can stall Blender
        // once for half a second (526 ms in a clean-clone run at load 15, every other frame
        // 21-26 ms), which a backlog is not; a backlog delays every frame after it.
        let mut sorted: Vec<f64> = latency_ms.iter().map(|(_, l)| *l).collect();
        sorted.sort_by(f64::total_cmp);
        let p95 = sorted[(sorted.len() * 95 / 100).min(sorted.len().saturating_sub(1))];
        println!(
            "{label}: subject {id}: {} frames applied at {rate:.1}/s, latency first s {first_second:.1} ms, last s {last_second:.1} ms, p95 {p95:.1} ms, max {max_latency:.1} ms, worst pose error {worst_m:e} m",
            mine.len()
        );
        assert!(
            p95 < 250.0,
            "subject {id}: latency p95 reached {p95:.1} ms (max {max_latency:.1})"
        );
        assert!(
            last_second < first_second + 20.0,
            "subject {id}: latency grew from {first_second:.1} ms to {last_second:.1} ms (backlog)"
        );

        // 4. The recorded Action: quaternion curves grouped by bone at the scene frame rate.
        let action = &result["actions"][id.to_string()];
        let fcurves = action["fcurves"].as_array().expect("recorded fcurves");
        if action["layered"] == true {
            // 4.4+: one slot per armature, and the armature bound to it (5.0 plays nothing
            // through an unbound slot).
            assert_eq!(action["num_slots"], 1, "{label}: subject {id}: {action:#}");
            assert!(
                action["slot"].as_str().is_some_and(|s| s.starts_with("OB")),
                "{label}: subject {id}: armature not bound to an object slot: {}",
                action["slot"]
            );
        }
        let record_secs = result["record_secs"].as_f64().unwrap();
        // A key is made on one of Blender's ticks for a frame the server sent: the longest
        // wait for either (tick stalls, or a server that produced nothing meanwhile) is as
        // many scene frames as may pass without a key.
        let max_tick_gap = result["max_tick_gap_secs"].as_f64().unwrap();
        let captures: Vec<f64> = mine
            .iter()
            .map(|o| o["capture_nanos"].as_f64().unwrap() * 1e-9)
            .collect();
        let max_frame_gap = captures.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        let max_key_gap = 8f64.max((max_tick_gap.max(max_frame_gap) * scene_fps).ceil() + 1.0);
        let ticked_frames = result["record_ticked_frames"].as_f64().unwrap();
        for name in &skeleton.names {
            let path = format!("pose.bones[\"{name}\"].rotation_quaternion");
            let curves: Vec<&Value> = fcurves
                .iter()
                .filter(|c| c["data_path"] == path.as_str())
                .collect();
            assert_eq!(curves.len(), 4, "{name}: want w, x, y, z curves");
            for curve in &curves {
                assert_eq!(
                    curve["group"],
                    name.as_str(),
                    "{name}: curve not grouped by bone"
                );
                let frames = rigcast_tests::f64s(&curve["frames"]);
                assert!(
                    frames.iter().all(|f| f.fract() == 0.0),
                    "{name}: keys off whole frames"
                );
                // One key per scene frame at most; a display tick stalled by a loaded machine
                // (the test runs four Blenders beside the server on shared cores) may skip
                // frames, as many as the longest wait between two of its ticks spans (keys are
                // made on ticks), and the coverage check below bounds how many overall.
                assert!(
                    frames
                        .windows(2)
                        .all(|w| w[1] - w[0] >= 1.0 && w[1] - w[0] <= max_key_gap),
                    "{name}: key spacing {frames:?} (longest wait: tick {max_tick_gap:.3} s, frame {max_frame_gap:.3} s)"
                );
                // Keys span the recorded time at the scene's rate (capture time → frame).
                let span = frames.last().unwrap() - frames.first().unwrap() + 1.0;
                let expected = record_secs * scene_fps;
                assert!(
                    (span - expected).abs() <= 0.15 * expected + 2.0,
                    "{name}: keys span {span} frames over {record_secs:.2} s at {scene_fps} fps"
                );
                // Most scene frames keyed, of those Blender ticked in at all: a machine that
                // stalls Blender's ticks for whole frames (four Blenders beside the server on
                // shared cores) leaves those frames without a chance of a key.
                let chances = span.min(ticked_frames);
                assert!(
                    frames.len() as f64 >= 0.8 * chances,
                    "{name}: only {} keys over {span} frames ({ticked_frames} with a tick)",
                    frames.len()
                );
            }
            // Keys are unit quaternions.
            let values: Vec<Vec<f64>> = curves
                .iter()
                .map(|c| rigcast_tests::f64s(&c["values"]))
                .collect();
            for k in 0..values[0].len() {
                let norm = values.iter().map(|c| c[k] * c[k]).sum::<f64>().sqrt();
                assert!(
                    (norm - 1.0).abs() < 1e-3,
                    "{name}: key {k} has |q| = {norm}"
                );
            }
        }
    }

    // 5. Playback: the Action, evaluated at keyed scene frames, poses the armature exactly as
    // the server's frame keyed there (found by seq), by the same forward kinematics.
    let playback = result["playback"].as_array().expect("playback samples");
    let mut worst_playback = 0.0f32;
    let mut played: HashMap<u64, usize> = HashMap::new();
    for sample in playback {
        let id = sample["subject"].as_u64().unwrap();
        let frame_no = sample["frame"].as_f64().unwrap();
        let keyed = observations
            .iter()
            .find(|o| {
                o["subject"].as_u64() == Some(id) && o["keyed_frame"].as_f64() == Some(frame_no)
            })
            .expect("a keyed observation for every played frame");
        let seq = keyed["seq"].as_u64().unwrap();
        let Some(frame) = observed.frames.get(&(id as u32, seq)) else {
            continue;
        };
        let skeleton = WireSkeleton::from_message(&observed.skeletons[&id]);
        let error = pose_error(
            &skeleton,
            &result["rest_points"][id.to_string()],
            frame,
            &sample["heads"],
        );
        worst_playback = worst_playback.max(error);
        *played.entry(id).or_default() += 1;
    }
    for subject in subjects {
        let id = subject["id"].as_u64().unwrap();
        assert!(
            played.get(&id).copied().unwrap_or(0) >= 4,
            "{label}: subject {id}: only {:?} played-back frames matched a server frame",
            played.get(&id)
        );
    }
    assert!(
        worst_playback < POSE_TOLERANCE_M,
        "{label}: played-back pose differs from the recorded server frame by {worst_playback} m"
    );
    println!(
        "{label}: live pose error per subject {worst_pose:?} m; playback of {} keyed frames within {worst_playback:e} m",
        playback.len()
    );
    let _ = std::fs::remove_dir_all(&work);
}

/// Poses must equal forward kinematics of the server's frame to this (metres): float32
/// rounding in Blender's matrices, nothing more.
const POSE_TOLERANCE_M: f32 = 1e-5;

/// Largest distance between the three points per bone Blender reports (`heads`: head, tail,
/// head + Z) and where forward kinematics of `frame` puts them (rigid in each joint's frame,
/// from the rest points).
fn pose_error(
    skeleton: &WireSkeleton,
    rest_points: &Value,
    frame: &DecodedFrame,
    heads: &Value,
) -> f32 {
    let rest = skeleton.fk(None);
    let world = skeleton.fk(Some(frame));
    let mut worst = 0.0f32;
    for (i, name) in skeleton.names.iter().enumerate() {
        let expected = posed_points(&rest_points[name], rest[i], world[i]);
        for (k, expected) in expected.into_iter().enumerate() {
            worst = worst.max((vec3(&heads[name][k]) - expected).length());
        }
    }
    worst
}

/// Where a bone's three points Blender reports (head, tail and head + Z, at rest in
/// `rest_points`) are when its joint moves from `rest` to `posed` (rotation, position): rigid
/// in the joint's frame.
fn posed_points(rest_points: &Value, rest: (Quat, Vec3), posed: (Quat, Vec3)) -> [Vec3; 3] {
    let (rest_rotation, rest_position) = rest;
    let (rotation, position) = posed;
    std::array::from_fn(|k| {
        let rest_point = ours_from_blender(vec3(&rest_points[k]));
        let local = rest_rotation.inverse() * (rest_point - rest_position);
        blender_from_ours(position + rotation * local)
    })
}

/// A take that fails mid-recording stops alone, reported once; the live pose of every
/// armature keeps its rate and the other takes record on (the Blender 5.0 failure mode before
/// layered Actions: an exception per frame starved the second armature to 8.6 fps).
async fn survives_a_failing_take(blender: Blender) {
    let server = start_demo_server().await;
    let addr = server.local_addr();
    let work = work_dir();
    let result = run_blender_off_runtime(blender, addr, &work, "record_failure", Zip::Build).await;
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let label = format!(
        "Blender {}",
        result["blender_version"].as_str().unwrap_or("?")
    );
    let broken = result["broken_armature"].as_str().unwrap();
    let errors = result["record_errors"].as_object().expect("record errors");
    assert_eq!(
        errors.keys().collect::<Vec<_>>(),
        vec![broken],
        "{label}: want exactly the broken take reported: {errors:?}"
    );
    // Starving shows as a drop against the rate the same armature had a moment before with
    // every take recording (the bug: 8.6 fps against 60); a busy machine lowers both alike.
    let before = result["applied_fps_before_break"].as_object().unwrap();
    for (id, fps) in result["applied_fps_after_break"].as_object().unwrap() {
        let fps = fps.as_f64().unwrap();
        let was = before[id].as_f64().unwrap();
        println!(
            "{label}: subject {id} applied {fps:.1} frames/s after the take broke, {was:.1} before"
        );
        assert!(
            fps >= (0.75 * was).min(30.0),
            "{label}: subject {id} starved to {fps:.1} frames/s (was {was:.1})"
        );
    }
    // The other armature's take finished with its curves.
    let actions = result["actions"].as_object().unwrap();
    assert!(
        actions
            .values()
            .any(|a| a["fcurves"].as_array().is_some_and(|c| !c.is_empty())),
        "{label}: no take survived: {actions:?}"
    );
    let _ = std::fs::remove_dir_all(&work);
}

/// The foot-lock state reaches Blender: the first labelled walk (found by its motion) drives
/// the mannequin (foot lock on), and
/// the target armature's `rigcast_footplants` property and its foot bones' `rigcast_planted`
/// equal the server's `footplants` messages (state, and position in Blender axes), with each
/// foot seen planted and lifted. Skips without the shared walk.
async fn exposes_the_footplants(blender: Blender) {
    let Some((_, clip, _)) = rigcast_tests::first_walk() else {
        return;
    };
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![rigcast_tests::clip_source(clip)],
        performers: vec![PerformerSpec::target_file("builtin:mannequin")],
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.expect("server starts");
    let addr = server.local_addr();
    let observed = Arc::new(Mutex::new(Observed::default()));
    let watcher = tokio::spawn(watch_stream(addr, observed.clone()));
    let work = work_dir();
    let result = run_blender_off_runtime(blender, addr, &work, "footplants", Zip::Build).await;
    watcher.abort();
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let observed = observed.lock().unwrap();
    let label = format!(
        "Blender {}",
        result["blender_version"].as_str().unwrap_or("?")
    );
    let samples = result["footplant_samples"].as_array().unwrap();
    let mut seen = std::collections::HashSet::new();
    let mut matched = 0;
    for sample in samples {
        let Some(message) = observed
            .footplants
            .iter()
            .find(|m| m["seq"] == sample["seq"])
        else {
            continue; // our client joined later than Blender
        };
        for foot in message["feet"].as_array().unwrap() {
            let bone = foot["bone"].as_str().unwrap();
            let planted = i64::from(foot["planted"].as_bool().unwrap());
            let shown = &sample["property"][bone];
            assert_eq!(
                shown["planted"].as_i64(),
                Some(planted),
                "{label}: {bone} in {sample}"
            );
            assert_eq!(
                sample["bone_planted"][bone].as_i64(),
                Some(planted),
                "{label}: {bone}"
            );
            let expected = blender_from_ours(vec3(&foot["position"]));
            let error = (vec3(&shown["position"]) - expected).length();
            assert!(error < 1e-5, "{label}: {bone} position off by {error} m");
            seen.insert((bone.to_string(), planted));
        }
        matched += 1;
    }
    println!(
        "{label}: {matched} footplants states shown on the armature equal the server's: {seen:?}"
    );
    assert!(
        matched >= 3,
        "{label}: only {matched} states matched ({} samples)",
        samples.len()
    );
    for bone in ["foot_l", "foot_r"] {
        for planted in [0, 1] {
            assert!(
                seen.contains(&(bone.to_string(), planted)),
                "{label}: {bone} never {planted}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&work);
}

fn applied_first(observations: &[&Value]) -> f64 {
    observations[0]["applied_nanos"].as_f64().unwrap()
}

/// The add-on's transport unit tests (WebSocket framing, reconnect, newest-frame-wins, wire
/// decoding, VMC, conversions), run under Blender's own Python.
#[test]
fn blender_addon_unit_tests_pass() {
    let Some(blender) = find_app("blender") else {
        return;
    };
    let _one_at_a_time = BLENDER.lock().unwrap_or_else(|e| e.into_inner());
    let output = Command::new(blender)
        .args([
            "-b",
            "--factory-startup",
            "--python-exit-code",
            "1",
            "--python",
        ])
        .arg(repo_root().join("clients/blender/tests/run_unit_tests.py"))
        .output()
        .expect("blender runs");
    let log = format!(
        "{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.status.success(), "add-on unit tests failed:\n{log}");
    assert!(log.contains(" passed, 0 failed"), "no test summary:\n{log}");
}

/// The add-on zip, built into `work` with the documented command (`build_zip.py --out`).
fn build_zip(python3: &Path, work: &Path) -> PathBuf {
    let zip = work.join("rigcast_livelink.zip");
    let built = Command::new(python3)
        .arg(repo_root().join("clients/blender/build_zip.py"))
        .arg("--out")
        .arg(&zip)
        .output()
        .expect("python3 runs");
    assert!(
        built.status.success() && zip.is_file(),
        "build_zip.py failed: {}",
        String::from_utf8_lossy(&built.stderr)
    );
    zip
}

/// The extensions platform's own validator (`blender_ext.py validate`, shipped inside Blender
/// 4.2+) accepts the built zip's `blender_manifest.toml`, in 4.2, 4.5 and 5.0.
#[test]
fn extension_manifest_passes_blenders_validator() {
    let Some(python3) = find_app("python3") else {
        return;
    };
    let work = work_dir();
    let zip = build_zip(&python3, &work);
    for series in ["4.2", "4.5", "5.0"] {
        let Some(Blender::Module { python, .. }) = Blender::module(series) else {
            continue;
        };
        let site = python.parent().unwrap().parent().unwrap().join("lib");
        let validator = std::fs::read_dir(&site)
            .unwrap()
            .filter_map(Result::ok)
            .map(|d| {
                d.path().join(format!(
                    "site-packages/bpy/{series}/scripts/addons_core/bl_pkg/cli/blender_ext.py"
                ))
            })
            .find(|p| p.is_file())
            .unwrap_or_else(|| {
                panic!(
                    "no blender_ext.py in the bpy {series} wheel under {}",
                    site.display()
                )
            });
        let out = Command::new(&python)
            .arg(&validator)
            .arg("validate")
            .arg(&zip)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        println!("Blender {series} validator: {}", text.trim());
        assert!(
            out.status.success() && text.contains("Success"),
            "Blender {series} rejects the manifest: {text}"
        );
    }
    let _ = std::fs::remove_dir_all(&work);
}

/// Asserts that the add-on's mapping list (from the in-Blender script) equals a `mapping`
/// message's entries: same rows in the same order, same bones, scores and colours.
fn assert_list_equals_message(list: &Value, message: &Value, what: &str) {
    let rows = list.as_array().expect("mapping list");
    let entries = message["entries"].as_array().expect("entries");
    assert_eq!(rows.len(), entries.len(), "{what}: row count");
    for (row, entry) in rows.iter().zip(entries) {
        assert_eq!(row["target"], entry["target"], "{what}: row order");
        assert_eq!(
            row["source"], entry["source"],
            "{what}: source of {}",
            entry["target"]
        );
        let score = row["score"].as_f64().unwrap();
        assert!(
            (score - entry["score"].as_f64().unwrap()).abs() < 1e-5,
            "{what}: score of {}: {score} vs {}",
            entry["target"],
            entry["score"]
        );
        check_flag_shown(row, entry, what);
        for key in ["color_gradient", "color_random"] {
            let distance = (vec3(&row[key]) - vec3(&entry[key])).length();
            assert!(
                distance < 1e-5,
                "{what}: {key} of {}: {} vs {}",
                entry["target"],
                row[key],
                entry[key]
            );
        }
    }
}

/// A row shows the entry's confidence, and the warning icon exactly when the entry is flagged
/// (with the reason kept for the panel).
fn check_flag_shown(row: &Value, entry: &Value, what: &str) {
    let target = &entry["target"];
    let flagged = entry.get("flagged").cloned().unwrap_or(Value::Null);
    assert_eq!(row["flagged"], flagged, "{what}: flag of {target}");
    let icon = if flagged.is_null() { "NONE" } else { "ERROR" };
    assert_eq!(row["icon"], icon, "{what}: icon of {target}");
    let want = entry["confidence"].as_f64().unwrap_or(1.0);
    let got = row["confidence"].as_f64().unwrap();
    assert!(
        (got - want).abs() < 1e-5,
        "{what}: confidence of {target}: {got} vs {want}"
    );
    assert_eq!(
        row["confidence_text"],
        format!("{want:.2}"),
        "{what}: {target}"
    );
}

/// Checks the armatures' bone colours against a mapping message: every target bone with an
/// entry wears its colour, every coloured source bone wears the colour of an entry mapped to it.
fn assert_bone_colors(colors: &Value, message: &Value, key: &str) {
    // Blender 3.x stores bone group colours with 8 bits per channel.
    let near = |a: Vec3, b: Vec3| (a - b).length() < 0.01;
    let entries = message["entries"].as_array().unwrap();
    let target = colors["target"].as_object().expect("target colours");
    let mut checked = 0;
    for entry in entries {
        let name = entry["target"].as_str().unwrap();
        let got = target
            .get(name)
            .unwrap_or_else(|| panic!("{key}: target bone {name} not coloured"));
        assert!(
            near(vec3(got), vec3(&entry[key])),
            "{key}: target bone {name} is {got}, mapping says {}",
            entry[key]
        );
        checked += 1;
    }
    assert!(checked >= 15, "{key}: only {checked} target bones");
    if let Some(source) = colors.get("source").and_then(Value::as_object) {
        let mut mapped_sources = 0;
        for (name, got) in source {
            let candidates: Vec<Vec3> = entries
                .iter()
                .filter(|e| e["source"] == name.as_str())
                .map(|e| vec3(&e[key]))
                .collect();
            assert!(
                candidates.iter().any(|c| near(*c, vec3(got))),
                "{key}: source bone {name} is {got}, not a colour of the entries it drives"
            );
            mapped_sources += 1;
        }
        assert!(
            mapped_sources >= 10,
            "{key}: only {mapped_sources} source bones coloured"
        );
    }
}

/// The add-on's mapping scenario against `server` (its control token typed into the Token
/// field: overriding a mapping changes the server), our own client watching the stream until
/// it has seen `mappings` mapping messages (at most 5 s after Blender finished); the server is
/// shut down after. The script's result and what the watcher saw.
async fn mapping_scenario(
    blender: Blender,
    server: rigcast_server::ServerHandle,
    work: &Path,
    mappings: usize,
) -> (Value, Arc<Mutex<Observed>>) {
    let addr = server.local_addr();
    let observed = Arc::new(Mutex::new(Observed::default()));
    let watcher = tokio::spawn(watch_stream(addr, observed.clone()));
    let token = server.control_token().reveal().to_string();
    let result =
        run_blender_with_token(blender, addr, work, "mapping", Zip::Build, Some(token)).await;
    let deadline = Instant::now() + Duration::from_secs(5);
    while observed.lock().unwrap().mappings.len() < mappings && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    watcher.abort();
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    (result, observed)
}

async fn shows_and_overrides_the_server_mapping(blender: Blender) {
    let work = work_dir();
    // The override's rebuilt mapping is the second message our client sees.
    let (result, observed) = mapping_scenario(blender, start_demo_server().await, &work, 2).await;
    let observed = observed.lock().unwrap();

    let target = result["override"]["target"].as_str().unwrap().to_string();
    let new_source = result["override"]["source"].as_str().unwrap().to_string();
    let source_of = |m: &Value| -> Value {
        m["entries"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["target"] == target.as_str())
            .map(|e| e["source"].clone())
            .unwrap_or(Value::Null)
    };
    let has_override = |m: &&Value| source_of(m) == new_source.as_str();
    let before = observed
        .mappings
        .iter()
        .rfind(|m| !has_override(m))
        .expect("the server's mapping before the override");
    let after = observed
        .mappings
        .iter()
        .find(has_override)
        .unwrap_or_else(|| {
            panic!(
                "the server never broadcast a mapping with {target} ← {new_source}; got {} mapping messages; add-on error: {}",
                observed.mappings.len(),
                result["last_error"]
            )
        });

    // The list is the server's mapping of the demo's target, fed from the source's bones.
    let hello = observed.hello.as_ref().unwrap();
    let mannequin = hello["subjects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["kind"] == "target")
        .expect("a target subject");
    assert_eq!(result["mapping_subject"], mannequin["id"]);
    assert_eq!(before["subject"], mannequin["id"]);
    assert_eq!(result["source_subject"], before["source_subject"]);
    let rows = result["list_before"].as_array().unwrap().len();
    assert!(rows >= 15, "only {rows} mapping rows");
    assert_list_equals_message(&result["list_before"], before, "before the override");
    let source_id = before["source_subject"].as_u64().unwrap();
    let source_bones: Vec<&Value> = observed.skeletons[&source_id]["bones"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| &b["name"])
        .collect();
    let choices: Vec<&Value> = result["source_bone_choices"]
        .as_array()
        .unwrap()
        .iter()
        .collect();
    assert_eq!(
        choices, source_bones,
        "bone picker offers the source's bones"
    );

    // Bones wear the message's colours, in both modes.
    assert_bone_colors(&result["colors_gradient"], before, "color_gradient");
    assert_bone_colors(&result["colors_random"], before, "color_random");

    // Picking a row shows its current source bone; the override comes back from the server.
    assert_eq!(
        result["picked_row"]["shown_source"],
        source_of(before),
        "picking a row shows its source bone"
    );
    assert_ne!(source_of(before), new_source.as_str());
    assert_eq!(
        result["override_shown"], true,
        "the add-on's list never showed {target} ← {new_source}"
    );
    let entry = after["entries"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["target"] == target.as_str())
        .unwrap();
    assert_eq!(entry["score"].as_f64(), Some(0.0), "overrides score 0");
    // The user has decided the bone: full confidence, no flag (a flagged row is the one picked
    // when the mapping has one).
    assert_eq!(
        entry["confidence"].as_f64(),
        Some(1.0),
        "overrides are sure"
    );
    assert!(
        entry.get("flagged").is_none(),
        "an override stays flagged: {entry}"
    );
    let flagged_before = before["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e.get("flagged").is_some())
        .count();
    if flagged_before > 0 {
        assert!(
            !result["picked_row"]["flagged"].is_null(),
            "{flagged_before} flagged rows, but an unflagged one was picked"
        );
    }
    println!("mapping: {flagged_before} flagged bones before the override");
    assert_list_equals_message(&result["list_after"], after, "after the override");
    assert_bone_colors(&result["colors_after"], after, "color_gradient");
    println!(
        "mapping: {rows} rows equal the server's; override {target} ← {new_source} (was {}) came back from the server and is shown",
        source_of(before)
    );
    let _ = std::fs::remove_dir_all(&work);
}

/// A mapping with flagged bones (the shared data's first labelled human clip without a neck,
/// a sparse spine, onto the built-in mannequin, whose chest and neck no source bone can drive;
/// skipped without one): the
/// add-on's list equals the server's message with its flags, marks exactly the flagged rows
/// with the warning icon and shows each row's confidence.
async fn marks_the_bones_the_mapper_flagged(blender: Blender) {
    let Some((_, clip)) = rigcast_tests::first_neckless_clip() else {
        return;
    };
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![rigcast_tests::clip_source(clip)],
        performers: vec![PerformerSpec::target_file("builtin:mannequin")],
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let work = work_dir();
    let (result, observed) = mapping_scenario(blender, server, &work, 1).await;
    let observed = observed.lock().unwrap();
    let before = observed
        .mappings
        .first()
        .expect("the server's first mapping");
    let flagged: Vec<&Value> = before["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e.get("flagged").is_some())
        .collect();
    assert!(
        !flagged.is_empty(),
        "a sparse spine onto the mannequin flags nothing"
    );
    assert_list_equals_message(&result["list_before"], before, "flagged mapping");
    let marked = result["list_before"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|row| row["icon"] == "ERROR")
        .count();
    assert_eq!(marked, flagged.len(), "marked rows");
    println!(
        "mapping: {marked} flagged rows marked in the add-on's list: {:?}",
        flagged.iter().map(|e| &e["target"]).collect::<Vec<_>>()
    );
    let _ = std::fs::remove_dir_all(&work);
}

/// What a user does: build the zip with the documented command, start `rigcast serve` (only
/// the listen address given, the port being free), install and enable the add-on with default
/// settings, type the address, connect.
async fn zip_connects_to_the_rigcast_binary(blender: Blender) {
    let Some(python) = find_app("python3") else {
        return;
    };
    let work = work_dir();
    let zip = build_zip(&python, &work);

    let binary = tokio::task::spawn_blocking(rigcast_binary).await.unwrap();
    let listen = format!("127.0.0.1:{}", free_port());
    let mut child = Command::new(&binary)
        .args(["serve", "--listen", &listen])
        // Its own config folder: the token it creates is not the user's.
        .env("XDG_CONFIG_HOME", work.join("config"))
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("rigcast starts");
    let stdout = child.stdout.take().unwrap();
    let server = KillOnDrop(child);
    // Read until the stream address is printed, then keep draining so prints never block.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
        {
            if line.trim().starts_with("stream: ") {
                let _ = tx.send(line);
            }
        }
    });
    let line = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("rigcast printed its stream address");
    assert!(line.contains(&listen), "{line}");
    let addr: SocketAddr = listen.parse().unwrap();

    let result = run_blender_off_runtime(blender, addr, &work, "connect", Zip::Use(zip)).await;
    drop(server);

    // Default settings: the server's default address, WebSocket, the panel in the sidebar.
    assert_eq!(
        result["default_address"],
        ServerConfig::default().listen.to_string().as_str()
    );
    assert_eq!(result["default_transport"], "WEBSOCKET");
    assert_eq!(result["panel"]["space"], "VIEW_3D");
    assert_eq!(result["panel"]["region"], "UI");
    assert_eq!(result["panel"]["category"], "rigcast");
    let connect = &result["connect"];
    assert_eq!(connect["connected"], true, "{connect}");
    assert_eq!(connect["status"], "connected", "{connect}");
    assert_eq!(
        connect["subjects"],
        serde_json::json!(["demo", "mannequin"]),
        "{connect}"
    );
    for (id, n) in connect["applied"].as_object().unwrap() {
        assert!(n.as_u64() >= Some(10), "subject {id}: {n} frames applied");
    }
    assert!(connect["mapping_rows"].as_u64() >= Some(15), "{connect}");
    assert_eq!(result["status_after_disconnect"], "not connected");
    println!("binary: {connect}");
    let _ = std::fs::remove_dir_all(&work);
}
