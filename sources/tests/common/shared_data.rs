//! The shared real test data (`../shared/data` beside the workspace), which the project may not
//! redistribute: tests that read it skip with a printed reason when it is absent. Included by
//! path in the tests and benches of several crates (`sources/tests`, `sources/benches`,
//! `server/tests`, the server's unit tests, `tests/src/lib.rs`); every crate folder sits one
//! level below the workspace, so the same relative path finds the data from each of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The CMU walk (mocap, 31 joints, MotionBuilder names), for the tests that check figures read
/// by hand from it (known answers: they skip without it). Every other test finds its data by
/// what it is (the helpers below).
pub const CMU_WALK: &str = "bvh/cmu_131_01_walk.bvh";

/// The shared data folder, whether or not it exists: `RIGCAST_SHARED_DATA` when set (a checkout
/// elsewhere than beside the data), else `../shared/data` beside the workspace.
pub fn shared_data_root() -> PathBuf {
    match std::env::var_os("RIGCAST_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    }
}

/// Path of a file in the shared test data, or `None` (with a printed reason) when absent.
pub fn shared_data(relative: &str) -> Option<PathBuf> {
    let p = shared_data_root().join(relative);
    if p.exists() {
        Some(p)
    } else {
        println!("SKIP: test data {} not found", p.display());
        None
    }
}

/// A clip of the shared test data, loaded, or `None` (with a printed reason) when absent.
pub fn shared_clip(relative: &str) -> Option<rigcast_retarget::Clip> {
    let path = shared_data(relative)?;
    Some(rigcast_sources::load_clip(&path).expect("a shared clip loads"))
}

/// Paths of several files in the shared test data, or `None` when any is absent (with a printed
/// reason for each one absent).
pub fn shared_data_all<const N: usize>(relative: [&str; N]) -> Option<[PathBuf; N]> {
    let found: Option<Vec<PathBuf>> = relative.map(shared_data).into_iter().collect();
    found?.try_into().ok()
}

/// The shared data folder when `probe` (a file in it) exists, or `None` with a printed reason
/// naming `what` the test needed.
pub fn shared_data_dir(probe: &str, what: &str) -> Option<PathBuf> {
    let p = shared_data_root();
    if p.join(probe).exists() {
        Some(p)
    } else {
        println!("SKIP: {what} not found ({})", p.join(probe).display());
        None
    }
}

/// Every label file of the shared data: `labels.json` at its root and `*/labels.json` in each
/// folder below it (later batches such as `zoo2/`), in a stable order. Keys in each are paths
/// relative to the root.
pub fn label_files(root: &std::path::Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(root)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path().join("labels.json"))
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    let top = root.join("labels.json");
    if top.is_file() {
        out.insert(0, top);
    }
    out
}

/// The labelled files of every label file ([`label_files`]) merged into one map: relative path
/// → its labels (`kind` and role → acceptable bone names). Keys starting with `_` (docs) are
/// left out; a file labelled twice keeps its first entry.
pub fn all_labels(root: &std::path::Path) -> serde_json::Map<String, serde_json::Value> {
    let mut out = serde_json::Map::new();
    for file in label_files(root) {
        let text =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let value: serde_json::Value =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        for (key, v) in value.as_object().into_iter().flatten() {
            if !key.starts_with('_') && !out.contains_key(key) {
                out.insert(key.clone(), v.clone());
            }
        }
    }
    out
}

/// The sided leg roles a labelled rig with two legs carries.
pub const LEG_ROLES: [&str; 6] = [
    "upperLeg.L",
    "upperLeg.R",
    "lowerLeg.L",
    "lowerLeg.R",
    "foot.L",
    "foot.R",
];

/// One labelled file of the shared data that is present: its key in the label files (a path
/// relative to the data root), its full path and its labels. Tests pick files by what these
/// say they are (and by what the file itself shows), never by name.
#[derive(Clone, Debug)]
pub struct Labelled {
    pub rel: String,
    pub path: PathBuf,
    pub labels: serde_json::Value,
}

impl Labelled {
    /// `kind` of the labels: human, quadruped, biped_creature, hand or other.
    pub fn kind(&self) -> &str {
        self.labels
            .get("kind")
            .and_then(|k| k.as_str())
            .unwrap_or("")
    }

    pub fn has_role(&self, role: &str) -> bool {
        self.labels.get(role).is_some()
    }

    /// The primary (first) bone name labelled for `role`.
    pub fn bone(&self, role: &str) -> Option<&str> {
        self.labels.get(role)?.as_array()?.first()?.as_str()
    }

