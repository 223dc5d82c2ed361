//! Issue 35, live: the legs of a character under the causal foot lock stay the performer's,
//! measured through the real server, on every source the offline judge (retarget_quality's
//! locked_legs) reads: each labelled human whose own motion walks or runs as that judge finds
//! one (both feet stand, three stances or more, the hips travel a leg length; today 8 clips,
//! 1.2-13.0 s), its first `SOURCE_SECS` (15 s: all of each today), onto each labelled human
//! character. One server per source replays it once through, not looping, onto every
//! character twice, with the foot lock on and off (the same source sample drives both in the
//! same tick: their frames carry the same capture time). A version 2 client rebuilds both by
//! its own forward kinematics of the wire skeleton and judges each source sample once (a tick
//! that got no new sample re-sends its frame); per pair:
//! - thigh, shin and foot (ankle to toes) directions of the locked character against the
//!   unlocked one (the source's directions as retargeted; the offline retarget keeps them
//!   within 2° mean of the source's), mean and 95th percentile; the foot on the character's
//!   own standing foot, as offline (retarget_quality's locked_legs): pitched back about its
//!   own side axis by how far its rest's standing foot is pitched past the source's (the
//!   unlocked foot's median pitch over the frames the lock shows it planted), the raw
//!   direction printed beside it;
//! - planted-foot drift: the horizontal move per frame of the joint the foot stands on (its
//!   labelled foot or toe joint, the lower on the frame before) while the lock's `footplants`
//!   messages show the foot planted (both frames), cm of a 1.75 m body, as the offline measure
//!   judges it (a foot rolling over its ball moves its ankle without sliding); the move of
//!   every foot joint printed beside it;
//! - feet on the floor: on those frames, the 95th percentile of how far the foot's lowest
//!   joint stands from its height in the character's own rest (authored standing on y = 0).
//!   A foot without labelled toes only where the performer's ankle stands within 1 cm (of a
//!   1.75 m body) of its floor, as the offline judge reads the joints both rigs have: at a
//!   toe-off the performer's heel rises, and so does such a foot's ankle (the lock raises it
//!   with the heel; pinned to the floor, the hips came down onto it and bent the other leg).
//!   The walk's frame of each sample is found from the capture times, the replay's frames
//!   being a frame time apart, from the first where the free character's hips rise and fall
//!   with the walk's.
//!
//! The thigh and shin errors are split by each leg's phase on the source, as offline: the
//! lock's own two-sided detection on the source clip, read at the source frame each sample
//! shows (standing alone, both standing, the 0.15 s before a plant, after one, swinging).
//! The foot is judged where both the source and the character have labelled toes, the floor
//! where ten planted foot-frames or more were seen, as offline judges only what both show.
//!
//! Issue 35's bounds: thigh and shin 3° mean / 8° p95, foot 5° / 15°, drift ≤ 0.05 cm/frame,
//! floor ≤ 1 cm. Not met yet: run with `--ignored` for the table (`cargo test -p
//! rigcast-tests --test footlock_live_legs -- --ignored --nocapture`; 1:16 wall time in debug
//! at load 7, 2:05 with the build). On 2eb5ae4, two runs (load 7-12), 40 pairs (8
//! sources × 5 characters), within: thigh and shin 22 and 22, foot 4 and 5 of the 12 with
//! toes, drift 28 and 23 (every foot joint: 19 and 16), floor 29 and 30, every bound at once
//! 12 and 10. The same 40 pairs offline (locked_legs): 30, 12, 40 (39), 38, 30; locked
//! causally in process (locked_legs with `RIGCAST_QUALITY_LIVE=1`, `apply_live` frame by
//! frame): 20, 4, 33 (29), 28, 13, failing thigh and shin on the same pairs: the gap is the
//! causal lock's, not the server's. Thigh and shin fail live only on 7 pairs in both runs
//! (the CMU 31-joint walk onto the Godot robot and UE-style; Meredith onto X Bot, Casual and
//! UE-style; LaFAN1 onto Casual and UE-style) and 2 more in one (CMU 31-joint onto
//! RobotExpressive, Xia onto UE-style at 8.01° shin p95). Their frames over 8° (thigh and
//! shin, both runs) by phase: single 2690, double 20, approach 1235, release 845, swing 653
//! (without LaFAN1 onto Casual, below: 1253, 0, 733, 524, 73): the standing leg bent while
//! the other swings, the largest phase on 12 of the 16 failing pair-runs (release on 3).
//! Two classes were far off live on every run: LaFAN1 onto the three toeless characters
//! (thigh: Casual 45/90°, RobotExpressive 30-31/90, the robot 23-24/50-51) and Xia onto both
//! robots (27-29/79-82). On these pairs the mapping does not know where the character's floor
//! is (`FloorAt::Unknown`) and the retargeted feet do not stand at the height it gives
//! (LaFAN1 onto Casual's about 1 m under it); the live lock pinned them there and the legs
//! folded to reach (LaFAN1 onto Casual: pins 78-101 cm over the animation's ankles). Since
//! the lock learns such a foot's standing heights from its stances, as offline, two runs at
//! load 16-19 (fewer frames per source than at load 7): LaFAN1 onto Casual 3.2/10.2 and
//! 2.5/7.6° thigh, RobotExpressive 17.8/42.9 and 17.6/40.9, Xia onto the robot 5.1/14.6 and
//! 4.4/15.7, RobotExpressive 4.9/15.6 and 5.1/16.6. The floor, judged against the
//! character's own rest ground, now shows where the retarget stands these characters:
//! LaFAN1 onto Casual 95 cm (5-8 pinned at the mapping's floor), RobotExpressive 42-44
//! (10), Xia onto Casual 7 (2), the robots 147-150 and 206-209 (138, 193). The cause was the
//! mapping: those characters' armature roots were driven by the source's zero-length head end
//! (and RobotExpressive's finger by LaFAN1's toe end). Since helpers match only helpers that
//! hang alike (b19a22d), one run at load 9-11: thigh and shin 24, foot 4 of 12, drift 28,
//! floor 32, every bound at once 13; those floors 0.45-0.81 cm, LaFAN1 onto RobotExpressive
//! 5.6/18.5° thigh (drift 0.022 cm/frame). With a foot's heading held to its side axis's
//! where it points straight down (85ddb1a) and the standing heights learnt where the posture
//! is a frame of motion (e2c2cf6; none of these five), one run at load 14-17: 26, 5 of 12,
//! drift 22 (the two shortest sources, 1.4-2.3 s, 0.25-0.56 cm/frame at that load; their
//! causal drift in process did not move), floor 33, every bound at once 10; Meredith onto X
//! Bot 4.9/15.5 -> 3.8/11.4° thigh.
//!
//! Before, the first walk alone (CMU 131_01), the figures below. With the toeless
//! feet rising with the heel, five runs at load 7-14 (before, two runs of the lock before
//! in the same build): the Godot robot thigh 6.4-7.0/24.2-26.1° (7.4-7.6/27.9-28.5), shin
//! 3.2-3.5/9.3-11.8 (3.6-3.7/11.9-12.7), floor 0.54-0.59 cm (0.35); RobotExpressive
//! 3.2-3.7/10.9-13.0 (4.2-4.3/13.7-14.4), 2.4-2.7/8.8-11.0 (2.8-3.0/11.6-12.0), 0.55-0.56
//! (0.33-0.35); Quaternius Casual 2.4-2.7/6.8-7.9 (3.0-3.1/9.2-9.6), 2.1-2.4/6.8-7.7
//! (2.6-2.7/9.1-9.5), 0.50-0.54 (0.21-0.24): Casual meets every bound; drift 0.003-0.011 on
//! all three; the characters with toes as before (X Bot 2.4-2.6/5.6-6.9, UE-style mannequin
//! 2.9-3.1/7.3-8.2). Judged on every planted frame (before the toeless foot was judged where
//! the performer's ankle stands), the toeless floors read 3.3 cm with the feet rising and
//! 0.79-1.43 before (below). Earlier, three runs at load
//! 15-18 (387, 474 and 497 frames sampled): the foot on each character's own standing foot
//! X Bot 11.7-13.4/29.4-32.9° (raw 21.9-22.5/33.7-34.8), the UE-style mannequin
//! 10.4-11.2/21.7-23.9 (raw 26.6-27.2/38.1-39.3); thigh, shin X Bot 2.1-2.6/6.4-7.1,
//! 2.0-2.1/6.3-6.9; mannequin 2.6-3.2/7.7-7.8, 2.3-2.4/7.0-7.9; Casual 2.7-2.9/7.9-9.0,
//! 2.4-2.7/8.4-11.0; robot 6.6-6.7/24.3-25.9, 3.3-3.8/10.6-13.3; floor p95 0.44-0.52,
//! 0.47-0.67, 0.71-1.05, 1.25-2.07 cm. Before, two
//! runs at load 14-17 with the free foot brought down ahead of a plant the source's heel
//! foretells (the debug server sampled 453-466 of the walk's 497 ticks), against one of the
//! lock before in between: X Bot thigh 2.6-2.7/7.1-7.7° (2.5/7.0), shin 2.1/6.3-6.7 (2.1/7.0),
//! foot (raw) 22.4-22.5/34.8-35.8 (22.5/34.9), drift 0.018-0.029 cm/frame (0.021), floor 0.49-0.66
//! cm (0.64); UE-style mannequin 3.1/7.1-8.0 (3.0/7.7), 2.3/6.6-7.3 (2.3/7.8), 27.2/39.0-40.3
//! (27.2/39.1), 0.024-0.034 (0.026), 0.50-0.64 (0.54); Quaternius Casual (no toes) 2.9-3.0/
//! 8.3-8.5 (2.8/8.5), 2.4-2.5/8.1-8.2 (2.3/8.0), 0.014-0.022 (0.010), 0.82-0.91 (0.88); the
//! robot (no toes) 6.5-6.8/23.4-24.1 (6.5/25.6), 3.2-3.5/9.8-10.4 (3.3/10.4), 0.018-0.027
//! (0.012), 1.07-1.36 (1.48; two runs at load 8-10 on 4eca62c: 1.48-1.53). Its left foot
//! hangs 20-30 cm above the floor in the retargeted walk while the source's stands: a plant
//! pins it and blends it down, and the floor's 95th percentile falls on those frames, so it
//! swings with which samples the server takes. RobotExpressive (an IK-style rig: its feet hang
//! from its root, carried at its shins' ends, their translations on the wire), two runs at load
//! 13-18 and 6-9 (the second after 5d607be's blends): 5.2/16.3 and 4.5/14.3, 3.3/12.3 and
//! 3.1/12.1, 0.008 both, floor 0.96 and 1.18 (the Godot robot's 1.30 and 1.39 alike).
//! Until then six seconds were watched of the looping walk, wherever the stream began: the
//! same lock, run without the server from where each of six starts 1.25 s apart put it, read
//! the floor at robot 0.96-3.54, Casual 0.57-1.89, X Bot 0.30-0.72 cm; over the whole walk
//! from the same starts (a sample now and then taken late) 1.84-2.32, 0.89-1.31, 0.40-0.64.
//! The live lock pitches planted feet flat as it learns the stance, two planted feet share
//! their disagreement through the legs, a plant's first frames blend onto the pin.
//! Skips when the shared data is absent.
#![allow(clippy::unwrap_used)]

