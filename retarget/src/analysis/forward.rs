//! Forward: which way the character faces, from the body itself.
//!
//! The lateral axis comes from mirror twins; what remains is its sign (is the `+lat` twin the
//! character's left?). Each cue below votes with a signed, scale-free number; positive means
//! "forward is `lat × up`":
//!
//! - **feet**: segments ending near the ground (ankle → toes) point forward;
//! - **bends**: over the motion's frames (and the posture), knees flex forward and elbows
//!   backward of the line through their neighbours — true of every human and most animals,
//!   whatever the rest pose;
//! - **thumbs**: a hand's odd digit (the thumb) sits on the front of the palm in T-, A- and
//!   I-poses alike;
//! - **slope**: a horizontal body's higher end is its head;
//! - **lean**: the top end of the centerline (neck and head) leans forward.
//!
//! Names are not a cue here: the caller compares the geometric vote with the side markers in
//! the names and lets geometry win whenever it is clear (two real rigs name their left side
//! `r-*`).

use glam::Vec3;

use super::topology::Topology;
use crate::skeleton::{BoneId, Skeleton};

/// Inputs shared by the cues.
pub(crate) struct ForwardInput<'a> {
    pub skel: &'a Skeleton,
    pub topo: &'a Topology,
    /// Posture positions (the frame `up` and `fwd0` are expressed in).
    pub pos: &'a [Vec3],
    /// Sampled motion frames (world positions), possibly in another orientation.
    pub samples: &'a [Vec<Vec3>],
    pub up: Vec3,
    /// `lat × up`: forward if the `+lat` twins are the character's left.
    pub fwd0: Vec3,
    pub size: f32,
    pub ground: f32,
    pub hext: f32,
    /// Leg pairs (`[+lat member, -lat member]`, chain roots).
    pub legs: Vec<[BoneId; 2]>,
    /// Arm pairs, same convention.
    pub arms: Vec<[BoneId; 2]>,
}

/// The cues' votes (each signed; see the module doc).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ForwardVote {
    pub feet: f32,
    pub bends: f32,
    pub thumbs: f32,
    pub slope: f32,
    pub lean: f32,
}

impl ForwardVote {
    /// Combined vote. Feet and bends are the most reliable; thumbs and the slope break ties.
    pub fn total(&self) -> f32 {
        self.feet + self.bends + 0.5 * self.thumbs + self.slope + 0.5 * self.lean
    }
}

/// All cues.
pub(crate) fn vote(inp: &ForwardInput<'_>, path: &[BoneId]) -> ForwardVote {
    let ends = path.first().copied().zip(path.last().copied());
    ForwardVote {
        feet: feet_cue(inp),
        bends: bend_cue(inp),
        thumbs: thumb_cue(inp),
        slope: slope_cue(inp, ends),
        lean: lean_cue(inp, path),
    }
}

/// The head leans forward: the top end of the centerline (its last quarter by length) points
/// ahead of the body, a little for an upright human, a lot for a crawling creature's head.
fn lean_cue(inp: &ForwardInput<'_>, path: &[BoneId]) -> f32 {
    if path.len() < 2 {
        return 0.0;
    }
    let mut p: Vec<Vec3> = path.iter().map(|b| inp.pos[b.index()]).collect();
    if p[0].dot(inp.up) > p[p.len() - 1].dot(inp.up) {
        p.reverse();
    }
    let total: f32 = p.windows(2).map(|w| (w[1] - w[0]).length()).sum();
    let head = p[p.len() - 1];
    let mut walked = 0.0;
    let mut from = head;
    for w in p.windows(2).rev() {
        walked += (w[1] - w[0]).length();
        from = w[0];
        if walked >= 0.25 * total {
            break;
        }
    }
    let d = head - from;
    let len = d.length();
    if len < 1e-6 * inp.size {
        return 0.0;
    }
    d.dot(inp.fwd0) / len
}

fn h(inp: &ForwardInput<'_>, b: BoneId) -> f32 {
    inp.pos[b.index()].dot(inp.up)
}

/// Foot segments near the ground point forward (scale-free: summed horizontal length over
/// the leg length).
fn feet_cue(inp: &ForwardInput<'_>) -> f32 {
    let mut cue = 0.0;
    let mut reach = 0.0;
    for pair in &inp.legs {
        for &m in pair {
            reach += inp.topo.reach[m.index()];
            let s = m.index();
            for i in s + 1..s + inp.topo.size[s] {
                let b = BoneId(i as u16);
                if h(inp, b) >= inp.ground + 0.12 * inp.hext {
                    continue;
                }
                if let Some(p) = inp.skel.parent(b) {
                    cue += (inp.pos[i] - inp.pos[p.index()]).dot(inp.fwd0);
                }
            }
        }
    }
    if reach > 1e-6 {
        4.0 * cue / reach
    } else {
        0.0
    }
}

