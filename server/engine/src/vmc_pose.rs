//! VMC output in the frame VMC receivers expect.
//!
//! Receivers (VSeeFace, EVMC4U-style marionettes, VMC4B) apply each streamed local rotation
//! straight onto their own avatar, whose rest is a VRM-normalised T-pose: identity rotations,
//! facing +Z, arms along ±X, legs down. Our bones' local frames are whatever the rig's author
//! chose (glTF bones along +Y with a roll, Maya bones along +X, an A-pose rest), so raw local
//! rotations only look right on rigs built like the receiver's. Each sent bone therefore gets a
//! *normaliser* `N` so that `W · N` (its world rotation times `N`) is identity when the rig
//! stands in its rest pose turned into a T-pose:
//!
//! ```text
//!  N = Wrest⁻¹ · S      S: the rest posture relative to a +Z-facing T-pose —
//!                         the facing (yaw) of the rest, and for upper/lower arms, hands and
//!                         upper/lower legs the swing from the T-pose direction (±X, −Y) to the
//!                         rest direction (an A-pose arm, a splayed leg)
//!  sent local = (W_anc · N_anc)⁻¹ · (W · N)
//! ```
//!
//! `W · Wrest⁻¹` is the bone's rotation since rest in world axes, free of any axis convention,
//! so a twist stays a twist about the bone and a bend a bend, on any receiver.

use std::collections::HashMap;

use glam::{Quat, Vec3};
use rigcast_retarget::{world_transforms, Skeleton, WorldTransform};

/// Limb roles whose rest direction is compared with the T-pose's: (role, role whose joint ends
/// the segment, T-pose direction on the character's left (+X internally) or down).
const LIMBS: [(&str, &str, Vec3); 10] = [
    ("LeftUpperArm", "LeftLowerArm", Vec3::X),
    ("LeftLowerArm", "LeftHand", Vec3::X),
    ("RightUpperArm", "RightLowerArm", Vec3::NEG_X),
    ("RightLowerArm", "RightHand", Vec3::NEG_X),
    ("LeftUpperLeg", "LeftLowerLeg", Vec3::NEG_Y),
    ("LeftLowerLeg", "LeftFoot", Vec3::NEG_Y),
    ("RightUpperLeg", "RightLowerLeg", Vec3::NEG_Y),
    ("RightLowerLeg", "RightFoot", Vec3::NEG_Y),
    // Hands continue their forearm: measured along the forearm.
    ("LeftHand", "", Vec3::X),
    ("RightHand", "", Vec3::NEG_X),
];

/// Normalisers per skeleton bone (identity for bones not sent), from the sent bones' role names,
/// the skeleton's rest and its forward direction (the analysis's).
pub fn normalisers(skeleton: &Skeleton, sent: &[(String, usize)], forward: Vec3) -> Vec<Quat> {
    let rest = world_transforms(skeleton, &skeleton.rest_pose());
    let by_role: HashMap<&str, usize> = sent.iter().map(|(n, b)| (n.as_str(), *b)).collect();
    // The rest's facing, as a turn about up from +Z.
    let flat = Vec3::new(forward.x, 0.0, forward.z);
    let yaw = match flat.try_normalize() {
        Some(f) => Quat::from_rotation_arc(Vec3::Z, f),
        None => Quat::IDENTITY,
    };
    let mut out = vec![Quat::IDENTITY; skeleton.num_bones()];
    for (role, bone) in sent {
        let posture = limb_swing(role, &by_role, &rest, yaw).unwrap_or(Quat::IDENTITY);
        out[*bone] = (rest[*bone].rotation.inverse() * posture * yaw).normalize();
    }
    out
}

/// The swing from the T-pose direction (turned by the rest's yaw) to the limb's rest direction.
fn limb_swing(
    role: &str,
    by_role: &HashMap<&str, usize>,
    rest: &[WorldTransform],
    yaw: Quat,
) -> Option<Quat> {
    let &(_, end, tpose) = LIMBS.iter().find(|(r, _, _)| *r == role)?;
    let (from, to) = if end.is_empty() {
        // A hand: along its forearm.
        let forearm = if role.starts_with("Left") {
            "LeftLowerArm"
        } else {
            "RightLowerArm"
        };
        (*by_role.get(forearm)?, *by_role.get(role)?)
    } else {
        (*by_role.get(role)?, *by_role.get(end)?)
    };
    let dir = (rest[to].translation - rest[from].translation).try_normalize()?;
    Some(Quat::from_rotation_arc(yaw * tpose, dir))
}

