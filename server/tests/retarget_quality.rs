//! How faithfully `rigcast retarget` moves real characters: every labelled human with motion in
//! the shared data onto every other labelled human, measured in world space with the labels
//! (not rigcast's own analysis) naming the joints on both sides:
//! - limb directions: upper/lower arm, upper/lower leg, foot→toes of the output vs the source,
//!   each from joint to end as the character shows them (its own forward kinematics, the
//!   translations of bones carried beside a limb included);
//! - horizontal root travel, scaled by the leg-length ratio;
//! - feet on the floor where the source's are: on every frame at the clip's own rate, each
//!   rig's up the coordinate axis nearest its hips-over-feet, a foot planted when it is within
//!   1 cm of its floor and slower than 0.15 m/s (REFERENCE §7's toe-speed rule), each foot's
//!   floor the 5th percentile of its lowest points while still. The target's foot stands as
//!   high above its floor as the source's above its own (scaled), or on it where the source's
//!   dips below (the lock never puts a foot under the floor); rigs whose labelled feet are not
//!   their feet are left out of this measure and named.
//!
//! A table of every pair is printed. The bounds (≤ 2° mean, ≤ 5° max per pair; travel within
//! 5 %; planted feet within 1 cm of the floor) are asserted on the pairs whose automatic mapping
//! is right per the labels (each measured target joint driven by one of the source's acceptable
//! bones for the same role), so the assertion covers more pairs as the mapping improves.
#![allow(clippy::unwrap_used)]

mod common;
#[path = "common/leg_phases.rs"]
mod leg_phases;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{world_transforms, BoneId, Clip, RootMotion, Skeleton};
use rigcast_server::offline::{plan_mapping, retarget_clip_locked};
use serde_json::Value;

use leg_phases::{
    phase, print_phase_sums, print_phases, tally_phases, PhaseSums, PHASES, PHASE_NEAR_SECS,
};

/// Source frames measured per pair (evenly spread over the clip).
const FRAMES_PER_PAIR: usize = 90;
/// (joint, child joint) roles of the measured segments, per side.
const SEGMENTS: [(&str, &str); 5] = [
    ("upperArm", "lowerArm"),
    ("lowerArm", "hand"),
    ("upperLeg", "lowerLeg"),
    ("lowerLeg", "foot"),
    ("foot", "toes"),
];
/// The leg's segments (the legs' judge measures these alone).
const LEG_SEGMENTS: [(&str, &str); 3] = [
    ("upperLeg", "lowerLeg"),
    ("lowerLeg", "foot"),
    ("foot", "toes"),
];

struct Labelled {
    path: PathBuf,
    labels: Value,
    clip: Clip,
}

impl Labelled {
    /// The primary labelled bone of `role`, if the rig has it.
    fn bone(&self, role: &str) -> Option<BoneId> {
        let name = self.labels[role].as_array()?.first()?.as_str()?;
        self.clip.skeleton.bone(name)
    }

    /// Every labelled bone of `role` the rig has (a hand labelled as three palm bones
    /// starting at the wrist is any of them).
    fn bones(&self, role: &str) -> Vec<BoneId> {
        (self.labels[role].as_array().into_iter().flatten())
            .filter_map(|n| self.clip.skeleton.bone(n.as_str()?))
            .collect()
    }

    fn accepts(&self, role: &str, name: &str) -> bool {
        self.labels[role]
            .as_array()
            .is_some_and(|a| a.iter().any(|n| n.as_str() == Some(name)))
    }

    fn name(&self) -> String {
        self.path
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned()
    }
}

fn load_humans(root: &Path) -> Vec<Labelled> {
    load_humans_from(root, &[root.join("labels.json")])
}

/// Every labels file of the shared data: its own `labels.json` and each folder's (keys are
/// paths relative to the data folder in all of them; they are judged together).
fn label_files(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("labels.json")];
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("labels.json").is_file())
        .collect();
    dirs.sort();
    files.extend(dirs.into_iter().map(|d| d.join("labels.json")));
    files
}

fn load_humans_from(root: &Path, files: &[PathBuf]) -> Vec<Labelled> {
    let mut out = Vec::new();
    for file in files {
        let labels: Value = serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
        load_labelled(root, &labels, &mut out);
    }
    out
}

fn load_labelled(root: &Path, labels: &Value, out: &mut Vec<Labelled>) {
    for (key, v) in labels.as_object().unwrap() {
        if v["kind"] != "human" {
            continue;
        }
        let path = root.join(key);
        let clip = rigcast_sources::load_clip(&path).unwrap();
        out.push(Labelled {
            path,
            labels: v.clone(),
            clip,
        });
    }
}

fn sided(role: &str, side: &str) -> String {
    format!("{role}.{side}")
}

/// Roles a measurement of `segments` uses, both sides, and the hips.
fn measured_roles(segments: &[(&str, &str)]) -> Vec<String> {
    let mut roles = vec!["hips".to_string()];
    for side in ["L", "R"] {
        for &(a, b) in segments {
            for r in [a, b] {
                let r = sided(r, side);
                if !roles.contains(&r) {
                    roles.push(r);
                }
            }
        }
    }
    roles
}

/// Whether every role of the target a measurement of `segments` uses (present on both rigs)
/// is driven by one of the source's acceptable bones for that role; and the roles that are
/// not. A judge of the legs asks this of the legs' roles: a hand mapped wrong moves no leg.
/// A role the target labels with several bones is right when any of them is so driven, as
/// the mapping's own judges read the labels (zoo_mapping, map_real): RobotExpressive's hand is
/// three palm bones starting at the wrist, one of them driven by the source's wrist.
fn mapping_right(
    src: &Labelled,
    tgt: &Labelled,
    table: &rigcast_retarget::mapping::MappingTable,
    segments: &[(&str, &str)],
) -> Vec<String> {
    let mut wrong = Vec::new();
    for role in measured_roles(segments) {
        let (Some(t), Some(_)) = (tgt.bone(&role), src.bone(&role)) else {
            continue;
        };
        let mapped = |t: BoneId| {
            table
                .get(t)
                .and_then(|e| e.primary())
                .map(|r| src.clip.skeleton.name(r.bone).to_string())
        };
        let right = |t: &BoneId| mapped(*t).is_some_and(|n| src.accepts(&role, &n));
        if !tgt.bones(&role).iter().any(right) {
            wrong.push(format!(
                "{role}←{}",
                mapped(t).unwrap_or_else(|| "-".into())
            ));
        }
    }
    wrong
}

fn subsample(clip: &Clip) -> Clip {
    let step = (clip.num_frames() / FRAMES_PER_PAIR).max(1);
    let poses: Vec<_> = clip.poses.iter().step_by(step).cloned().collect();
    Clip::new(
        clip.name.clone(),
        clip.skeleton.clone(),
        poses,
        clip.frame_time_secs * step as f64,
    )
    .unwrap()
}

fn leg_length(s: &Skeleton, l: &Labelled) -> Option<f32> {
    let rest = world_transforms(s, &s.rest_pose());
    let p = |r: &str| l.bone(r).map(|b| rest[b.index()].translation);
    let mut total = 0.0;
    for side in ["L", "R"] {
        let (a, b, c) = (
            p(&sided("upperLeg", side))?,
            p(&sided("lowerLeg", side))?,
            p(&sided("foot", side))?,
        );
        total += (b - a).length() + (c - b).length();
    }
    Some(total / 2.0)
}

#[derive(Debug, Default)]
struct Figures {
    mean_deg: f32,
    max_deg: f32,
    worst_segment: String,
    travel_error: Option<f32>,
    feet: Option<FeetFigures>,
}

/// How high the target's feet are where the source's stand, each above its own floor.
#[derive(Debug, Clone, Copy, Default)]
struct FeetFigures {
    /// Source frames (both sides) with a planted foot.
    planted: usize,
    /// 95th percentile and largest |target height − scaled source height|, cm.
    p95_cm: f32,
    max_cm: f32,
}

/// Highest share of its hips' height a rig's labelled ankles may stand at in its own rest for
/// its feet to be judged against a floor (a person's ankle: about 0.1 of the hip joint's height).
const MAX_REST_ANKLE_SHARE: f32 = 0.25;

/// How high a rig's labelled ankles stand in its own rest, as a share of its labelled thighs'
/// roots' height, both above its lowest labelled foot joint. A rig whose offsets are shifted one
/// level (its joint labelled ankle at the knee, REFERENCE §14) stands far higher: its labelled
/// joints do not say where its feet are, and no height of theirs above a floor can be judged.
fn rest_ankle_share(l: &Labelled) -> Option<f32> {
    let s = &l.clip.skeleton;
    let rest = world_transforms(s, &s.rest_pose());
    let p = |r: String| l.bone(&r).map(|b| rest[b.index()].translation);
    let mut worst: Option<f32> = None;
    for side in ["L", "R"] {
        let (hip, ankle) = (p(sided("upperLeg", side))?, p(sided("foot", side))?);
        let d = hip - ankle;
        let axis = d.abs().max_position();
        let up = Vec3::AXES[axis] * d[axis].signum();
        let lowest = [Some(ankle), p(sided("toes", side))]
            .into_iter()
            .flatten()
            .map(|v| v.dot(up))
            .fold(f32::MAX, f32::min);
        let share = (ankle.dot(up) - lowest) / (hip.dot(up) - lowest).max(1e-6);
        worst = Some(worst.map_or(share, |w| w.max(share)));
    }
    worst
}

/// Whether a rig's feet can be judged against a floor ([`rest_ankle_share`]); prints why not.
fn feet_judged(l: &Labelled) -> bool {
    match rest_ankle_share(l) {
        Some(share) if share <= MAX_REST_ANKLE_SHARE => true,
        share => {
            println!(
                "feet not judged on {}: its labelled ankles stand at {} of its hip joints' height \
                 in its rest (bound {MAX_REST_ANKLE_SHARE})",
                l.name(),
                share.map_or("?".to_string(), |s| format!("{s:.2}"))
            );
            false
        }
    }
}