use std::collections::HashMap;
use std::time::{Duration, Instant};

use glam::{Quat, Vec3};
use rigcast_protocol::control::BoneInfo;
use rigcast_protocol::frame::DecodedFrame;
use rigcast_protocol::ServerMessage;
use rigcast_server::{PerformerSpec, ServerConfig};
use rigcast_tests::*;

#[path = "../../server/tests/common/leg_phases.rs"]
mod leg_phases;
use leg_phases::{
    phase, print_phase_sums, print_phases, tally_phases, PhaseSums, PHASES, PHASE_NEAR_SECS,
};

/// The server's tick rate.
const RATE_HZ: f64 = 60.0;

/// How much of each source is replayed: its first seconds (every source of today's data is
/// shorter: the longest, LaFAN1's, lasts 13.0 s), so the whole run's wall time is bounded
/// (each source is watched this long and `WATCH_MARGIN` more at most).
const SOURCE_SECS: f64 = 15.0;

/// How much longer than the source it is watched (the first frames arrive after the client
/// connects).
const WATCH_MARGIN: Duration = Duration::from_secs(2);

/// Half the standing height of the 1.75 m body drift and floor are normalised to.
const LEG_OF_175_CM_BODY: f32 = 0.875;

/// One subject as the client saw it.
#[derive(Default)]
struct Seen {
    bones: Vec<BoneInfo>,
    frames: Vec<DecodedFrame>,
    /// (frame seq, per foot bone: planted) from the `footplants` messages.
    plants: Vec<(u64, Vec<(String, bool)>)>,
}

