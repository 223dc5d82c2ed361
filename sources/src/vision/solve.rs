//! Landmarks → local rotations of the BlazePose source skeleton, with a confidence per bone.
//!
//! Each bone's world rotation is the rotation that carries two rest directions onto two
//! measured ones: a *primary* direction that is matched exactly (usually the bone's own
//! segment) and a *secondary* one that fixes the twist about it:
//!
//! | bone | primary | secondary (twist) |
//! |---|---|---|
//! | hips | right hip → left hip | hip centre → shoulder centre |
//! | chest | right → left shoulder | hip centre → shoulder centre |
//! | spine | halfway between hips and chest | |
//! | neck | shoulder centre → ear centre | shoulder line |
//! | head | right ear → left ear | ear centre → nose |
//! | upper arm | shoulder → elbow | elbow → wrist (bend plane) |
//! | forearm, hand | elbow → wrist, wrist → hand centre | pinky → index (palm plane) |
//! | thigh, shin | hip → knee, knee → ankle | heel → toe |
//! | foot | ankle → toe | ankle → knee (knee–ankle–toe plane) |
//!
//! When the secondary direction is nearly parallel to the primary (a straight arm) the twist
//! comes from the previous frame instead of noise. Local rotation = parent world⁻¹ · world.
//!
//! Confidence per bone is the lowest visibility among the landmarks it uses. Output rotations
//! move towards the solved ones by a weight that falls to zero for low confidence, so such
//! bones hold their last rotation; after [`SolverConfig::hold_secs`] of low confidence they
//! ease back to rest.

use std::sync::Arc;

use glam::{Mat3, Quat, Vec3};
use rigcast_retarget::{Pose, Skeleton};

use super::body::{bone, BONES, REST_HIP_HEIGHT};
use super::landmarks::{idx, Landmarks};

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverConfig {
    /// At or below this confidence a bone holds its rotation.
    pub confidence_low: f32,
    /// At or above this confidence a bone follows the landmarks fully.
    pub confidence_high: f32,
    /// How long a bone holds before easing to rest, seconds.
    pub hold_secs: f32,
    /// Time constant of the ease to rest, seconds.
    pub ease_secs: f32,
}

impl Default for SolverConfig {
    fn default() -> Self {
        SolverConfig {
            confidence_low: 0.3,
            confidence_high: 0.6,
            hold_secs: 0.5,
            ease_secs: 0.4,
        }
    }
}

/// Turns landmarks into poses of the BlazePose skeleton. Allocates only in `new`.
#[derive(Debug, Clone)]
pub struct PoseSolver {
    skeleton: Arc<Skeleton>,
    config: SolverConfig,
    rest_dir: [Vec3; bone::NUM_BONES],
    world: [Quat; bone::NUM_BONES],
    confidence: [f32; bone::NUM_BONES],
    low_secs: [f32; bone::NUM_BONES],
    output: Pose,
    last_time: Option<f64>,
}

/// The point halfway between landmarks `a` and `b`, in the solver's frame.
fn midpoint(landmarks: &Landmarks, a: usize, b: usize) -> Vec3 {
    (landmarks.world_internal(a) + landmarks.world_internal(b)) * 0.5
}

