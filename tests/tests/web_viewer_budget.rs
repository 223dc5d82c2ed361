//! The viewer's frame-time budget (issue 15) in real headless Chromium (SwiftShader: a CPU
//! rasteriser, so the page must trade detail for rate) against the real server: the embedded
//! demo at 60 Hz driving two of the heaviest labelled skinned human GLB of the shared data (the
//! one with the most skinned vertices: the budget's hardest case; skipped with a printed reason
//! when none is present) and the built-in mannequin.
//!
//! - With the budget left to itself, once it has settled, the page draws at least
//!   [`TARGET_FPS`] new frames per second, counted by three.js's own render counter and the
//!   page's clock over a window the test chooses (not by the budget's report, which is only
//!   checked to agree), both characters are still drawn as skinned meshes and their bone
//!   matrices still change. Where the machine is too busy to draw even the stick figures at
//!   the lowest level at that rate in the same run, the budget must instead have stepped down
//!   to the lowest level and draw about as fast as that level alone.
//! - `?quality=full` draws the file's own meshes: as many vertices as the file's skinned
//!   primitives have and at least their triangles per render, both counted from the GLB here.
//! - The proxies skin like the originals: three.js's CPU skinning puts every proxy vertex where
//!   it puts the file's vertex it came from, in the live pose.
//! - Every level and the stick figures are measured in the same run; the table is printed
//!   (BENCHMARKS.md, "Viewer with skinned characters").
//! - The budget's stepping on its own (budget.js in the page, fed synthetic frame times): down
//!   while over budget, back up with headroom, a failed step up retried later and later.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::{Duration, Instant};

use rigcast_server::{PerformerSpec, ServerConfig, SourceSpec};
use rigcast_tests::chromium::{one_browser, DevTools};
use rigcast_tests::skinned_human_glbs;
use serde_json::{json, Value};

/// New frames per second the page must reach with the budget on. Measured on this 2-core
/// machine (BENCHMARKS.md): the lowest level reaches 24-31 frames/s under a load average of
/// 8-10 from other builds, the file's own meshes 9-10; 20 is the smoothness asked for and
/// leaves a margin for a busier machine.
const TARGET_FPS: f64 = 20.0;

/// Seconds of each measuring window.
const WINDOW_SECS: f64 = 5.0;

/// The least share of one window's rate another window of the same page reaches on a busy
/// machine (the budget's level against the same level forced, measured one after the other).
const WINDOW_SWING: f64 = 0.75;

/// Vertices and triangles of the GLB's skinned primitives (nodes with a `skin` and a `mesh`),
/// read from its JSON: the independent count `?quality=full` is checked against.
fn skinned_size(glb: &[u8]) -> (u64, u64) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let (mut vertices, mut triangles) = (0, 0);
    for node in doc["nodes"].as_array().unwrap() {
        if node.get("skin").is_none() {
            continue;
        }
        let Some(mesh) = node["mesh"].as_u64() else {
            continue;
        };
        for primitive in doc["meshes"][mesh as usize]["primitives"]
            .as_array()
            .unwrap()
        {
            let count = |accessor: &Value| {
                doc["accessors"][accessor.as_u64().unwrap() as usize]["count"]
                    .as_u64()
                    .unwrap()
            };
            let v = count(&primitive["attributes"]["POSITION"]);
            vertices += v;
            triangles += primitive.get("indices").map_or(v, count) / 3;
        }
    }
    (vertices, triangles)
}

async fn serve(xbot: &Path) -> rigcast_server::ServerHandle {
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![SourceSpec::demo()],
        performers: vec![
            PerformerSpec::target_file(xbot),
            PerformerSpec::target_file(xbot),
            PerformerSpec::target_file("builtin:mannequin"),
        ],
        ..ServerConfig::default()
    };
    rigcast_server::start(config).await.unwrap()
}

/// Evaluates a promise-returning expression (its result a JSON string) and parses it.
async fn eval_async(cdp: &mut DevTools, expression: &str) -> Value {
    let result = cdp
        .call(
            "Runtime.evaluate",
            json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }),
        )
        .await;
    assert!(
        result.get("exceptionDetails").is_none(),
        "page script threw: {}",
        result["exceptionDetails"]
    );
    serde_json::from_str(result["result"]["value"].as_str().expect("a JSON string")).unwrap()
}