/// Every labelled human (any format, both legs labelled) whose own motion walks or runs as
/// the offline judge reads it ([`walks_or_runs`]), its first [`SOURCE_SECS`]; empty with a
/// printed reason when none.
fn sources() -> Vec<(Labelled, rigcast_retarget::Clip)> {
    let humans = labelled_where("human with legs", |l| l.kind() == "human" && l.has_legs());
    let mut out = Vec::new();
    for l in humans {
        let Ok(mut clip) = rigcast_sources::load_clip(&l.path) else {
            continue;
        };
        if !walks_or_runs(&l, &clip) {
            continue;
        }
        let frames = (SOURCE_SECS / clip.frame_time_secs).floor() as usize;
        clip.poses.truncate(frames.max(2));
        println!(
            "a source: {}, its first {:.1} s",
            l.rel,
            clip.duration_secs()
        );
        out.push((l, clip));
    }
    if out.is_empty() {
        println!("SKIP: no labelled human walks or runs");
    }
    out
}

/// A foot stands still below this speed (m/s of a 1.75 m body) over at least
/// [`STILL_WINDOW_SECS`], within [`NEAR_FLOOR`] (m of a 1.75 m body) of its floor: the offline
/// judge's standing frames.
const STILL_SPEED: f32 = 0.15;
const STILL_WINDOW_SECS: f64 = 1.0 / 30.0;
const NEAR_FLOOR: f32 = 0.01;

/// A walk or a run, as the offline judge (retarget_quality's `is_gait`) finds one: both feet
/// stand (still, near their floor) at least once, three stances or more in all, and the hips
/// travel at least one leg length over the ground.
fn walks_or_runs(l: &Labelled, clip: &rigcast_retarget::Clip) -> bool {
    let s = &clip.skeleton;
    let bone = |role: String| l.bone(&role).and_then(|n| s.bone(n));
    let Some(hips) = bone("hips".into()) else {
        return false;
    };
    if clip.num_frames() < 2 {
        return false;
    }
    let rest: Vec<Vec3> = (rigcast_retarget::world_transforms(s, &s.rest_pose()).iter())
        .map(|w| w.translation)
        .collect();
    let mut leg = 0.0;
    let mut sides = Vec::new();
    for side in ["L", "R"] {
        let [u, k, f] = ["upperLeg", "lowerLeg", "foot"].map(|r| bone(format!("{r}.{side}")));
        let (Some(u), Some(k), Some(f)) = (u, k, f) else {
            return false;
        };
        leg += 0.5
            * ((rest[k.index()] - rest[u.index()]).length()
                + (rest[f.index()] - rest[k.index()]).length());
        sides.push([Some(f), bone(format!("toes.{side}"))]);
    }
    let worlds: Vec<Vec<Vec3>> = (clip.poses.iter())
        .map(|p| {
            (rigcast_retarget::world_transforms(s, p).iter())
                .map(|w| w.translation)
                .collect()
        })
        .collect();
    // Up: the coordinate axis nearest hips over the ankles, summed over the frames.
    let up_sum: Vec3 = (worlds.iter())
        .map(|w| {
            w[hips.index()] - sides.iter().map(|j| w[j[0].unwrap().index()]).sum::<Vec3>() / 2.0
        })
        .sum();
    let axis = up_sum.abs().max_position();
    let up = Vec3::AXES[axis] * up_sum[axis].signum();
    let unit = LEG_OF_175_CM_BODY / leg;
    let lag = ((STILL_WINDOW_SECS / clip.frame_time_secs).ceil() as usize).max(1);
    let secs = (lag as f64 * clip.frame_time_secs) as f32;
    let flat = |v: Vec3| v - up * v.dot(up);
    let n = worlds.len();
    let stances: Vec<usize> = (sides.iter())
        .map(|joints| {
            let joints: Vec<usize> = joints.iter().flatten().map(|b| b.index()).collect();
            let track: Vec<(f32, bool)> = (0..n)
                .map(|i| {
                    let low =
                        (joints.iter().map(|&j| worlds[i][j].dot(up))).fold(f32::MAX, f32::min);
                    let (a, b) = (i.saturating_sub(lag / 2), (i + lag - lag / 2).min(n - 1));
                    let still = b > a
                        && joints.iter().all(|&j| {
                            let d = flat(worlds[b][j] - worlds[a][j]).length();
                            d / (secs * (b - a) as f32 / lag as f32) < STILL_SPEED / unit
                        });
                    (low, still)
                })
                .collect();
            // Its floor: the 5th percentile of its lowest points while still.
            let mut h: Vec<f32> = (track.iter()).filter(|t| t.1).map(|t| t.0).collect();
            h.sort_by(f32::total_cmp);
            let floor = h.get(h.len() / 20).copied();
            let stands: Vec<bool> = (track.iter())
                .map(|(h, still)| *still && floor.is_some_and(|f| h - f < NEAR_FLOOR / unit))
                .collect();
            stands.windows(2).filter(|w| w[1] && !w[0]).count()
                + usize::from(stands.first() == Some(&true))
        })
        .collect();
    let travel = (worlds.iter())
        .map(|w| flat(w[hips.index()] - worlds[0][hips.index()]).length())
        .fold(0.0, f32::max);
    stances.iter().all(|n| *n >= 1) && stances.iter().sum::<usize>() >= 3 && travel >= leg
}

