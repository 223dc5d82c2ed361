//! The body points a motion graph compares, found by role so that clips of different rigs
//! land in one comparable space, and the per-frame heading frame (where the body stands and
//! which way it faces on the floor) that makes the comparison independent of where in the room
//! and in which direction a clip was captured.

use glam::{Quat, Vec3};

use crate::analysis::{Analysis, Role, Side};
use crate::fk::{forward_kinematics, WorldTransform};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

use super::GraphError;

/// Which body points are compared, in this order. Each entry lists roles to try in turn (a
/// sparse rig without a chest bone uses its spine). Feet and hands carry most of what tells
/// two motions apart; hips, chest and head carry posture.
const POINTS: [&[(Role, Side)]; NUM_POINTS] = [
    &[(Role::Hips, Side::Center)],
    &[
        (Role::Chest, Side::Center),
        (Role::SpineMid, Side::Center),
        (Role::Spine, Side::Center),
    ],
    &[(Role::Head, Side::Center), (Role::Neck(0), Side::Center)],
    &[(Role::UpperArm, Side::Left)],
    &[(Role::UpperArm, Side::Right)],
    &[(Role::Hand, Side::Left), (Role::LowerArm, Side::Left)],
    &[(Role::Hand, Side::Right), (Role::LowerArm, Side::Right)],
    &[(Role::UpperLeg, Side::Left)],
    &[(Role::UpperLeg, Side::Right)],
    &[(Role::LowerLeg, Side::Left)],
    &[(Role::LowerLeg, Side::Right)],
    &[(Role::Foot, Side::Left)],
    &[(Role::Foot, Side::Right)],
];

/// Number of compared body points.
pub const NUM_POINTS: usize = 13;

const LEFT_ARM: usize = 3;
const RIGHT_ARM: usize = 4;
const LEFT_LEG: usize = 7;
const RIGHT_LEG: usize = 8;
const LEFT_KNEE: usize = 9;
const RIGHT_KNEE: usize = 10;
const LEFT_FOOT: usize = 11;
const RIGHT_FOOT: usize = 12;

/// The compared bones of one rig, its up axis and the length that normalises distances.
#[derive(Debug, Clone)]
pub struct BodyPoints {
    bones: [BoneId; NUM_POINTS],
    up: Vec3,
    forward: Vec3,
    left: Vec3,
    /// Mean leg length (hip → knee → ankle), metres: distances are in leg lengths so a child
    /// and an adult walking alike are close.
    leg: f32,
}

/// Where the body stands and which way it faces, on the floor plane: a rotation `yaw` about
/// up followed by a horizontal `offset`. Also the type of root alignments (heading to heading).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Planar {
    /// Rotation about the rig's up axis, radians.
    pub yaw: f32,
    /// Horizontal translation (no up component), metres.
    pub offset: Vec3,
}

impl Planar {
    /// The identity.
    pub const IDENTITY: Planar = Planar {
        yaw: 0.0,
        offset: Vec3::ZERO,
    };

    /// The rotation part as a quaternion about `up`.
    pub fn rotation(&self, up: Vec3) -> Quat {
        Quat::from_axis_angle(up, self.yaw)
    }

    /// Maps a point.
    pub fn apply(&self, up: Vec3, p: Vec3) -> Vec3 {
        self.rotation(up) * p + self.offset
    }

    /// `self ∘ other` (apply `other` first).
    pub fn then_after(&self, up: Vec3, other: &Planar) -> Planar {
        Planar {
            yaw: self.yaw + other.yaw,
            offset: self.rotation(up) * other.offset + self.offset,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self, up: Vec3) -> Planar {
        let back = Quat::from_axis_angle(up, -self.yaw);
        Planar {
            yaw: -self.yaw,
            offset: -(back * self.offset),
        }
    }
}

impl BodyPoints {
    /// Finds the compared bones from `analysis`; fails with the first missing body part (a
    /// motion graph needs a two-legged, two-armed body).
    pub fn find(analysis: &Analysis) -> Result<BodyPoints, GraphError> {
        let mut bones = [BoneId(0); NUM_POINTS];
        for (slot, choices) in bones.iter_mut().zip(POINTS) {
            *slot = choices
                .iter()
                .find_map(|&(role, side)| analysis.find(role, side))
                .ok_or_else(|| GraphError::MissingBodyPart {
                    part: describe(choices[0]),
                })?;
        }
        let at = |i: usize| analysis.positions[bones[i].index()];
        let leg = |hip: usize, knee: usize, foot: usize| {
            (at(knee) - at(hip)).length() + (at(foot) - at(knee)).length()
        };
        let leg =
            0.5 * (leg(LEFT_LEG, LEFT_KNEE, LEFT_FOOT) + leg(RIGHT_LEG, RIGHT_KNEE, RIGHT_FOOT));
        if !(leg.is_finite() && leg > 1e-6) {
            return Err(GraphError::MissingBodyPart {
                part: "legs with length".into(),
            });
        }
        Ok(BodyPoints {
            bones,
            up: analysis.up,
            forward: analysis.forward,
            left: analysis.left,
            leg,
        })
    }

    /// The rig's up axis.
    pub fn up(&self) -> Vec3 {
        self.up
    }

    /// The rig's forward axis (the analysis').
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The rig's left axis (the analysis').
    pub fn left(&self) -> Vec3 {
        self.left
    }

    /// Mean leg length, metres.
    pub fn leg_length(&self) -> f32 {
        self.leg
    }

    /// World positions of the compared points of `pose`, using `worlds` as scratch (one entry
    /// per bone). Allocates nothing.
    pub fn points(
        &self,
        skeleton: &Skeleton,
        pose: &Pose,
        worlds: &mut [WorldTransform],
    ) -> [Vec3; NUM_POINTS] {
        forward_kinematics(skeleton, pose, worlds);
        self.bones.map(|b| worlds[b.index()].translation)
    }

    /// The heading frame of a body given its points: origin under the hips, facing the way
    /// the hips and shoulders face (perpendicular to the line between the left and right
    /// thighs and upper arms), which works for any rig the analysis labelled.
    pub fn heading(&self, p: &[Vec3; NUM_POINTS]) -> Planar {
        let across = (p[LEFT_LEG] - p[RIGHT_LEG]) + (p[LEFT_ARM] - p[RIGHT_ARM]);
        let flat = |v: Vec3| v - self.up * v.dot(self.up);
        let left = flat(across).try_normalize().unwrap_or(self.left);
        let facing = left.cross(self.up);
        Planar {
            yaw: facing.dot(self.left).atan2(facing.dot(self.forward)),
            offset: flat(p[0]),
        }
    }
}

fn describe((role, side): (Role, Side)) -> String {
    let side = match side {
        Side::Left => "left ",
        Side::Right => "right ",
        Side::Center => "",
    };
    format!("{side}{}", role.name().replace('_', " "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planar_inverse_and_composition_round_trip() {
        let up = Vec3::Y;
        let a = Planar {
            yaw: 0.7,
            offset: Vec3::new(1.0, 0.0, -2.0),
        };
        let b = Planar {
            yaw: -2.1,
            offset: Vec3::new(0.3, 0.0, 0.5),
        };
        let p = Vec3::new(0.2, 1.0, 0.9);
        let ab = a.then_after(up, &b);
        assert!((ab.apply(up, p) - a.apply(up, b.apply(up, p))).length() < 1e-5);
        let back = a.inverse(up).apply(up, a.apply(up, p));
        assert!((back - p).length() < 1e-5);
    }
}
