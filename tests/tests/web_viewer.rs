//! Real headless Chromium loads the web viewer from the real server.
//!
//! The server (in-process, 127.0.0.1:0) runs the default demo, as `rigcast serve` without
//! arguments does: the bundled walk `demo` (source) and the built-in `mannequin` retargeted
//! from it (target), with its `mapping` message and `source_status`. Chromium is driven over the
//! DevTools protocol (a WebSocket, so the test needs no extra crate). Our own WebSocket client
//! on the same server holds the real `mapping` message, and the test checks the page against
//! it: frames arrive for both subjects, both skeletons move side by side without overlapping
//! and are labelled, the mapping table shows the message's rows and colours (gradient and
//! random), the target's bones and the mapped source bones are drawn in those colours, and the
//! subject list shows the source's health. The screenshot is saved to target/viewer.png.
//! The page is opened with the `?token=` link the server prints and must pass the token on
//! (its stream has control access); a page from another origin in the same browser cannot
//! open the stream at all.
//!
//! Needs `chromium` (scripts/install-apps.sh installs it). Missing Chromium fails the test
//! with a clear message, unless RIGCAST_SKIP_APPS=1, which skips it with a printed reason.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::time::{Duration, Instant};

use rigcast_protocol::control::{MappingEntry, SubjectKind};
use rigcast_protocol::ServerMessage;
use rigcast_tests::chromium::DevTools;
use rigcast_tests::{connect, find_app, handshake, next_json, repo_root, start_demo_server};
use serde_json::{json, Value};

/// Parses CSS `rgb(r, g, b)` into 0..255 channels.
fn parse_rgb(css: &str) -> [f32; 3] {
    let inner = css
        .trim()
        .strip_prefix("rgb(")
        .and_then(|s| s.strip_suffix(')'))
        .unwrap_or_else(|| panic!("not an rgb() colour: {css}"));
    let v: Vec<f32> = inner
        .split(',')
        .map(|c| c.trim().parse().unwrap())
        .collect();
    [v[0], v[1], v[2]]
}

/// Whether a rendered 8-bit colour shows the mapping colour `c` (0..1): within one step per
/// channel, as the page and this test may round an exact half differently.
fn shows_color(css: &str, c: [f32; 3]) -> bool {
    let got = parse_rgb(css);
    (0..3).all(|i| (got[i] - c[i] * 255.0).abs() <= 1.0)
}

/// The server's own view, through an independent client: hello subjects and the first
/// `mapping` message of the target subject.
async fn server_mapping(
    url: &str,
) -> (
    Vec<rigcast_protocol::control::SubjectInfo>,
    u32,
    u32,
    Vec<MappingEntry>,
) {
    let mut ws = connect(url).await;
    let (hello, _) = handshake(&mut ws).await;
    let ServerMessage::Hello { subjects, .. } = hello else {
        unreachable!("handshake checks hello")
    };
    loop {
        match next_json(&mut ws, Duration::from_secs(10)).await {
            Some(ServerMessage::Mapping {
                subject,
                source_subject,
                entries,
                ..
            }) => return (subjects, subject, source_subject, entries),
            Some(_) => {}
            None => panic!("no mapping message within 10 s"),
        }
    }
}

/// Checks that every mapping-table row shows the message's target, source and colour.
async fn check_table(cdp: &mut DevTools, entries: &[MappingEntry], random: bool) {
    let rows = cdp
        .eval_json(
            "JSON.stringify([...document.querySelectorAll('#mapping tbody tr')].map(tr => ({ \
               target: tr.children[1].textContent, source: tr.children[2].textContent, \
               color: getComputedStyle(tr.querySelector('.swatch span')).backgroundColor, \
               flagged: tr.classList.contains('flagged'), mark: tr.children[4].textContent, \
               why: tr.title })))",
        )
        .await;
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), entries.len(), "one table row per mapping entry");
    assert!(rows.len() >= 15, "only {} mapping rows", rows.len());
    let mut distinct = std::collections::HashSet::new();
    for (row, entry) in rows.iter().zip(entries) {
        assert_eq!(row["target"], entry.target.as_str());
        assert_eq!(row["source"], entry.source.as_deref().unwrap_or("—"));
        check_flag(row, entry);
        let want = if random {
            entry.color_random
        } else {
            entry.color_gradient
        };
        let shown = row["color"].as_str().unwrap();
        assert!(
            shows_color(shown, want),
            "row {}: shows {shown}, mapping says {want:?}",
            entry.target
        );
        distinct.insert(shown.to_string());
    }
    // A table painted one colour would match a constant message; the real one is not constant.
    assert!(
        distinct.len() >= 10,
        "only {} distinct colours",
        distinct.len()
    );
}