/// Streams `clip` (labelled `labels`) once through (watched `WATCH_MARGIN` longer) onto every
/// rig of `targets`, locked and free, through one server; per target (locked, free), how long
/// the source takes (ns) and the source as the judge reads it.
async fn stream(
    labels: &Labelled,
    clip: rigcast_retarget::Clip,
    targets: &[Labelled],
) -> Option<(Vec<(Seen, Seen)>, u64, Walk)> {
    let source = Walk::new(labels, &clip)?;
    let pass_nanos = (clip.duration_secs() * 1e9) as u64;
    let watch = Duration::from_secs_f64(clip.duration_secs()) + WATCH_MARGIN;
    let mut performers = Vec::new();
    for rig in targets {
        let path = rig.path.clone();
        for lock in [true, false] {
            performers.push(PerformerSpec {
                name: Some(format!("{}-{lock}", performers.len())),
                foot_lock: Some(lock),
                ..PerformerSpec::target_file(path.clone())
            });
        }
    }
    let config = ServerConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        rate_hz: RATE_HZ,
        // Once through, not looping: the jump back to the start would read as every planted
        // foot's drift.
        sources: vec![rigcast_server::SourceSpec::ReplayClip(
            rigcast_server::config::ReplayClipSpec {
                clip,
                name: None,
                settings: rigcast_server::ReplaySettings {
                    looping: false,
                    ..rigcast_server::ReplaySettings::default()
                },
            },
        )],
        performers,
        ..ServerConfig::default()
    };
    let server = rigcast_server::start(config).await.unwrap();
    let mut ws = connect(&format!("ws://{}/v1/stream", server.local_addr())).await;
    send_text(&mut ws, r#"{"type":"set_protocol","version":2}"#).await;
    let mut seen: HashMap<u32, Seen> = HashMap::new();
    let mut ids: HashMap<String, u32> = HashMap::new();
    let t0 = Instant::now();
    while let Some(left) = watch.checked_sub(t0.elapsed()) {
        match next(&mut ws, left).await {
            Some(Incoming::Json(ServerMessage::Skeleton {
                subject,
                name,
                bones,
                ..
            })) => {
                ids.insert(name, subject);
                seen.entry(subject).or_default().bones = bones;
            }
            Some(Incoming::Json(ServerMessage::Footplants { subject, seq, feet })) => {
                let states = feet.into_iter().map(|f| (f.bone, f.planted)).collect();
                seen.entry(subject).or_default().plants.push((seq, states));
            }
            Some(Incoming::Frame(f, _)) if f.version == 2 => {
                seen.entry(f.header.subject).or_default().frames.push(f);
            }
            Some(_) => {}
            None => break,
        }
    }
    server.shutdown().await;
    let mut out = Vec::new();
    for k in 0..targets.len() {
        let mut take = |name: String| {
            let id = ids
                .get(&name)
                .unwrap_or_else(|| panic!("no skeleton for {name}"));
            seen.remove(id).unwrap_or_default()
        };
        let locked = take(format!("{}-true", 2 * k));
        let free = take(format!("{}-false", 2 * k + 1));
        out.push((locked, free));
    }
    Some((out, pass_nanos, source))
}

/// The replayed walk, as the judge reads it: per frame, each side's ankle's height above its
/// floor, and the hips' height.
struct Walk {
    frame_secs: f64,
    hips: Vec<f32>,
    /// Per side (L, R), per frame: the ankle above its floor.
    feet: [Vec<f32>; 2],
    /// 1 cm of a 1.75 m body, in the walk's units.
    near: f32,
    /// Per side (L, R), per frame: the lock's own two-sided detection holds the foot planted
    /// (what the phase split reads, as offline).
    held: [Vec<bool>; 2],
    /// [`PHASE_NEAR_SECS`] in the walk's frames.
    near_frames: usize,
}