    pub fn is_bvh(&self) -> bool {
        self.path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("bvh"))
    }

    /// Two labelled legs (upper, lower leg and foot on each side).
    pub fn has_legs(&self) -> bool {
        LEG_ROLES.iter().all(|r| self.has_role(r))
    }

    /// A quadruped whose four legs are labelled: hind legs down to the foot, front legs down to
    /// the lower leg (the front foot is not labelled on every rig).
    pub fn four_legged(&self) -> bool {
        self.kind() == "quadruped"
            && self.has_legs()
            && [
                "frontUpper.L",
                "frontUpper.R",
                "frontLower.L",
                "frontLower.R",
            ]
            .iter()
            .all(|r| self.has_role(r))
    }

    /// A human labelled without any leg role (an upper body).
    pub fn upper_body_only(&self) -> bool {
        self.kind() == "human"
            && !["upperLeg", "lowerLeg", "foot", "toes"]
                .iter()
                .any(|r| self.has_role(&format!("{r}.L")) || self.has_role(&format!("{r}.R")))
    }

    /// Whether the rig's bone names say the opposite side to its labels: the labels' sides are
    /// the character's own, checked against its geometry (labels.json `_doc`), so a rig whose
    /// names disagree on most sided roles names its sides mirrored.
    pub fn names_mirrored(&self) -> bool {
        let (mut agree, mut disagree) = (0, 0);
        for (role, _) in self.labels.as_object().into_iter().flatten() {
            let labelled = match role.rsplit_once('.') {
                Some((_, "L")) => 'L',
                Some((_, "R")) => 'R',
                _ => continue,
            };
            match self.bone(role).and_then(name_side) {
                Some(s) if s == labelled => agree += 1,
                Some(_) => disagree += 1,
                None => {}
            }
        }
        disagree > agree
    }
}

/// The side a bone name spells (`Left…`, `…_R`, `r-…`, `.L`), if any.
fn name_side(name: &str) -> Option<char> {
    let lower = name.to_ascii_lowercase();
    let (left, right) = (lower.contains("left"), lower.contains("right"));
    if left != right {
        return Some(if left { 'L' } else { 'R' });
    }
    let tokens: Vec<&str> = lower
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|t| !t.is_empty())
        .collect();
    let (l, r) = (tokens.contains(&"l"), tokens.contains(&"r"));
    (l != r).then_some(if l { 'L' } else { 'R' })
}

/// Every labelled file present under the shared data (both label files' entries), sorted by
/// its relative path so tests run in a stable order.
pub fn labelled() -> Vec<Labelled> {
    let root = shared_data_root();
    let mut out: Vec<Labelled> = all_labels(&root)
        .into_iter()
        .map(|(rel, labels)| Labelled {
            path: root.join(&rel),
            rel,
            labels,
        })
        .filter(|l| l.path.is_file())
        .collect();
    out.sort_by(|a, b| a.rel.cmp(&b.rel));
    out
}

/// The labelled files `keep` accepts, sorted; empty with a printed reason naming `what` when
/// none is present.
pub fn labelled_where(what: &str, keep: impl Fn(&Labelled) -> bool) -> Vec<Labelled> {
    let out: Vec<Labelled> = labelled().into_iter().filter(|l| keep(l)).collect();
    if out.is_empty() {
        println!(
            "SKIP: no {what} among the labelled files of {}",
            shared_data_root().display()
        );
    }
    out
}

/// What a clip's own motion shows about walking, from its labelled hips and feet (joint
/// heights and positions only, independent of the footplant detector tests judge).
#[derive(Clone, Copy, Debug)]
pub struct Gait {
    /// Farthest the hips get from where they start, along the ground, in leg lengths.
    pub travel: f32,
    /// How many times the lower foot changes sides (a change counts once a foot is lower by
    /// more than 3 % of a leg length; a stride is two).
    pub switches: usize,
}

impl Gait {
    /// A walk (or run): the root travels at least one leg length over the ground and the feet
    /// take the lower place in turn at least twice.
    pub fn is_walk(&self) -> bool {
        self.travel >= 1.0 && self.switches >= 2
    }
}