/// A row is marked (class, ⚠, the reason on hover) exactly when its entry is flagged.
fn check_flag(row: &Value, entry: &MappingEntry) {
    match &entry.flagged {
        Some(why) => {
            assert_eq!(
                row["flagged"], true,
                "row {} not marked: {row}",
                entry.target
            );
            assert_eq!(row["mark"], "⚠", "row {}: {row}", entry.target);
            assert!(
                row["why"].as_str().unwrap().contains(why.as_str()),
                "row {}: hover text {} lacks {why:?}",
                entry.target,
                row["why"]
            );
        }
        None => {
            assert_eq!(row["flagged"], false, "row {} marked: {row}", entry.target);
            assert_eq!(row["mark"], "", "row {}: {row}", entry.target);
        }
    }
}

/// A mapping with flagged bones (a source whose sparse spine has no chest or neck for the
/// mannequin's: the first labelled human clip labelled without a neck; skipped without one):
/// the viewer marks exactly the flagged rows, gives their count, and the message's other rows
/// stay unmarked.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_marks_the_bones_the_mapper_flagged() {
    let Some(chromium) = find_app("chromium") else {
        return;
    };
    let Some((_, clip)) = rigcast_tests::first_neckless_clip() else {
        return;
    };
    let config = rigcast_server::ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![rigcast_tests::clip_source(clip)],
        performers: vec![rigcast_server::PerformerSpec::target_file(
            "builtin:mannequin",
        )],
        ..rigcast_server::ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let (_, _, _, entries) = server_mapping(&server.stream_url()).await;
    let flagged: Vec<&MappingEntry> = entries.iter().filter(|e| e.flagged.is_some()).collect();
    println!(
        "flagged: {:?}",
        flagged
            .iter()
            .map(|e| (&e.target, &e.flagged))
            .collect::<Vec<_>>()
    );
    assert!(
        !flagged.is_empty(),
        "a sparse spine onto the mannequin flags nothing"
    );
    assert!(
        flagged.len() < entries.len() / 2,
        "nearly everything flagged"
    );
    let (_browser, mut cdp) = DevTools::open_viewer(&chromium, server.local_addr()).await;
    let shown = cdp
        .poll_json(
            "JSON.stringify(document.querySelectorAll('#mapping tbody tr').length)",
            Duration::from_secs(20),
            Duration::from_millis(200),
            |n| n.as_u64() == Some(entries.len() as u64),
        )
        .await;
    assert_eq!(shown, entries.len() as u64, "mapping table never filled");
    check_table(&mut cdp, &entries, false).await;
    let count = cdp
        .eval("document.getElementById('mapping-flags').textContent")
        .await;
    assert!(
        count
            .as_str()
            .is_some_and(|c| c.starts_with(&format!("{} bone", flagged.len()))),
        "flag count: {count}"
    );
}

/// Per bone of a subject: the colour its joint is drawn in, by name.
async fn drawn_colors(cdp: &mut DevTools, subject: u32) -> HashMap<String, [f32; 3]> {
    let colors = cdp
        .eval_json(&format!(
            "(() => {{ const v = window.rigcast.views.get({subject}); const out = {{}}; \
              const c = v.joints.instanceColor.array; \
              v.bones.forEach((b, i) => {{ out[b.name] = [...c.slice(i * 3, i * 3 + 3)]; }}); \
              return JSON.stringify(out); }})()"
        ))
        .await;
    colors
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| {
            let a = v.as_array().unwrap();
            let f = |i: usize| a[i].as_f64().unwrap() as f32;
            (k.clone(), [f(0), f(1), f(2)])
        })
        .collect()
}

fn close(a: [f32; 3], b: [f32; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-3)
}