impl Walk {
    fn new(labels: &Labelled, clip: &rigcast_retarget::Clip) -> Option<Walk> {
        let s = &clip.skeleton;
        let bone = |role: String| labels.bone(&role).and_then(|n| s.bone(n));
        let worlds: Vec<Vec<Vec3>> = (clip.poses.iter())
            .map(|p| {
                rigcast_retarget::world_transforms(s, p)
                    .iter()
                    .map(|w| w.translation)
                    .collect()
            })
            .collect();
        let rest: Vec<Vec3> = (rigcast_retarget::world_transforms(s, &s.rest_pose()).iter())
            .map(|w| w.translation)
            .collect();
        let hips = bone("hips".into())?;
        let mut feet: [Vec<f32>; 2] = Default::default();
        let mut leg = 0.0;
        for (k, side) in ["L", "R"].iter().enumerate() {
            let [u, l, f] = ["upperLeg", "lowerLeg", "foot"].map(|r| bone(format!("{r}.{side}")));
            let (u, l, f) = (u?, l?, f?);
            leg += 0.5
                * ((rest[l.index()] - rest[u.index()]).length()
                    + (rest[f.index()] - rest[l.index()]).length());
            // The ankle's floor: the 5th percentile of its heights (most frames of a walk have
            // the foot down; a dip through the floor does not move it).
            let mut heights: Vec<f32> = worlds.iter().map(|w| w[f.index()].y).collect();
            heights.sort_by(f32::total_cmp);
            let floor = heights[heights.len() / 20];
            feet[k] = worlds.iter().map(|w| w[f.index()].y - floor).collect();
        }
        Some(Walk {
            frame_secs: clip.frame_time_secs,
            hips: worlds.iter().map(|w| w[hips.index()].y).collect(),
            feet,
            near: 0.01 * leg / LEG_OF_175_CM_BODY,
            held: held_plants(clip),
            near_frames: (PHASE_NEAR_SECS / clip.frame_time_secs.max(1e-6)).round() as usize,
        })
    }

    /// The phase of side `side` on the walk's `frame` (as retarget_quality's `phase`): its
    /// foot standing alone (0) or with the other (1), or free: within [`PHASE_NEAR_SECS`]
    /// before a stance (2), after one (3), or swinging (4).
    fn phase(&self, side: usize, frame: usize) -> usize {
        phase(&self.held, side, frame, self.near_frames)
    }

    /// The walk's frame each capture time of `free`'s frames shows: the replay samples frame k
    /// k frame times after it starts, so the frames follow the capture times from an unknown
    /// first frame, found where the free character's hips rise and fall with the walk's
    /// (the retarget scales the hips' height: the two correlate best there).
    fn frames_of(&self, free: &Seen, hips: usize) -> HashMap<u64, usize> {
        let mut seen: Vec<(u64, f32)> = (free.frames.iter())
            .filter(|f| f.header.capture_nanos != 0)
            .map(|f| (f.header.capture_nanos, wire_fk(&free.bones, f)[hips].y))
            .collect();
        seen.sort_by_key(|s| s.0);
        let Some(&(first, _)) = seen.first() else {
            return HashMap::new();
        };
        let step = |c: u64| ((c - first) as f64 * 1e-9 / self.frame_secs).round() as usize;
        let n = self.hips.len();
        let correlation = |k0: usize| {
            let pairs: Vec<(f32, f32)> = (seen.iter())
                .filter_map(|&(c, y)| Some((*self.hips.get(k0 + step(c))?, y)))
                .collect();
            if pairs.len() * 5 < seen.len() * 4 {
                return f32::NEG_INFINITY;
            }
            let m = pairs.len() as f32;
            let (ma, mb) = pairs
                .iter()
                .fold((0.0, 0.0), |(a, b), p| (a + p.0 / m, b + p.1 / m));
            let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
            for (a, b) in &pairs {
                (ab, aa, bb) = (
                    ab + (a - ma) * (b - mb),
                    aa + (a - ma).powi(2),
                    bb + (b - mb).powi(2),
                );
            }
            ab / (aa * bb).sqrt().max(1e-12)
        };
        let k0 = (0..n)
            .max_by(|&a, &b| correlation(a).total_cmp(&correlation(b)))
            .unwrap_or(0);
        (seen.iter())
            .filter(|&&(c, _)| k0 + step(c) < n)
            .map(|&(c, _)| (c, k0 + step(c)))
            .collect()
    }

    /// Whether side `side`'s ankle stands on its floor on `frame` (within `near`).
    fn down(&self, side: usize, frame: usize) -> bool {
        self.feet[side][frame] < self.near
    }
}

/// Per side (L, R), the frames the lock's own two-sided detection holds the source's foot
/// planted (on its labelled-side first hind leg), as the offline judge's `lock_plants`.
fn held_plants(clip: &rigcast_retarget::Clip) -> [Vec<bool>; 2] {
    use rigcast_retarget::analysis::{analyze, Side, SkeletonView};
    use rigcast_retarget::footplant::{detect_clip, find_contact_legs, LegKind, PlantSettings};
    let analysis = analyze(&SkeletonView::from_clip(&clip.skeleton, &clip.poses));
    let legs = find_contact_legs(&clip.skeleton, &analysis);
    let dt = clip.frame_time_secs as f32;
    let settings = PlantSettings::default();
    let plants = detect_clip(
        &clip.skeleton,
        &legs,
        &clip.poses,
        dt,
        analysis.up,
        &settings,
    );
    [Side::Left, Side::Right].map(|side| {
        let leg = (plants.legs.iter())
            .position(|l| l.side == side && l.kind == LegKind::Hind && l.limb == 0);
        (0..clip.num_frames())
            .map(|f| leg.is_some_and(|l| plants.is_planted(f, l)))
            .collect()
    })
}