/// The gait of `clip`, whose labels are `l`; `None` without labelled hips and feet found in
/// its skeleton or with fewer than two frames.
pub fn gait(l: &Labelled, clip: &rigcast_retarget::Clip) -> Option<Gait> {
    use rigcast_retarget::analysis::{analyze, SkeletonView};
    let bone = |role: &str| clip.skeleton.bone(l.bone(role)?);
    let (hips, left, right) = (bone("hips")?, bone("foot.L")?, bone("foot.R")?);
    if clip.poses.len() < 2 {
        return None;
    }
    let up = analyze(&SkeletonView::from_clip(&clip.skeleton, &clip.poses)).up;
    let worlds: Vec<_> = clip
        .poses
        .iter()
        .map(|p| rigcast_retarget::world_transforms(&clip.skeleton, p))
        .collect();
    let at = |f: usize, b: rigcast_retarget::BoneId| worlds[f][b.index()].translation;
    let first = at(0, hips);
    let leg = (first - 0.5 * (at(0, left) + at(0, right))).dot(up);
    if leg <= 0.0 {
        return None;
    }
    let mut travel: f32 = 0.0;
    let (mut lower, mut switches) = (None, 0);
    for f in 0..worlds.len() {
        let moved = at(f, hips) - first;
        travel = travel.max((moved - moved.dot(up) * up).length() / leg);
        let d = (at(f, left) - at(f, right)).dot(up) / leg;
        let now = if d > 0.03 {
            Some('R')
        } else if d < -0.03 {
            Some('L')
        } else {
            continue;
        };
        if lower.is_some() && lower != now {
            switches += 1;
        }
        lower = now;
    }
    Some(Gait { travel, switches })
}

/// Every labelled BVH clip of a biped (human or biped creature, legs labelled) whose own motion
/// is a walk ([`Gait::is_walk`]), loaded, with its gait, sorted; empty with a printed reason
/// when none is present.
pub fn walks() -> Vec<(Labelled, rigcast_retarget::Clip, Gait)> {
    gait_clips("walk", is_biped, Gait::is_walk, usize::MAX)
}

/// The first walk of [`walks`] in their sorted order (for tests too slow to run on each), or
/// `None` with a printed reason.
pub fn first_walk() -> Option<(Labelled, rigcast_retarget::Clip, Gait)> {
    let walk = gait_clips("walk", is_biped, Gait::is_walk, 1).pop()?;
    println!("the walk: {} ({:?})", walk.0.rel, walk.2);
    Some(walk)
}

/// The first `n` walks of [`walks`] in their sorted order (for tests that pair walks but are
/// too slow to run on each), fewer when fewer are present (with a printed reason when none).
pub fn first_walks(n: usize) -> Vec<(Labelled, rigcast_retarget::Clip, Gait)> {
    let found = gait_clips("walk", is_biped, Gait::is_walk, n);
    for w in &found {
        println!("a walk: {} ({:?})", w.0.rel, w.2);
    }
    found
}

/// Every labelled BVH clip with legs (any kind) whose root travels at least a leg length over
/// the ground, sorted; empty with a printed reason when none is present.
pub fn travelling_clips() -> Vec<(Labelled, rigcast_retarget::Clip, Gait)> {
    gait_clips(
        "travelling clip",
        Labelled::has_legs,
        |g| g.travel >= 1.0,
        usize::MAX,
    )
}

/// The first labelled biped clip that steps on the spot: its feet change places at least twice
/// while its root stays within a tenth of a leg length (an in-place walk cycle); `None` with a
/// printed reason.
pub fn first_in_place_cycle() -> Option<(Labelled, rigcast_retarget::Clip, Gait)> {
    let in_place = |g: &Gait| g.switches >= 2 && g.travel < 0.1;
    let cycle = gait_clips("in-place walk cycle", is_biped, in_place, 1).pop()?;
    println!("the in-place cycle: {} ({:?})", cycle.0.rel, cycle.2);
    Some(cycle)
}

/// One animation of a labelled file, loaded at 30 fps (`animation` `None` for a BVH clip).
#[derive(Clone, Debug)]
pub struct Animation {
    pub file: Labelled,
    pub animation: Option<String>,
    pub clip: rigcast_retarget::Clip,
    pub gait: Gait,
}

