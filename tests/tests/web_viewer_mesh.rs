//! The viewer shows a target character's own skinned mesh (issue 15), in real headless Chromium
//! against the real server.
//!
//! - GLB: the embedded demo drives the first labelled human GLB of the shared data that draws a
//!   skinned mesh (Chromium runs are expensive: the first only; without one, a skinned GLB of
//!   the mannequin the tests make). The server serves the file at
//!   `/v1/subjects/{id}/model.glb` (byte-identical to the file); the page loads it with
//!   GLTFLoader, a `SkinnedMesh` exists, its bone matrices change between two frames, and with
//!   the stream paused the screenshot with the mesh covers far more of the view than the
//!   stick-figure-only one (meshes toggled off). Both screenshots are saved to
//!   `target/viewer-mesh.png` and `target/viewer-stick.png`.
//! - VRM: the first such character whose labels hold every bone VRM requires, turned into a
//!   VRM 1.0 file (the `VRMC_vrm` extension with its labelled humanoid bones added to the GLB's
//!   JSON); the page renders it through three-vrm.
//! - Bad requests: an unknown subject, a target without a model file and a non-numeric id are
//!   404s that say why; a model the browser cannot decode (Draco-compressed) leaves the stick
//!   figure and the subject list says why.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use rigcast_server::{PerformerSpec, ServerConfig, SourceSpec};
use rigcast_tests::chromium::{one_browser, DevTools};
use rigcast_tests::{http_get, repo_root, skinned_human_glbs, Labelled};
use serde_json::{json, Value};

/// The demo driving `targets` (subjects 1, 2, …) and the built-in mannequin (no model).
async fn serve(targets: &[&Path]) -> rigcast_server::ServerHandle {
    let mut performers: Vec<PerformerSpec> = targets
        .iter()
        .map(|t| PerformerSpec::target_file(*t))
        .collect();
    performers.push(PerformerSpec::target_file("builtin:mannequin"));
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        sources: vec![SourceSpec::demo()],
        performers,
        ..ServerConfig::default()
    };
    rigcast_server::start(config).await.unwrap()
}

/// Opens the viewer and waits until subject `id`'s model is on the page.
async fn open_viewer(
    chromium: &Path,
    server: &rigcast_server::ServerHandle,
    id: u32,
) -> (rigcast_tests::chromium::Browser, DevTools, Value) {
    let (browser, mut cdp) = DevTools::open_viewer(chromium, server.local_addr()).await;
    let meshes = cdp
        .poll_json(
            "JSON.stringify(window.rigcast?.meshes ? window.rigcast.meshes() : {})",
            Duration::from_secs(60),
            Duration::from_millis(250),
            |m| m[id.to_string()]["skinnedMeshes"].as_u64() > Some(0),
        )
        .await;
    let errors = cdp
        .eval_json("JSON.stringify(Object.fromEntries(window.rigcast.modelErrors))")
        .await;
    assert!(
        meshes[id.to_string()]["skinnedMeshes"].as_u64() > Some(0),
        "no skinned mesh for subject {id} within 60 s: {meshes}; model errors {errors}; page errors {:?}",
        cdp.errors()
    );
    (browser, cdp, meshes[id.to_string()].clone())
}

/// Keeps the canvas's pixels now (for [`COMPARE`]).
const SNAPSHOT: &str = "(() => { const c = document.getElementById('scene'); const t = document.createElement('canvas'); \
  t.width = c.width; t.height = c.height; const g = t.getContext('2d'); g.drawImage(c, 0, 0); \
  window.__snapshot = g.getImageData(0, 0, t.width, t.height).data; return true; })()";

/// How many canvas pixels differ (by more than a little) from the [`SNAPSHOT`].
const COMPARE: &str = "(() => { const c = document.getElementById('scene'); const t = document.createElement('canvas'); \
  t.width = c.width; t.height = c.height; const g = t.getContext('2d'); g.drawImage(c, 0, 0); \
  const d = g.getImageData(0, 0, t.width, t.height).data; const a = window.__snapshot; let n = 0; \
  if (!a || a.length !== d.length) return JSON.stringify(null); \
  for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - a[i]) + Math.abs(d[i+1] - a[i+1]) + Math.abs(d[i+2] - a[i+2]) > 30) n++; \
  return JSON.stringify([n, d.length / 4]); })()";

async fn set_checkbox(cdp: &mut DevTools, id: &str, on: bool) {
    cdp.eval(&format!(
        "(() => {{ const c = document.getElementById('{id}'); c.checked = {on}; c.dispatchEvent(new Event('change')); return c.checked; }})()"
    ))
    .await;
}

