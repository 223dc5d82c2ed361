//! Analytic two-bone IK (hip–knee–ankle) by the law of cosines. The knee stays on the side of
//! the hip–goal line given by a pole direction (the animated knee's own side), so it bends in
//! the leg's bend plane and can never flip through it.

use glam::{Quat, Vec3};

/// A solved leg: world-space rotations to pre-multiply onto the upper bone (about the hip)
/// and then onto the lower bone (about the new knee), and where the ankle ends up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoBoneSolution {
    /// Rotation of the upper bone (and everything below it) about the hip.
    pub upper: Quat,
    /// Further rotation of the lower bone (and below) about the new knee.
    pub lower: Quat,
    /// The new knee position.
    pub knee: Vec3,
    /// The new ankle position: the goal, or the nearest point the leg reaches.
    pub ankle: Vec3,
}

/// Fraction of full extension the solver stops at, so the knee keeps a defined bend plane
/// (unless the animation itself holds the leg straighter).
pub const MAX_EXTENSION: f32 = 0.9995;

/// Moves the chain `hip → knee → ankle` so the ankle reaches `goal` (or as close as the bone
/// lengths allow), keeping the knee on the `pole` side of the hip–goal line.
pub fn solve_two_bone(
    hip: Vec3,
    knee: Vec3,
    ankle: Vec3,
    goal: Vec3,
    pole: Vec3,
) -> TwoBoneSolution {
    let placed = Chain::new(hip, knee, ankle).and_then(|c| c.place(goal - hip, pole));
    let Some((to_knee, to_ankle)) = placed else {
        return TwoBoneSolution {
            upper: Quat::IDENTITY,
            lower: Quat::IDENTITY,
            knee,
            ankle,
        };
    };
    let (new_knee, new_ankle) = (hip + to_knee, hip + to_ankle);
    let upper = arc(knee - hip, new_knee - hip);
    let lower = arc(upper * (ankle - knee), new_ankle - new_knee);
    TwoBoneSolution {
        upper,
        lower,
        knee: new_knee,
        ankle: new_ankle,
    }
}

/// A hip–knee–ankle chain's bone lengths and the hip-to-ankle distances it may take, worked
/// out once where many goals are tried on the same leg (the body's height search: it needs
/// the bones' places, not [`solve_two_bone`]'s rotations, which cost as much again).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Chain {
    upper: f32,
    lower: f32,
    nearest: f32,
    farthest: f32,
}

impl Chain {
    /// The chain as the animation holds it; `None` when a bone has no length.
    pub(crate) fn new(hip: Vec3, knee: Vec3, ankle: Vec3) -> Option<Self> {
        let a = (knee - hip).length();
        let b = (ankle - knee).length();
        if a <= f32::EPSILON || b <= f32::EPSILON {
            return None;
        }
        Some(Self {
            upper: a,
            lower: b,
            nearest: (a - b).abs() * 1.0005 + 1e-6,
            // A leg the animation already holds straighter than MAX_EXTENSION may stay that
            // straight.
            farthest: ((a + b) * MAX_EXTENSION).max((ankle - hip).length().min(a + b)),
        })
    }

    /// The knee and the ankle from the hip when the ankle goes towards `to_goal` (from the
    /// hip) as far as the chain reaches, the knee on the `pole` side of the hip–goal line;
    /// `None` for a goal on the hip.
    pub(crate) fn place(&self, to_goal: Vec3, pole: Vec3) -> Option<(Vec3, Vec3)> {
        let (a, b) = (self.upper, self.lower);
        let u = to_goal.try_normalize()?;
        let d = crate::bounds::clamp_safe(to_goal.length(), self.nearest, self.farthest);
        // The pole, made perpendicular to the hip–goal line.
        let v = (pole - u * pole.dot(u))
            .try_normalize()
            .unwrap_or_else(|| u.any_orthonormal_vector());
        let cos_hip = ((a * a + d * d - b * b) / (2.0 * a * d)).clamp(-1.0, 1.0);
        let sin_hip = (1.0 - cos_hip * cos_hip).max(0.0).sqrt();
        Some((a * (cos_hip * u + sin_hip * v), d * u))
    }
}

/// Shortest rotation taking direction `from` to direction `to` (identity when either is 0).
fn arc(from: Vec3, to: Vec3) -> Quat {
    match (from.try_normalize(), to.try_normalize()) {
        (Some(f), Some(t)) => Quat::from_rotation_arc(f, t),
        _ => Quat::IDENTITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approx::vec_close;

    /// A leg standing 1 m tall: hip, knee (`knee_z` in front of the line) and ankle at the
    /// floor.
    fn leg(knee_z: f32) -> (Vec3, Vec3, Vec3) {
        (
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.5, knee_z),
            Vec3::ZERO,
        )
    }

    fn apply(s: &TwoBoneSolution, hip: Vec3, knee: Vec3, ankle: Vec3) -> (Vec3, Vec3) {
        let k = hip + s.upper * (knee - hip);
        let a = k + s.lower * (s.upper * (ankle - knee));
        (k, a)
    }

    #[test]
    fn reaches_a_goal_and_bends_towards_the_pole() {
        let (hip, knee, ankle) = leg(0.02);
        let goal = Vec3::new(0.1, 0.2, 0.05);
        let s = solve_two_bone(hip, knee, ankle, goal, Vec3::Z);
        let (k, a) = apply(&s, hip, knee, ankle);
        assert!(vec_close(a, goal, 1e-4), "{a} vs {goal}");
        assert!(vec_close(k, s.knee, 1e-4));
        // Bone lengths kept, knee forward (+Z) of the hip–ankle line.
        assert!(((k - hip).length() - (knee - hip).length()).abs() < 1e-4);
        assert!(((a - k).length() - (ankle - knee).length()).abs() < 1e-4);
        let mid = hip + (goal - hip) * ((k - hip).dot(goal - hip) / (goal - hip).length_squared());
        assert!((k - mid).z > 0.05);
    }

    #[test]
    fn an_unreachable_goal_stretches_the_leg_towards_it_without_flipping() {
        let (hip, knee, ankle) = leg(0.05);
        let goal = Vec3::new(0.0, -1.0, 0.3);
        let s = solve_two_bone(hip, knee, ankle, goal, Vec3::Z);
        let (k, a) = apply(&s, hip, knee, ankle);
        let reach = (knee - hip).length() + (ankle - knee).length();
        assert!(((a - hip).length() - reach * MAX_EXTENSION).abs() < 1e-3);
        assert!(
            (a - hip)
                .normalize_or_zero()
                .dot((goal - hip).normalize_or_zero())
                > 0.9999
        );
        // Still bent forward, however little.
        let line = (a - hip).normalize_or_zero();
        assert!(((k - hip) - line * (k - hip).dot(line)).z > 0.0);
    }

    #[test]
    fn the_pole_side_decides_the_bend_even_from_a_straight_leg() {
        let (hip, knee, ankle) = leg(0.0);
        for pole in [Vec3::Z, -Vec3::Z, Vec3::X] {
            let s = solve_two_bone(hip, knee, ankle, Vec3::new(0.0, 0.3, 0.0), pole);
            assert!(
                (s.knee - Vec3::new(0.0, 0.65, 0.0)).dot(pole) > 0.3,
                "{pole}"
            );
        }
    }
}
