//! Which bones' translations a subject's version 2 frames carry.
//!
//! Rotations are sent for every bone; translations only for the bones that can move, so a
//! frame stays small while the hips' bob and sway (and any per-bone position channel) reach
//! clients. The set is fixed per skeleton and announced in the `skeleton` message (`translated`
//! per bone), so clients know the layout before the first frame:
//!
//! * every root, and the single-child chain below it down to the first branching bone (a
//!   ground `root` above the pelvis, an armature node above the hips);
//! * every bone the analysis calls hips, with its ancestors (rigs whose root branches into
//!   helper bones before the pelvis, like UE's `root → pelvis, ik_foot_root`);
//! * every foot hanging beside its leg instead of below its shin (an IK-style rig's lone foot
//!   under the armature root, `Leg::carried`): the retargeter and the foot lock place it at
//!   the shin's end, a translation no rotation of its parent gives;
//! * for a replayed file, every bone whose translation leaves its rest in some frame (BVH
//!   position channels on non-root joints, animated glTF translations);
//! * for a live input, every bone (a VMC sender may move any bone, and the set must not change
//!   while the input runs).

use std::sync::Arc;

use rigcast_retarget::analysis::{Analysis, Role};
use rigcast_retarget::footplant::find_legs;
use rigcast_retarget::{Pose, Skeleton};

/// Translation leaving its rest by more than this counts as moving (metres).
const MOVE_TOLERANCE_M: f32 = 1e-6;

/// What besides the structural bones (roots, their chains, the hips) moves.
#[derive(Debug, Clone, Default)]
pub enum MovingBones {
    /// Only the structural bones (retargeted targets: root motion goes to the hips).
    #[default]
    Structural,
    /// Also these bones (indexed by bone), measured over a replayed clip.
    Measured(Arc<[bool]>),
    /// Every bone (live inputs).
    All,
}

impl MovingBones {
    /// The bones whose translation leaves the rest in some pose of `poses`.
    pub fn measured(skeleton: &Skeleton, poses: &[Pose]) -> MovingBones {
        let rest = skeleton.rest();
        let moves: Vec<bool> = (0..skeleton.num_bones())
            .map(|i| {
                poses.iter().any(|p| {
                    p.translations.get(i).is_some_and(|t| {
                        (*t - rest[i].translation).abs().max_element() > MOVE_TOLERANCE_M
                    })
                })
            })
            .collect();
        MovingBones::Measured(moves.into())
    }
}

/// Ascending indices of the bones whose translation version 2 frames carry.
pub fn translated_bones(
    skeleton: &Skeleton,
    analysis: &Analysis,
    moving: &MovingBones,
) -> Vec<u16> {
    let n = skeleton.num_bones();
    let mut marked = vec![false; n];
    for root in skeleton.roots() {
        let mut bone = root;
        marked[bone.index()] = true;
        while let [only] = skeleton.children(bone) {
            bone = *only;
            marked[bone.index()] = true;
        }
    }
    for b in skeleton.bone_ids() {
        if analysis.roles.get(b.index()).map(|r| r.role) == Some(Role::Hips) {
            let mut up = Some(b);
            while let Some(a) = up {
                marked[a.index()] = true;
                up = skeleton.parent(a);
            }
        }
    }
    for leg in find_legs(skeleton, analysis).iter().filter(|l| l.carried) {
        marked[leg.foot.index()] = true;
    }
    match moving {
        MovingBones::Structural => {}
        MovingBones::Measured(moves) => {
            for (m, &v) in marked.iter_mut().zip(moves.iter()) {
                *m |= v;
            }
        }
        MovingBones::All => marked.fill(true),
    }
    (0..n).filter(|&i| marked[i]).map(|i| i as u16).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_retarget::analysis::{analyze, SkeletonView};

    fn names_of(s: &Skeleton, bones: &[u16]) -> Vec<String> {
        bones
            .iter()
            .map(|&b| s.name(rigcast_retarget::BoneId(b)).to_string())
            .collect()
    }

    #[test]
    fn mannequin_carries_its_ground_root_and_pelvis() {
        let m = crate::builtin::mannequin().unwrap();
        let a = analyze(&SkeletonView::rest(&m));
        let t = translated_bones(&m, &a, &MovingBones::Structural);
        assert_eq!(names_of(&m, &t), ["root", "pelvis"]);
        assert_eq!(
            translated_bones(&m, &a, &MovingBones::All).len(),
            m.num_bones()
        );
    }

    #[test]
    fn a_foot_beside_its_leg_is_carried() {
        // An IK-style rig: the feet hang from the armature root beside the body, the shins
        // end in leaves.
        use glam::Vec3;
        use rigcast_retarget::{RawSkeleton, Transform};
        let mut raw = RawSkeleton::default();
        let mut add = |name: &str, parent: Option<usize>, t: [f32; 3]| {
            raw.add(name, parent, Transform::from_translation(Vec3::from(t)))
        };
        let armature = add("Armature", None, [0.0, 0.0, 0.0]);
        let hips = add("Hips", Some(armature), [0.0, 1.0, 0.0]);
        let spine = add("Spine", Some(hips), [0.0, 0.2, 0.0]);
        let chest = add("Chest", Some(spine), [0.0, 0.2, 0.0]);
        add("Head", Some(chest), [0.0, 0.3, 0.0]);
        for (side, x) in [("L", 0.1), ("R", -0.1)] {
            let thigh = add(&format!("UpperLeg.{side}"), Some(hips), [x, -0.05, 0.0]);
            add(&format!("LowerLeg.{side}"), Some(thigh), [0.0, -0.45, 0.0]);
        }
        for (side, x) in [("L", 0.1), ("R", -0.1)] {
            add(&format!("Foot.{side}"), Some(armature), [x, 0.05, 0.0]);
        }
        let s = Skeleton::build(&raw).unwrap();
        let a = analyze(&SkeletonView::rest(&s));
        let t = translated_bones(&s, &a, &MovingBones::Structural);
        assert_eq!(names_of(&s, &t), ["Armature", "Hips", "Foot.L", "Foot.R"]);
    }

    #[test]
    fn measured_adds_bones_that_move_in_the_clip() {
        let m = crate::builtin::mannequin().unwrap();
        let a = analyze(&SkeletonView::rest(&m));
        let mut pose = m.rest_pose();
        let hand = m.bone("hand_l").unwrap().index();
        pose.translations[hand].x += 0.01;
        let moving = MovingBones::measured(&m, &[m.rest_pose(), pose]);
        let t = translated_bones(&m, &a, &moving);
        assert_eq!(names_of(&m, &t), ["root", "pelvis", "hand_l"]);
    }
}