/// Knees bend forward, elbows backward: the middle joint's offset from the line through its
/// neighbours, in each frame's own body frame, averaged over frames.
fn bend_cue(inp: &ForwardInput<'_>) -> f32 {
    // Spiders and crabs bend their legs up and out, not forward: only bipeds and quadrupeds.
    if inp.legs.len() > 2 {
        return 0.0;
    }
    let Some(legs) = inp.legs.first() else {
        return 0.0;
    };
    let mut frames: Vec<&[Vec3]> = inp.samples.iter().map(|s| s.as_slice()).collect();
    frames.push(inp.pos);
    // (chain, middle joint, sign): knees bend forward, elbows backward at half the weight.
    let chains: Vec<(Vec<BoneId>, usize, f32)> = [(&inp.legs, true, 1.0), (&inp.arms, false, -0.5)]
        .into_iter()
        .flat_map(|(pairs, leg, w)| pairs.iter().flatten().map(move |&m| (m, leg, w)))
        .filter_map(|(m, leg, w)| {
            let chain = inp.topo.chain(m);
            let k = middle_joint(inp, &chain, leg)?;
            Some((chain, k, w))
        })
        .collect();
    let mut sum = 0.0;
    for p in &frames {
        let Some(fwd) = frame_forward(inp, p, legs) else {
            continue;
        };
        for (chain, k, w) in &chains {
            sum += w * bend(p, chain, *k, fwd);
        }
    }
    3.0 * sum / frames.len() as f32
}

/// A frame's `lat × up` from its own hips (lateral) and legs (hanging down).
fn frame_forward(inp: &ForwardInput<'_>, p: &[Vec3], legs: &[BoneId; 2]) -> Option<Vec3> {
    let end = |m: BoneId| p[inp.topo.chain(m).last().copied().unwrap_or(m).index()];
    // Zero-length thigh helpers on one joint say nothing of the lateral: the hip joints below.
    let (a, b) = inp.topo.parted(p, legs[0], legs[1], 0.02 * inp.size);
    let lat = (p[a.index()] - p[b.index()]).try_normalize()?;
    let hips = (p[a.index()] + p[b.index()]) * 0.5;
    let up = (hips - (end(a) + end(b)) * 0.5).try_normalize()?;
    lat.cross(up).try_normalize()
}

/// The middle joint of a limb chain (its index in the chain), where the knee or elbow bends:
/// the joint 0.42 of the way from the chain's first joint to its end, down a leg that hangs in
/// the posture (its lowest joint at least half its length below its first), else along the
/// chain's length. Height, not length, for a hanging leg: the foot and toes run along the
/// ground and add length but no height, so a cartoon's short legs on full-size feet put 0.42
/// of the length at the ankle, whose bend points the other way, while the knee still sits
/// about halfway down. Chosen once from the posture, since a running frame folds the leg.
fn middle_joint(inp: &ForwardInput<'_>, chain: &[BoneId], leg: bool) -> Option<usize> {
    let p = inp.pos;
    let mut cum = vec![0.0f32; chain.len()];
    for i in 1..chain.len() {
        cum[i] = cum[i - 1] + (p[chain[i].index()] - p[chain[i - 1].index()]).length();
    }
    let total = cum[chain.len() - 1];
    if chain.len() < 3 || total < 1e-6 {
        return None;
    }
    let top = h(inp, chain[0]);
    let drop = top - chain.iter().map(|&b| h(inp, b)).fold(f32::MAX, f32::min);
    let along: Vec<f32> = if leg && drop >= 0.5 * total {
        chain.iter().map(|&b| (top - h(inp, b)) / drop).collect()
    } else {
        cum.iter().map(|c| c / total).collect()
    };
    (1..chain.len() - 1)
        .min_by(|&x, &y| (along[x] - 0.42).abs().total_cmp(&(along[y] - 0.42).abs()))
}

