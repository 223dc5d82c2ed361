//! Hostile files to the real commands: each is refused with a one-line error, quickly and in
//! little memory (measured on the child process itself), never by a panic, an abort or a
//! hang. The files are made here, small and adversarial, as an attacker would write them.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

/// Wall-clock bound for a refusal.
const MAX_SECS: f64 = 2.0;
/// Memory bound for a refusal: the child's data segment limit (RLIMIT_DATA: heap and private
/// writable mappings), so going beyond it is an allocation failure (an abort, which fails the
/// test), not a number to read afterwards. A peak RSS read with wait4 would include the
/// forking test process's own pages.
const MAX_DATA_BYTES: u64 = 100 * 1000 * 1000;

/// What one run of the binary did.
struct Run {
    code: Option<i32>,
    stderr: String,
    secs: f64,
}

/// Runs `rigcast ARGS` to completion under [`MAX_DATA_BYTES`] (killed after 20 s). With
/// `RIGCAST_HOSTILE_TIME=1` it runs under `/usr/bin/time` and prints the command's peak RSS and
/// wall time (the figures in BENCHMARKS.md).
fn run(args: &[&str]) -> Run {
    use std::os::unix::process::CommandExt;
    let dir = common::test_dir("hostile_files_home");
    let timed = std::env::var_os("RIGCAST_HOSTILE_TIME").is_some();
    let time_file = dir.join(format!("time-{}.txt", std::process::id()));
    let start = Instant::now();
    let mut cmd = if timed {
        let mut c = Command::new("/usr/bin/time");
        c.args(["-f", "%M %e", "-o"])
            .arg(&time_file)
            .arg(env!("CARGO_BIN_EXE_rigcast"));
        c
    } else {
        Command::new(env!("CARGO_BIN_EXE_rigcast"))
    };
    cmd.args(args)
        .env("XDG_CONFIG_HOME", &dir)
        .env("XDG_CACHE_HOME", dir.join("cache"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    // SAFETY: only setrlimit (async-signal-safe) runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: MAX_DATA_BYTES,
                rlim_max: MAX_DATA_BYTES,
            };
            if libc::setrlimit(libc::RLIMIT_DATA, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = cmd.spawn().unwrap();
    let pid = child.id() as libc::pid_t;
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        use std::io::Read;
        let mut s = String::new();
        let _ = stderr.take(1 << 20).read_to_string(&mut s);
        s
    });
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watchdog = {
        let done = done.clone();
        std::thread::spawn(move || {
            let until = Instant::now() + Duration::from_secs(20);
            while Instant::now() < until && !done.load(std::sync::atomic::Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(20));
            }
            if !done.load(std::sync::atomic::Ordering::Relaxed) {
                // SAFETY: kill(2) on our own child, which has not been reaped yet (`done` is
                // set only after the wait below returns).
                unsafe { libc::kill(pid, libc::SIGKILL) };
            }
        })
    };
    let status = child.wait().unwrap();
    let secs = start.elapsed().as_secs_f64();
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    watchdog.join().unwrap();
    if timed {
        report_time(args, &time_file);
    }
    Run {
        code: status.code(),
        stderr: reader.join().unwrap(),
        secs,
    }
}

/// Prints what `/usr/bin/time` measured of one run: peak RSS and wall time.
fn report_time(args: &[&str], time_file: &Path) {
    let measured = std::fs::read_to_string(time_file).unwrap_or_default();
    let figures: Vec<&str> = measured.lines().last().unwrap_or("").split(' ').collect();
    let [rss_kb, wall] = figures[..] else {
        panic!("/usr/bin/time wrote {measured:?}");
    };
    // File names only: the test folders' paths say nothing.
    let shown: Vec<&str> = args
        .iter()
        .map(|a| a.rsplit('/').next().unwrap_or(a))
        .collect();
    println!(
        "hostile: rigcast {}: peak RSS {:.1} MB, {wall} s",
        shown.join(" "),
        rss_kb.parse::<f64>().unwrap_or(f64::NAN) / 1000.0
    );
}

