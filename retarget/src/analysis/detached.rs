//! Detached bones: control, IK and pole bones that hang beside the body instead of in it.
//!
//! Rigs exported from animation packages often carry their controls in the skeleton: IK foot
//! targets and pole targets under the root (`FootL`, `PoleTargetL`), `*CONTROL` / `*ORIENT`
//! bones, an armature root above the hips. Taken as body parts they become extra legs or a
//! tail. The rule is structural, so it holds without names: from the root down, while a bone
//! has exactly one large child subtree and only single-bone leaves beside it, the
//! bone is a *carrier* (armature root, master control) and the small siblings are *detached*.
//! The body starts at the first bone with two or more large children (or with one large child
//! and nothing else worth detaching).
//!
//! A detached bone still carries motion when it continues a limb: an IK-driven foot placed at
//! the end of a shin that has no foot of its own. [`continuation`] finds such bones so the
//! analysis can give them the extremity's role.

use glam::Vec3;

use super::topology::Topology;
use crate::skeleton::{BoneId, Skeleton};

/// Subtrees of at most this many bones beside the body count as detached controls (leaves:
/// a limb of a small rig can have three bones, a control has one).
const SMALL: usize = 1;

/// Where the body starts, and which bones are not part of it.
pub(crate) struct BodyRoot {
    /// First bone of the body proper.
    pub root: BoneId,
    /// Bones above the body root (armature root, master control).
    pub carriers: Vec<BoneId>,
    /// Per bone: part of a detached control subtree.
    pub detached: Vec<bool>,
}

/// Finds the body root from the (first) skeleton root.
pub(crate) fn find(skel: &Skeleton, topo: &Topology) -> BodyRoot {
    let n = skel.num_bones();
    let mut detached = vec![false; n];
    let mut carriers = Vec::new();
    // Several roots: the body is the largest tree; the others are controls (Quaternius'
    // IK feet are roots of their own).
    let mut b = skel
        .roots()
        .max_by_key(|r| (topo.size[r.index()], std::cmp::Reverse(r.index())))
        .unwrap_or(BoneId(0));
    for r in skel.roots().filter(|&r| r != b) {
        let s = r.index();
        for d in detached.iter_mut().skip(s).take(topo.size[s]) {
            *d = true;
        }
    }
    let mut plain_steps = 0;
    loop {
        let ch = skel.children(b);
        let big: Vec<BoneId> = ch
            .iter()
            .copied()
            .filter(|c| topo.size[c.index()] > SMALL)
            .collect();
        if big.len() != 1 {
            break;
        }
        let body = big[0];
        // Without small siblings a single child continues the body only below one armature
        // node at the top, and only when the body branches right below it (a plain chain of
        // bones is a body of its own, not a stack of carriers).
        if ch.len() == 1 {
            let branches_soon = skel.children(body).len() >= 2
                || skel
                    .children(body)
                    .iter()
                    .any(|g| skel.children(*g).len() >= 2);
            if plain_steps > 0 || !branches_soon {
                break;
            }
            plain_steps += 1;
        }
        carriers.push(b);
        for &c in ch.iter().filter(|&&c| c != body) {
            let s = c.index();
            for d in detached.iter_mut().skip(s).take(topo.size[s]) {
                *d = true;
            }
        }
        b = body;
    }
    BodyRoot {
        root: b,
        carriers,
        detached,
    }
}

/// How well a detached bone continues limb leaf `l` (its segment from its parent, prolonged):
/// onwards from the leaf (under 90°: a hock or wrist may bend sharply), 0.3–3 segment lengths
/// away. The cost is `1 − cos` of the bend; `None` when it does not continue it at all.
fn continuation_cost(skel: &Skeleton, pos: &[Vec3], bone: BoneId, l: BoneId) -> Option<f32> {
    let pb = pos[bone.index()];
    let p = skel.parent(l)?;
    let seg = pos[l.index()] - pos[p.index()];
    let to = pb - pos[l.index()];
    let (ls, lt) = (seg.length(), to.length());
    if ls < 1e-6 || !(0.3 * ls..=3.0 * ls).contains(&lt) {
        return None;
    }
    let cos = seg.dot(to) / (ls * lt);
    if cos < 0.0 || (pb - pos[p.index()]).length() <= ls {
        return None;
    }
    Some(1.0 - cos)
}