/// Figures of one character, as `locked_legs_follow_the_source_on_walks_and_runs` offline.
#[derive(Debug)]
struct Legs {
    frames: usize,
    thigh: (f32, f32),
    shin: (f32, f32),
    /// The foot on each rig's own standing foot, and raw (ankle to toes).
    foot: (f32, f32),
    raw_foot: (f32, f32),
    drift: f32,
    /// The same over every foot joint (an ankle rolling over its ball included).
    joints_drift: f32,
    planted_frames: usize,
    floor_p95: f32,
    /// Thigh and shin errors split by the leg's phase on the source ([`Walk::phase`]); frames
    /// whose source frame is not found are left out.
    phases: [[Vec<f32>; PHASES]; 2],
}

/// World rotations down the wire skeleton's parent chain from each bone's local rotation.
fn world_rotations(bones: &[BoneInfo], local: impl Fn(usize) -> Quat) -> Vec<Quat> {
    let mut world: Vec<Quat> = Vec::with_capacity(bones.len());
    for (i, b) in bones.iter().enumerate() {
        let r = local(i);
        world.push(b.parent.map_or(r, |p| world[p as usize] * r));
    }
    world
}

/// A foot's pitch (radians, toes above the ankle positive) from its ankle-to-toes direction.
fn pitch_of(d: Vec3) -> f32 {
    (d.y / d.length().max(1e-9)).clamp(-1.0, 1.0).asin()
}

fn mean_p95(mut v: Vec<f32>) -> (f32, f32) {
    if v.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    v.sort_by(f32::total_cmp);
    let mean = v.iter().sum::<f32>() / v.len() as f32;
    (mean, v[(v.len() * 95 / 100).min(v.len() - 1)])
}