/// Every animation (each of a glTF's, a BVH's one) of the labelled files `keep` accepts that
/// steps on the spot: its feet change places at least twice while its hips stay within a
/// tenth of a leg length (an in-place gait cycle, as game assets walk), loaded at 30 fps, in
/// sorted order; empty with a printed reason when none.
pub fn in_place_cycles(keep: impl Fn(&Labelled) -> bool) -> Vec<Animation> {
    let mut out = Vec::new();
    for file in labelled().into_iter().filter(|l| l.has_legs() && keep(l)) {
        let names: Vec<Option<String>> = if file.is_bvh() {
            vec![None]
        } else {
            animation_names(&file.path).into_iter().map(Some).collect()
        };
        for animation in names {
            let opts = rigcast_sources::LoadOptions {
                animation: animation.clone(),
                sample_fps: Some(30.0),
                ..rigcast_sources::LoadOptions::default()
            };
            let Ok(clip) = rigcast_sources::load_clip_with(&file.path, &opts) else {
                continue;
            };
            match gait(&file, &clip) {
                Some(gait) if gait.switches >= 2 && gait.travel < 0.1 => out.push(Animation {
                    file: file.clone(),
                    animation,
                    clip,
                    gait,
                }),
                _ => {}
            }
        }
    }
    if out.is_empty() {
        println!(
            "SKIP: no labelled in-place gait cycle under {}",
            shared_data_root().display()
        );
    }
    out
}

fn is_biped(l: &Labelled) -> bool {
    matches!(l.kind(), "human" | "biped_creature") && l.has_legs()
}

/// Up to `limit` labelled BVH clips that `label` accepts and whose gait `motion` accepts,
/// loaded, in sorted order; empty with a printed reason naming `what` when none.
fn gait_clips(
    what: &str,
    label: impl Fn(&Labelled) -> bool,
    motion: impl Fn(&Gait) -> bool,
    limit: usize,
) -> Vec<(Labelled, rigcast_retarget::Clip, Gait)> {
    let mut out = Vec::new();
    for l in labelled().into_iter().filter(|l| l.is_bvh() && label(l)) {
        if out.len() >= limit {
            break;
        }
        let Ok(clip) = rigcast_sources::load_clip(&l.path) else {
            continue;
        };
        match gait(&l, &clip) {
            Some(g) if motion(&g) => out.push((l, clip, g)),
            g => println!("not a {what}: {} ({g:?})", l.rel),
        }
    }
    if out.is_empty() {
        println!(
            "SKIP: no labelled {what} among the clips of {}",
            shared_data_root().display()
        );
    }
    out
}

/// Labelled human BVH clips with both legs labelled whose motion lasts a second or more and
/// moves (a bone turns by more than a degree from its first pose; a still capture is no motion
/// to join), loaded and resampled to 120 Hz, in sorted order, each taken while the frames
/// taken so far and its own fit within `budget_frames` (a motion graph's build grows with the
/// square of its frames; a clip that does not fit is passed over for the next); empty with a
/// printed reason when none is found.
pub fn graph_clips(budget_frames: usize) -> Vec<(Labelled, rigcast_retarget::Clip)> {
    let mut out = Vec::new();
    let mut total = 0;
    let human = |l: &Labelled| l.kind() == "human" && l.has_legs() && l.is_bvh();
    for l in labelled().into_iter().filter(human) {
        let Ok(clip) = rigcast_sources::load_clip(&l.path) else {
            continue;
        };
        // Resampled only when not at 120 Hz already (a resampling drops a last frame that
        // falls a rounding short of the new grid).
        let at_120 = (clip.frame_time_secs * 120.0 - 1.0).abs() < 1e-3;
        let Ok(clip) = (if at_120 {
            Ok(clip)
        } else {
            clip.resampled(1.0 / 120.0)
        }) else {
            continue;
        };
        let first = &clip.poses[0];
        let moves = clip.poses.iter().any(|p| {
            p.rotations
                .iter()
                .zip(&first.rotations)
                .any(|(a, b)| a.angle_between(*b) > 1f32.to_radians())
        });
        let frames = clip.num_frames();
        if frames < 120 || !moves || total + frames > budget_frames {
            println!(
                "not taken for a graph: {} ({frames} frames, moves: {moves})",
                l.rel
            );
            continue;
        }
        total += frames;
        println!("for a graph: {} ({frames} frames at 120 Hz)", l.rel);
        out.push((l, clip));
    }
    if out.is_empty() {
        println!(
            "SKIP: no labelled human clip for a graph under {}",
            shared_data_root().display()
        );
    }
    out
}

/// Every labelled human character rig (not a BVH clip) with both legs labelled, sorted; empty
/// with a printed reason when none is present.
pub fn human_rigs() -> Vec<Labelled> {
    labelled_where("human rig with legs", |l| {
        l.kind() == "human" && l.has_legs() && !l.is_bvh()
    })
}