#[inline]
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0).max(1e-6)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Stores a solved world rotation and its confidence; an unsolvable bone (degenerate
/// directions) keeps its previous rotation with zero confidence.
fn set(
    solved: &mut [Quat; bone::NUM_BONES],
    conf: &mut [f32; bone::NUM_BONES],
    b: usize,
    q: Option<Quat>,
    c: f32,
) {
    if let Some(q) = q {
        solved[b] = q;
        conf[b] = c;
    } else {
        conf[b] = 0.0;
    }
}

/// Orthonormal basis (columns) with x along `a` and the x–y plane containing `b`.
fn basis(a: Vec3, b: Vec3) -> Option<Mat3> {
    let x = a.try_normalize()?;
    let z = x.cross(b).try_normalize()?;
    let y = z.cross(x);
    Some(Mat3::from_cols(x, y, z))
}

/// The rotation taking `a_rest` to `a` exactly and `b_rest` into the plane of (`a`, `b`).
fn two_axis(a_rest: Vec3, b_rest: Vec3, a: Vec3, b: Vec3) -> Option<Quat> {
    let from = basis(a_rest, b_rest)?;
    let to = basis(a, b)?;
    Some(Quat::from_mat3(&(to * from.transpose())).normalize())
}

/// An arm's bones (upper arm, forearm, hand) and landmarks (shoulder, elbow, wrist, pinky,
/// index).
struct Arm {
    bones: (usize, usize, usize),
    joints: (usize, usize, usize, usize, usize),
}

const ARMS: [Arm; 2] = [
    Arm {
        bones: (bone::LEFT_UPPER_ARM, bone::LEFT_LOWER_ARM, bone::LEFT_HAND),
        joints: (
            idx::LEFT_SHOULDER,
            idx::LEFT_ELBOW,
            idx::LEFT_WRIST,
            idx::LEFT_PINKY,
            idx::LEFT_INDEX,
        ),
    },
    Arm {
        bones: (
            bone::RIGHT_UPPER_ARM,
            bone::RIGHT_LOWER_ARM,
            bone::RIGHT_HAND,
        ),
        joints: (
            idx::RIGHT_SHOULDER,
            idx::RIGHT_ELBOW,
            idx::RIGHT_WRIST,
            idx::RIGHT_PINKY,
            idx::RIGHT_INDEX,
        ),
    },
];

/// A leg's bones (thigh, shin, foot, toes) and landmarks (hip, knee, ankle, heel, toe).
struct Leg {
    bones: (usize, usize, usize, usize),
    joints: (usize, usize, usize, usize, usize),
}

const LEGS: [Leg; 2] = [
    Leg {
        bones: (
            bone::LEFT_UPPER_LEG,
            bone::LEFT_LOWER_LEG,
            bone::LEFT_FOOT,
            bone::LEFT_TOES,
        ),
        joints: (
            idx::LEFT_HIP,
            idx::LEFT_KNEE,
            idx::LEFT_ANKLE,
            idx::LEFT_HEEL,
            idx::LEFT_FOOT_INDEX,
        ),
    },
    Leg {
        bones: (
            bone::RIGHT_UPPER_LEG,
            bone::RIGHT_LOWER_LEG,
            bone::RIGHT_FOOT,
            bone::RIGHT_TOES,
        ),
        joints: (
            idx::RIGHT_HIP,
            idx::RIGHT_KNEE,
            idx::RIGHT_ANKLE,
            idx::RIGHT_HEEL,
            idx::RIGHT_FOOT_INDEX,
        ),
    },
];

impl PoseSolver {
    /// A solver for `skeleton` (the one from [`super::body::blazepose_skeleton`]).
    pub fn new(skeleton: Arc<Skeleton>, config: SolverConfig) -> PoseSolver {
        let mut rest_dir = [Vec3::ZERO; bone::NUM_BONES];
        // A bone's rest direction is its first child's offset (leaves: their own offset).
        for (_, parent, t) in BONES.iter() {
            if let Some(p) = parent {
                if rest_dir[*p] == Vec3::ZERO {
                    rest_dir[*p] = Vec3::from_array(*t);
                }
            }
        }
        for (i, (_, _, t)) in BONES.iter().enumerate() {
            if rest_dir[i] == Vec3::ZERO {
                rest_dir[i] = Vec3::from_array(*t);
            }
        }
        let output = skeleton.rest_pose();
        PoseSolver {
            skeleton,
            config,
            rest_dir,
            world: [Quat::IDENTITY; bone::NUM_BONES],
            confidence: [0.0; bone::NUM_BONES],
            low_secs: [0.0; bone::NUM_BONES],
            output,
            last_time: None,
        }
    }

    /// The skeleton poses are solved for.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// Confidence per bone of the last solve, in [0, 1].
    pub fn confidence(&self) -> &[f32; bone::NUM_BONES] {
        &self.confidence
    }

    /// Back to rest and no history.
    pub fn reset(&mut self) {
        self.output = self.skeleton.rest_pose();
        self.world = [Quat::IDENTITY; bone::NUM_BONES];
        self.low_secs = [0.0; bone::NUM_BONES];
        self.last_time = None;
    }

    /// Solves `landmarks` (at `time_secs`) and writes the held/eased pose into `out`.
    pub fn solve(&mut self, landmarks: &Landmarks, time_secs: f64, out: &mut Pose) {
        let dt = match self.last_time {
            Some(t) if time_secs > t => (time_secs - t) as f32,
            _ => 0.0,
        };
        self.last_time = Some(time_secs);
        // Every bone starts from last frame's rotation; one not seen keeps it.
        let mut solved = self.world;
        let mut conf = [0.0f32; bone::NUM_BONES];
        self.solve_torso(landmarks, &mut solved, &mut conf);
        self.solve_arms(landmarks, &mut solved, &mut conf);
        self.solve_legs(landmarks, &mut solved, &mut conf);
        self.world = solved;
        self.confidence = conf;
        self.blend_into_output(dt);
        out.copy_from(&self.output);
    }

    /// How far a landmark of visibility `v` is trusted, 0..1, between the configured
    /// confidence thresholds.
    fn seen(&self, v: f32) -> f32 {
        smoothstep(self.config.confidence_low, self.config.confidence_high, v)
    }

    /// Hips, spine, chest, neck and head from the hips, shoulders, ears and nose.
    fn solve_torso(
        &self,
        landmarks: &Landmarks,
        solved: &mut [Quat; bone::NUM_BONES],
        conf: &mut [f32; bone::NUM_BONES],
    ) {
        let p = |i: usize| landmarks.world_internal(i);
        let vis = |i: usize| landmarks.visibility(i);
        let mid = |a: usize, b: usize| midpoint(landmarks, a, b);
        let hip_c = mid(idx::LEFT_HIP, idx::RIGHT_HIP);
        let sho_c = mid(idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER);
        let ear_c = mid(idx::LEFT_EAR, idx::RIGHT_EAR);
        let up = sho_c - hip_c;
        let hip_line = p(idx::LEFT_HIP) - p(idx::RIGHT_HIP);
        let sho_line = p(idx::LEFT_SHOULDER) - p(idx::RIGHT_SHOULDER);
        let torso_vis = vis(idx::LEFT_HIP)
            .min(vis(idx::RIGHT_HIP))
            .min(vis(idx::LEFT_SHOULDER))
            .min(vis(idx::RIGHT_SHOULDER));

        let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);

        set(
            solved,
            conf,
            bone::HIPS,
            two_axis(x, y, hip_line, up),
            torso_vis,
        );
        set(
            solved,
            conf,
            bone::CHEST,
            two_axis(x, y, sho_line, up),
            torso_vis,
        );
        let spine = solved[bone::HIPS].slerp(solved[bone::CHEST], 0.5);
        set(solved, conf, bone::SPINE, Some(spine), torso_vis);
        let ear_vis = vis(idx::LEFT_EAR).min(vis(idx::RIGHT_EAR));
        set(
            solved,
            conf,
            bone::NECK,
            two_axis(y, x, ear_c - sho_c, sho_line),
            ear_vis.min(torso_vis),
        );
        set(
            solved,
            conf,
            bone::HEAD,
            two_axis(
                x,
                z,
                p(idx::LEFT_EAR) - p(idx::RIGHT_EAR),
                p(idx::NOSE) - ear_c,
            ),
            ear_vis.min(vis(idx::NOSE)),
        );
    }

    /// Upper arms, forearms and hands; a twist reference not seen keeps last frame's twist.
    fn solve_arms(
        &self,
        landmarks: &Landmarks,
        solved: &mut [Quat; bone::NUM_BONES],
        conf: &mut [f32; bone::NUM_BONES],
    ) {
        for arm in &ARMS {
            self.solve_arm(landmarks, arm, (&mut *solved, &mut *conf));
        }
    }

    /// One arm's upper arm, forearm and hand.
    fn solve_arm(
        &self,
        landmarks: &Landmarks,
        arm: &Arm,
        (solved, conf): (&mut [Quat; bone::NUM_BONES], &mut [f32; bone::NUM_BONES]),
    ) {
        let p = |i: usize| landmarks.world_internal(i);
        let vis = |i: usize| landmarks.visibility(i);
        let z = Vec3::Z;
        let (ub, lb, hb) = arm.bones;
        let (s, e, w, pk, ix) = arm.joints;
        let upper = p(e) - p(s);
        let fore = p(w) - p(e);
        let palm = p(ix) - p(pk);
        let hand = midpoint(landmarks, ix, pk) - p(w);
        let fallback = |b: usize| self.world[b] * z;
        // The twist references come from landmarks outside the bone (wrist, hand); where
        // those are not seen, the bone keeps its previous twist instead of following them.
        let bend = stable_secondary(
            upper,
            trusted(fore, fallback(ub), self.seen(vis(w))),
            fallback(ub),
        );
        let rotation = two_axis(self.rest_dir[ub], z, upper, bend);
        set(solved, conf, ub, rotation, vis(s).min(vis(e)));
        let hand_vis = vis(pk).min(vis(ix)).min(vis(w));
        let twist = stable_secondary(
            fore,
            trusted(palm, fallback(lb), self.seen(hand_vis)),
            fallback(lb),
        );
        let fore_conf = vis(e).min(vis(w)).min(hand_vis.max(0.5 * vis(w)));
        let rotation = two_axis(self.rest_dir[lb], z, fore, twist);
        set(solved, conf, lb, rotation, fore_conf);
        let palm2 = stable_secondary(hand, palm, fallback(hb));
        let rotation = two_axis(self.rest_dir[hb], z, hand, palm2);
        set(solved, conf, hb, rotation, hand_vis);
    }

    /// Thighs, shins, feet and toes; legs face the way their foot points.
    fn solve_legs(
        &self,
        landmarks: &Landmarks,
        solved: &mut [Quat; bone::NUM_BONES],
        conf: &mut [f32; bone::NUM_BONES],
    ) {
        for leg in &LEGS {
            self.solve_leg(landmarks, leg, (&mut *solved, &mut *conf));
        }
    }

    /// One leg's thigh, shin, foot and toes.
    fn solve_leg(
        &self,
        landmarks: &Landmarks,
        leg: &Leg,
        (solved, conf): (&mut [Quat; bone::NUM_BONES], &mut [f32; bone::NUM_BONES]),
    ) {
        let p = |i: usize| landmarks.world_internal(i);
        let vis = |i: usize| landmarks.visibility(i);
        let (y, z) = (Vec3::Y, Vec3::Z);
        let (tb, sb, fb, toes) = leg.bones;
        let (h, k, a, he, t) = leg.joints;
        let thigh = p(k) - p(h);
        let shin = p(a) - p(k);
        let foot_fwd = p(t) - p(he);
        let foot = p(t) - p(a);
        let foot_vis = vis(he).min(vis(t));
        let fallback = |b: usize| self.world[b] * z;
        let foot_seen = self.seen(foot_vis);
        // Thigh and shin: along the segment, facing the way the foot points.
        for (b, along, c) in [
            (tb, thigh, vis(h).min(vis(k))),
            (sb, shin, vis(k).min(vis(a))),
        ] {
            let fwd = stable_secondary(
                along,
                trusted(foot_fwd, fallback(b), foot_seen),
                fallback(b),
            );
            set(
                solved,
                conf,
                b,
                two_axis(self.rest_dir[b], z, along, fwd),
                c,
            );
        }
        let leg_up = stable_secondary(foot, -shin, self.world[fb] * y);
        let rotation = two_axis(self.rest_dir[fb], y, foot, leg_up);
        set(solved, conf, fb, rotation, foot_vis.min(vis(a)));
        // Toes have no landmark of their own: they follow the foot.
        solved[toes] = solved[fb];
        conf[toes] = conf[fb];
    }

    /// Converts solved world rotations to local ones and moves the output towards them by
    /// confidence; low-confidence bones hold, then ease to rest.
    #[allow(clippy::needless_range_loop)] // five parallel per-bone arrays share the index
    fn blend_into_output(&mut self, dt: f32) {
        let parents = self.skeleton.parents();
        let cfg = self.config;
        let first = dt == 0.0;
        for b in 0..bone::NUM_BONES {
            let parent_world = parents[b].map_or(Quat::IDENTITY, |p| self.world[p.index()]);
            let target = (parent_world.inverse() * self.world[b]).normalize();
            let w = smoothstep(cfg.confidence_low, cfg.confidence_high, self.confidence[b]);
            let current = self.output.rotations[b];
            let next = if w > 0.0 {
                self.low_secs[b] = 0.0;
                if first {
                    target
                } else {
                    current.slerp(target, w)
                }
            } else {
                self.low_secs[b] += dt;
                if self.low_secs[b] > cfg.hold_secs {
                    let k = 1.0 - (-dt / cfg.ease_secs.max(1e-3)).exp();
                    current.slerp(Quat::IDENTITY, k)
                } else {
                    current
                }
            };
            self.output.rotations[b] = next.normalize();
        }
        // World landmarks are hip-centred: the root stays at its rest height.
        self.output.translations[bone::HIPS] = Vec3::new(0.0, REST_HIP_HEIGHT, 0.0);
        // Keep the world rotations consistent with what was output, so the next frame's twist
        // fallbacks continue from the displayed pose.
        for b in 0..bone::NUM_BONES {
            let parent_world = parents[b].map_or(Quat::IDENTITY, |p| self.world[p.index()]);
            self.world[b] = parent_world * self.output.rotations[b];
        }
    }
}