/// `rigcast ARGS` must refuse: exit status 1 (not a signal, not a panic's 101), one line on
/// stderr mentioning `expect`, under [`MAX_SECS`] and [`MAX_DATA_BYTES`].
fn refused(args: &[&str], expect: &str) {
    let r = run(args);
    let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(
        r.code,
        Some(1),
        "{args:?}: exit {:?}, stderr {}",
        r.code,
        r.stderr
    );
    assert_eq!(lines.len(), 1, "{args:?}: one line expected: {}", r.stderr);
    assert!(
        lines[0].contains(expect),
        "{args:?}: {:?} does not mention {expect:?}",
        lines[0]
    );
    assert!(
        lines[0].len() < 400,
        "{args:?}: a short error: {}",
        lines[0]
    );
    assert!(r.secs < MAX_SECS, "{args:?}: took {:.2} s", r.secs);
}

fn write(name: &str, text: &str) -> PathBuf {
    common::test_file("hostile_files", name, text)
}

/// A BVH whose joints nest `depth` deep (one channel set per joint, one frame).
fn nested_bvh(depth: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT j0\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n");
    for i in 1..depth {
        s.push_str(&format!(
            "JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
        ));
    }
    s.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
    for _ in 0..depth {
        s.push_str("}\n");
    }
    let channels = 6 + 3 * (depth - 1);
    s.push_str(&format!(
        "MOTION\nFrames: 1\nFrame Time: 0.0333\n{}\n",
        vec!["0"; channels].join(" ")
    ));
    s
}

/// A small humanoid-ish BVH with the given frame time and motion lines.
fn small_bvh(frame_time: &str, frames: &[&str]) -> String {
    let mut s = String::from(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 90 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
         JOINT LeftUpLeg\n {\n  OFFSET 10 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n\
         JOINT LeftLeg\n  {\n   OFFSET 0 -45 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 -45 0\n   }\n  }\n }\n\
         JOINT RightUpLeg\n {\n  OFFSET -10 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n\
         JOINT RightLeg\n  {\n   OFFSET 0 -45 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 -45 0\n   }\n  }\n }\n\
         JOINT Spine\n {\n  OFFSET 0 20 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 40 0\n   }\n }\n}\n",
    );
    s.push_str(&format!(
        "MOTION\nFrames: {}\nFrame Time: {frame_time}\n",
        frames.len()
    ));
    for f in frames {
        s.push_str(f);
        s.push('\n');
    }
    s
}

const STILL: &str = "0 90 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";

fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | (b as u32) << (16 - 8 * i));
        for i in 0..4 {
            if i <= c.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A glTF of `nodes` (JSON objects) whose first skin's joints are `joints`, with `extra`
/// top-level members (buffers, accessors, animations) appended.
fn gltf(nodes: &str, joints: &str, extra: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"nodes":[{nodes}],"skins":[{{"joints":[{joints}]}}]{extra}}}"#
    )
}