/// The target's bones wear their entry's colour; each mapped source bone wears the colour of
/// one of the entries mapped to it.
async fn check_bone_colors(
    cdp: &mut DevTools,
    target: u32,
    source: u32,
    entries: &[MappingEntry],
    random: bool,
) {
    let pick = |e: &MappingEntry| {
        if random {
            e.color_random
        } else {
            e.color_gradient
        }
    };
    let drawn = drawn_colors(cdp, target).await;
    let mut checked = 0;
    for entry in entries {
        if let Some(got) = drawn.get(&entry.target) {
            assert!(
                close(*got, pick(entry)),
                "target bone {} drawn {got:?}, mapping says {:?}",
                entry.target,
                pick(entry)
            );
            checked += 1;
        }
    }
    assert!(checked >= 15, "only {checked} target bones checked");
    let drawn = drawn_colors(cdp, source).await;
    let mut checked = 0;
    for (name, got) in &drawn {
        let candidates: Vec<[f32; 3]> = entries
            .iter()
            .filter(|e| e.source.as_deref() == Some(name.as_str()))
            .map(pick)
            .collect();
        if !candidates.is_empty() {
            assert!(
                candidates.iter().any(|c| close(*c, *got)),
                "source bone {name} drawn {got:?}, not one of its mapped colours {candidates:?}"
            );
            checked += 1;
        }
    }
    assert!(checked >= 10, "only {checked} mapped source bones checked");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_shows_source_and_retargeted_target_in_chromium() {
    let Some(chromium) = find_app("chromium") else {
        return;
    };
    let server = start_demo_server().await;
    let (subjects, target, source, entries) = server_mapping(&server.stream_url()).await;
    assert_eq!(subjects.len(), 2, "the demo streams a source and a target");
    assert_eq!(subjects[target as usize].kind, SubjectKind::Target);
    assert_eq!(subjects[source as usize].kind, SubjectKind::Source);
    assert_eq!(subjects[target as usize].source, Some(source));
    let page_url = format!(
        "http://{}/?token={}",
        server.local_addr(),
        server.control_token().reveal()
    );

    let (browser, mut cdp) = DevTools::open(&chromium, &page_url).await;

    // Frames arrive for both subjects; the mapping message has been received.
    let start = Instant::now();
    let mut counts = Value::Null;
    while start.elapsed() < Duration::from_secs(20) {
        counts = cdp
            .eval_json(
                "JSON.stringify(window.rigcast ? { frames: Object.fromEntries([...window.rigcast.stats].map(([id, s]) => [id, s.count])), \
                  mappings: window.rigcast.mappings.size, health: window.rigcast.sourceStatus.size } : {})",
            )
            .await;
        let per = |id: u32| counts["frames"][id.to_string()].as_u64().unwrap_or(0);
        if per(source) >= 60
            && per(target) >= 60
            && counts["mappings"] == 1
            && counts["health"] == 1
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    for id in [source, target] {
        let n = counts["frames"][id.to_string()].as_u64().unwrap_or(0);
        assert!(
            n >= 60,
            "subject {id}: viewer counted {n} frames in 20 s ({counts}); page events: {:?}",
            cdp.events
        );
    }
    assert_eq!(
        counts["mappings"], 1,
        "mapping message not received: {counts}"
    );
    assert_eq!(counts["health"], 1, "source_status not received: {counts}");
    // The page handed its ?token= on: its stream (the only client now) has control access.
    let (_, status_body) = rigcast_tests::http_get(server.local_addr(), "/v1/status").await;
    let status: Value = serde_json::from_str(&status_body).unwrap();
    let access: Vec<&str> = status["clients"]["list"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| c["access"].as_str())
        .collect();
    assert_eq!(access, ["control"], "{status_body}");

    // Both skeletons move.
    let pose_probe = "JSON.stringify(Object.fromEntries([...window.rigcast.views].map(([id, v]) => [id, v.worldP.map(p => [p.x, p.y, p.z])])))";
    let before = cdp.eval_json(pose_probe).await;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let after = cdp.eval_json(pose_probe).await;
    for id in [source, target] {
        let key = id.to_string();
        let (a, b) = (
            before[&key].as_array().unwrap(),
            after[&key].as_array().unwrap(),
        );
        let moved = a
            .iter()
            .zip(b)
            .map(|(p, q)| {
                (0..3)
                    .map(|k| (p[k].as_f64().unwrap() - q[k].as_f64().unwrap()).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        assert!(
            moved > 0.01,
            "subject {id} did not move ({moved} m); page events: {:?}",
            cdp.events
        );
    }

    // The viewer asked for protocol version 2 (the mannequin's pelvis moves under its ground
    // root only there), and draws the pelvis bobbing.
    let version = cdp
        .eval_json("JSON.stringify(window.rigcast.protocolVersion ?? null)")
        .await;
    assert_eq!(version, 2, "the viewer did not switch to protocol v2");
    let pelvis_probe = format!(
        "JSON.stringify((() => {{ const v = window.rigcast.views.get({target}); \
           const i = v.bones.findIndex(b => b.name === 'pelvis'); return v.worldP[i].y - v.worldP[0].y; }})())"
    );
    let mut heights = Vec::new();
    for _ in 0..12 {
        heights.push(cdp.eval_json(&pelvis_probe).await.as_f64().unwrap());
        tokio::time::sleep(Duration::from_millis(90)).await;
    }
    let range = heights.iter().cloned().fold(f64::MIN, f64::max)
        - heights.iter().cloned().fold(f64::MAX, f64::min);
    println!("viewer: mannequin pelvis height above its root varies over {range:.4} m");
    assert!(
        range > 0.005,
        "the viewer's pelvis does not bob: {heights:?}"
    );

    // Side by side: on screen, inside the view, not overlapping.
    let bounds = cdp
        .eval_json("JSON.stringify(window.rigcast.screenBounds())")
        .await;
    let view_size = cdp
        .eval_json("JSON.stringify([document.getElementById('view').clientWidth, document.getElementById('view').clientHeight])")
        .await;
    let (w, h) = (
        view_size[0].as_f64().unwrap(),
        view_size[1].as_f64().unwrap(),
    );
    let rect = |id: u32| -> [f64; 4] {
        let a = bounds[id.to_string()].as_array().unwrap();
        [0, 1, 2, 3].map(|i| a[i].as_f64().unwrap())
    };
    let (rs, rt) = (rect(source), rect(target));
    for (id, r) in [(source, rs), (target, rt)] {
        assert!(
            r[0] >= 0.0 && r[1] >= 0.0 && r[2] <= w && r[3] <= h,
            "subject {id} leaves the {w}x{h} view: {r:?}"
        );
        assert!(
            r[3] - r[1] > 0.3 * h,
            "subject {id} is tiny on screen: {r:?}"
        );
    }
    let apart = rs[2] < rt[0] || rt[2] < rs[0];
    assert!(
        apart,
        "skeletons overlap on screen: source {rs:?}, target {rt:?}"
    );

    // The mapping table is the server's message, in gradient and in random colours, and the
    // 3D bones wear the same colours.
    let title = cdp
        .eval("document.getElementById('mapping-title').textContent")
        .await;
    assert_eq!(
        title.as_str(),
        Some(
            format!(
                "{} ← {}",
                subjects[target as usize].name, subjects[source as usize].name
            )
            .as_str()
        )
    );
    check_table(&mut cdp, &entries, false).await;
    check_bone_colors(&mut cdp, target, source, &entries, false).await;
    let switch = |mode: &str| {
        format!(
            "(() => {{ const s = document.getElementById('color-mode'); s.value = '{mode}'; \
              s.dispatchEvent(new Event('change')); return s.value; }})()"
        )
    };
    assert_eq!(cdp.eval(&switch("random")).await, "random");
    check_table(&mut cdp, &entries, true).await;
    check_bone_colors(&mut cdp, target, source, &entries, true).await;
    assert_eq!(cdp.eval(&switch("gradient")).await, "gradient");
    check_table(&mut cdp, &entries, false).await;

    let summary = cdp
        .eval_json(
            "JSON.stringify({ frames: window.rigcast.framesReceived, drawn: window.rigcast.framesDrawn, \
              title: document.title, connection: document.getElementById('connection').textContent, \
              subjects: [...document.querySelectorAll('#subjects li')].map(li => ({ id: li.dataset.subject, health: li.dataset.health, text: li.textContent })), \
              subjectLabels: [...document.querySelectorAll('.label.subject')].filter(l => l.style.display !== 'none').map(l => l.textContent), \
              boneLabels: [...document.querySelectorAll('.label.bone')].filter(l => l.style.display !== 'none').length, \
              rates: Object.fromEntries([...window.rigcast.stats].map(([id, s]) => [id, s.arrivals.length])), \
              latency: Object.fromEntries([...window.rigcast.stats].map(([id, s]) => [id, s.latencyMs])), \
              badFrames: window.rigcast.stream.badFrames })",
        )
        .await;
    println!("viewer: {summary}");
    assert_eq!(summary["connection"], "connected");
    assert_eq!(summary["badFrames"], 0);
    assert!(summary["title"].as_str().unwrap().contains("frames"));
    // Subject list: both subjects; the source's health from `source_status` (a replay is live).
    let listed = summary["subjects"].as_array().unwrap();
    assert_eq!(listed.len(), 2);
    for li in listed {
        assert_eq!(li["health"], "live", "subject list health: {li}");
    }
    let source_li = listed
        .iter()
        .find(|li| li["id"] == source.to_string().as_str())
        .unwrap();
    let text = source_li["text"].as_str().unwrap();
    assert!(
        text.contains("replay") && text.contains("dropped 0"),
        "source health not shown: {text}"
    );
    // Readable labels: each subject's name over its skeleton, plus some bone names.
    let labels: Vec<&str> = summary["subjectLabels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l.as_str())
        .collect();
    for id in [source, target] {
        let name = &subjects[id as usize].name;
        assert!(
            labels.iter().any(|l| l.starts_with(name.as_str())),
            "no visible label for {name}: {labels:?}"
        );
    }
    assert!(
        summary["boneLabels"].as_u64().unwrap() >= 6,
        "bone labels missing: {summary}"
    );
    for id in [source, target] {
        let rate = summary["rates"][id.to_string()].as_u64().unwrap_or(0);
        assert!(rate >= 20, "subject {id}: page receives {rate} frames/s");
    }

    // The WebGL canvas really drew the skeletons: count pixels away from the background.
    let lit = cdp
        .eval(
            "(() => { const c = document.getElementById('scene'); const t = document.createElement('canvas'); \
              t.width = c.width; t.height = c.height; const g = t.getContext('2d'); g.drawImage(c, 0, 0); \
              const d = g.getImageData(0, 0, t.width, t.height).data; let n = 0; \
              for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x15) + Math.abs(d[i+1] - 0x17) + Math.abs(d[i+2] - 0x1c) > 60) n++; \
              return n; })()",
        )
        .await
        .as_u64()
        .unwrap_or(0);
    assert!(lit > 500, "the 3D view drew only {lit} bright pixels");

    let exceptions = cdp.thrown();
    assert!(exceptions.is_empty(), "page threw: {exceptions:?}");
    let failed_loads: Vec<&Value> = cdp
        .events
        .iter()
        .filter(|e| e["method"] == "Log.entryAdded" && e["params"]["entry"]["level"] == "error")
        .collect();
    assert!(
        failed_loads.is_empty(),
        "page logged errors: {failed_loads:?}"
    );

    let png = cdp.screenshot().await;
    let out = repo_root().join("target").join("viewer.png");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    std::fs::write(&out, &png).unwrap();
    println!("screenshot: {} ({} bytes)", out.display(), png.len());

    // A page of another origin (another port on the same host) tries what an attacker's page
    // would: open the stream. The browser sends that page's Origin, and the server refuses.
    let foreign = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let foreign_url = format!("http://{}/", foreign.local_addr().unwrap());
    let page = format!(
        "<!doctype html><title>waiting</title><script>\
         const ws = new WebSocket('ws://{}/v1/stream');\
         ws.onopen = () => {{ document.title = 'open'; }};\
         ws.onerror = () => {{ document.title = 'refused'; }};</script>",
        server.local_addr()
    );
    let serve_foreign = tokio::spawn(async move {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        // Bounded: the page and at most a few extra requests (favicon).
        for _ in 0..8 {
            let Ok((mut s, _)) = foreign.accept().await else {
                return;
            };
            let mut buf = [0u8; 4096];
            let _ = s.read(&mut buf).await;
            let response = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{page}",
                page.len()
            );
            let _ = s.write_all(response.as_bytes()).await;
        }
    });
    cdp.call("Page.navigate", json!({ "url": foreign_url }))
        .await;
    let start = Instant::now();
    let mut title = Value::Null;
    while start.elapsed() < Duration::from_secs(10) {
        title = cdp.eval("document.title").await;
        if title == "open" || title == "refused" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(title, "refused", "a foreign page's WebSocket to the server");
    serve_foreign.abort();

    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
}