/// Navigates to `query` and waits (60 s) until subjects 1 and 2 have their models on the page.
async fn open(cdp: &mut DevTools, base: &str, query: &str) {
    cdp.call("Page.navigate", json!({ "url": format!("{base}{query}") }))
        .await;
    let start = Instant::now();
    loop {
        let meshes = cdp
            .eval_json("JSON.stringify(window.rigcast?.meshes ? window.rigcast.meshes() : {})")
            .await;
        if meshes["1"]["skinnedMeshes"].as_u64() > Some(0)
            && meshes["2"]["skinnedMeshes"].as_u64() > Some(0)
        {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{query}: both models not on the page within 60 s: {meshes}; page errors {:?}",
            cdp.errors()
        );
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
}

/// Waits until the budget has kept its level for 4 s (at most 40 s); returns the level.
async fn settle(cdp: &mut DevTools) -> String {
    let start = Instant::now();
    let (mut level, mut since) = (String::new(), Instant::now());
    while start.elapsed() < Duration::from_secs(40) {
        let now = cdp
            .eval_json("JSON.stringify(window.rigcast.perf().quality)")
            .await;
        let now = now.as_str().unwrap().to_string();
        if now != level {
            (level, since) = (now, Instant::now());
        } else if since.elapsed() >= Duration::from_secs(4) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    level
}

/// One measuring window: renders counted by three.js (`renderer.info.render.frame`) over the
/// page's clock, display frames by a requestAnimationFrame loop of the test's own, and what
/// the page draws (its report and meshes) at the end.
async fn measure(cdp: &mut DevTools) -> Value {
    let script = format!(
        "(async () => {{ const r = window.rigcast; const t0 = performance.now(); const f0 = r.perf().renders; \
           let raf = 0, on = true; const tick = () => {{ raf++; if (on) requestAnimationFrame(tick); }}; requestAnimationFrame(tick); \
           const reported = []; const sampler = setInterval(() => reported.push(r.perf().rendersPerSecond), 1000); \
           await new Promise((done) => setTimeout(done, {ms} + 50)); on = false; clearInterval(sampler); \
           const t1 = performance.now(); const p = r.perf(); \
           return JSON.stringify({{ fps: (p.renders - f0) * 1000 / (t1 - t0), displayFps: raf * 1000 / (t1 - t0), \
             reportedFps: reported.reduce((a, b) => a + b, 0) / reported.length, \
             perf: p, meshes: r.meshes(), status: document.getElementById('quality').textContent, \
             statusLevel: document.getElementById('quality').dataset.quality }}); }})()",
        ms = WINDOW_SECS * 1000.0
    );
    eval_async(cdp, &script).await
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

/// Per proxy of subject 1's meshes: vertex and triangle counts, proxy vertices not found among
/// the original's (by rest position), the largest distance between a proxy vertex and its
/// original vertex after skinning, the largest difference of the posed bounding boxes' corners,
/// and the posed original's height.
const PROXY_CHECK: &str = "(() => { const m = window.rigcast.views.get(1).model; const out = []; \
  for (const [fraction, proxies] of m.proxies) for (const [mesh, proxy] of proxies) { \
    const V = mesh.position.constructor; const a = new V(), b = new V(); \
    const key = (p, i) => `${p.getX(i)},${p.getY(i)},${p.getZ(i)}`; \
    const pa = mesh.geometry.attributes.position, qa = proxy.geometry.attributes.position; \
    const original = new Map(); for (let i = 0; i < pa.count; i++) original.set(key(pa, i), i); \
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity], plo = [...lo], phi = [...hi]; \
    const grow = (l, h, v) => { v.toArray().forEach((x, k) => { l[k] = Math.min(l[k], x); h[k] = Math.max(h[k], x); }); }; \
    for (let i = 0; i < pa.count; i++) grow(lo, hi, mesh.getVertexPosition(i, b)); \
    let worst = 0, unmatched = 0; \
    for (let i = 0; i < qa.count; i++) { proxy.getVertexPosition(i, a); grow(plo, phi, a); const j = original.get(key(qa, i)); \
      if (j === undefined) { unmatched++; continue; } worst = Math.max(worst, a.distanceTo(mesh.getVertexPosition(j, b))); } \
    const boxDiff = Math.max(...[0, 1, 2].map((k) => Math.max(Math.abs(lo[k] - plo[k]), Math.abs(hi[k] - phi[k])))); \
    out.push({ mesh: mesh.name, fraction, vertices: qa.count, of: pa.count, triangles: proxy.geometry.index.count / 3, \
      ofTriangles: (mesh.geometry.index ? mesh.geometry.index.count : pa.count) / 3, unmatched, worst, boxDiff, height: hi[1] - lo[1] }); } \
  return JSON.stringify(out); })()";

/// One row of the printed table.
struct Row {
    mode: &'static str,
    level: String,
    fps: f64,
    display_fps: f64,
    frame_ms: f64,
    triangles: u64,
    vertices: Vec<u64>,
    work: String,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn budget_keeps_two_skinned_characters_smooth() {
    let Some((chromium, _one)) = one_browser().await else {
        return;
    };
    let sized = skinned_human_glbs()
        .into_iter()
        .map(|l| (skinned_size(&std::fs::read(&l.path).unwrap()), l));
    let Some(((file_vertices, file_triangles), heaviest)) = sized.max_by_key(|(size, _)| size.0)
    else {
        return;
    };
    println!("the heaviest skinned character: {}", heaviest.rel);
    let xbot = heaviest.path;
    let server = serve(&xbot).await;
    let base = format!("http://{}/", server.local_addr());
    let (browser, mut cdp) = DevTools::open(&chromium, "about:blank").await;
    let load_before = load_average();
    let mut rows = Vec::new();

    // The budget on its own: it settles, then the page keeps the rate.
    open(&mut cdp, &base, "").await;
    let level = settle(&mut cdp).await;
    let auto = measure(&mut cdp).await;
    let moved = [
        cdp.bone_matrices_move(1).await,
        cdp.bone_matrices_move(2).await,
    ];
    let png = cdp.screenshot().await;
    let shot = rigcast_tests::repo_root()
        .join("target")
        .join("viewer-budget.png");
    std::fs::create_dir_all(shot.parent().unwrap()).unwrap();
    std::fs::write(&shot, png).unwrap();
    println!(
        "viewer budget, settled at {level} ({}): {auto}",
        shot.display()
    );
    rows.push(row("budget (auto)", &auto));

    // Each level forced, and the stick figures, in the same run.
    let mut by_level = std::collections::HashMap::new();
    let mut modes = vec![
        ("full", "?quality=full"),
        ("balanced", "?quality=balanced"),
        ("low", "?quality=low"),
        ("stick figures (full)", "?quality=full&meshes=off"),
        ("stick figures (low)", "?quality=low&meshes=off"),
    ];
    // Where a full frame's time goes: one cost taken out at a time (the page's switches).
    if std::env::var("RIGCAST_VIEWER_BREAKDOWN").as_deref() == Ok("1") {
        modes.extend([
            ("full, no vertex skinning", "?quality=full&skinning=off"),
            ("full, pixel ratio 0.1 (no fill)", "?quality=full&ratio=0.1"),
            ("full, pixel ratio 0.5", "?quality=full&ratio=0.5"),
            (
                "full, no labels, no panel",
                "?quality=full&labels=off&panel=off",
            ),
            (
                "stick figures, no WebGL draw",
                "?quality=full&meshes=off&render=off",
            ),
        ]);
    }
    for (mode, query) in modes {
        open(&mut cdp, &base, query).await;
        tokio::time::sleep(Duration::from_secs(2)).await;
        let m = measure(&mut cdp).await;
        rows.push(row(mode, &m));
        by_level.insert(mode, m);
    }
    let load_after = load_average();
    println!(
        "viewer budget: two skinned {} ({file_vertices} vertices, {file_triangles} triangles each) + stick figures, 60 Hz, \
         headless Chromium (SwiftShader), 1280x800; load average before {load_before}, after {load_after}",
        heaviest.rel
    );
    println!("| mode | level | frames/s | display frames/s | frame ms | ratio to full's frame | triangles/render | skinned vertices drawn | main thread ms/s (decode, apply, render call, labels, panel) |");
    let full_ms = rows
        .iter()
        .find(|r| r.mode == "full")
        .map_or(1.0, |r| r.frame_ms);
    for r in &rows {
        println!(
            "| {} | {} | {:.1} | {:.1} | {:.0} | {:.2} | {} | {:?} | {} |",
            r.mode,
            r.level,
            r.fps,
            r.display_fps,
            r.frame_ms,
            r.frame_ms / full_ms,
            r.triangles,
            r.vertices,
            r.work
        );
    }

    // Settled: the rate reached, the page's own report agreeing with the independent count.
    // Where this run's machine cannot draw even the cheapest picture (the stick figures at the
    // lowest level) at the target, the target cannot be judged (a CPU rasteriser starved by
    // other work: the clean-clone CI once measured 5.0 frames/s for those while another build
    // ran); the budget must then have stepped all the way down and draw as fast as that level
    // does alone in the same run, within the swing of two 5 s windows on a busy machine.
    let fps = auto["fps"].as_f64().unwrap();
    let cheapest = by_level["stick figures (low)"]["fps"].as_f64().unwrap();
    if cheapest >= TARGET_FPS {
        assert!(
            fps >= TARGET_FPS,
            "with the budget on, {fps:.1} new frames/s (< {TARGET_FPS}) at level {level}: {auto}"
        );
    } else {
        let low_alone = by_level["low"]["fps"].as_f64().unwrap();
        println!(
            "the stick figures at the lowest level draw {cheapest:.1} frames/s (< {TARGET_FPS}): \
             too busy a machine to judge the target; the budget is judged against the lowest \
             level alone ({low_alone:.1} frames/s)"
        );
        assert_eq!(
            level, "low",
            "the budget did not step down on a machine this slow"
        );
        assert!(
            fps >= WINDOW_SWING * low_alone,
            "with the budget on, {fps:.1} new frames/s, the lowest level alone {low_alone:.1}"
        );
    }
    // (The page's report is per 1 s window: sampled once a second over the same 5 s.)
    let reported = auto["reportedFps"].as_f64().unwrap();
    assert!(
        (reported - fps).abs() <= 0.3 * fps,
        "the page reports {reported:.1} frames/s, three.js counted {fps:.1}"
    );
    assert_eq!(
        auto["statusLevel"], auto["perf"]["quality"],
        "the status line shows the level: {}",
        auto["status"]
    );
    // Still the characters, still driven.
    for id in ["1", "2"] {
        let mesh = &auto["meshes"][id];
        assert!(
            mesh["drawnSkinned"].as_u64() > Some(0),
            "subject {id}: no skinned mesh drawn: {mesh}"
        );
    }
    for (id, moved) in moved.iter().enumerate() {
        assert!(
            *moved > 1e-3,
            "subject {}: bone matrices did not change ({moved})",
            id + 1
        );
    }

    // The proxies skin like the originals: every proxy vertex is a vertex of the file, and
    // three.js's own CPU skinning (`getVertexPosition`: skin indices, weights, bind matrix and
    // the live bone matrices) puts both at the same place in the current pose; the posed proxy
    // spans the same box as the posed original.
    let proxies = cdp.eval_json(PROXY_CHECK).await;
    println!("viewer budget: proxies of subject 1: {proxies}");
    assert!(!proxies.as_array().unwrap().is_empty(), "no proxies");
    for p in proxies.as_array().unwrap() {
        assert_eq!(
            p["unmatched"], 0,
            "proxy vertices that are no vertex of the file: {p}"
        );
        assert!(
            p["worst"].as_f64().unwrap() < 1e-4 * p["height"].as_f64().unwrap(),
            "a proxy vertex skins elsewhere than its original: {p}"
        );
        assert!(
            p["boxDiff"].as_f64().unwrap() < 0.1 * p["height"].as_f64().unwrap(),
            "the posed proxy's box differs from the original's: {p}"
        );
        assert!(
            p["vertices"].as_u64() < p["of"].as_u64()
                && p["triangles"].as_u64() < p["ofTriangles"].as_u64(),
            "not lighter: {p}"
        );
    }

    // `?quality=full`: the file's own meshes, all their vertices and triangles.
    let full = &by_level["full"];
    assert_eq!(full["perf"]["quality"], "full");
    for id in ["1", "2"] {
        assert_eq!(
            full["meshes"][id]["drawnVertices"].as_u64(),
            Some(file_vertices),
            "subject {id} at quality=full: {}",
            full["meshes"][id]
        );
    }
    let full_triangles = full["perf"]["triangles"].as_u64().unwrap();
    assert!(
        full_triangles >= 2 * file_triangles,
        "quality=full drew {full_triangles} triangles, the two files have {}",
        2 * file_triangles
    );
    // When the full meshes miss the rate, the budget has given detail up: fewer triangles.
    let full_fps = full["fps"].as_f64().unwrap();
    if full_fps < TARGET_FPS {
        let auto_triangles = auto["perf"]["triangles"].as_u64().unwrap();
        assert!(
            auto_triangles < full_triangles && level != "full",
            "full draws {full_fps:.1} frames/s, yet the budget stays at {level} ({auto_triangles} triangles)"
        );
    }
    // Lower levels are faster (the point of each step), measured in the same run.
    let low_fps = by_level["low"]["fps"].as_f64().unwrap();
    assert!(
        low_fps > full_fps,
        "low ({low_fps:.1} frames/s) is not faster than full ({full_fps:.1})"
    );

    // Nothing new to show (paused: frames still arrive, the pose stays): no renders.
    cdp.eval("document.getElementById('pause').click()").await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let probe = "JSON.stringify([window.rigcast.perf().renders, window.rigcast.framesReceived, window.rigcast.perf().renderReasons, window.rigcast.paused, window.rigcast.camera()])";
    let before = cdp.eval_json(probe).await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let after = cdp.eval_json(probe).await;
    let renders = after[0].as_u64().unwrap() - before[0].as_u64().unwrap();
    let received = after[1].as_u64().unwrap() - before[1].as_u64().unwrap();
    println!("viewer budget: paused for 2 s: {renders} renders, {received} frames received");
    assert!(
        received > 60,
        "frames stopped arriving while paused ({received})"
    );
    assert!(
        renders <= 2,
        "{renders} renders in 2 s of a paused view (why, before and after: {} {}; paused {}, camera {} {})",
        before[2],
        after[2],
        after[3],
        before[4],
        after[4]
    );

    assert!(cdp.errors().is_empty(), "page errors: {:?}", cdp.errors());
    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    // A slow shutdown only delays the end of the test; it has been measured by then.
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
}

fn row(mode: &'static str, m: &Value) -> Row {
    let meshes = m["meshes"].as_object().unwrap();
    Row {
        mode,
        level: m["perf"]["quality"].as_str().unwrap_or("?").to_string(),
        fps: m["fps"].as_f64().unwrap(),
        display_fps: m["displayFps"].as_f64().unwrap(),
        frame_ms: m["perf"]["frameMs"].as_f64().unwrap(),
        triangles: m["perf"]["triangles"].as_u64().unwrap(),
        vertices: meshes
            .values()
            .map(|v| v["drawnVertices"].as_u64().unwrap_or(0))
            .collect(),
        work: ["decode", "apply", "render", "labels", "panel"]
            .iter()
            .map(|k| {
                format!(
                    "{:.0}",
                    m["perf"]["workMsPerSecond"][k].as_f64().unwrap_or(0.0)
                )
            })
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// budget.js alone, fed frame times: the stepping rules, without depending on the machine.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn budget_steps_down_when_slow_and_back_up_with_headroom() {
    let Some((chromium, _one)) = one_browser().await else {
        return;
    };
    let (server, browser, mut cdp) = DevTools::open_demo(&chromium).await;
    // Wait for the page's modules (budget.js is served with them).
    let up = "typeof window.rigcast?.perf === 'function'";
    assert!(
        cdp.wait_true(up, Duration::from_secs(30), Duration::from_millis(200))
            .await,
        "viewer not up"
    );
    // A simulated clock: each display frame renders and takes `ms`; returns the level after.
    let steps = eval_async(
        &mut cdp,
        "(async () => { const { QualityBudget } = await import('/budget.js'); \
           const b = new QualityBudget({ budgetMs: 33 }); let t = 0; const seen = []; \
           const run = (ms, secs) => { for (const end = t + secs * 1000; t < end; t += ms) { b.frame(t); b.rendered(t, 1); } seen.push(b.current.name); }; \
           run(50, 1.5); run(50, 1); run(50, 1); run(10, 2); run(10, 1); \
           run(50, 2); run(10, 4); run(10, 2); run(10, 3); \
           b.hold(true); run(50, 3); b.hold(false); run(50, 1.5); \
           return JSON.stringify({ seen, changes: b.changes }); })()",
    )
    .await;
    println!("budget steps: {steps}");
    let seen: Vec<&str> = steps["seen"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    // 50 ms frames (over 33): one level down per 1 s window, then it stays at the lowest.
    assert_eq!(&seen[..3], ["balanced", "low", "low"], "{steps}");
    // 10 ms frames (headroom): not at once, but after three good windows one level up.
    assert_eq!(
        seen[3], "low",
        "stepped up before three good windows: {steps}"
    );
    assert_eq!(seen[4], "balanced", "{steps}");
    // Slow again in the step's second window: the trial failed, back down, and the next one
    // waits twice as long: four good windows are not enough, six are.
    assert_eq!(seen[5], "low", "{steps}");
    assert_eq!(
        seen[6], "low",
        "retried after a failed trial as soon as before: {steps}"
    );
    assert_eq!(seen[7], "balanced", "{steps}");
    // A trial that holds three windows resets the wait: the next level after three more.
    assert_eq!(seen[8], "full", "{steps}");
    // Paused (held), slow frames change nothing: a level change would re-size the held
    // picture. Resumed, the first slow window steps down.
    assert_eq!(seen[9], "full", "a held budget stepped: {steps}");
    assert_eq!(seen[10], "balanced", "{steps}");
    assert!(cdp.errors().is_empty(), "page errors: {:?}", cdp.errors());
    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    // A slow shutdown only delays the end of the test; it has been measured by then.
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
}
