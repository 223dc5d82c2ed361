//! The body frame's first two axes: lateral (from mirror twins: sibling subtrees of equal
//! shape) and up (legs hang down and the body stands above its feet; the default is +Y). The
//! third, forward, needs the limbs and is decided in `forward`.

use glam::Vec3;

use super::detached::BodyRoot;
use super::topology::Topology;
use crate::skeleton::{BoneId, Skeleton};

/// Up and lateral axes (unit, orthogonal) of a posture. The lateral axis' sign is provisional.
pub(super) fn up_and_lateral(
    skel: &Skeleton,
    topo: &Topology,
    pos: &[Vec3],
    body: &BodyRoot,
    size: f32,
) -> (Vec3, Vec3) {
    let (lateral, shallow_pair) = lateral_from_twins(skel, topo, pos, &body.detached);
    let up = shallow_pair
        .and_then(|pair| up_from_legs(skel, topo, pos, body, size, lateral, pair))
        .unwrap_or(Vec3::Y);
    // Rigs are built along axes; a rest or frame that is not quite symmetric (one arm
    // forward) must not tilt the lateral axis into the body's length.
    let mut lat = snap_axis((lateral - up * lateral.dot(up)).normalize_or_zero());
    if lat == Vec3::ZERO {
        lat = if up.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
        lat = (lat - up * lat.dot(up)).normalize_or_zero();
    }
    (up, lat)
}

/// Up from the shallowest twin pair (the legs, on most bodies), when it differs from +Y.
fn up_from_legs(
    skel: &Skeleton,
    topo: &Topology,
    pos: &[Vec3],
    body: &BodyRoot,
    size: f32,
    lateral: Vec3,
    (p, a, b): (BoneId, BoneId, BoneId),
) -> Option<Vec3> {
    let ends = |x: BoneId| pos[topo.chain(x).last().copied().unwrap_or(x).index()];
    let feet = (ends(a) + ends(b)) * 0.5;
    let d = feet - pos[p.index()];
    let down = d - lateral * d.dot(lateral);
    if down.length() <= 0.05 * size {
        return None;
    }
    // The legs hang down and the body stands above its feet. When both say so the rig is
    // turned as a whole (Z-up or any other way) and comes out the same; a quadruped's
    // slanted hind legs alone (the body stands ahead of them) do not tilt it.
    let in_body: Vec<Vec3> = skel
        .bone_ids()
        .filter(|x| !body.detached[x.index()])
        .map(|x| pos[x.index()])
        .collect();
    let centroid = in_body.iter().copied().sum::<Vec3>() / in_body.len().max(1) as f32;
    let above = centroid - feet;
    let above = (above - lateral * above.dot(lateral)).normalize_or_zero();
    let legs_up = -down.normalize_or_zero();
    if above.dot(legs_up) > 0.94 && legs_up.dot(Vec3::Y) < 0.9 {
        // Legs and body agree: a rig turned as a whole.
        Some(snap_axis((above + legs_up).normalize_or_zero()))
    } else if legs_up.dot(Vec3::Y) < 0.5 {
        // Only the legs say so, and strongly (a Z-up quadruped).
        Some(snap_axis(legs_up))
    } else {
        None
    }
}

/// Lateral axis estimate from mirror twins (sibling subtrees with equal shape hashes), and the
/// shallowest twin pair (parent, a, b), used to check the up axis against the legs.
fn lateral_from_twins(
    skel: &Skeleton,
    topo: &Topology,
    pos: &[Vec3],
    detached: &[bool],
) -> (Vec3, Option<(BoneId, BoneId, BoneId)>) {
    let mut pairs = twin_pairs(skel, topo, pos, detached);
    pairs.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.3.cmp(&y.3)));
    let Some(first) = pairs.first() else {
        return (Vec3::X, None);
    };
    let reference = first.1;
    let mut sum = Vec3::ZERO;
    for (w, v, ..) in &pairs {
        let v = if v.dot(reference) < 0.0 { -*v } else { *v };
        sum += v.normalize_or_zero() * *w;
    }
    // Make the estimate independent of which twin came first.
    let lat = major_positive(sum.normalize_or_zero());
    // Shallowest pair (closest to the root), the heaviest among those.
    let shallow = pairs
        .iter()
        .min_by(|x, y| x.2.cmp(&y.2).then(y.0.total_cmp(&x.0)))
        .map(|t| (t.3, t.4, t.5));
    (lat, shallow)
}