/// A foot stands still below this speed (REFERENCE §7: toe speed < 0.15 m/s), for a 1.75 m
/// body (scaled with the rig's legs, so rigs in inches or CMU units are judged alike).
const STILL_SPEED: f32 = 0.15;
/// A still foot is planted within this height of its floor (1 cm of a 1.75 m body, scaled
/// alike).
const NEAR_FLOOR: f32 = 0.01;

/// Metres of a 1.75 m body per unit of `l`'s rig (its legs against [`LEG_OF_175_CM_BODY`]).
fn body_scale(l: &Labelled, s: &Skeleton) -> Option<f32> {
    Some(LEG_OF_175_CM_BODY / leg_length(s, l)?)
}
/// Speeds are taken over at least this long (REFERENCE §7: at least 1/30 s).
const SPEED_WINDOW_SECS: f64 = 1.0 / 30.0;

/// Per side: each frame's lowest foot point (ankle or toes, along the rig's up) and whether the
/// foot's joints stand still (all slower than [`STILL_SPEED`]). Up is the coordinate axis
/// nearest to hips over feet, averaged.
fn foot_tracks(l: &Labelled, other: &Labelled, clip: &Clip) -> Option<Vec<Vec<(f32, bool)>>> {
    foot_tracks_up(l, other, clip).map(|(t, _)| t)
}

/// [`foot_tracks`] and the up axis they were measured along.
type Tracks = (Vec<Vec<(f32, bool)>>, Vec3);

fn foot_tracks_up(l: &Labelled, other: &Labelled, clip: &Clip) -> Option<Tracks> {
    let s = &clip.skeleton;
    let hips = l.bone("hips")?;
    let worlds: Vec<Vec<Vec3>> = clip
        .poses
        .iter()
        .map(|p| {
            world_transforms(s, p)
                .iter()
                .map(|w| w.translation)
                .collect()
        })
        .collect();
    let sides: Vec<Vec<BoneId>> = ["L", "R"]
        .iter()
        .map(|side| {
            [sided("foot", side), sided("toes", side)]
                .iter()
                .filter(|r| other.bone(r).is_some())
                .filter_map(|r| l.bone(r))
                .collect()
        })
        .collect();
    let mut up = Vec3::ZERO;
    for w in &worlds {
        let feet: Vec<Vec3> = sides
            .iter()
            .filter_map(|b| b.first())
            .map(|b| w[b.index()])
            .collect();
        if !feet.is_empty() {
            up += w[hips.index()] - feet.iter().sum::<Vec3>() / feet.len() as f32;
        }
    }
    // Mocap floors are level with a coordinate axis: hips-over-feet averaged leans (people
    // walk leaning forward, sit with their feet ahead), so it only picks which axis is up.
    let axis = up.abs().max_position();
    let up = Vec3::AXES[axis] * up[axis].signum();
    let still_speed = STILL_SPEED / body_scale(l, s)?;
    let lag = ((SPEED_WINDOW_SECS / clip.frame_time_secs).ceil() as usize).max(1);
    let secs = (lag as f64 * clip.frame_time_secs) as f32;
    let flat = |v: Vec3| v - up * v.dot(up);
    let track = |bones: &[BoneId]| -> Vec<(f32, bool)> {
        (0..worlds.len())
            .map(|i| {
                let w = &worlds[i];
                let low = bones
                    .iter()
                    .map(|b| w[b.index()].dot(up))
                    .fold(f32::MAX, f32::min);
                let (a, b) = (
                    i.saturating_sub(lag / 2),
                    (i + lag - lag / 2).min(worlds.len() - 1),
                );
                let still = b > a
                    && bones.iter().all(|j| {
                        let d = flat(worlds[b][j.index()] - worlds[a][j.index()]).length();
                        d / (secs * (b - a) as f32 / lag as f32) < still_speed
                    });
                (low, still)
            })
            .collect()
    };
    let tracks: Vec<_> = sides
        .iter()
        .filter(|b| !b.is_empty())
        .map(|b| track(b))
        .collect();
    (!tracks.is_empty()).then_some((tracks, up))
}

/// A rig's floor: the 5th percentile of its feet's lowest points while they stand still (one
/// frame dipping lower does not move it).
fn floor_of(tracks: &[Vec<(f32, bool)>]) -> Option<f32> {
    let mut h: Vec<f32> = tracks
        .iter()
        .flatten()
        .filter(|(_, still)| *still)
        .map(|(h, _)| *h)
        .collect();
    h.sort_by(f32::total_cmp);
    h.get(h.len() / 20).copied()
}

/// Where the source's foot is planted (still, within 1 cm of its floor), the target's lowest
/// foot point must be as high above the target's floor, scaled by the leg-length ratio; a
/// source foot below its floor (a capture dipping into the ground) asks for the target's on
/// its floor, where the foot lock keeps every foot. In cm of a 1.75 m body (the target's
/// legs scaled to [`LEG_OF_175_CM_BODY`]): rigs in other units (inches, CMU's) are judged
/// alike.
fn planted_feet(src: &Labelled, tgt: &Labelled, clip: &Clip, out: &Clip) -> Option<FeetFigures> {
    let ratio = leg_length(&out.skeleton, tgt)? / leg_length(&clip.skeleton, src)?;
    let body = body_scale(tgt, &out.skeleton)?;
    let src_body = body_scale(src, &clip.skeleton)?;
    let (ts, tt) = (foot_tracks(src, tgt, clip)?, foot_tracks(tgt, src, out)?);
    // Each foot's own floor: a rig's two feet may stand at different heights (mocap markers
    // placed differently on each foot, an asymmetric rest), and each stands on its own level.
    let mut errors: Vec<f32> = Vec::new();
    for (a, b) in ts.iter().zip(&tt) {
        let (Some(fs), Some(ft)) = (
            floor_of(std::slice::from_ref(a)),
            floor_of(std::slice::from_ref(b)),
        ) else {
            continue;
        };
        let dump = std::env::var_os("RIGCAST_QUALITY_FRAMES").is_some();
        for (frame, ((hs, still), (ht, _))) in a.iter().zip(b).enumerate() {
            if !(*still && hs - fs < NEAR_FLOOR / src_body) {
                continue;
            }
            let e = ((ht - ft) - ratio * (hs - fs).max(0.0)).abs() * 100.0 * body;
            if dump {
                println!(
                    "  frame {frame}: source {:.2} cm, target {:.2} cm above their floors: {e:.2}",
                    (hs - fs) * 100.0 * src_body,
                    (ht - ft) * 100.0 * body
                );
            }
            errors.push(e);
        }
    }
    errors.sort_by(f32::total_cmp);
    let planted = errors.len();
    Some(FeetFigures {
        planted,
        p95_cm: *errors.get(planted * 95 / 100)?,
        max_cm: *errors.last()?,
    })
}

fn measure(src: &Labelled, tgt: &Labelled, clip: &Clip, out: &Clip) -> Figures {
    let (ss, ts) = (&clip.skeleton, &out.skeleton);
    let mut f = Figures::default();
    let (mut sum, mut n) = (0.0f32, 0usize);
    let pairs: Vec<(String, [BoneId; 4])> = ["L", "R"]
        .iter()
        .flat_map(|side| {
            SEGMENTS
                .iter()
                .map(move |(a, b)| (sided(a, side), sided(b, side)))
        })
        .filter_map(|(a, b)| {
            Some((
                format!("{a}→{b}"),
                [src.bone(&a)?, src.bone(&b)?, tgt.bone(&a)?, tgt.bone(&b)?],
            ))
        })
        .collect();
    let (mut src_hips, mut tgt_hips) = (Vec::new(), Vec::new());
    let mut ups = Vec3::ZERO;
    let (sh, th) = (src.bone("hips"), tgt.bone("hips"));
    for (sp, tp) in clip.poses.iter().zip(&out.poses) {
        let (fs, ft) = (world_transforms(ss, sp), world_transforms(ts, tp));
        let ws: Vec<Vec3> = fs.iter().map(|w| w.translation).collect();
        let wt: Vec<Vec3> = ft.iter().map(|w| w.translation).collect();
        for (label, [a, b, c, d]) in &pairs {
            let ds = segment_direction(&fs, *a, *b);
            let dt = segment_direction(&ft, *c, *d);
            if ds.length() < 1e-4 || dt.length() < 1e-4 {
                continue;
            }
            let deg = ds.angle_between(dt).to_degrees();
            sum += deg;
            n += 1;
            if deg > f.max_deg {
                f.max_deg = deg;
                f.worst_segment = label.clone();
            }
        }
        if let (Some(sh), Some(th)) = (sh, th) {
            src_hips.push(ws[sh.index()]);
            tgt_hips.push(wt[th.index()]);
            let feet_mid: Vec<Vec3> = ["foot.L", "foot.R"]
                .iter()
                .filter_map(|r| src.bone(r).map(|b| ws[b.index()]))
                .collect();
            if !feet_mid.is_empty() {
                ups += ws[sh.index()] - feet_mid.iter().sum::<Vec3>() / feet_mid.len() as f32;
            }
        }
    }
    f.mean_deg = if n > 0 { sum / n as f32 } else { f32::NAN };
    let up = ups.normalize_or_zero();
    let ratio = leg_length(ts, tgt)
        .zip(leg_length(ss, src))
        .map(|(t, s)| t / s);
    if let (Some(ratio), Some(first_s), Some(first_t)) = (ratio, src_hips.first(), tgt_hips.first())
    {
        let flat = |v: Vec3| v - up * v.dot(up);
        let ds = flat(*src_hips.last().unwrap() - *first_s) * ratio;
        let dt = flat(*tgt_hips.last().unwrap() - *first_t);
        if ds.length() > 0.2 {
            f.travel_error = Some((dt - ds).length() / ds.length());
        }
    }
    f
}

/// One measured pair: its name, its figures, and the measured roles mapped wrong.
struct Pair {
    name: String,
    figures: Figures,
    wrong: Vec<String>,
}

/// Whether the target's feet are locked while the source's are planted (`rigcast retarget`'s
/// default; `--no-foot-lock` turns it off).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lock {
    On,
    Off,
}