/// Every video of the shared data's `video/` folder and of `pose2sim` (the clips
/// `scripts/setup-vision.sh` installs), sorted per folder, found by listing; only those whose
/// name holds one of `RIGCAST_FOOTAGE_CLIPS`' comma-separated parts when it is set. A folder
/// missing is said and skipped.
pub fn footage_clips(pose2sim: &Path) -> Vec<PathBuf> {
    let only = std::env::var("RIGCAST_FOOTAGE_CLIPS").unwrap_or_default();
    let mut found = Vec::new();
    for dir in [shared_data_root().join("video"), pose2sim.to_path_buf()] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            println!("SKIP part: no folder {}", dir.display());
            continue;
        };
        let mut here: Vec<PathBuf> = entries
            .filter_map(|e| Some(e.ok()?.path()))
            .filter(|p| {
                let name = p.file_name().unwrap_or_default().to_string_lossy();
                ["mp4", "avi", "mkv", "mov", "webm"]
                    .iter()
                    .any(|e| name.ends_with(&format!(".{e}")))
                    && (only.is_empty() || only.split(',').any(|part| name.contains(part)))
            })
            .collect();
        here.sort();
        found.extend(here);
    }
    found
}

/// Every file of the shared data whose extension is one of `exts` (any case), labelled or not,
/// found by listing its folders (up to three levels down), sorted by path; empty with a printed
/// reason naming `what` when none is present.
pub fn data_files(what: &str, exts: &[&str]) -> Vec<PathBuf> {
    let root = shared_data_root();
    let out: Vec<PathBuf> = files_under(&root)
        .into_iter()
        .filter(|path| {
            path.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
        })
        .collect();
    if out.is_empty() {
        println!("SKIP: no {what} ({exts:?}) under {}", root.display());
    }
    out
}

/// Every file under `root`, found by listing its folders (up to three levels down; a loop of
/// links cannot run away), sorted by path.
pub fn files_under(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut folders = vec![(root.to_path_buf(), 0)];
    while let Some((dir, depth)) = folders.pop() {
        for path in std::fs::read_dir(&dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
        {
            if path.is_dir() {
                if depth < 3 {
                    folders.push((path, depth + 1));
                }
            } else {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// `path` relative to the shared data folder (as the label files key it), for messages.
pub fn data_rel(path: &Path) -> String {
    let root = shared_data_root();
    path.strip_prefix(&root)
        .unwrap_or(path)
        .to_string_lossy()
        .into_owned()
}

/// The JSON document of a glTF file (`.gltf` text, or a GLB's JSON chunk), or `None` when the
/// file cannot be read as one.
pub fn gltf_json(path: &Path) -> Option<serde_json::Value> {
    let bytes = std::fs::read(path).ok()?;
    let json = if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        bytes.get(20..20 + len)?
    } else {
        &bytes[..]
    };
    serde_json::from_slice(json).ok()
}

/// Whether a glTF file draws a skinned mesh: a node carries both a `skin` and a `mesh`.
pub fn has_skinned_mesh(path: &Path) -> bool {
    gltf_json(path).is_some_and(|doc| {
        doc["nodes"]
            .as_array()
            .into_iter()
            .flatten()
            .any(|n| n.get("skin").is_some() && n.get("mesh").is_some())
    })
}

/// Every labelled human character with both legs labelled stored as a binary glTF (`.glb`)
/// that draws a skinned mesh, sorted; empty with a printed reason when none is present.
pub fn skinned_human_glbs() -> Vec<Labelled> {
    labelled_where("human GLB with legs and a skinned mesh", |l| {
        l.kind() == "human"
            && l.has_legs()
            && l.path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
            && has_skinned_mesh(&l.path)
    })
}

/// The first labelled human clip with legs whose labels give it no neck (a sparse spine, the
/// head straight on the spine: a character with a neck has a bone no source bone drives),
/// loaded; `None` with a printed reason.
pub fn first_neckless_clip() -> Option<(Labelled, rigcast_retarget::Clip)> {
    let found = labelled_where("human clip with legs and no neck", |l| {
        l.kind() == "human" && l.is_bvh() && l.has_legs() && !l.has_role("neck")
    });
    let first = found.into_iter().next()?;
    println!("the neckless clip: {}", first.rel);
    let clip = rigcast_sources::load_clip(&first.path).expect("a labelled clip loads");
    Some((first, clip))
}

/// The names of a file's animations, in the file's order (one for a BVH); empty when it has
/// none or cannot be read.
pub fn animation_names(path: &Path) -> Vec<String> {
    rigcast_sources::describe(path)
        .map(|info| info.animations.into_iter().map(|a| a.name).collect())
        .unwrap_or_default()
}