/// `pass_nanos`: the walk's length. The frames judged are those of source samples within it of
/// the first the client saw, each sample once: all of the walk but its first moments, whatever
/// the server's timing (six seconds of the looping 8.3 s walk read the robot's floor at
/// 0.84-4.25 cm by where they began, the same lock; the jump back to the start read as drift).
fn measure(rig: &Labelled, locked: &Seen, free: &Seen, pass_nanos: u64, walk: &Walk) -> Legs {
    let bones = &locked.bones;
    let index = |role: String| {
        let names = rig.labels[&role].as_array()?;
        (names.iter()).find_map(|n| {
            bones
                .iter()
                .position(|b| Some(b.name.as_str()) == n.as_str())
        })
    };
    // Per side: thigh, shin and foot joints, and the toes where labelled.
    let legs: Vec<([usize; 3], Option<usize>)> = ["L", "R"]
        .iter()
        .map(|s| {
            let joints = ["upperLeg", "lowerLeg", "foot"].map(|r| {
                index(format!("{r}.{s}")).unwrap_or_else(|| {
                    panic!("{}: {r}.{s} not labelled in the wire skeleton", rig.rel)
                })
            });
            (joints, index(format!("toes.{s}")))
        })
        .collect();
    let rest = wire_rest_positions(bones);
    let leg_length = legs
        .iter()
        .map(|(l, _)| (rest[l[1]] - rest[l[0]]).length() + (rest[l[2]] - rest[l[1]]).length())
        .sum::<f32>()
        / legs.len() as f32;
    let body = LEG_OF_175_CM_BODY / leg_length;
    let hips = index("hips".into()).unwrap_or_else(|| panic!("{}: hips not labelled", rig.rel));
    let walk_frame = walk.frames_of(free, hips);
    // The free character's frames by capture time: the same source sample.
    let free_at: HashMap<u64, &DecodedFrame> = (free.frames.iter())
        .filter(|f| f.header.capture_nanos != 0)
        .map(|f| (f.header.capture_nanos, f))
        .collect();
    // Each locked frame's planted flags per leg, from the messages (a state holds until the
    // next message).
    let planted_at = |seq: u64, foot: usize| -> bool {
        let name = &bones[foot].name;
        (locked.plants.iter().rev())
            .find(|(s, _)| *s <= seq)
            .and_then(|(_, feet)| feet.iter().find(|(b, _)| b == name))
            .is_some_and(|(_, p)| *p)
    };
    // Each side's standing foot in the character's own rest, as the offline measure reads it
    // (retarget_quality's `rest_standing_pitch`): its pitch where the rest stands on the
    // ground (its lowest foot joint within a quarter of a leg of y = 0, the toe joint no
    // higher than the ankle), and its left-to-right axis fixed in the foot bone's frame (what
    // it pitches about, carried by the bone however it turns).
    let rest_rot = world_rotations(bones, |i| Quat::from_array(bones[i].rest_rotation));
    let own: Vec<Option<(Option<f32>, Vec3)>> = (legs.iter())
        .map(|(l, toes)| {
            let (ankle, toes) = (rest[l[2]], rest[(*toes)?]);
            let d0 = toes - ankle;
            let flat = Vec3::new(d0.x, 0.0, d0.z).try_normalize()?;
            let p = pitch_of(d0);
            let stands = p <= 0.0 && ankle.y.min(toes.y).abs() <= 0.25 * leg_length;
            Some((
                stands.then_some(p),
                rest_rot[l[2]].inverse() * flat.cross(Vec3::Y),
            ))
        })
        .collect();
    // The source's standing foot: the free character's pitch (the source's direction as
    // retargeted) over the frames the source's foot is planted, median.
    let standing: Vec<Option<f32>> = (legs.iter())
        .map(|(l, toes)| {
            let toes = (*toes)?;
            let mut v: Vec<f32> = (locked.frames.iter())
                .filter(|f| planted_at(f.header.seq, l[2]))
                .filter_map(|f| free_at.get(&f.header.capture_nanos))
                .map(|g| {
                    let v = wire_fk(&free.bones, g);
                    pitch_of(v[toes] - v[l[2]])
                })
                .collect();
            v.sort_by(f32::total_cmp);
            v.get(v.len() / 2).copied()
        })
        .collect();
    let mut own_errors = Vec::new();
    let mut errors: [Vec<f32>; 3] = Default::default();
    let mut phases: [[Vec<f32>; PHASES]; 2] = Default::default();
    let (mut drift_sum, mut drift_n) = (0.0f32, 0usize);
    let (mut all_sum, mut all_n) = (0.0f32, 0usize);
    let mut off_floor = Vec::new();
    let mut frames = 0;
    let mut last: Option<(u64, Vec<Vec3>)> = None;
    let first = locked.frames.first().map_or(0, |f| f.header.capture_nanos);
    let mut shown = None;
    let one_pass = (locked.frames.iter())
        .take_while(|f| f.header.capture_nanos.saturating_sub(first) < pass_nanos)
        // A tick without a new source sample re-sends the last one's frame: each sample once.
        .filter(|f| shown.replace(f.header.seq) != Some(f.header.seq));
    for f in one_pass {
        let w = wire_fk(bones, f);
        if let Some(g) = free_at.get(&f.header.capture_nanos) {
            frames += 1;
            let v = wire_fk(&free.bones, g);
            let rot = world_rotations(bones, |i| f.rotations[i]);
            let src = walk_frame.get(&f.header.capture_nanos).copied();
            for (side, ((l, toes), (own, standing))) in
                legs.iter().zip(own.iter().zip(&standing)).enumerate()
            {
                let chain = [Some(l[0]), Some(l[1]), Some(l[2]), *toes];
                for k in 0..3 {
                    let (Some(a0), Some(a1)) = (chain[k], chain[k + 1]) else {
                        continue;
                    };
                    let (a, b) = (w[a1] - w[a0], v[a1] - v[a0]);
                    if a.length() > 1e-6 && b.length() > 1e-6 {
                        let e = a.angle_between(b).to_degrees();
                        errors[k].push(e);
                        if let (0 | 1, Some(frame)) = (k, src) {
                            phases[k][walk.phase(side, frame)].push(e);
                        }
                        // On the character's own standing foot: pitched back about its own
                        // side axis by how much its standing foot is pitched past the source's.
                        if let (2, Some((pt, axis)), Some(ps)) = (k, own, standing) {
                            let pitch = pt.unwrap_or(*ps) - ps;
                            let back = Quat::from_axis_angle(rot[l[2]] * *axis, -pitch);
                            own_errors.push((back * a).angle_between(b).to_degrees());
                        }
                    }
                }
            }
        }
        for (side, (l, toes)) in legs.iter().enumerate() {
            if !planted_at(f.header.seq, l[2]) {
                continue;
            }
            let joints: Vec<usize> = [Some(l[2]), *toes].into_iter().flatten().collect();
            let lowest = (joints.iter().map(|&j| w[j].y - rest[j].y)).fold(f32::INFINITY, f32::min);
            // A foot without toes stands on toes its skeleton does not show: at a toe-off the
            // performer's heel rises, and so does its ankle. It is judged where the
            // performer's ankle stands on the floor, as the offline judge reads the joints
            // both rigs have; a foot with toes stands on them, judged on every planted frame.
            let src = walk_frame.get(&f.header.capture_nanos);
            if toes.is_some() || src.is_some_and(|&k| walk.down(side, k)) {
                off_floor.push(lowest.abs() * 100.0 * body);
            }
            if let Some((seq, before)) = &last {
                if *seq + 1 == f.header.seq && planted_at(*seq, l[2]) {
                    let moved = |j: usize| {
                        let d = w[j] - before[j];
                        Vec3::new(d.x, 0.0, d.z).length() * 100.0 * body
                    };
                    // The joint the foot stands on: the lowest on the frame before.
                    let contact = (joints.iter().copied())
                        .min_by(|&a, &b| before[a].y.total_cmp(&before[b].y))
                        .unwrap_or(l[2]);
                    drift_sum += moved(contact);
                    drift_n += 1;
                    for &j in &joints {
                        all_sum += moved(j);
                        all_n += 1;
                    }
                }
            }
        }
        last = Some((f.header.seq, w));
    }
    let [thigh, shin, raw_foot] = errors.map(mean_p95);
    let foot = mean_p95(own_errors);
    let planted_frames = off_floor.len();
    off_floor.sort_by(f32::total_cmp);
    Legs {
        frames,
        thigh,
        shin,
        foot,
        raw_foot,
        drift: drift_sum / drift_n.max(1) as f32,
        joints_drift: all_sum / all_n.max(1) as f32,
        planted_frames,
        floor_p95: off_floor
            .get(planted_frames * 95 / 100)
            .copied()
            .unwrap_or(f32::NAN),
        phases,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "issue 35's bounds are not met live yet; the test prints the table per pair"]
async fn live_locked_legs_follow_the_source_on_walks_and_runs() {
    let targets = human_rigs();
    let sources = sources();
    if targets.is_empty() || sources.is_empty() {
        return;
    }
    println!("each source's first {SOURCE_SECS} s at most, through one server per source");
    let mut failures = Vec::new();
    println!(
        "{:<36} {:<36} {:>6} {:>11} {:>11} {:>11} {:>11} {:>7} {:>7} {:>7}",
        "source (live)",
        "target",
        "frames",
        "thigh°",
        "shin°",
        "foot°",
        "(raw°)",
        "drift",
        "floor",
        "(drift)"
    );
    let name = |rel: &str| {
        let file = rel.rsplit('/').next().unwrap_or(rel);
        file.rsplit_once('.')
            .map_or(file, |(stem, _)| stem)
            .to_string()
    };
    // Pairs judged, and within the bounds: thigh and shin, foot (of those with toes), drift,
    // floor, every bound at once.
    let (mut judged, mut with_toes, mut joints_within) = (0, 0, 0);
    let mut tally = [0usize; 5];
    // Over the pairs whose thigh or shin misses: per segment and phase, frames, over 8°, sum.
    let mut by_phase: PhaseSums = Default::default();
    for (labels, clip) in sources {
        // The source samples the server can show: one a tick, or each of the source's frames
        // where it has fewer (a 30 Hz capture at 60 Hz).
        let samples = (clip.duration_secs() * RATE_HZ).min(clip.num_frames() as f64);
        let src = name(&labels.rel);
        let source_toes = ["toes.L", "toes.R"].iter().all(|r| labels.has_role(r));
        let Some((streams, pass_nanos, walk)) = stream(&labels, clip, &targets).await else {
            println!("{src}: its legs are not found in its skeleton, not streamed");
            continue;
        };
        for (rig, (locked, free)) in targets.iter().zip(&streams) {
            let tgt = name(&rig.rel);
            // A character whose feet the lock holds none of (no leg to bend) is not this
            // one's case.
            if locked.plants.iter().all(|(_, feet)| feet.is_empty()) {
                println!("{src} → {tgt}: the lock holds none of its feet, not judged");
                continue;
            }
            let f = measure(rig, locked, free, pass_nanos, &walk);
            let pair = |(m, p): (f32, f32)| format!("{m:.1}/{p:.1}");
            println!(
                "{src:<36} {tgt:<36} {:>6} {:>11} {:>11} {:>11} {:>11} {:>7.3} {:>7.2} {:>7.3}  ({} planted foot-frames)",
                f.frames,
                pair(f.thigh),
                pair(f.shin),
                pair(f.foot),
                pair(f.raw_foot),
                f.drift,
                f.floor_p95,
                f.joints_drift,
                f.planted_frames
            );
            // Enough to judge: half the source's samples paired (a loaded debug server shows
            // 80-100 % of them). (Every pair is judged before the test fails.)
            if (f.frames as f64) < 0.5 * samples {
                failures.push(format!(
                    "{src} → {tgt}: too little to judge: {} frames",
                    f.frames
                ));
                continue;
            }
            judged += 1;
            let within = |(m, p): (f32, f32), bm: f32, bp: f32| m <= bm && p <= bp;
            let legs = within(f.thigh, 3.0, 8.0) && within(f.shin, 3.0, 8.0);
            // The foot's direction is judged where both have labelled toes, as offline (a
            // source without them gives its foot no direction to follow).
            let toes = !f.foot.0.is_nan() && source_toes;
            let foot = !toes || within(f.foot, 5.0, 15.0);
            // The floor where planted feet were seen standing on ten frames or more (a run's
            // toeless feet, judged where the performer's ankle is down, may show fewer).
            let floor = f.planted_frames < 10 || f.floor_p95 <= 1.0;
            let drift = f.drift <= 0.05;
            if !legs {
                failures.push(format!(
                    "{src} → {tgt}: thigh {:?} shin {:?}",
                    f.thigh, f.shin
                ));
                print_phases(&f.phases);
                tally_phases(&mut by_phase, &f.phases);
            }
            if !foot {
                failures.push(format!("{src} → {tgt}: foot {:?}", f.foot));
            }
            if !drift {
                failures.push(format!("{src} → {tgt}: drift {:.3} cm/frame", f.drift));
            }
            if !floor {
                failures.push(format!(
                    "{src} → {tgt}: planted feet {:.2} cm off",
                    f.floor_p95
                ));
            }
            with_toes += usize::from(toes);
            joints_within += usize::from(f.joints_drift <= 0.05);
            for (t, ok) in tally.iter_mut().zip([legs, toes && foot, drift, floor]) {
                *t += usize::from(ok);
            }
            tally[4] += usize::from(legs && foot && drift && floor);
        }
    }
    println!(
        "{judged} pairs judged live; within the bounds: thigh and shin {}, foot {} of the \
         {with_toes} with toes, drift {} (every foot joint: {joints_within}), floor {}; every \
         bound at once {}; {} failures",
        tally[0],
        tally[1],
        tally[2],
        tally[3],
        tally[4],
        failures.len()
    );
    print_phase_sums(&by_phase);
    assert!(judged > 0, "no pair judged");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