/// Signed offset (over the segment length) of a limb chain's middle joint `k` from the line
/// through the joints around it, along `fwd`.
fn bend(p: &[Vec3], chain: &[BoneId], k: usize, fwd: Vec3) -> f32 {
    let total: f32 = chain
        .windows(2)
        .map(|w| (p[w[1].index()] - p[w[0].index()]).length())
        .sum();
    if total < 1e-6 {
        return 0.0;
    }
    let pk = p[chain[k].index()];
    // The segment before the middle joint: walk back over short helpers.
    let mut s = k - 1;
    while s > 0 && (pk - p[chain[s].index()]).length() < 0.2 * total {
        s -= 1;
    }
    let ps = p[chain[s].index()];
    let upper = (pk - ps).length();
    let Some(j) =
        (k + 1..chain.len()).find(|&j| (p[chain[j].index()] - pk).length() >= 0.6 * upper)
    else {
        return 0.0;
    };
    let pj = p[chain[j].index()];
    let Some(u) = (pj - ps).try_normalize() else {
        return 0.0;
    };
    let d = (pk - ps) - u * (pk - ps).dot(u);
    d.dot(fwd) / upper.max(1e-6)
}

/// The thumb sits on the front of the palm: in each hand with three or more digits, the digit
/// whose shape differs from the others (or, if all agree, the one farthest from the rest).
fn thumb_cue(inp: &ForwardInput<'_>) -> f32 {
    let mut cue = 0.0;
    for pair in &inp.arms {
        for &m in pair {
            if let Some(v) = thumb_offset(inp, m) {
                cue += v;
            }
        }
    }
    cue
}

fn thumb_offset(inp: &ForwardInput<'_>, arm: BoneId) -> Option<f32> {
    let hand = inp
        .topo
        .chain(arm)
        .into_iter()
        .find(|&b| inp.skel.children(b).len() >= 3)?;
    let digits = inp.skel.children(hand);
    let hash = |b: &BoneId| inp.topo.hash[b.index()];
    let odd: Vec<usize> = (0..digits.len())
        .filter(|&i| {
            digits
                .iter()
                .filter(|d| hash(d) == hash(&digits[i]))
                .count()
                == 1
        })
        .collect();
    let thumb = if odd.len() == 1 {
        odd[0]
    } else {
        return None;
    };
    let others: Vec<Vec3> = digits
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != thumb)
        .map(|(_, d)| inp.topo.centroid[d.index()])
        .collect();
    let mean = others.iter().copied().sum::<Vec3>() / others.len() as f32;
    let off = inp.topo.centroid[digits[thumb].index()] - mean;
    let len = off.length();
    if len < 1e-6 * inp.size {
        return None;
    }
    Some(off.dot(inp.fwd0) / len)
}

/// A horizontal body (quadruped) carries its head higher than its tail.
fn slope_cue(inp: &ForwardInput<'_>, path_ends: Option<(BoneId, BoneId)>) -> f32 {
    let Some((a, b)) = path_ends else { return 0.0 };
    let d = inp.pos[b.index()] - inp.pos[a.index()];
    let (dh, dv) = (d.dot(inp.fwd0), d.dot(inp.up));
    if dh.abs() > dv.abs() {
        0.1 * dh.signum() * dv.signum()
    } else {
        0.0
    }
}

/// A forward vote at least this large decides the sides against the names. Each cue read from
/// one posture (feet, thumbs, lean, slope) stays within ±1, so one of them alone, or two
/// weakly agreeing, never outweighs side markers that agree on three quarters of a rig's limb
/// bones (a depth-camera export's feet, read in camera space, voted 0.6 the wrong way); the
/// knees' and elbows' bends over a motion's frames, or several posture cues agreeing, do
/// (real rigs that name their left side `r-*` vote above 4).
const GEOMETRY_CLEAR: f32 = 2.0;

/// Which way the character faces, and what the analysis had to overrule to say so.
pub(super) struct Facing {
    /// Forward (unit).
    pub forward: Vec3,
    /// The provisional sides (`+lat` = left) were the wrong way round.
    pub flipped: bool,
    /// Names that disagreed with clear geometry.
    pub warnings: Vec<String>,
    /// When the sides rest on a weak geometric vote alone (no names decided, no clear vote):
    /// the vote and how close the mirror reading came, 0..1 (1: no vote at all, a coin toss;
    /// 0 at a vote of one posture cue's full worth, 1).
    pub doubt: Option<(f32, f32)>,
}