/// Retargets every labelled human with motion onto every other one and measures each pair,
/// printing the table. `None` when the shared data is absent.
fn measure_pairs(locks: Lock) -> Option<Vec<Pair>> {
    let root =
        common::shared_data("labels.json").and_then(|p| p.parent().map(Path::to_path_buf))?;
    let humans = load_humans(&root);
    let judged: Vec<bool> = humans.iter().map(feet_judged).collect();
    let sources: Vec<&Labelled> = humans
        .iter()
        .filter(|h| h.clip.num_frames() >= 30)
        .collect();
    println!("foot lock {locks:?}");
    println!(
        "{:<40} {:<40} {:>6} {:>6} {:>8} {:>16}  mapping",
        "source", "target", "mean°", "max°", "travel%", "feet p95/max cm"
    );
    let mut pairs = Vec::new();
    for src in &sources {
        let clip = subsample(&src.clip);
        for tgt in humans.iter().filter(|t| t.path != src.path) {
            let plan = plan_mapping(&src.clip, &tgt.clip, None).unwrap();
            let opts = plan.retarget_options(&src.clip, RootMotion::Scaled);
            let target = Arc::new((*tgt.clip.skeleton).clone());
            // The whole clip at its own rate (plants are detected and locks blend in time),
            // measured on the same frames as the source.
            let lock = (locks == Lock::On).then_some(&plan);
            let out =
                retarget_clip_locked(&src.clip, &target, &plan.table, &opts, lock, &mut |_| {})
                    .unwrap();
            let mut figures = measure(src, tgt, &clip, &subsample(&out));
            let judge = |l: &Labelled| {
                humans
                    .iter()
                    .zip(&judged)
                    .any(|(h, j)| *j && h.path == l.path)
            };
            if judge(src) && judge(tgt) {
                figures.feet = planted_feet(src, tgt, &src.clip, &out);
            }
            let wrong = mapping_right(src, tgt, &plan.table, &SEGMENTS);
            let opt =
                |v: Option<f32>, k: f32| v.map_or("-".to_string(), |v| format!("{:.1}", v * k));
            let feet = figures.feet.map_or("-".to_string(), |f| {
                format!("{:.1}/{:.1} ({})", f.p95_cm, f.max_cm, f.planted)
            });
            println!(
                "{:<40} {:<40} {:>6.2} {:>6.2} {:>8} {:>16}  {}",
                src.name(),
                tgt.name(),
                figures.mean_deg,
                figures.max_deg,
                opt(figures.travel_error, 100.0),
                feet,
                if wrong.is_empty() {
                    "right".to_string()
                } else {
                    format!("wrong: {}", wrong.join(" "))
                }
            );
            pairs.push(Pair {
                name: format!("{} → {}", src.name(), tgt.name()),
                figures,
                wrong,
            });
        }
    }
    Some(pairs)
}

/// The pairs the automatic mapping gets right per the labels (asserted); at least one.
fn right_pairs(pairs: &[Pair]) -> Vec<&Pair> {
    let right: Vec<&Pair> = pairs.iter().filter(|p| p.wrong.is_empty()).collect();
    println!(
        "{} of {} pairs are mapped right per the labels and checked against the bounds",
        right.len(),
        pairs.len()
    );
    assert!(!right.is_empty(), "no pair maps right: nothing was checked");
    right
}