/// Two joints, animated by one rotation channel with keys at 0 s and `end_secs`.
fn gltf_keyed_until(end_secs: f32) -> String {
    let mut bytes = Vec::new();
    for t in [0.0f32, end_secs] {
        bytes.extend_from_slice(&t.to_le_bytes());
    }
    for _ in 0..2 {
        for v in [0.0f32, 0.0, 0.0, 1.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let extra = format!(
        r#","buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":8}},{{"buffer":0,"byteOffset":8,"byteLength":32}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[{end_secs}]}},
{{"bufferView":1,"componentType":5126,"count":2,"type":"VEC4"}}],
"animations":[{{"channels":[{{"sampler":0,"target":{{"node":1,"path":"rotation"}}}}],"samplers":[{{"input":0,"output":1}}]}}]"#,
        len = bytes.len(),
        b64 = base64(&bytes)
    );
    gltf(
        r#"{"name":"root","children":[1]},{"name":"child","translation":[0,1,0]}"#,
        "0,1",
        &extra,
    )
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn deeply_nested_bvh_is_refused_by_every_command() {
    let deep = write("deep.bvh", &nested_bvh(20_000));
    let d = path_str(&deep);
    let out = common::test_dir("hostile_files_out");
    let glb = out.join("o.glb");
    refused(&["info", d], "joint depth");
    refused(&["map", d, "builtin:mannequin"], "joint depth");
    let target = write("target.bvh", &small_bvh("0.0333", &[STILL]));
    refused(
        &[
            "retarget",
            d,
            "--target",
            path_str(&target),
            "-o",
            path_str(&glb),
        ],
        "joint depth",
    );
    refused(&["convert", d, path_str(&glb)], "joint depth");
    let deep5k = write("deep5k.bvh", &nested_bvh(5_000));
    let listen = "--listen=127.0.0.1:0";
    refused(
        &[
            "serve",
            listen,
            "--source",
            &format!("replay:{}", path_str(&deep5k)),
        ],
        "joint depth",
    );
    // Within the limit it reads (depth is not refused for its own sake).
    let ok = write("deep500.bvh", &nested_bvh(500));
    common::rigcast_ok(["info", path_str(&ok)]);
}

#[test]
fn numbers_that_overflow_f32_or_bounds_are_refused() {
    let out = common::test_dir("hostile_files_out");
    let glb = out.join("o.glb");
    let bvh_out = out.join("o.bvh");
    let target = write("target.bvh", &small_bvh("0.0333", &[STILL]));
    let huge = write(
        "huge_value.bvh",
        &small_bvh("0.0333", &[STILL, &STILL.replacen("0 90", "1e300 90", 1)]),
    );
    for cmd in [
        vec![
            "retarget",
            path_str(&huge),
            "--target",
            path_str(&target),
            "-o",
            path_str(&glb),
        ],
        vec!["convert", path_str(&huge), path_str(&bvh_out)],
        vec!["info", path_str(&huge)],
    ] {
        refused(&cmd, "finite number");
    }
    // Finite as f32, each, but far beyond any capture volume.
    let far = write(
        "far_value.bvh",
        &small_bvh("0.0333", &[STILL, &STILL.replacen("0 90", "3e38 90", 1)]),
    );
    refused(&["convert", path_str(&far), path_str(&bvh_out)], "10 km");
    let slow = write("frame_time_huge.bvh", &small_bvh("1e300", &[STILL, STILL]));
    refused(&["info", path_str(&slow)], "Frame Time");
    refused(
        &[
            "serve",
            "--listen=127.0.0.1:0",
            "--source",
            &format!("replay:{}", path_str(&slow)),
        ],
        "Frame Time",
    );
    let frames: Vec<&str> = vec![STILL; 40];
    let long = write("frame_time_1e4.bvh", &small_bvh("1e4", &frames));
    refused(
        &[
            "retarget",
            path_str(&long),
            "--target",
            path_str(&target),
            "--fps",
            "30",
            "-o",
            path_str(&glb),
        ],
        "Frame Time",
    );
}

#[test]
fn upsampling_is_bounded_by_what_the_file_holds() {
    // A legal frame time (1 s) and a few frames, asked for 240 fps on a long clip: the frames
    // it would make are bounded by the file's own size, not by the request.
    let frames: Vec<&str> = vec![STILL; 3_000];
    let target = write("target.bvh", &small_bvh("0.0333", &[STILL]));
    let sparse = write("sparse.bvh", &small_bvh("1", &frames));
    let glb = common::test_dir("hostile_files_out").join("o.glb");
    refused(
        &[
            "retarget",
            path_str(&sparse),
            "--target",
            path_str(&target),
            "--fps",
            "240",
            "-o",
            path_str(&glb),
        ],
        "bone samples",
    );
}

#[test]
fn gltf_node_cycles_and_far_keyframes_are_refused() {
    let own = write(
        "own_child.gltf",
        &gltf(r#"{"name":"a","children":[0]}"#, "0", ""),
    );
    refused(&["info", path_str(&own)], "own ancestor");
    let pair = write(
        "pair.gltf",
        &gltf(
            r#"{"name":"a","children":[1]},{"name":"b","children":[0]}"#,
            "0,1",
            "",
        ),
    );
    refused(&["info", path_str(&pair)], "own ancestor");
    refused(
        &[
            "serve",
            "--listen=127.0.0.1:0",
            "--source",
            &format!("replay:{}", path_str(&pair)),
        ],
        "own ancestor",
    );
    let two_parents = write(
        "two_parents.gltf",
        &gltf(
            r#"{"name":"a","children":[2]},{"name":"b","children":[2]},{"name":"c"}"#,
            "0,1,2",
            "",
        ),
    );
    refused(&["info", path_str(&two_parents)], "child of both");
    let far = write("far_key.gltf", &gltf_keyed_until(1e6));
    refused(&["info", path_str(&far)], "bone samples");
    let bvh_out = common::test_dir("hostile_files_out").join("o.bvh");
    refused(
        &["convert", path_str(&far), path_str(&bvh_out)],
        "bone samples",
    );
    // A key a few seconds out reads.
    let near = write("near_key.gltf", &gltf_keyed_until(2.0));
    common::rigcast_ok(["info", path_str(&near)]);
}

#[test]
fn gltf_buffers_come_only_from_the_file_or_beside_it() {
    let dir = common::test_dir("hostile_files_buffers");
    std::fs::write(dir.join("beside.bin"), [0u8; 8]).unwrap();
    let with_buffer = |name: &str, uri: &str, len: u64| {
        let text = gltf(
            r#"{"name":"a"}"#,
            "0",
            &format!(r#","buffers":[{{"byteLength":{len},"uri":"{uri}"}}]"#),
        );
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    for (name, uri, expect) in [
        ("dev.gltf", "/dev/zero", "not a file beside"),
        ("passwd.gltf", "../../../../etc/passwd", "not a file beside"),
        (
            "encoded.gltf",
            "%2e%2e/%2e%2e/etc/passwd",
            "not a file beside",
        ),
        ("scheme.gltf", "file:///etc/passwd", "not a file beside"),
    ] {
        refused(&["info", path_str(&with_buffer(name, uri, 8))], expect);
    }
    let link = dir.join("zero.bin");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    refused(
        &["info", path_str(&with_buffer("link.gltf", "zero.bin", 8))],
        "out of the glTF",
    );
    refused(
        &[
            "info",
            path_str(&with_buffer("huge.gltf", "beside.bin", 1 << 40)),
        ],
        "declared buffer bytes",
    );
    // The file beside it is read (the document itself is fine without animation).
    common::rigcast_ok(["info", path_str(&with_buffer("ok.gltf", "beside.bin", 8))]);
}

#[test]
fn clip_paths_that_name_no_regular_file_are_refused_before_reading() {
    let dir = common::test_dir("hostile_files_special");
    // A device, a FIFO (whose open would block until a writer came) and a folder, each named
    // like a clip; and a sparse file past the size bound (nothing of it is read).
    let zero = dir.join("zero.bvh");
    let _ = std::fs::remove_file(&zero);
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let fifo = dir.join("fifo.glb");
    let _ = std::fs::remove_file(&fifo);
    let c = std::ffi::CString::new(path_str(&fifo)).unwrap();
    // SAFETY: mkfifo(3) with a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let folder = dir.join("folder.bvh");
    std::fs::create_dir_all(&folder).unwrap();
    for p in [&zero, &fifo, &folder] {
        refused(&["info", path_str(p)], "not a regular file");
        refused(
            &["map", path_str(p), "builtin:mannequin"],
            "not a regular file",
        );
    }
    let huge = dir.join("huge.bvh");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len((1 << 30) + 1)
        .unwrap();
    refused(&["info", path_str(&huge)], "limit");
    let _ = std::fs::remove_file(&huge);
    // Buffers that each declare a byte of one large file beside it: the file would be read
    // once per buffer, so the files' sizes count together.
    let big = dir.join("big.bin");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(600 << 20)
        .unwrap();
    let text = gltf(
        r#"{"name":"a"}"#,
        "0",
        r#","buffers":[{"byteLength":1,"uri":"big.bin"},{"byteLength":1,"uri":"big.bin"}]"#,
    );
    let twice = dir.join("twice.gltf");
    std::fs::write(&twice, text).unwrap();
    refused(&["info", path_str(&twice)], "buffer files");
    let _ = std::fs::remove_file(&big);
}

#[test]
fn durations_that_are_finite_but_no_duration_are_refused() {
    // 1e300 s passes a finite, positive check and still panics `Duration::from_secs_f64`.
    let listen = "--listen=127.0.0.1:0";
    for (name, text, expect) in [
        (
            "stall.toml",
            "stalled_client_timeout_secs = 1e300\n",
            "stalled_client_timeout_secs",
        ),
        (
            "lost.toml",
            "[cluster]\nservers = [\"nats://127.0.0.1:1\"]\nsite = \"a\"\nlost_after_secs = 1e30\n",
            "lost_after_secs",
        ),
    ] {
        let config = write(name, text);
        refused(
            &[
                "serve",
                listen,
                "--source",
                "demo",
                "--config",
                path_str(&config),
            ],
            expect,
        );
    }
    refused(
        &[
            "record",
            "--url",
            "ws://127.0.0.1:1/v1/stream",
            "-o",
            "/dev/null",
            "--duration",
            "1e300",
        ],
        "--duration",
    );
}

#[test]
fn gltf_files_that_broke_the_gltf_crate_are_refused() {
    // Found by the fuzzer (tests/tests/fuzz_targets.rs): a GLB total length under the 12-byte
    // header made the glTF crate subtract past zero (a panic in a debug build).
    let dir = common::test_dir("hostile_files_glb");
    let mut bytes = b"glTF".to_vec();
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&8u32.to_le_bytes());
    bytes.extend_from_slice(b"JSON{}  ");
    let p = dir.join("short_header.glb");
    std::fs::write(&p, &bytes).unwrap();
    refused(&["info", path_str(&p)], "GLB header declares 2 bytes");
    refused(&["map", path_str(&p), "builtin:mannequin"], "GLB header");
    // Also found by the fuzzer: a mesh whose POSITION names an accessor that does not exist
    // made the glTF crate's validation index past its list (a panic in release builds too).
    let mesh = gltf(
        r#"{"name":"a","mesh":0}"#,
        "0",
        r#","meshes":[{"primitives":[{"attributes":{"POSITION":5}}]}]"#,
    );
    let p = dir.join("position_past_accessors.gltf");
    std::fs::write(&p, mesh).unwrap();
    refused(&["info", path_str(&p)], "POSITION names accessor 5 of");
}

#[test]
fn node_names_with_newlines_make_a_bvh_that_reads_back() {
    // Names legal in glTF JSON but not on one BVH line; two of them collapse to the same words.
    let nodes = r#"{"name":"hips\nroot","children":[1,2,3]},{"name":"left\tleg","translation":[0.1,-0.5,0]},{"name":"left leg","translation":[-0.1,-0.5,0]},{"name":"","translation":[0,0.5,0]}"#;
    let src = write("newline_names.gltf", &gltf(nodes, "0,1,2,3", ""));
    let out = common::test_dir("hostile_files_out").join("newline_names.bvh");
    common::rigcast_ok(["convert", path_str(&src), path_str(&out)]);
    let info = common::rigcast_ok(["info", path_str(&out)]);
    for name in ["hips root", "left leg"] {
        assert!(info.contains(name), "{name} in {info}");
    }
    // And it converts on, its four bones intact.
    let again = common::test_dir("hostile_files_out").join("again.bvh");
    common::rigcast_ok(["convert", path_str(&out), path_str(&again)]);
    let text = std::fs::read_to_string(&again).unwrap();
    assert_eq!(
        text.matches("JOINT").count() + text.matches("ROOT").count(),
        4,
        "{text}"
    );
}

/// A BVH of `joints` (name, parent index or `None` for a child of the root, offset), each joint
/// with three rotation channels and leaves closed by an End Site; one frame of zeros. Written
/// with an explicit stack (the shapes below are up to 1,000 deep).
fn rig_bvh(joints: &[(String, Option<usize>, [i32; 3])]) -> String {
    let mut children = vec![Vec::new(); joints.len()];
    let mut top = Vec::new();
    for (i, (_, parent, _)) in joints.iter().enumerate() {
        match parent {
            Some(p) => children[*p].push(i),
            None => top.push(i),
        }
    }
    let mut s = String::from("HIERARCHY\nROOT Hips\n{\nOFFSET 0 90 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n");
    // (joint, opened): a joint is written when first popped, closed when popped again.
    let mut stack: Vec<(usize, bool)> = top.iter().rev().map(|&j| (j, false)).collect();
    while let Some((j, opened)) = stack.pop() {
        if opened {
            s.push_str("}\n");
            continue;
        }
        let (name, _, [x, y, z]) = &joints[j];
        s.push_str(&format!(
            "JOINT {name}\n{{\nOFFSET {x} {y} {z}\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
        ));
        if children[j].is_empty() {
            s.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
        }
        stack.push((j, true));
        stack.extend(children[j].iter().rev().map(|&c| (c, false)));
    }
    s.push_str(&format!(
        "}}\nMOTION\nFrames: 1\nFrame Time: 0.0333\n{}\n",
        vec!["0"; 6 + 3 * joints.len()].join(" ")
    ));
    s
}

#[test]
fn rigs_of_four_thousand_joints_map_without_quadratic_work() {
    // Each shape once met a search per bone or per pair of bones: 4,000 siblings (the
    // mirror-pair search: 32 s in a release build), a binary tree, many short chains, a few
    // long ones (the unmapped-bone check and the detached-foot lookup: 9 s in a debug build).
    let fan: Vec<_> = (0..4000)
        .map(|i| (format!("j{i}"), None, [i % 50, i / 50, 1]))
        .collect();
    let tree: Vec<_> = (0..4094usize)
        .map(|i| {
            let side = if i % 2 == 0 { -1 } else { 1 };
            (format!("t{i}"), (i >= 2).then(|| i / 2 - 1), [side, 1, 0])
        })
        .collect();
    let chains = |count: usize, len: usize| -> Vec<_> {
        (0..count * len)
            .map(|i| {
                let (c, k) = (i / len, i % len);
                let at = [(c % 7) as i32 - 3, 1, (c / 7) as i32];
                (format!("c{c}_{k}"), (k > 0).then(|| i - 1), at)
            })
            .collect()
    };
    let target = write("fan_target.bvh", &small_bvh("0.0333", &[STILL]));
    let start = Instant::now();
    for (name, joints) in [
        ("fan4000.bvh", fan),
        ("tree4094.bvh", tree),
        ("chains400x10.bvh", chains(400, 10)),
        ("chains4x1000.bvh", chains(4, 1000)),
    ] {
        let rig = write(name, &rig_bvh(&joints));
        for (from, onto) in [(&rig, &target), (&target, &rig)] {
            let t = Instant::now();
            common::rigcast_ok(["map", path_str(from), path_str(onto)]);
            println!(
                "map {} onto {}: {:.2} s",
                from.file_name().unwrap().to_string_lossy(),
                onto.file_name().unwrap().to_string_lossy(),
                t.elapsed().as_secs_f64()
            );
        }
    }
    // A guard against a quadratic search's return (minutes in this debug build), not a speed
    // target: the figures are in BENCHMARKS.md.
    assert!(
        start.elapsed() < Duration::from_secs(60),
        "{:?}",
        start.elapsed()
    );
}