/// Decides forward from the geometric vote; side markers in the names decide only when the
/// geometry has no clear answer, and a clear answer they contradict is reported.
pub(super) fn facing(
    ctx: &super::context::Ctx<'_>,
    limbs: &[super::context::Limb],
    path: &[BoneId],
    samples: &[Vec<Vec3>],
    lat: Vec3,
    (ground, hext): (f32, f32),
) -> Facing {
    let fwd0 = lat.cross(ctx.up).normalize_or_zero();
    let pairs = |want_ground: bool| -> Vec<[BoneId; 2]> {
        limbs
            .iter()
            .filter(|l| {
                l.members.len() == 2 && l.ground == want_ground && l.reach > 0.12 * ctx.size
            })
            .map(|l| [l.members[0].0, l.members[1].0])
            .collect()
    };
    let input = ForwardInput {
        skel: ctx.skel,
        topo: ctx.topo,
        pos: ctx.pos,
        samples,
        up: ctx.up,
        fwd0,
        size: ctx.size,
        ground,
        hext,
        legs: pairs(true),
        arms: pairs(false),
    };
    let v = vote(&input, path);
    let cue = v.total();
    let geometry = if cue < 0.0 { -1.0 } else { 1.0 };
    let mut warnings = Vec::new();
    // Two or more pairs of ground limbs: a horizontal body whose facing puts its head in
    // front; side markers that would turn it round cannot be right.
    let clear = cue.abs() >= GEOMETRY_CLEAR || (input.legs.len() >= 2 && cue != 0.0);
    let named = name_sign(ctx, limbs);
    let doubt = (named.is_none() && !clear).then(|| (cue, (1.0 - cue.abs()).max(0.0)));
    let sign = match named {
        Some(s) if !clear => s,
        Some(s) if s != geometry => {
            warnings.push(format!(
                "names mark the sides the other way round from the geometry (forward vote \
                 {cue:.2}: feet {:.2}, bends {:.2}, thumbs {:.2}); the geometry's sides are used",
                v.feet, v.bends, v.thumbs
            ));
            geometry
        }
        _ => geometry,
    };
    Facing {
        forward: fwd0 * sign,
        flipped: sign < 0.0,
        warnings,
        doubt,
    }
}

/// The sides the names mark, relative to the provisional ones: `Some(1.0)` when at least
/// three quarters of the side markers in the limbs agree with them, `Some(-1.0)` when as many
/// disagree, `None` otherwise (or with fewer than four markers).
fn name_sign(ctx: &super::context::Ctx<'_>, limbs: &[super::context::Limb]) -> Option<f32> {
    use super::Side;
    let (mut agree, mut disagree) = (0usize, 0usize);
    for l in limbs {
        for &(m, s) in &l.members {
            for b in ctx.subtree(m) {
                match (ctx.names[b.index()].side, s) {
                    (Some(Side::Left), Side::Left) | (Some(Side::Right), Side::Right) => agree += 1,
                    (Some(Side::Left), Side::Right) | (Some(Side::Right), Side::Left) => {
                        disagree += 1
                    }
                    _ => {}
                }
            }
        }
    }
    let total = (agree + disagree) as f32;
    if agree + disagree < 4 {
        None
    } else if agree as f32 >= 0.75 * total {
        Some(1.0)
    } else if disagree as f32 >= 0.75 * total {
        Some(-1.0)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use crate::analysis::{analyze, Side, SkeletonView};

    /// One rest pose's cues (feet, thumbs) are weak evidence: side markers that agree with
    /// each other decide over them, even when they are the mirror image of the geometry's
    /// reading. (Clear geometry, knees and elbows bending over a motion, beats lying names:
    /// the real Godot robot in the shared data's zoo test.)
    #[test]
    fn weak_geometry_defers_to_consistent_names() {
        let e = crate::corpus::get("mixamo_apose").expect("corpus");
        let honest = analyze(&SkeletonView::rest(&e.skeleton));
        assert!(honest.forward.z > 0.99 && honest.warnings.is_empty());
        // The same rig with its names mirrored (`Left` ↔ `Right`).
        let mirrored = e
            .skeleton
            .renamed(|_, n| {
                n.replace("Left", "Tmp")
                    .replace("Right", "Left")
                    .replace("Tmp", "Right")
            })
            .expect("rename");
        let a = analyze(&SkeletonView::rest(&mirrored));
        assert!(a.forward.z < -0.99, "{}", a.forward);
        assert!(a.warnings.is_empty(), "{:?}", a.warnings);
        let b = mirrored.bone("mixamorig:RightUpLeg").expect("bone");
        assert_eq!(a.roles[b.index()].side, Side::Right);
    }
}