/// Per bone: the top-level detached bone that continues it downwards, for the body's leaves.
/// Leaves and detached bones pair off best first (smallest bend): each leaf takes at most one
/// continuation, so a stray control bone that also lies ahead of a leaf cannot take the place
/// of the one that carries the foot, and each detached bone continues at most one leaf, so an
/// IK foot below a shin does not also continue a twist leaf of the arm hanging above it.
pub(crate) fn extensions(
    skel: &Skeleton,
    pos: &[Vec3],
    body: &BodyRoot,
    up: Vec3,
) -> Vec<Option<BoneId>> {
    let mut pairs: Vec<(f32, BoneId, BoneId)> = Vec::new();
    let leaves: Vec<BoneId> = skel
        .bone_ids()
        .filter(|&b| !body.detached[b.index()] && skel.children(b).is_empty())
        .collect();
    for b in skel.bone_ids() {
        let top =
            body.detached[b.index()] && !skel.parent(b).is_some_and(|p| body.detached[p.index()]);
        if !top {
            continue;
        }
        for &l in &leaves {
            let Some(cost) = continuation_cost(skel, pos, b, l) else {
                continue;
            };
            // Feet hang below the limb that ends above them; a control level with or above
            // it (an orient bone) continues nothing.
            let drop = (pos[l.index()] - pos[b.index()]).dot(up);
            if drop < 0.3 * (pos[b.index()] - pos[l.index()]).length() {
                continue;
            }
            pairs.push((cost, l, b));
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut out: Vec<Option<BoneId>> = vec![None; skel.num_bones()];
    let mut used = vec![false; skel.num_bones()];
    for (_, l, b) in pairs {
        if out[l.index()].is_none() && !used[b.index()] {
            out[l.index()] = Some(b);
            used[b.index()] = true;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::topology::joint_positions;
    use crate::skeleton::{RawSkeleton, Transform};

    fn skeleton(bones: &[(&str, Option<usize>, [f32; 3])]) -> Skeleton {
        let mut raw = RawSkeleton::default();
        for (name, parent, t) in bones {
            raw.add(
                *name,
                *parent,
                Transform::from_translation(Vec3::from_array(*t)),
            );
        }
        Skeleton::build(&raw).expect("skeleton")
    }

    #[test]
    fn controls_beside_the_body_and_the_foot_they_stand_for() {
        // root at the floor: a body (hips with a leg ending at the shin, and a spine) and two
        // leaf controls, one at the ankle below the shin, one far in front of the knee.
        let s = skeleton(&[
            ("root", None, [0.0, 0.0, 0.0]),
            ("hips", Some(0), [0.0, 1.0, 0.0]),
            ("thigh", Some(1), [0.1, 0.0, 0.0]),
            ("shin", Some(2), [0.0, -0.45, 0.0]),
            ("spine", Some(1), [0.0, 0.3, 0.0]),
            ("chest", Some(4), [0.0, 0.3, 0.0]),
            ("ik_foot", Some(0), [0.1, 0.08, 0.0]),
            ("pole", Some(0), [0.1, 0.55, 0.8]),
        ]);
        let pos = joint_positions(&s, None);
        let topo = Topology::build(&s, &pos);
        let body = find(&s, &topo);
        let id = |n: &str| s.bone(n).expect("bone");
        assert_eq!(body.root, id("hips"));
        assert_eq!(body.carriers, vec![id("root")]);
        assert!(body.detached[id("ik_foot").index()] && body.detached[id("pole").index()]);
        assert!(!body.detached[id("shin").index()]);
        let ext = extensions(&s, &pos, &body, Vec3::Y);
        assert_eq!(ext[id("shin").index()], Some(id("ik_foot")));
        assert_eq!(ext.iter().flatten().count(), 1);
    }

    #[test]
    fn a_plain_chain_has_no_carriers() {
        let s = skeleton(&[
            ("a", None, [0.0, 0.0, 0.0]),
            ("b", Some(0), [0.0, 0.2, 0.0]),
            ("c", Some(1), [0.0, 0.2, 0.0]),
            ("d", Some(2), [0.0, 0.2, 0.0]),
            ("e", Some(3), [0.0, 0.2, 0.0]),
        ]);
        let pos = joint_positions(&s, None);
        let body = find(&s, &Topology::build(&s, &pos));
        assert_eq!(body.root, BoneId(0));
        assert!(body.carriers.is_empty());
        assert!(body.detached.iter().all(|d| !d));
    }
}