/// Direction `b` when its landmarks are seen (`seen` = 1), the unit `fallback` when not
/// (`seen` = 0), blended in between.
fn trusted(b: Vec3, fallback: Vec3, seen: f32) -> Vec3 {
    b.normalize_or_zero() * seen + fallback * (1.0 - seen)
}

/// The secondary direction `b`, or `fallback` when `b` is nearly parallel to `a` (blended
/// smoothly between 6° and 17° so the twist does not jump).
fn stable_secondary(a: Vec3, b: Vec3, fallback: Vec3) -> Vec3 {
    let an = a.normalize_or_zero();
    let bn = b.normalize_or_zero();
    let sin = an.cross(bn).length();
    let w = smoothstep(0.1, 0.3, sin);
    let b_perp = (bn - an * an.dot(bn)).normalize_or_zero();
    let f_perp = (fallback - an * an.dot(fallback)).normalize_or_zero();
    (b_perp * w + f_perp * (1.0 - w)).normalize_or_zero()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::vision::body::blazepose_skeleton;
    use crate::vision::landmarks::{world_to_internal, NUM_MODEL_LANDMARKS};
    use glam::{vec3, Vec4};
    use rigcast_retarget::approx::quat_close;
    use rigcast_retarget::forward_kinematics;
    use rigcast_retarget::WorldTransform;

    /// Inverse of `world_to_internal` (it is its own inverse).
    fn to_model(v: Vec3) -> Vec3 {
        world_to_internal(v)
    }

    /// Landmarks of the skeleton's own joints after FK of `pose` (hip-centred, model axes).
    fn landmarks_from_pose(pose: &Pose) -> Landmarks {
        let s = blazepose_skeleton().unwrap();
        let mut w = vec![WorldTransform::IDENTITY; s.num_bones()];
        forward_kinematics(&s, pose, &mut w);
        let at = |b: usize| w[b].translation;
        let local = |b: usize, v: Vec3| w[b].transform_point(v);
        let hip_c = at(bone::HIPS);
        let mut lm = Landmarks {
            image: [Vec4::new(0.0, 0.0, 0.0, 1.0); NUM_MODEL_LANDMARKS],
            world: [Vec3::ZERO; NUM_MODEL_LANDMARKS],
            presence: 1.0,
            ..Landmarks::default()
        };
        let mut put = |i: usize, v: Vec3| lm.world[i] = to_model(v - hip_c);
        // Joints at a bone's origin.
        for (landmark, b) in [
            (idx::LEFT_HIP, bone::LEFT_UPPER_LEG),
            (idx::RIGHT_HIP, bone::RIGHT_UPPER_LEG),
            (idx::LEFT_SHOULDER, bone::LEFT_UPPER_ARM),
            (idx::RIGHT_SHOULDER, bone::RIGHT_UPPER_ARM),
            (idx::LEFT_ELBOW, bone::LEFT_LOWER_ARM),
            (idx::RIGHT_ELBOW, bone::RIGHT_LOWER_ARM),
            (idx::LEFT_WRIST, bone::LEFT_HAND),
            (idx::RIGHT_WRIST, bone::RIGHT_HAND),
            (idx::LEFT_KNEE, bone::LEFT_LOWER_LEG),
            (idx::RIGHT_KNEE, bone::RIGHT_LOWER_LEG),
            (idx::LEFT_ANKLE, bone::LEFT_FOOT),
            (idx::RIGHT_ANKLE, bone::RIGHT_FOOT),
            (idx::LEFT_FOOT_INDEX, bone::LEFT_TOES),
            (idx::RIGHT_FOOT_INDEX, bone::RIGHT_TOES),
        ] {
            put(landmark, at(b));
        }
        // Points in a bone's frame.
        for (landmark, b, offset) in [
            // Hand points: forward (+Z) is the index side.
            (idx::LEFT_INDEX, bone::LEFT_HAND, vec3(0.08, 0.0, 0.03)),
            (idx::LEFT_PINKY, bone::LEFT_HAND, vec3(0.08, 0.0, -0.03)),
            (idx::RIGHT_INDEX, bone::RIGHT_HAND, vec3(-0.08, 0.0, 0.03)),
            (idx::RIGHT_PINKY, bone::RIGHT_HAND, vec3(-0.08, 0.0, -0.03)),
            (idx::LEFT_HEEL, bone::LEFT_FOOT, vec3(0.0, -0.07, -0.05)),
            (idx::RIGHT_HEEL, bone::RIGHT_FOOT, vec3(0.0, -0.07, -0.05)),
            // Ears on either side of the head bone's origin, nose in front.
            (idx::LEFT_EAR, bone::HEAD, vec3(0.07, 0.0, 0.0)),
            (idx::RIGHT_EAR, bone::HEAD, vec3(-0.07, 0.0, 0.0)),
            (idx::NOSE, bone::HEAD, vec3(0.0, 0.0, 0.1)),
        ] {
            put(landmark, local(b, offset));
        }
        lm
    }

    fn test_pose() -> Pose {
        let s = blazepose_skeleton().unwrap();
        let mut pose = s.rest_pose();
        let r = |b: usize, q: Quat, pose: &mut Pose| pose.rotations[b] = q;
        r(bone::HIPS, Quat::from_rotation_y(0.6), &mut pose);
        r(
            bone::LEFT_UPPER_ARM,
            Quat::from_rotation_z(-1.0) * Quat::from_rotation_x(0.4),
            &mut pose,
        );
        // Elbows bend forward (towards +Z from the T-pose); a backward bend is read as a
        // half-turn twist of the upper arm, which is the anatomically possible reading.
        r(bone::LEFT_LOWER_ARM, Quat::from_rotation_y(-0.9), &mut pose);
        r(bone::RIGHT_UPPER_ARM, Quat::from_rotation_z(0.7), &mut pose);
        r(
            bone::RIGHT_LOWER_ARM,
            Quat::from_rotation_y(1.2) * Quat::from_rotation_x(0.5),
            &mut pose,
        );
        r(bone::LEFT_UPPER_LEG, Quat::from_rotation_x(-0.8), &mut pose);
        r(bone::LEFT_LOWER_LEG, Quat::from_rotation_x(1.1), &mut pose);
        r(
            bone::RIGHT_UPPER_LEG,
            Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.3),
            &mut pose,
        );
        r(bone::RIGHT_FOOT, Quat::from_rotation_x(0.3), &mut pose);
        r(bone::LEFT_HAND, Quat::from_rotation_z(0.3), &mut pose);
        pose
    }

    #[test]
    fn recovers_a_known_pose_from_its_joint_positions() {
        let s = blazepose_skeleton().unwrap();
        let truth = test_pose();
        let lm = landmarks_from_pose(&truth);
        let mut solver = PoseSolver::new(s.clone(), SolverConfig::default());
        let mut out = s.rest_pose();
        solver.solve(&lm, 0.0, &mut out);
        // Bones whose two directions are fully determined by the synthetic landmarks.
        for b in [
            bone::HIPS,
            bone::LEFT_UPPER_ARM,
            bone::LEFT_LOWER_ARM,
            bone::RIGHT_UPPER_ARM,
            bone::RIGHT_LOWER_ARM,
            bone::LEFT_UPPER_LEG,
            bone::LEFT_LOWER_LEG,
            bone::RIGHT_UPPER_LEG,
            bone::RIGHT_FOOT,
            bone::LEFT_HAND,
            bone::HEAD,
        ] {
            // Compare world rotations: the solver's spine split differs from the test pose's.
            let mut wt = vec![WorldTransform::IDENTITY; s.num_bones()];
            let mut wo = wt.clone();
            forward_kinematics(&s, &truth, &mut wt);
            forward_kinematics(&s, &out, &mut wo);
            assert!(
                quat_close(wt[b].rotation, wo[b].rotation, 0.03),
                "bone {} truth {:?} got {:?}",
                s.names()[b],
                wt[b].rotation,
                wo[b].rotation
            );
        }
        assert!(solver.confidence().iter().all(|&c| c > 0.9));
    }

    #[test]
    fn rest_pose_landmarks_give_rest_rotations() {
        let s = blazepose_skeleton().unwrap();
        let lm = landmarks_from_pose(&s.rest_pose());
        let mut solver = PoseSolver::new(s.clone(), SolverConfig::default());
        let mut out = s.rest_pose();
        solver.solve(&lm, 0.0, &mut out);
        for b in 0..bone::NUM_BONES {
            assert!(
                quat_close(out.rotations[b], Quat::IDENTITY, 0.03),
                "bone {b}"
            );
        }
    }

    #[test]
    fn low_confidence_bone_holds_then_eases_to_rest() {
        let s = blazepose_skeleton().unwrap();
        let pose = test_pose();
        let mut lm = landmarks_from_pose(&pose);
        let mut solver = PoseSolver::new(s.clone(), SolverConfig::default());
        let mut out = s.rest_pose();
        solver.solve(&lm, 0.0, &mut out);
        let held = out.rotations[bone::LEFT_LOWER_ARM];
        // The wrist becomes invisible and jumps: the forearm must not follow.
        lm.image[idx::LEFT_WRIST].w = 0.05;
        lm.world[idx::LEFT_WRIST] += Vec3::new(0.0, 0.3, 0.2);
        solver.solve(&lm, 0.1, &mut out);
        assert!(quat_close(out.rotations[bone::LEFT_LOWER_ARM], held, 1e-4));
        // After the hold time it eases towards rest, monotonically.
        let mut last = rigcast_retarget::approx::quat_angle(held, Quat::IDENTITY);
        for i in 2..40 {
            solver.solve(&lm, 0.1 * i as f64, &mut out);
            let a = rigcast_retarget::approx::quat_angle(
                out.rotations[bone::LEFT_LOWER_ARM],
                Quat::IDENTITY,
            );
            assert!(a <= last + 1e-5);
            last = a;
        }
        assert!(last < 0.05, "eased to rest: {last}");
    }

    #[test]
    fn secondary_falls_back_when_parallel() {
        let f = stable_secondary(Vec3::X, Vec3::X * 2.0, Vec3::Z);
        assert!((f - Vec3::Z).length() < 1e-5);
        let g = stable_secondary(Vec3::X, Vec3::Y, Vec3::Z);
        assert!((g - Vec3::Y).length() < 1e-5);
    }
}