/// The local (translation, rotation) sent for bone `bone` relative to its sent ancestor `anc`,
/// both normalised, from this tick's world transforms.
#[inline]
pub fn normalised_local(
    worlds: &[WorldTransform],
    norm: &[Quat],
    bone: usize,
    anc: Option<usize>,
) -> (Vec3, Quat) {
    let w = worlds[bone];
    let rotation = w.rotation * norm[bone];
    match anc {
        Some(a) => {
            let inv = (worlds[a].rotation * norm[a]).inverse();
            (
                inv * (w.translation - worlds[a].translation),
                inv * rotation,
            )
        }
        None => (w.translation, rotation),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rig whose every bone frame is turned arbitrarily (world positions unchanged) sends
    /// the same VMC rotations as the plain rig: normalisation removes axis conventions.
    #[test]
    fn bone_axis_conventions_do_not_reach_the_wire() {
        let plain = crate::builtin::mannequin().unwrap();
        let mut raw = rigcast_retarget::RawSkeleton::default();
        let offsets: Vec<Quat> = (0..plain.num_bones())
            .map(|i| {
                Quat::from_axis_angle(
                    Vec3::new(1.0, i as f32, 2.0).normalize_or_zero(),
                    0.3 * i as f32,
                )
            })
            .collect();
        let rest = plain.rest();
        for b in plain.bone_ids() {
            let i = b.index();
            let p = plain.parent(b).map(|p| p.index());
            let rp = p.map_or(Quat::IDENTITY, |p| offsets[p]);
            raw.add(
                plain.name(b),
                p,
                rigcast_retarget::Transform {
                    translation: rp.inverse() * rest[i].translation,
                    rotation: rp.inverse() * rest[i].rotation * offsets[i],
                },
            );
        }
        let turned = Skeleton::build(&raw).unwrap();
        let sent: Vec<(String, usize)> = [
            ("Hips", "pelvis"),
            ("LeftUpperArm", "upperarm_l"),
            ("LeftLowerArm", "lowerarm_l"),
            ("LeftHand", "hand_l"),
            ("LeftUpperLeg", "thigh_l"),
            ("LeftLowerLeg", "calf_l"),
            ("LeftFoot", "foot_l"),
        ]
        .iter()
        .map(|(r, n)| (r.to_string(), plain.bone(n).unwrap().index()))
        .collect();
        let (np, nt) = (
            normalisers(&plain, &sent, Vec3::Z),
            normalisers(&turned, &sent, Vec3::Z),
        );
        // A pose of the plain rig, and the same pose on the turned rig.
        let mut pose = plain.rest_pose();
        for (i, q) in pose.rotations.iter_mut().enumerate() {
            *q *= Quat::from_rotation_x(0.1 * (i % 5) as f32);
        }
        let mut turned_pose = turned.rest_pose();
        for b in plain.bone_ids() {
            let i = b.index();
            let rp = plain
                .parent(b)
                .map_or(Quat::IDENTITY, |p| offsets[p.index()]);
            turned_pose.rotations[i] = rp.inverse() * pose.rotations[i] * offsets[i];
        }
        let (wp, wt) = (
            world_transforms(&plain, &pose),
            world_transforms(&turned, &turned_pose),
        );
        for (k, (_, b)) in sent.iter().enumerate() {
            let anc = (k > 0).then(|| sent[0].1);
            let (_, a) = normalised_local(&wp, &np, *b, anc);
            let (_, c) = normalised_local(&wt, &nt, *b, anc);
            assert!(a.dot(c).abs() > 1.0 - 1e-6, "{}: {a:?} vs {c:?}", sent[k].0);
        }
        // At rest the mannequin's A-pose arm is sent as its A-pose (45° down), the T-pose
        // normalisation taking it from the receiver's +X rest: not as a T-pose.
        let rest_w = world_transforms(&plain, &plain.rest_pose());
        let arm = sent[1].1;
        let (_, q) = normalised_local(&rest_w, &np, arm, Some(sent[0].1));
        let dir = q * Vec3::X;
        assert!(
            (dir.y + std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-3,
            "{dir:?}"
        );
    }
}