/// Waits for two display frames, so a toggle has been drawn.
async fn settle(cdp: &mut DevTools) {
    cdp.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))")
        .await;
    tokio::time::sleep(Duration::from_millis(300)).await;
}

fn save(name: &str, png: &[u8]) -> PathBuf {
    let out = repo_root().join("target").join(name);
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    std::fs::write(&out, png).unwrap();
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_draws_the_glb_target_skinned() {
    let Some((chromium, _one)) = one_browser().await else {
        return;
    };
    // The first labelled skinned human GLB when the shared characters are here, else a skinned
    // GLB of the mannequin made by the tests (tests/src/skinned.rs).
    let fixture_dir = rigcast_tests::temp_path("skinned");
    let found = skinned_human_glbs().into_iter().next();
    let (xbot, name) = match found {
        Some(l) => {
            println!("the skinned character: {}", l.rel);
            let stem = l.path.file_stem().unwrap().to_string_lossy().into_owned();
            (l.path, stem)
        }
        None => {
            std::fs::create_dir_all(&fixture_dir).unwrap();
            let path = fixture_dir.join("skinned_mannequin.glb");
            let skeleton = rigcast_engine::builtin::builtin("mannequin").unwrap();
            std::fs::write(&path, rigcast_tests::skinned::skinned_glb(&skeleton)).unwrap();
            eprintln!("using the project's skinned GLB {} instead", path.display());
            (path, "skinned_mannequin".to_string())
        }
    };
    // Two skinned characters on one 60 Hz stream (the frame budget's case).
    let server = serve(&[&xbot, &xbot]).await;
    let (_, status) = http_get(server.local_addr(), "/v1/status").await;
    let status: Value = serde_json::from_str(&status).unwrap();
    let target = status["subjects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .expect("the skinned target")["id"]
        .as_u64()
        .unwrap() as u32;

    // The served model is the configured file, byte for byte.
    let served = raw_get(
        server.local_addr(),
        &format!("/v1/subjects/{target}/model.glb"),
    )
    .await;
    let file = std::fs::read(&xbot).unwrap();
    assert_eq!(served.0, 200);
    assert!(
        served.1 == file,
        "served model differs from the file ({} vs {} bytes)",
        served.1.len(),
        file.len()
    );

    let (browser, mut cdp, mesh) = open_viewer(&chromium, &server, target).await;
    assert_eq!(mesh["isVrm"], false);
    assert!(
        mesh["bound"].as_u64().unwrap() >= mesh["bones"].as_u64().unwrap() - 1,
        "only {} of {} bones found in the model",
        mesh["bound"],
        mesh["bones"]
    );
    let moved = cdp.bone_matrices_move(target).await;
    assert!(
        moved > 1e-3,
        "bone matrices did not change between frames ({moved})"
    );

    // Both skinned; then a few seconds of streaming: the page keeps up (newest frame wins,
    // renders leave it time to read the socket), so latency stays bounded instead of frames
    // queueing in the browser.
    cdp.poll_json(
        "JSON.stringify(window.rigcast.meshes())",
        Duration::from_secs(30),
        Duration::from_millis(250),
        |m| m["2"]["skinnedMeshes"].as_u64() > Some(0),
    )
    .await;
    tokio::time::sleep(Duration::from_secs(4)).await;
    let perf = cdp
        .eval_json(
            "JSON.stringify({ ...window.rigcast.perf(), received: window.rigcast.framesReceived, drawn: window.rigcast.framesDrawn, \
              skinned: Object.keys(window.rigcast.meshes()).length, \
              latencyMs: Object.fromEntries([...window.rigcast.stats].map(([id, s]) => [id, s.latencyMs])) })",
        )
        .await;
    println!("viewer: two skinned characters at 60 Hz: {perf}");
    assert_eq!(perf["skinned"], 2, "both characters skinned: {perf}");
    for (id, latency) in perf["latencyMs"].as_object().unwrap() {
        let latency = latency.as_f64().unwrap();
        assert!(
            latency < 1000.0,
            "subject {id}: frames reach the page {latency:.0} ms late (backlog)"
        );
    }

    // Pause, then the same pose with and without the mesh: the canvas pixels that change.
    cdp.eval("document.getElementById('pause').click()").await;
    settle(&mut cdp).await;
    cdp.eval(SNAPSHOT).await;
    let mesh_png = cdp.screenshot().await;
    set_checkbox(&mut cdp, "show-meshes", false).await;
    settle(&mut cdp).await;
    let compared = cdp.eval_json(COMPARE).await;
    assert!(
        compared.is_array(),
        "the canvas changed size between the two pictures"
    );
    let (changed, total) = (compared[0].as_u64().unwrap(), compared[1].as_u64().unwrap());
    let stick_png = cdp.screenshot().await;
    let mesh_path = save("viewer-mesh.png", &mesh_png);
    let stick_path = save("viewer-stick.png", &stick_png);
    println!(
        "viewer: {} skinned mesh(es), {} of {} bones bound, bone matrices moved {moved:.4}; {changed} of {total} canvas pixels differ between mesh and stick figure only; {} and {}",
        mesh["skinnedMeshes"], mesh["bound"], mesh["bones"], mesh_path.display(), stick_path.display()
    );
    assert_ne!(
        mesh_png, stick_png,
        "the screenshot with the mesh equals the stick-figure one"
    );
    // The character stands ~2/3 of the view high: its body covers a few percent of the
    // canvas (whatever resolution the frame budget chose).
    assert!(
        changed as f64 > 0.01 * total as f64,
        "the mesh hardly shows: {changed} of {total} pixels differ"
    );
    assert!(cdp.errors().is_empty(), "page errors: {:?}", cdp.errors());
    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let _ = std::fs::remove_dir_all(&fixture_dir);
}

/// VRM 1.0 humanoid bones and the label files' roles they are; the first
/// [`VRM_REQUIRED`] are the ones VRM requires.
const VRM_BONES: [(&str, &str); 22] = [
    ("hips", "hips"),
    ("spine", "spine"),
    ("head", "head"),
    ("leftUpperArm", "upperArm.L"),
    ("leftLowerArm", "lowerArm.L"),
    ("leftHand", "hand.L"),
    ("rightUpperArm", "upperArm.R"),
    ("rightLowerArm", "lowerArm.R"),
    ("rightHand", "hand.R"),
    ("leftUpperLeg", "upperLeg.L"),
    ("leftLowerLeg", "lowerLeg.L"),
    ("leftFoot", "foot.L"),
    ("rightUpperLeg", "upperLeg.R"),
    ("rightLowerLeg", "lowerLeg.R"),
    ("rightFoot", "foot.R"),
    ("chest", "chest"),
    ("neck", "neck"),
    ("leftShoulder", "shoulder.L"),
    ("rightShoulder", "shoulder.R"),
    ("leftToes", "toes.L"),
    ("rightToes", "toes.R"),
    ("jaw", "jaw"),
];
const VRM_REQUIRED: usize = 15;

/// Adds a `VRMC_vrm` (VRM 1.0) extension with the character's labelled humanoid bones to its
/// GLB (`l`'s file): a VRM avatar made from a file the project may not ship.
fn glb_as_vrm(l: &Labelled, glb: &[u8]) -> Vec<u8> {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let node = |name: &str| {
        doc["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .position(|n| n["name"] == name)
            .unwrap_or_else(|| panic!("{}: no node {name}", l.rel))
    };
    // Each labelled role once (a spine labelled as the chest too is the spine).
    let mut used = Vec::new();
    let mut human = serde_json::Map::new();
    for (vrm, role) in VRM_BONES {
        let Some(n) = l.bone(role).map(node) else {
            continue;
        };
        if !used.contains(&n) {
            used.push(n);
            human.insert(vrm.to_string(), json!({ "node": n }));
        }
    }
    doc["extensionsUsed"]
        .as_array_mut()
        .map(|a| a.push(json!("VRMC_vrm")))
        .unwrap_or_else(|| doc["extensionsUsed"] = json!(["VRMC_vrm"]));
    doc["extensions"]["VRMC_vrm"] = json!({
        "specVersion": "1.0",
        "meta": { "name": "test VRM", "authors": ["rigcast tests"], "licenseUrl": "https://vrm.dev/licenses/1.0/" },
        "humanoid": { "humanBones": human },
    });
    let mut json_bytes = serde_json::to_vec(&doc).unwrap();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let rest = &glb[20 + json_len..]; // the BIN chunk, unchanged
    let mut out = Vec::with_capacity(glb.len() + 1024);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json_bytes.len() + rest.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(rest);
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_draws_a_vrm_target_through_three_vrm() {
    let Some((chromium, _one)) = one_browser().await else {
        return;
    };
    let Some(character) = skinned_human_glbs()
        .into_iter()
        .find(|l| VRM_BONES[..VRM_REQUIRED].iter().all(|(_, r)| l.has_role(r)))
    else {
        println!("SKIP: no labelled skinned human GLB with every bone VRM requires");
        return;
    };
    println!("the character: {}", character.rel);
    let dir = rigcast_tests::temp_path("vrm");
    std::fs::create_dir_all(&dir).unwrap();
    let vrm = dir.join("character.vrm");
    let glb = std::fs::read(&character.path).unwrap();
    std::fs::write(&vrm, glb_as_vrm(&character, &glb)).unwrap();
    let server = serve(&[&vrm]).await;
    let (_, status) = http_get(server.local_addr(), "/v1/status").await;
    assert!(status.contains("\"character\""), "{status}");
    let (browser, mut cdp, mesh) = open_viewer(&chromium, &server, 1).await;
    assert_eq!(mesh["isVrm"], true, "not loaded as a VRM: {mesh}");
    let moved = cdp.bone_matrices_move(1).await;
    assert!(moved > 1e-3, "VRM bone matrices did not change ({moved})");
    let png = cdp.screenshot().await;
    let path = save("viewer-vrm.png", &png);
    println!(
        "viewer: VRM through three-vrm, {} skinned mesh(es), bone matrices moved {moved:.4}; {}",
        mesh["skinnedMeshes"],
        path.display()
    );
    assert!(cdp.errors().is_empty(), "page errors: {:?}", cdp.errors());
    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let _ = std::fs::remove_dir_all(&dir);
}

/// A GET returning (status, body bytes).
async fn raw_get(addr: std::net::SocketAddr, path: &str) -> (u16, Vec<u8>) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes())
        .await
        .unwrap();
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).await.unwrap();
    let end = buf.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    let head = String::from_utf8_lossy(&buf[..end]).to_string();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    (status, buf[end..].to_vec())
}

#[tokio::test]
async fn model_requests_without_a_model_are_404s_that_say_why() {
    // The mannequin (built-in) is a target without a file; the demo a source.
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let addr = server.local_addr();
    for (path, says) in [
        ("/v1/subjects/1/model.glb", "has no model file"),
        ("/v1/subjects/0/model.glb", "has no model file"),
        ("/v1/subjects/99/model.glb", "no subject 99"),
        ("/v1/subjects/x/model.glb", "not a number"),
        ("/v1/subjects/4294967296/model.glb", "not a number"),
    ] {
        let (status, body) = raw_get(addr, path).await;
        let body = String::from_utf8_lossy(&body);
        assert_eq!(status, 404, "{path}: {body}");
        assert!(body.contains(says), "{path}: {body}");
    }
    // Subjects without a model announce none.
    let (_, status) = http_get(addr, "/v1/status").await;
    assert!(!status.contains("model.glb"));
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
}

/// A model the browser cannot decode (here: one that requires Draco mesh compression, which
/// the server reads past but the viewer has no decoder for) leaves the stick figure, and the
/// subject list says why; the page throws nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn viewer_keeps_the_stick_figure_when_a_model_cannot_load() {
    let Some((chromium, _one)) = one_browser().await else {
        return;
    };
    let skeleton = rigcast_engine::builtin::builtin("mannequin").unwrap();
    let glb = rigcast_tests::skinned::skinned_glb(&skeleton);
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    doc["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    doc["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let mut json_bytes = serde_json::to_vec(&doc).unwrap();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let rest = &glb[20 + json_len..];
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((20 + json_bytes.len() + rest.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(rest);
    let dir = rigcast_tests::temp_path("draco");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("compressed.glb");
    std::fs::write(&path, out).unwrap();

    let server = serve(&[&path]).await;
    let (browser, mut cdp) = DevTools::open_viewer(&chromium, server.local_addr()).await;
    let error = cdp
        .poll_json(
            "JSON.stringify(window.rigcast?.modelErrors?.get(1) ?? null)",
            Duration::from_secs(30),
            Duration::from_millis(200),
            |e| !e.is_null(),
        )
        .await;
    let message = error
        .as_str()
        .unwrap_or_else(|| panic!("no model error reported: {error}"));
    assert!(message.to_lowercase().contains("draco"), "{message}");
    let page = cdp
        .eval_json(
            "JSON.stringify({ meshes: window.rigcast.meshes(), overlay: window.rigcast.views.get(1).overlay.visible, \
              note: document.querySelector('#subjects li[data-subject=\"1\"] .model')?.textContent })",
        )
        .await;
    println!("viewer: model not loadable: {page}");
    assert_eq!(page["meshes"], json!({}), "no mesh attached");
    assert_eq!(page["overlay"], true, "the stick figure stays");
    assert!(
        page["note"].as_str().unwrap().contains("not shown"),
        "{page}"
    );
    let thrown = cdp.thrown();
    assert!(thrown.is_empty(), "page threw: {thrown:?}");
    let _ = cdp.call("Browser.close", json!({})).await;
    drop(browser);
    let _ = tokio::time::timeout(Duration::from_secs(5), server.shutdown()).await;
    let _ = std::fs::remove_dir_all(&dir);
}