/// Measured without the foot lock: its leg IK bends the legs away from the source's on
/// purpose, and these bounds judge the rotations the retarget itself produces.
///
/// 130 of 130 pairs map right (122 before a role labelled with several bones counted as
/// right when any of them is driven right: the 8 onto RobotExpressive, whose hand is three
/// palm bones starting at the wrist). Judged, two of them showed a real miss: its forearm aimed
/// at the thumb, not at the palm the source's wrist drives (CMU 131_01 and the CMU 31-joint
/// rig onto it, 1.79° mean, 14.32° max on lowerArm→hand on every frame); the retarget now
/// aims a segment at the child driven by the joint the source's segment ends in, where it
/// ends in one: 0.00-0.01° / 0.03°, like every other pair.
#[test]
fn limb_directions_and_root_travel_on_real_pairs() {
    let Some(pairs) = measure_pairs(Lock::Off) else {
        return;
    };
    let mut failures = Vec::new();
    for p in right_pairs(&pairs) {
        let f = &p.figures;
        if !(f.mean_deg <= 2.0 && f.max_deg <= 5.0) {
            failures.push(format!(
                "{}: limbs {:.2}° mean, {:.2}° max ({})",
                p.name, f.mean_deg, f.max_deg, f.worst_segment
            ));
        }
        if let Some(e) = f.travel_error.filter(|e| *e > 0.05) {
            failures.push(format!("{}: root travel off by {:.1} %", p.name, 100.0 * e));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Planted feet within 1 cm of the floor, with the foot lock on (the command's default): per
/// pair, the 95th percentile over every source frame with a planted foot (a few frames of a
/// landing blend may exceed it; the largest is printed too). Last measured: 100 of 100 judged
/// pairs, median 0.18 cm. Before, 101 of 122 (the Kinect rig's pairs then included): the target's
/// foot and ball only came down onto their pins once the source's foot had landed, settling for
/// the blend's length while the source's already stood (1.0–2.7 cm on cmu_31joint_example as
/// the source, 1.5 cm sparse_spine_head → xsens); and a source foot dipping below its own floor
/// (cmu_131_01_walk, 2–4 cm) asked the target's to dip as far, where the lock keeps every foot
/// on its floor. 81 before a pinned foot followed the source's clearance above its ground; 78
/// with the lock off.
///
/// Rigs whose labelled ankles stand far off the floor in their own rest
/// ([`rest_ankle_share`]: kinect2__test's offsets are shifted one level, its "ankle" at the
/// knee) are left out and named: their labelled joints are not their feet.
#[test]
fn planted_feet_stay_on_the_floor_on_real_pairs() {
    let Some(pairs) = measure_pairs(Lock::On) else {
        return;
    };
    let right = right_pairs(&pairs);
    let mut cms: Vec<f32> = right
        .iter()
        .filter_map(|p| p.figures.feet.map(|f| f.p95_cm))
        .collect();
    cms.sort_by(f32::total_cmp);
    // Most pairs are judged: leaving rigs out must not empty the check.
    assert!(
        cms.len() * 2 >= right.len(),
        "only {} of {} right pairs judged",
        cms.len(),
        right.len()
    );
    if !cms.is_empty() {
        println!(
            "planted feet: {} of {} judged pairs within 1 cm (95th percentile), median {:.2} cm",
            cms.iter().filter(|c| **c <= 1.0).count(),
            cms.len(),
            cms[cms.len() / 2]
        );
    }
    let failures: Vec<String> = right
        .iter()
        .filter_map(|p| {
            let f = p.figures.feet.filter(|f| f.p95_cm > 1.0)?;
            Some(format!(
                "{}: planted feet {:.2} cm off the floor (95th percentile; largest {:.2})",
                p.name, f.p95_cm, f.max_cm
            ))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The limb measure reads what a character shows, so it can fail where a rig's foot hangs
/// beside its shin (a labelled foot not below its labelled shin, found by the hierarchy): a
/// walk retargeted onto such a rig without the lock, then every such foot put back where the
/// rig's rest has it under its parent (what the character shows when nothing carries it),
/// must read a large knee-to-foot error, where the retarget as made reads a small one.
#[test]
fn limb_measure_sees_a_carried_foot_left_behind() {
    let Some(root) =
        common::shared_data("labels.json").and_then(|p| p.parent().map(Path::to_path_buf))
    else {
        return;
    };
    let humans = load_humans(&root);
    let beside = |h: &Labelled| -> Vec<BoneId> {
        ["L", "R"]
            .iter()
            .filter_map(|side| {
                let knee = h.bone(&sided("lowerLeg", side))?;
                let foot = h.bone(&sided("foot", side))?;
                (!h.clip.skeleton.is_below(foot, knee)).then_some(foot)
            })
            .collect()
    };
    let Some(src) = humans.iter().find(|h| is_gait(h)) else {
        println!("SKIP: no labelled walk or run");
        return;
    };
    let mut checked = 0;
    for tgt in humans.iter().filter(|t| t.path != src.path) {
        let feet = beside(tgt);
        if feet.is_empty() {
            continue;
        }
        let plan = plan_mapping(&src.clip, &tgt.clip, None).unwrap();
        let opts = plan.retarget_options(&src.clip, RootMotion::Scaled);
        let target = Arc::new((*tgt.clip.skeleton).clone());
        let out = retarget_clip_locked(&src.clip, &target, &plan.table, &opts, None, &mut |_| {})
            .unwrap();
        let (clip, made) = (subsample(&src.clip), subsample(&out));
        let mut left = made.clone();
        let rest = tgt.clip.skeleton.rest();
        for pose in &mut left.poses {
            for f in &feet {
                pose.translations[f.index()] = rest[f.index()].translation;
            }
        }
        let (a, b) = (
            measure(src, tgt, &clip, &made),
            measure(src, tgt, &clip, &left),
        );
        println!(
            "{} → {}: as made {:.2}° mean, {:.2}° max ({}); feet left behind {:.2}° mean, \
             {:.2}° max ({})",
            src.name(),
            tgt.name(),
            a.mean_deg,
            a.max_deg,
            a.worst_segment,
            b.mean_deg,
            b.max_deg,
            b.worst_segment
        );
        assert!(
            b.max_deg >= 30.0 && b.max_deg >= a.max_deg + 20.0,
            "the measure did not see the feet left behind"
        );
        assert!(b.worst_segment.contains("lowerLeg"), "{}", b.worst_segment);
        checked += 1;
    }
    if checked == 0 {
        println!("SKIP: no labelled rig whose foot hangs beside its shin");
    }
}

/// Half the standing height of the 1.75 m body drift is normalised to: a person's hip joint
/// stands about as far above the ankle as half their height.
const LEG_OF_175_CM_BODY: f32 = 0.875;

/// How well the legs of a locked output follow the source's, per pair.
#[derive(Debug, Clone, Default)]
struct LegFigures {
    /// Mean and 95th percentile (degrees) of the thigh, shin and foot direction errors.
    thigh: (f32, f32),
    shin: (f32, f32),
    foot: (f32, f32),
    /// The foot's on each rig's own standing foot ([`rest_standing_pitch`]).
    foot_own: (f32, f32),
    /// The foot's, on the frames the source's foot stands and on the others.
    foot_standing: (f32, f32),
    foot_free: (f32, f32),
    /// Horizontal move of the joint the target's foot stands on per frame while the source's
    /// foot stands (cm/frame, scaled to a 1.75 m body), mean over both sides; and the source's
    /// own, alike (printed beside it: a source whose standing feet slide moves that much itself).
    drift: f32,
    source_drift: f32,
    /// The target's drift over every foot joint (the ankle rolling over a ball included).
    joints_drift: f32,
    /// Planted feet's height error (95th percentile, cm), as [`planted_feet`].
    floor_p95: Option<f32>,
    /// Thigh and shin errors (degrees) split by the leg's phase ([`Phase`]).
    phases: [[Vec<f32>; PHASES]; 2],
}

/// Per side ("L", "R"), the frames the lock holds the source's foot as planted (its own
/// two-sided detection on the source's labelled-side hind leg): the phases the lock goes
/// through, which the judge's stricter standing frames (within 1 cm, still) see only part of.
fn lock_plants(clip: &Clip, plan: &rigcast_server::offline::MappingPlan) -> Vec<Vec<bool>> {
    use rigcast_retarget::analysis::Side;
    use rigcast_retarget::footplant::{detect_clip, find_contact_legs, LegKind, PlantSettings};
    let legs = find_contact_legs(&clip.skeleton, &plan.source_analysis);
    let dt = clip.frame_time_secs as f32;
    let up = plan.source_analysis.up;
    let plants = detect_clip(
        &clip.skeleton,
        &legs,
        &clip.poses,
        dt,
        up,
        &PlantSettings::default(),
    );
    [Side::Left, Side::Right]
        .iter()
        .map(|side| {
            let leg = (plants.legs.iter())
                .position(|l| l.side == *side && l.kind == LegKind::Hind && l.limb == 0);
            (0..clip.num_frames())
                .map(|f| leg.is_some_and(|l| plants.is_planted(f, l)))
                .collect()
        })
        .collect()
}

fn mean_p95(v: &mut [f32]) -> (f32, f32) {
    if v.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    v.sort_by(f32::total_cmp);
    let mean = v.iter().sum::<f32>() / v.len() as f32;
    (mean, v[(v.len() * 95 / 100).min(v.len() - 1)])
}

/// Each side's frames on which the foot stands (still, within 1 cm of its floor), with the rig's up.
fn standing_frames(l: &Labelled, other: &Labelled, clip: &Clip) -> Option<(Vec<Vec<bool>>, Vec3)> {
    let (tracks, up) = foot_tracks_up(l, other, clip)?;
    let near = NEAR_FLOOR / body_scale(l, &clip.skeleton)?;
    let sides = tracks
        .iter()
        .map(|t| {
            let floor = floor_of(std::slice::from_ref(t));
            t.iter()
                .map(|(h, still)| *still && floor.is_some_and(|f| h - f < near))
                .collect()
        })
        .collect();
    Some((sides, up))
}

/// A walk or a run: both feet stand at least once, three stances or more in all, and the hips
/// travel at least one leg length over the ground.
fn is_gait(l: &Labelled) -> bool {
    let clip = &l.clip;
    if clip.num_frames() < 2 {
        return false;
    }
    let (Some((sides, up)), Some(hips), Some(leg)) = (
        standing_frames(l, l, clip),
        l.bone("hips"),
        leg_length(&clip.skeleton, l),
    ) else {
        return false;
    };
    let stances: Vec<usize> = sides
        .iter()
        .map(|s| {
            s.windows(2).filter(|w| w[1] && !w[0]).count() + usize::from(s.first() == Some(&true))
        })
        .collect();
    let s = &clip.skeleton;
    let hip = |p| world_transforms(s, p)[hips.index()].translation;
    let start = hip(&clip.poses[0]);
    let travel = clip
        .poses
        .iter()
        .map(|p| {
            let d = hip(p) - start;
            (d - up * d.dot(up)).length()
        })
        .fold(0.0, f32::max);
    stances.len() == 2
        && stances.iter().all(|n| *n >= 1)
        && stances.iter().sum::<usize>() >= 3
        && travel >= leg
}

/// A foot's pitch (radians, toes above the ankle positive) from its ankle-to-toes direction.
fn pitch_along(d: Vec3, up: Vec3) -> f32 {
    (d.dot(up) / d.length().max(1e-9)).clamp(-1.0, 1.0).asin()
}

/// The up of a rig's own rest: the coordinate axis nearest its labelled thigh's root over its
/// ankle (as [`rest_ankle_share`] reads it; a rest may stand along another axis than its
/// motion, a Z-up BVH turned upright by its root's rotation).
fn rest_up(l: &Labelled, side: &str) -> Option<Vec3> {
    let s = &l.clip.skeleton;
    let rest = world_transforms(s, &s.rest_pose());
    let p = |r: String| l.bone(&r).map(|b| rest[b.index()].translation);
    let d = p(sided("upperLeg", side))? - p(sided("foot", side))?;
    let axis = d.abs().max_position();
    Some(Vec3::AXES[axis] * d[axis].signum())
}

/// A rig's foot's left-to-right axis (what it pitches about), fixed in the foot bone's frame:
/// its rest's ankle-to-toes direction over its rest's ground, across its rest's up. Carried by
/// the bone, it stays put however the foot turns or points down.
fn foot_side_local(l: &Labelled, side: &str) -> Option<Vec3> {
    let s = &l.clip.skeleton;
    let up = rest_up(l, side)?;
    let (foot, toes) = (l.bone(&sided("foot", side))?, l.bone(&sided("toes", side))?);
    let rest = world_transforms(s, &s.rest_pose());
    let d0 = segment_direction(&rest, foot, toes);
    let flat = (d0 - up * d0.dot(up)).try_normalize()?;
    Some(rest[foot.index()].rotation.inverse() * flat.cross(up))
}

/// How a performer's foot is pitched when it stands flat (radians, toes above the ankle
/// positive): the median over the frames of `clip` its foot stands (`stands`), as captured.
fn clip_standing_pitch(
    l: &Labelled,
    clip: &Clip,
    side: &str,
    stands: &[bool],
    up: Vec3,
) -> Option<f32> {
    let s = &clip.skeleton;
    let (foot, toes) = (l.bone(&sided("foot", side))?, l.bone(&sided("toes", side))?);
    let mut v: Vec<f32> = (clip.poses.iter().zip(stands))
        .filter(|(_, s)| **s)
        .map(|(p, _)| {
            let w = world_transforms(s, p);
            pitch_along(segment_direction(&w, foot, toes), up)
        })
        .collect();
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied()
}

/// How a character's foot is pitched when it stands flat: its rest's, where that rest stands
/// on the ground along its own up ([`rest_up`]), as a character authored standing does: its
/// lowest labelled foot joint within a quarter of a leg of the ground, its labelled ankles
/// low ([`rest_ankle_share`]) and its toe joint no higher than its ankle (a joint above the
/// ankle is no sole's). Else `None`: a rest floating at the origin (CMU's) or folded along
/// one axis (Bandai's, LaFAN1's) says nothing of how the rig stands.
fn rest_standing_pitch(l: &Labelled, side: &str) -> Option<f32> {
    let s = &l.clip.skeleton;
    let (foot, toes) = (l.bone(&sided("foot", side))?, l.bone(&sided("toes", side))?);
    let rest = world_transforms(s, &s.rest_pose());
    let up = rest_up(l, side)?;
    let p = pitch_along(segment_direction(&rest, foot, toes), up);
    let lowest = [foot, toes]
        .map(|b| rest[b.index()].translation.dot(up))
        .into_iter()
        .fold(f32::MAX, f32::min);
    let on_ground = lowest.abs() <= 0.25 * leg_length(s, l)?;
    let ankles_low = rest_ankle_share(l).is_some_and(|a| a <= MAX_REST_ANKLE_SHARE);
    (on_ground && ankles_low && p <= 0.0).then_some(p)
}

/// One frame's foot error as judged (`RIGCAST_QUALITY_FOOT`): the angle between the source's
/// direction `ds` and the target's `dt` (on the rig's own standing foot, as
/// [`measure_legs`] turns it), the angle between them over the ground (the heading) and each
/// one's pitch.
fn print_foot_frame(frame: usize, side: &str, standing: bool, ds: Vec3, dt: Vec3, up: Vec3) {
    let flat = |d: Vec3| d - up * d.dot(up);
    println!(
        "  {side} frame {frame}{}: {:.1}°, heading {:.1}°, pitch {:.1}° (source {:.1}°)",
        if standing { " standing" } else { "" },
        ds.angle_between(dt).to_degrees(),
        flat(ds).angle_between(flat(dt)).to_degrees(),
        pitch_along(dt, up).to_degrees(),
        pitch_along(ds, up).to_degrees()
    );
}

/// The legs of `out` (the whole clip, locked) against the source's.
fn measure_legs(
    src: &Labelled,
    tgt: &Labelled,
    clip: &Clip,
    out: &Clip,
    held: &[Vec<bool>],
) -> Option<LegFigures> {
    let (ss, ts) = (&clip.skeleton, &out.skeleton);
    let segments = LEG_SEGMENTS;
    let mut errors: [Vec<f32>; 3] = Default::default();
    // The foot's errors split by whether the source's foot stands on the frame.
    let mut foot_split: [Vec<f32>; 2] = Default::default();
    let (stands, up_s) = standing_frames(src, tgt, clip)?;
    // The foot against the source's on each rig's own standing foot: the target's pitched
    // back about its own side axis by how much its standing foot is pitched past the source's.
    let mut own: Vec<f32> = Vec::new();
    // Per side: the pitch the target's standing foot has past the source's, and its side
    // axis; `None` where the target's standing foot is not known (judged raw).
    let offsets: Vec<Option<(f32, Vec3)>> = ["L", "R"]
        .iter()
        .zip(&stands)
        .map(|(side, st)| {
            let ps = clip_standing_pitch(src, clip, side, st, up_s)?;
            let pt = rest_standing_pitch(tgt, side)?;
            Some((pt - ps, foot_side_local(tgt, side)?))
        })
        .collect();
    let step = (clip.num_frames() / 400).max(1);
    let mut phases: [[Vec<f32>; PHASES]; 2] = Default::default();
    let near = (PHASE_NEAR_SECS / clip.frame_time_secs.max(1e-6)).round() as usize;
    for (frame, (sp, tp)) in clip.poses.iter().zip(&out.poses).enumerate().step_by(step) {
        let (fs, ft) = (world_transforms(ss, sp), world_transforms(ts, tp));
        for (si, side) in ["L", "R"].into_iter().enumerate() {
            for (k, (a, b)) in segments.iter().enumerate() {
                let (a, b) = (sided(a, side), sided(b, side));
                let (Some(sa), Some(sb), Some(ta), Some(tb)) =
                    (src.bone(&a), src.bone(&b), tgt.bone(&a), tgt.bone(&b))
                else {
                    continue;
                };
                let ds = segment_direction(&fs, sa, sb);
                let dt = segment_direction(&ft, ta, tb);
                if ds.length() > 1e-4 && dt.length() > 1e-4 {
                    let e = ds.angle_between(dt).to_degrees();
                    errors[k].push(e);
                    if k < 2 && si < 2 {
                        phases[k][phase(held, si, frame, near)].push(e);
                    }
                    if k == 2 {
                        let back = match offsets.get(si) {
                            Some(Some((pitch, axis))) => {
                                Quat::from_axis_angle(ft[ta.index()].rotation * *axis, -pitch)
                            }
                            _ => Quat::IDENTITY,
                        };
                        own.push(ds.angle_between(back * dt).to_degrees());
                        if std::env::var_os("RIGCAST_QUALITY_FOOT").is_some() {
                            let standing = stands.get(si).and_then(|s| s.get(frame)) == Some(&true);
                            print_foot_frame(frame, side, standing, ds, back * dt, up_s);
                        }
                    }
                    if k == 2 {
                        let standing = stands.get(si).and_then(|s| s.get(frame)) == Some(&true);
                        foot_split[usize::from(!standing)].push(e);
                    }
                }
            }
        }
    }
    let [thigh, shin, foot] = errors.map(|mut e| mean_p95(&mut e));
    let foot_own = mean_p95(&mut own);
    let [foot_standing, foot_free] = foot_split.map(|mut e| mean_p95(&mut e));
    Some(LegFigures {
        thigh,
        shin,
        foot,
        foot_own,
        foot_standing,
        foot_free,
        drift: standing_drift(tgt, src, out, &stands, true)?,
        source_drift: standing_drift(src, tgt, clip, &stands, true)?,
        joints_drift: standing_drift(tgt, src, out, &stands, false)?,
        floor_p95: planted_feet(src, tgt, clip, out).map(|f| f.p95_cm),
        phases,
    })
}

/// How far `l`'s foot joints move over the ground per frame in `clip` on the frames `stands`
/// (each side's, from the source) and the frame before: cm/frame of a 1.75 m body, mean over
/// both sides. `contact`: only the joint the foot stands on (its labelled foot joint nearest
/// the floor), else every foot joint `other` has too.
fn standing_drift(
    l: &Labelled,
    other: &Labelled,
    clip: &Clip,
    stands: &[Vec<bool>],
    contact: bool,
) -> Option<f32> {
    let s = &clip.skeleton;
    let (_, up) = foot_tracks_up(l, other, clip)?;
    let scale = LEG_OF_175_CM_BODY / leg_length(s, l)?;
    let worlds: Vec<Vec<Vec3>> = clip
        .poses
        .iter()
        .map(|p| {
            world_transforms(s, p)
                .iter()
                .map(|w| w.translation)
                .collect()
        })
        .collect();
    let (mut sum, mut n) = (0.0f32, 0usize);
    for (side, stand) in ["L", "R"].iter().zip(stands) {
        // The contact is the rig's own (its toes count where the other rig has none).
        let mut joints: Vec<BoneId> = [sided("foot", side), sided("toes", side)]
            .iter()
            .filter(|r| contact || other.bone(r).is_some())
            .filter_map(|r| l.bone(r))
            .collect();
        // A foot whose toes are not labelled may still end in a joint of its own (a BVH End
        // Site ahead of and below the ankle, as the CMU-style rigs' feet do): the foot stands
        // on it too, and the lock turns such a foot about it.
        if let Some(foot) = l.bone(&sided("foot", side)).filter(|_| contact) {
            if l.bone(&sided("toes", side)).is_none() {
                let leaves = s.children(foot).iter().copied();
                joints.extend(leaves.filter(|c| s.children(*c).is_empty()));
            }
        }
        for f in 1..worlds.len().min(stand.len()) {
            if !(stand[f] && stand[f - 1]) {
                continue;
            }
            // The joint the foot stands on: the one nearest the floor on the frame before.
            let lowest = joints.iter().copied().min_by(|a, b| {
                let h = |j: &BoneId| worlds[f - 1][j.index()].dot(up);
                h(a).total_cmp(&h(b))
            });
            let measured: Vec<BoneId> = match (contact, lowest) {
                (true, Some(j)) => vec![j],
                _ => joints.clone(),
            };
            for j in &measured {
                let d = worlds[f][j.index()] - worlds[f - 1][j.index()];
                let cm = (d - up * d.dot(up)).length() * 100.0 * scale;
                if cm > 0.1 && std::env::var_os("RIGCAST_QUALITY_FRAMES").is_some() {
                    println!("  {side} frame {f}: {} moved {cm:.2} cm", s.name(*j));
                }
                sum += cm;
                n += 1;
            }
        }
    }
    Some(if n > 0 { sum / n as f32 } else { f32::NAN })
}

/// A segment's world direction as the character shows it: from its joint to its end, both
/// where the pose's forward kinematics put them. An IK-style rig's foot hangs beside its shin
/// (RobotExpressive's, under the armature root), and the retargeter carries it to the shin's
/// end by its translation, so the knee-to-foot line shows where that foot was put: a foot left
/// behind or carried wrong reads as the large error it is. (Read through the shin's own
/// rotation instead, as before, the line could not see the foot at all.)
fn segment_direction(w: &[rigcast_retarget::WorldTransform], a: BoneId, b: BoneId) -> Vec3 {
    w[b.index()].translation - w[a.index()].translation
}

/// `clip` retargeted onto `target` as [`retarget_clip_locked`] does, but locked by the causal
/// lock frame by frame as the server's tick runs it (`FootLock::apply_live`: plants detected
/// as they come, the fit learnt from the frames seen so far), for `RIGCAST_QUALITY_LIVE`: the
/// live rule on every pair, the rigs the live judge does not stream (BVH characters) too.
fn retarget_causal(
    clip: &Clip,
    target: &Skeleton,
    plan: &rigcast_server::offline::MappingPlan,
    opts: &rigcast_retarget::RetargetOptions,
) -> Clip {
    use rigcast_retarget::footplant::{FootLock, LockSettings};
    let mut mapping =
        rigcast_retarget::Mapping::build(&[&clip.skeleton], target, &plan.table, opts).unwrap();
    if let Some(floor) = mapping.measure_source_floor(&clip.poses) {
        mapping.set_source_floor_y(floor);
    }
    let settings = LockSettings::default();
    let analyses = (&plan.source_analysis, &plan.target_analysis);
    let mut lock = FootLock::new(&mapping, analyses.0, analyses.1, settings);
    let dt = clip.frame_time_secs as f32;
    let mut out = mapping.new_target_pose();
    let poses = (clip.poses.iter())
        .map(|p| {
            mapping.apply_one(p, &mut out).unwrap();
            if let Some(lock) = lock.as_mut() {
                lock.apply_live(p, true, dt, &mut out);
            }
            out.clone()
        })
        .collect();
    Clip::new(
        clip.name.clone(),
        Arc::new(target.clone()),
        poses,
        clip.frame_time_secs,
    )
    .unwrap()
}

/// Whether the pair named `name` ("source → target") is measured: all of them, or with
/// `RIGCAST_QUALITY_PAIRS` set, those whose name contains one of its comma-separated parts
/// (to look at a few pairs while working on the lock).
fn pair_wanted(name: &str) -> bool {
    match std::env::var("RIGCAST_QUALITY_PAIRS") {
        Ok(v) if !v.trim().is_empty() => v.split(',').any(|p| name.contains(p.trim())),
        _ => true,
    }
}

/// Issue 35: with the foot lock on, the legs stay the performer's. On every right pair of
/// labelled humans (every labels file) whose source walks or runs ([`is_gait`]): thigh and shin
/// within 3° mean, 8° p95 of the source's direction, the foot (ankle to toes) within 5° / 15°
/// on each rig's own standing foot (below), planted feet drifting ≤ 0.05 cm/frame (scaled to a 1.75 m body) and standing within 1 cm of
/// where the source's stand ([`planted_feet`], on rigs whose feet can be judged).
///
/// Drift is judged on the joint each foot stands on (its labelled joint nearest the floor; a
/// foot whose toes are not labelled counts the joint its foot bone ends in too, a BVH End
/// Site: the CMU run and dazfriendly rigs stand on theirs, which lies below the ankle): a foot
/// rolling over its ball at a toe-off, as the performer's does, moves its ankle without
/// sliding, while a ball sliding back under a rising ankle is a slide; a planted foot turning
/// with the performer's moves the end it does not turn about. The table prints beside
/// it the source's own drift (its standing feet measured alike: a source whose standing feet
/// slide more than the bound asks the target's to stand stiller than the performer's) and, as
/// `(drift)`, the target's over every foot joint (the measure before: the ankle included).
///
/// Not met yet (run it with `--ignored` for the table; `RIGCAST_QUALITY_PAIRS=a,b` measures
/// only the pairs whose name contains one of the parts, `RIGCAST_QUALITY_FRAMES=1` prints the
/// frames behind the drift and floor figures, `RIGCAST_QUALITY_FOOT=1` the foot's error as
/// judged frame by frame with its heading part and both pitches, `RIGCAST_QUALITY_LIVE=1` judges
/// the causal lock instead, run frame by frame as the server's tick runs it). Of 152 pairs whose legs'
/// roles map right, within the bounds: thigh and shin 137, foot 82 of the 84 with toes on both
/// rigs (59 raw), drift 151 (every foot joint: 129), floor 150; every bound at once (the
/// foot's where both rigs have toes) 136, since a foot landing toes down is pinned as high as
/// its own ball asks at the animation's pitch, not as high as the performer's heel rises
/// (Xia → pybvh test3 3.4/17.7 -> 1.6/7.9°; thigh and shin p95 up to 0.9° worse on 7 pairs
/// under Xia, all far within; 81 (58) and 135 before), since a pinned or landing foot's ball is brought
/// down no lower than the source's ball stands over its own flat standing height (the median
/// over the frames its heel and ball hold; the detector's ground for a ball is where a toe-off
/// rolls it, 2-5 cm lower): a heel strike's toes come down as the performer's do (LaFAN1 →
/// X Bot 5.3/15.0 -> 3.6/6.5°; foot means 3.02/10.73 -> 2.39/8.13°, no pair's foot, floor or
/// drift lost; measured from the ball's lowest point instead, floor 150 -> 135; keeping the
/// animation's pitch wherever the ball is not under the floor, foot 83 but floor 115; 136,
/// 74 (57), 151 (129), 150 and 128 before), since a foot landing toes down is brought to the ankle
/// height its own ball asks at the animation's pitch, not only to the source's heel's (73
/// and 127 before; never pitching an approaching ball down onto its standing height, only
/// up, gave foot 82 but floor 133, drift 143 and every bound 111: the landings' floor), since
/// a pinned foot whose source stands on its ball alone
/// rolls onto its ball as far as its own length asks, its ball where it stood and the
/// animation's pitch kept, not only as far as the source's heel rises (blended in and out
/// over the blends' half-life: switched at once, foot_lock's largest kick on the mannequin
/// 1.59 -> 2.81 cm/frame²): a foot longer against its leg than the performer's was flattened
/// up to 30° at a stand on the toes (CMU 131_01 → xsens, frames 348-426: the source's foot
/// 50-65° down, the target's 25-37°; 3.7/15.8 -> 2.9/8.8°); 69 (55) and 123 before, thigh
/// and shin p95 4.47 -> 4.49°, 3.53 -> 3.58 over the pairs (CMU 31-joint → Mousey 3.9 ->
/// 7.5, within), since a rest standing on its own ground along its own up
/// gives the fit its feet's pitch even where the retarget places no floor for it (MakeHuman,
/// below; 65 (60) and 119 before), since the fit to the standing posture pitches a foot about
/// the axis across its own rest's sole rather than one read off the aligned rest, which the
/// alignment may roll out of the sole (60 (60), 151 (128), 150 and 116 before; foot means
/// 4.23/12.05 -> 3.77/11.82°; X Bot, Mousey and the mannequin gained, CMU 131_01 → X Bot
/// 9.2/12.8 -> 4.2/10.3°, no pair's thigh, shin or foot p95 worse by over 0.5°), since a
/// pinned foot's heading catches up with the
/// animation's over 0.015 s (below; 54 (54), 151 (133) and 110 over the blends' 0.05 s), since
/// the body's height is set from the reach of the held legs and the landing one (below; 123,
/// 54, 151 (132), 149 and 100 before), and since a planted foot turns with the performer's
/// about the joint it stands on (below; 40 (40), 151 (141), 149 and 87 before; floor 150 before the
/// forearm's aim changed with RobotExpressive's rest alignment: Xia → RobotExpressive 1.00 →
/// 1.01 cm; it read 0.74 before the toeless feet rose with the heel). A pinned foot without toes (the
/// Godot robot, RobotExpressive, Quaternius Casual) now rises with the source's heel at a
/// toe-off, as its ankle does in the retarget: held on the floor, its leg was held down while
/// the performer's heel rose, and the hips came down onto it, bending the other leg, the one
/// about to land (Meredith → robot: hips 9 cm down, that thigh 40° off). Only the 24 pairs
/// onto those three changed, every one for the better in thigh and shin (112 before): CMU
/// 131_01 → robot thigh 6.1/25.0 → 5.8/22.9°, Meredith → robot 11.1/41.4 → 5.2/21.4,
/// LaFAN1 → robot 16.1/39.4 → 13.5/27.9, Meredith → RobotExpressive 7.9/32.2 → 3.8/16.5,
/// Meredith → Casual 6.1/23.1 → 1.8/7.0, Xia → RobotExpressive 6.9/17.4 → 5.9/15.0; floor
/// 0.17-1.00 cm on those pairs (0.33-1.06 before; Xia → RobotExpressive 0.74 → 1.00), drift
/// as before. Of 152 before, 112: the 8 onto RobotExpressive (its
/// feet carried beside its shins) are judged since only the legs' roles must map right (its
/// hands, which map from no source bone or a wrong one, kept them out: 144 pairs, 111 / 40 /
/// 143 / 143): thigh and shin within on the CMU run's alone (2.1/7.7°, 1.5/4.9°; the others'
/// thighs 3.2-7.9° mean, 11.7-32.2° p95), drift 0.000 on all 8, floor 0.54-1.06 cm (over
/// under the pymo Meredith walk). Of 144 before the blends' fix: 104, foot 33 (34 raw), drift
/// 143 (every foot joint: 133), floor 143, since the lock no longer takes a character's posture read off a frame of its own motion
/// (the Bandai rigs' and LaFAN1's folded rests) for how it stands: the medoid frame of the
/// Bandai run pitched its feet 50-76° down, and every frame was fitted to it (97 / 28 raw /
/// 141 / 141 before; all 16 pairs onto those rigs that changed got better: CMU 131_01 → Bandai run
/// thigh 4.4/14.1 → 1.7/5.1°, foot 47.9/59.3 → 6.0/24.1°, floor 1.25 → 0.67 cm; CMU run →
/// LaFAN1 thigh 4.9/19.9 → 1.2/7.3°, drift 0.185 → 0.020, floor 1.53 → 0.39). Before that,
/// 96 / 29 / 141 / 141 once a foot turned on the spot turns on its ball, stands flat about its
/// heel and keeps the way its ball points (96 / 32 / 136 (133) / 141 before, the ball swinging about a held
/// ankle; the three feet lost fall 0.2-0.5° over the 15° p95); with the detection before
/// d31149a's, 96 / 33 / 135 / 141 before the ball turned, 84 / 18 / 108 (142) / 140 while a pinned
/// ankle rose with the source's heel over the spot it was pinned at, its ball sliding back
/// under it (earlier, every foot joint: 69 / 1 / 143 / 138
/// while it rose by at most 2 % of the leg, 36 / 1 / 143 / 142 before the root was carried up
/// onto the held feet, 26 / 1 / 142 / 141 before it was carried over the ground). Thigh and
/// shin fail most on the robot (its left foot hangs in the retargeted walk: a mapping matter),
/// Quaternius Casual and Mousey as targets, and with the pymo Meredith walk and LaFAN1 as
/// sources: there the lock still bends the legs at landings (a landing foot brought down onto
/// a floor the hips' height over the standing foot puts it under) and two planted feet the
/// target's proportions set apart differently share their disagreement through the legs. The
/// one drift failure is under the CMU run (onto the pybvh test rig, 0.094 cm/frame), whose own
/// standing feet slide 0.30 cm/frame (the Bandai run and LaFAN1 targets, 0.083 and 0.185
/// before, are held at 0.024 and 0.020 now). The bound stays absolute, not relative to
/// the source's own slide: holding feet that the capture lets slide is what the lock is for,
/// and the other sources whose feet slide past the bound (cmu_dazfriendly 0.39, LaFAN1 0.15)
/// are now held within it on every target. Under the run few frames are judged (its stances
/// last about 0.2 s; the lock blends onto a pin over 0.1 s); the cause is not pinned down.
///
/// The table's last two columns split the foot's error over the frames the source's foot
/// stands on and the others. Where the foot misses its bound the error is on both alike (the
/// CMU 131_01 walk onto X Bot: 28.2/40.5° standing, 24.9/36.3° free; onto the CMU 31-joint
/// rig: 10.0/24.8 and 5.5/23.1): it is not the flattening of a planted foot. Two causes,
/// measured by turning each part of the lock off: the posture fit's pitch, given to every
/// frame so a foot built differently stands flat (off, X Bot 25.3 -> 14.8° mean, but its
/// planted feet 0.69 -> 1.22 cm off the floor, Bandai 47.9 -> 25.2° and 1.25 -> 2.22 cm),
/// and the heading a flat planted foot holds against the animation's turns (up to `PIVOT_RAD`
/// of the lock), whose lag shows while it stands and again while the released foot catches up
/// (turning with the animation on the ball instead: 29 -> 47 of the 84 within the foot's
/// bound, every CMU 131_01 and 131_02 pair onto a CMU-built rig, but the heel then swings
/// about the ball: foot_lock's drift over every foot joint 0.053 on the mannequin, 0.043 on
/// X Bot against its bound of a third of the free 0.106, and drift here 141 -> 133, the
/// targets whose toes are not labelled being judged at the ankle; not landed).
///
/// The foot is judged on each rig's own standing foot: the target's direction (ankle to toes)
/// pitched back, about its own left-to-right axis fixed in its foot bone, by how far its
/// standing foot is pitched past the source's, against the source's. Rigs build feet
/// differently (a toe joint on the ground far ahead of a high ankle, or nearly level with it):
/// X Bot's, the UE-style mannequin's and Mousey's rests stand their feet pitched 39-45° down,
/// the CMU 131_01 performer's stand 13-20°. The raw direction copied onto such a rig tips its
/// foot 20-30° toes up whenever the performer's stands flat; the lock stands it flat instead
/// (the floor bound), as retargeting carries every other bone's rest difference, so a raw
/// judge fails a foot for standing on its sole. The source's standing foot is read from its
/// clip ([`clip_standing_pitch`]: the median over the frames its foot stands), a character's
/// from its rest where that stands on the ground along its own up ([`rest_standing_pitch`],
/// the posture the lock fits to). Where the rest says nothing (CMU's floating at the origin,
/// Bandai's and LaFAN1's folded along one axis) the raw direction is judged, as the lock then
/// keeps the source's. The table prints the raw direction beside it as `(raw°)`.
///
/// Measured on the same lock: 33 of 84 within 5°/15° on the rig's own standing foot, 34 raw.
/// The fitted rigs pass where the lock holds the source's foot: X Bot 4.7-12.2° mean (raw
/// 12.9-25.3), the mannequin 5.0-9.3 (18.8-30.7), Mousey 4.9-15.4 (17.5-29.1), all three
/// within the bound under the Xia walk; their p95 (10.9-33.3°) is the heading a planted foot
/// holds (below). MakeHuman's rest stands along Z while its motion stands along Y: the lock
/// does not fit to it (the retarget finds no floor for that posture in its world), so its
/// foot keeps the source's pitch and is judged 5.1-16.8° off its own standing foot (raw
/// 3.2-6.4): three pairs within the bound raw fail here. Fitting it to that rest anyway (a
/// rest whose feet stand on its own ground along its own up) brought its foot to 3.6/10.1°
/// under the Xia walk but bent its legs and lifted its feet on the others (thigh+shin 104 ->
/// 100, floor 143 -> 141: cmu_dazfriendly 0.60 -> 3.95 cm, its standing heights read along
/// Z against a world along Y); not landed. Taking from that rest the feet's pitch alone, the
/// standing heights still the animation's, does not move them: MakeHuman's foot under the
/// CMU 131_01 walk 12.0/24.1 -> 4.0/9.8°, CMU 31-joint 16.5/23.1 -> 4.2/9.9, Meredith
/// 12.4/15.2 -> 3.7/8.3, CMU 131_02 11.6/15.1 -> 2.9/10.1, Xia 7.1/10.6 -> 2.4/10.3, LaFAN1
/// 4.3/12.9 -> 5.3/14.6 (lost), floor and drift unchanged on all eight, thigh and shin p95
/// 1.2° worse at most (Meredith 2.4 -> 3.6). Tried before and left: judging from
/// each rig's rest pitch alike (0 of 84; the pybvh rigs 67-91° off, their rests floating or
/// read along the motion's up), from each rig's own clip (0 of 84: another performer's foot),
/// and the pitch difference taken out about a side axis read off the foot's direction each
/// frame (25-60° p95: a foot pointing down in the swing has no such axis; the axis here is
/// carried by the foot bone).
///
/// Where the foot fails, it fails on its 95th percentile, under the CMU 131_01, 131_02 and
/// Meredith walks on every target alike (the CMU 31-joint rig, no fit: 6.0/23.5°): frame by
/// frame (CMU 131_01 onto Xia's rig) the error is the heading, held up to `PIVOT_RAD` (25.8°)
/// while the performer turns a planted foot, and again as the released foot catches up. A
/// pivot of 0.15 rad instead: foot 28 -> 42 of 84 raw, but thigh and shin 97 -> 91 (the pin
/// turned about the ball moves the ankle the leg must reach) and foot_lock's drift over every
/// foot joint 0.023 -> 0.034 on the mannequin (its bound about 0.035); not landed. Pitching a
/// heel strike's toes down onto the floor only where they would go under it (instead of
/// standing the pinned foot flat) kept the pitch (foot 28 -> 36 raw) but lost the floor on
/// 43 pairs (141 -> 98); not landed.
///
/// Where the thigh and shin miss: the table is followed by their errors over the pairs outside
/// the bounds, split by each leg's phase as the lock goes through it (its own two-sided
/// detection on the source, [`lock_plants`]): standing alone, both standing, the 0.15 s before
/// a plant (approach), the 0.15 s after one (release), swinging (`RIGCAST_QUALITY_PHASES=1`
/// prints each such pair's split). On main at the ball turn's commit, 29 pairs outside, thigh
/// (frames, mean, share over 8°): single stance 9651, 4.3°, 18 %; double 2110, 4.4°, 17 %;
/// approach 3947, 6.6°, 38 %; release 3516, 2.9°, 7 %; swing 6146, 0.8°, 3 % (shin alike,
/// 3.2 / 4.0 / 4.4 / 1.3 / 0.5°): the legs the lock bends are the standing one (most frames)
/// and the landing one (the worst rate), never a swinging one. 14 of the 29 pairs are under
/// the pymo Meredith walk, whose plants never overlap (no double stance): its standing leg
/// 2.6-3.8° mean, 8.5-11.7° p95, its approach 3.6-6.5 / 12.0-16.0° (onto CMU 131_01, X Bot);
/// 7 are onto the two robots, 5 onto Mousey. The approach is not the free foot's bringing
/// down alone: without it (no landing weight offline) thigh and shin 123 -> 127, foot 40 -> 45,
/// but floor 149 -> 126 and drift 151 -> 142 (the CMU 31-joint walk's landings 0.67 -> 3.04
/// cm onto most rigs; the CMU run's feet slide 0.02-0.04 -> 0.06-0.24), and its phase still
/// reads 6.4° mean, 38 % of frames over 8°: most of the landing leg's error has another cause.
///
/// That cause, traced frame by frame (Meredith → X Bot): the body's height was set by the
/// standing foot alone, and at its toe-off that foot rolls onto its ball. X Bot's foot stands
/// 39° down against the performer's 15°, so the same roll raises its ankle 4.8 cm where the
/// performer's rises 10 (scaled): the body, carried to keep that leg exact, came down 4.4 cm,
/// and the landing foot, 0.4 cm from its floor in the plain retarget, was 4.9 cm under it; its
/// leg bent 12° to reach its pin, and stayed bent (12° → 3° over 0.25 s) while the body came
/// back up after the plant. The height is now the one that turns the legs least (`pelvis`):
/// the held legs and the landing one (weighted by how near its plant is, its goal the height
/// it will be pinned at), each by the squared turn of its thigh and shin, so the bent toe-off
/// leg takes up the difference rather than the straight landing one. With the foot turning
/// about its contact (6cb826e): thigh and shin 123 → 136, every bound at once 100 → 110, floor
/// 149 → 150 (Meredith → Mousey 3.15 → 0.52 cm), foot 54 and drift 151 as before; over the
/// pairs thigh 1.72/6.09 → 1.36/4.51°, shin 1.30/4.70 → 1.04/3.52, foot 4.56/13.20 →
/// 4.57/13.19, drift 0.0056 → 0.0057, floor 0.544 → 0.520 cm (before it, 123 → 135 and 87 →
/// 96). Every Meredith pair gained (→ X Bot thigh 3.0/12.2 → 1.8/6.9°, → Godot robot 5.2/21.4
/// → 3.0/12.0, → UE-style 4.1/15.3 → 2.5/9.5), the largest loss Xia → pybvh test3 3.2 → 5.5°
/// p95 (within). The 16 pairs outside, thigh (frames, mean, share over 8°): single 4582,
/// 3.3°, 10 %; double 1696, 4.6°, 19 %; approach 2037, 6.2°, 33 %; release 1717, 5.1°, 20 %;
/// swing 2994, 1.4°, 6 %: ten onto the two robots, three onto Mousey. Tried before: the mean
/// of the standing and the landing feet's height gaps (123 → 118), which bends a straight leg
/// as much as a bent one.
///
/// By pair, the phase holding most of a pair's thigh and shin frames over 8° (the split's
/// `>8`; on a46e72e, the same 16 pairs): the approach on 7 (the pymo Meredith walk onto
/// pybvh test3, both robots, UE-style and Mousey; the CMU run onto the Godot robot; LaFAN1
/// onto Mousey), both feet standing on 5 (CMU 131_01 onto both robots and Mousey, CMU 131_02
/// onto pybvh test3, Xia onto RobotExpressive), one standing on 2 (LaFAN1 onto both robots),
/// the release on 1 (Xia onto the Godot robot), the swing on 1 (dazfriendly onto the Godot
/// robot); over the 16, frames over 8°: single 565, double 475, approach 934, release 425,
/// swing 227. The approach, traced frame by frame (Meredith onto UE-style, the landing leg's
/// thigh 10-17° off over the 0.1-0.2 s before each plant): the standing foot's toe-off rolls
/// it onto its ball, and its pin's ankle stands 2.0 cm under the animation's as the roll
/// begins, 3.9 cm as it ends, so the body comes down that far to keep that leg as
/// retargeted; the free foot, low over the
/// ground ahead of its plant (its ankle 5-9 cm up against a standing 9.0), goes under its
/// floor with it and the floor's clamp lifts its goal back up, bending its leg, before its
/// landing weight starts. The body's height counting that free foot's floor too (no cost
/// while the body leaves it on or above its floor) changes nothing: the toe-off leg, nearly
/// straight, turns more to reach a pin 4 cm under its reach than the free leg turns to lift
/// its foot (thigh against the retarget without the lock, in process: Meredith onto UE-style
/// 1.96/8.48 → 1.96/8.53°, CMU 131_01 onto the Godot robot 4.19/13.21 → 4.20/13.05); not
/// landed. The lever is the toe-off's roll (how far a pinned
/// ankle on its ball rises against the animation's), not the body's height.
///
/// A pinned foot standing on its ball alone (the source's heel rising: a toe-off, a turn on
/// the ball; which contacts hold is the plant rule's own test, `footplant::Contact`) turns with the
/// animation's heading on its ball, the root carried by the pin's move. The counts above are
/// unchanged by it; over the 152 pairs the means moved foot 5.85/16.21 -> 5.31/15.04°, thigh
/// 1.81/6.30 -> 1.75/6.22, shin 1.38/4.89 -> 1.33/4.80, drift 0.0058 -> 0.0057 (every foot
/// joint 0.0116 -> 0.0120), floor 0.537 -> 0.543 cm (Meredith onto Mousey 2.52 -> 3.21, onto
/// the CMU run and dazfriendly rigs 0.47 -> 0.67). Turning a foot that stands flat too (about
/// the character's own standing contact): foot 40 -> 54 of 84, every bound at once 87 -> 98,
/// but drift 151 -> 149 (LaFAN1, whose own standing feet slide 0.12 cm/frame, onto the CMU run
/// and dazfriendly rigs, whose toes are not labelled and are judged at the ankle: 0.002 ->
/// 0.058 both), and the joint the foot stands on slides where it turns: judged on it,
/// foot_lock's drift mannequin 0.0044 -> 0.0316 (a third of the free 0.0975 is 0.0325), X Bot
/// 0.0064 -> 0.0269, UE-style 0.0055 -> 0.0230, live mannequin 0.0093 -> 0.0421, and the live
/// lock's (footlock_live_legs) X Bot 0.014 -> 0.057, UE-style 0.020 -> 0.058 past 0.05 (every
/// foot joint: mannequin 0.029 -> 0.041); not landed then. Traced frame by frame (CMU 131_01
/// onto the mannequin, whose toe joint stands 1.5 cm up, its ankle 9 cm), two things turned
/// the foot about its ankle instead of the joint it stands on: a plant took the animation's
/// heading at once and blended the shown one onto it about the ankle; and while the source's
/// foot stood on its heel alone (the performer turning on it, 30° over 15 frames) the pin
/// turned about the heel, sweeping the toes, which the lock had stood flat on the floor, by
/// up to 0.88 cm a frame (7.8 cm over that plant). Now the pin keeps the heading shown as the
/// foot lands and catches up with the animation's over the blends' half-life about the joint
/// it stands on: its ball while only the source's ball holds, else its own lower joint
/// (`Foot::pivot_of`). foot_lock's drift on the standing joint is then as without the turn
/// (mannequin 0.0044 -> 0.0045, X Bot 0.0064, UE-style 0.0055 -> 0.0058, live mannequin 0.0093
/// -> 0.0084); here counts as above, no pair's thigh, shin or foot p95 worse by over 0.5° (the
/// foot better on 35 of 84), means foot 5.31/15.04 -> 4.56/13.20°, thigh 1.75/6.22 ->
/// 1.72/6.09, shin 1.33/4.80 -> 1.30/4.70, drift 0.0057 -> 0.0056, floor 0.543 -> 0.544 cm
/// (CMU 31-joint → Mousey 0.47 -> 0.66). Judged at the ankle alone on the rigs whose toes are
/// not labelled (the judge before), drift read 147: the CMU run and dazfriendly rigs under
/// the CMU 131_01 walk and LaFAN1 0.06, their feet turning about their End Sites. Tried
/// before: turning about the source's least-moving point (its heel or its ball, from their
/// moves): foot 60, drift 142 (a noisy capture's heading jitter ratchets the pin), 54 and 149
/// with the turn followed over the blends' half-life. The turn caught up over the blends'
/// half-life lagged a fast pivot (CMU 131_01 onto Xia's rig: 0.8 rad in 12 frames, the pin up
/// to 27° behind, the foot's p95 frames); over 0.015 s the foot went 54 -> 60 of 84 and every
/// bound at once 110 -> 116 (on 37cebb8's body height), means foot 4.57/13.19 -> 4.24/12.08°,
/// thigh 1.36/4.51 -> 1.34/4.47, no pair's thigh, shin or foot p95 worse by over 0.5° (the
/// foot better on 32), drift and floor counts as before (CMU run → Mousey floor 0.39 -> 0.76
/// cm); followed at once (before 37cebb8), the same counts but foot_lock's largest kick on the
/// mannequin 1.57 -> 1.69 cm/frame².
#[test]
#[ignore = "issue 35's bounds are not met yet; the test prints the table per pair"]
fn locked_legs_follow_the_source_on_walks_and_runs() {
    let Some(root) =
        common::shared_data("labels.json").and_then(|p| p.parent().map(Path::to_path_buf))
    else {
        return;
    };
    let humans = load_humans_from(&root, &label_files(&root));
    let judged: Vec<bool> = humans.iter().map(feet_judged).collect();
    let gaits: Vec<&Labelled> = humans.iter().filter(|h| is_gait(h)).collect();
    println!(
        "walk or run sources: {}",
        gaits
            .iter()
            .map(|g| g.name())
            .collect::<Vec<_>>()
            .join(", ")
    );
    assert!(
        !gaits.is_empty(),
        "no walk or run among the labelled humans"
    );
    for h in &humans {
        let pitch = |side| rest_standing_pitch(h, side).map(|p| format!("{:.1}", p.to_degrees()));
        if let (Some(l), Some(r)) = (pitch("L"), pitch("R")) {
            println!("{}: its rest stands, feet pitched {l}° / {r}°", h.name());
        }
    }
    println!(
        "{:<36} {:<36} {:>11} {:>11} {:>11} {:>11} {:>7} {:>7} {:>6} {:>7} {:>11} {:>11}",
        "source",
        "target",
        "thigh°",
        "shin°",
        "foot°",
        "(raw°)",
        "drift",
        "(src)",
        "floor",
        "(drift)",
        "(stand°)",
        "(free°)"
    );
    let mut failures = Vec::new();
    let mut checked = 0;
    // Pairs within the bounds: thigh and shin, foot, drift, floor.
    let mut tally = [0usize; 4];
    // Pairs whose feet have toes on both rigs (a foot direction to judge).
    let mut feet_judged = 0;
    // Pairs whose every foot joint drifts within the bound (not judged: see above).
    let mut joints_within = 0;
    // Pairs whose raw foot direction is within the foot's bound (printed, not judged).
    let mut raw_within = 0;
    // Pairs within every bound at once.
    let mut all_within = 0;
    // Over the pairs whose thigh or shin misses its bound, per segment and phase: frames
    // measured, frames past the p95 bound, summed error.
    let mut by_phase: PhaseSums = Default::default();
    for src in &gaits {
        for (tgt, judge_t) in humans
            .iter()
            .zip(&judged)
            .filter(|(t, _)| t.path != src.path)
        {
            if !pair_wanted(&format!("{} → {}", src.name(), tgt.name())) {
                continue;
            }
            let plan = plan_mapping(&src.clip, &tgt.clip, None).unwrap();
            if !mapping_right(src, tgt, &plan.table, &LEG_SEGMENTS).is_empty() {
                continue;
            }
            let opts = plan.retarget_options(&src.clip, RootMotion::Scaled);
            let target = Arc::new((*tgt.clip.skeleton).clone());
            let out = if std::env::var_os("RIGCAST_QUALITY_LIVE").is_some() {
                retarget_causal(&src.clip, &target, &plan, &opts)
            } else {
                retarget_clip_locked(
                    &src.clip,
                    &target,
                    &plan.table,
                    &opts,
                    Some(&plan),
                    &mut |_| {},
                )
                .unwrap()
            };
            if !*judge_t {
                println!(
                    "{} → {}: the target's labelled legs are not its legs, not judged",
                    src.name(),
                    tgt.name()
                );
                continue;
            }
            let held = lock_plants(&src.clip, &plan);
            let Some(mut f) = measure_legs(src, tgt, &src.clip, &out, &held) else {
                println!(
                    "{} → {}: legs not labelled on both, not measured",
                    src.name(),
                    tgt.name()
                );
                continue;
            };
            let judge_s = humans
                .iter()
                .zip(&judged)
                .any(|(h, j)| *j && h.path == src.path);
            if !(judge_s && *judge_t) {
                f.floor_p95 = None;
            }
            checked += 1;
            let pair = |(m, p): (f32, f32)| {
                if m.is_nan() {
                    "-".to_string()
                } else {
                    format!("{m:.1}/{p:.1}")
                }
            };
            println!(
                "{:<36} {:<36} {:>11} {:>11} {:>11} {:>11} {:>7.3} {:>7.3} {:>6} {:>7.3} {:>11} {:>11}",
                src.name(),
                tgt.name(),
                pair(f.thigh),
                pair(f.shin),
                pair(f.foot_own),
                pair(f.foot),
                f.drift,
                f.source_drift,
                f.floor_p95.map_or("-".into(), |c| format!("{c:.2}")),
                f.joints_drift,
                pair(f.foot_standing),
                pair(f.foot_free)
            );
            let name = format!("{} → {}", src.name(), tgt.name());
            let within = |(m, p): (f32, f32), bm: f32, bp: f32| m <= bm && p <= bp;
            if !(within(f.thigh, 3.0, 8.0) && within(f.shin, 3.0, 8.0)) {
                tally_phases(&mut by_phase, &f.phases);
                if std::env::var_os("RIGCAST_QUALITY_PHASES").is_some() {
                    print_phases(&f.phases);
                }
                failures.push(format!(
                    "{name}: thigh {} shin {}",
                    pair(f.thigh),
                    pair(f.shin)
                ));
            }
            // A rig without toes has no foot direction to judge.
            if !f.foot.0.is_nan() && !within(f.foot_own, 5.0, 15.0) {
                failures.push(format!("{name}: foot {}", pair(f.foot_own)));
            }
            tally[0] += usize::from(within(f.thigh, 3.0, 8.0) && within(f.shin, 3.0, 8.0));
            tally[1] += usize::from(!f.foot.0.is_nan() && within(f.foot_own, 5.0, 15.0));
            raw_within += usize::from(!f.foot.0.is_nan() && within(f.foot, 5.0, 15.0));
            feet_judged += usize::from(!f.foot.0.is_nan());
            tally[2] += usize::from(f.drift <= 0.05);
            joints_within += usize::from(f.joints_drift <= 0.05);
            tally[3] += usize::from(f.floor_p95.is_none_or(|c| c <= 1.0));
            // Every bound at once: the foot's only where both rigs have toes.
            all_within += usize::from(
                within(f.thigh, 3.0, 8.0)
                    && within(f.shin, 3.0, 8.0)
                    && (f.foot.0.is_nan() || within(f.foot_own, 5.0, 15.0))
                    && f.drift <= 0.05
                    && f.floor_p95.is_none_or(|c| c <= 1.0),
            );
            if !(f.drift <= 0.05) {
                failures.push(format!("{name}: drift {:.3} cm/frame", f.drift));
            }
            if f.floor_p95.is_some_and(|c| c > 1.0) {
                failures.push(format!(
                    "{name}: planted feet {:.2} cm off",
                    f.floor_p95.unwrap()
                ));
            }
        }
    }
    println!(
        "{checked} right walk/run pairs measured; within the bounds: thigh and shin {}, foot {} \
         of the {feet_judged} with toes (raw: {raw_within}), drift {} (every foot joint: \
         {joints_within}), floor {}; every bound at once {all_within}; {} failures",
        tally[0],
        tally[1],
        tally[2],
        tally[3],
        failures.len()
    );
    print_phase_sums(&by_phase);
    assert!(checked > 0, "no right pair with a walk or run source");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