/// A twin pair: its weight (separation × subtree size), the vector between the twins, the
/// parent's depth, and (parent, first twin, second twin).
type TwinPair = (f32, Vec3, usize, BoneId, BoneId, BoneId);

/// Every mirror pair of sibling subtrees (exactly two children of one shape, neither detached).
fn twin_pairs(skel: &Skeleton, topo: &Topology, pos: &[Vec3], detached: &[bool]) -> Vec<TwinPair> {
    let size = topo.reach.iter().copied().fold(0.0f32, f32::max).max(1e-6);
    let mut pairs: Vec<TwinPair> = Vec::new();
    // Per shape among one bone's children: how many, and the first two (in child order).
    let mut shapes: std::collections::HashMap<u64, (usize, BoneId, BoneId)> =
        std::collections::HashMap::new();
    for p in skel.bone_ids() {
        let ch = skel.children(p);
        // Counted once per parent, so a fan of thousands of siblings stays linear.
        shapes.clear();
        for &c in ch {
            let e = shapes.entry(topo.hash[c.index()]).or_insert((0, c, c));
            e.0 += 1;
            if e.0 == 2 {
                e.2 = c;
            }
        }
        for &a in ch {
            // Exactly two siblings of this shape: a mirror pair, not a row of fingers; taken
            // at its first twin, as the pairs are ordered by their first child.
            let (same, first, b) = shapes[&topo.hash[a.index()]];
            if same != 2 || first != a {
                continue;
            }
            if detached[a.index()] || detached[b.index()] {
                continue;
            }
            // The twins' own joints are mirror images even when the rest pose is not
            // (one arm raised, a leg mid-stride): use them, or, where they coincide (CMU's hip
            // helpers, zero-length thigh roots), the first joints down their chains that do
            // not; the subtrees' centroids only when the chains never part.
            let (x, y) = topo.parted(pos, a, b, 0.02 * size);
            let joints = pos[x.index()] - pos[y.index()];
            let v = if joints.length() > 0.02 * size {
                joints
            } else {
                topo.centroid[a.index()] - topo.centroid[b.index()]
            };
            let w = v.length() * topo.size[a.index()] as f32;
            if w > 0.0 {
                pairs.push((w, v, skel.depth(p), p, a, b));
            }
        }
    }
    pairs
}

/// `v` turned to point along its largest coordinate's positive axis.
fn major_positive(v: Vec3) -> Vec3 {
    let m = v.abs().max_element();
    let major = if v.x.abs() == m {
        v.x
    } else if v.y.abs() == m {
        v.y
    } else {
        v.z
    };
    if major < 0.0 {
        -v
    } else {
        v
    }
}

/// Snaps a direction to the nearest coordinate axis when within ~25 degrees of it.
pub(super) fn snap_axis(v: Vec3) -> Vec3 {
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for a in axes {
        if v.dot(a) > 0.9 {
            return a;
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::detached;
    use crate::analysis::topology::joint_positions;
    use glam::Quat;

    fn axes_of(skel: &Skeleton) -> (Vec3, Vec3) {
        let pos = joint_positions(skel, None);
        let topo = Topology::build(skel, &pos);
        let body = detached::find(skel, &topo);
        up_and_lateral(skel, &topo, &pos, &body, 1.8)
    }

    #[test]
    fn upright_and_z_up_humans() {
        let e = crate::corpus::get("mixamo").expect("corpus");
        let (up, lat) = axes_of(&e.skeleton);
        assert!(up.abs_diff_eq(Vec3::Y, 1e-4), "{up}");
        assert!(lat.x.abs() > 0.999, "{lat}");
        let mut raw = e.skeleton.to_raw();
        let turn = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        raw.bones[0].rest.rotation = turn * raw.bones[0].rest.rotation;
        let z_up = Skeleton::build(&raw).expect("skeleton");
        let (up, lat) = axes_of(&z_up);
        assert!(up.abs_diff_eq(Vec3::Z, 1e-4), "{up}");
        assert!(lat.x.abs() > 0.999, "{lat}");
    }

    #[test]
    fn snapping_only_near_an_axis() {
        assert_eq!(
            snap_axis(Vec3::new(0.1, -0.99, 0.0).normalize_or_zero()),
            -Vec3::Y
        );
        let v = Vec3::new(0.6, 0.8, 0.0);
        assert_eq!(snap_axis(v), v);
    }
}
