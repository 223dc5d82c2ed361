//! Root motion: where the target's root (hips) goes, and the foot-contact calibration that keeps
//! feet on the floor across leg proportions.

use glam::{Quat, Vec3};

use super::{
    align, primary, FootContact, RetargetContext, RetargetOptions, RetargetPlan, RootMotion,
};
use crate::fk::WorldTransform;
use crate::mapping::{MappingTable, SourceRef};
use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

/// Legs told apart by the foot-contact calibration (more share the last slot).
const MAX_LEGS: usize = 8;
/// A source foot this close to the lowest one (metres) counts as standing for the calibration.
const PLANTED_M: f32 = 0.02;

/// How the target's root bone is placed.
#[derive(Debug, Clone)]
pub(super) struct RootPlan {
    pub(super) bone: BoneId,
    pub(super) input: u16,
    pub(super) source_bone: BoneId,
    pub(super) scale: f32,
    /// The source's up direction (unit): heights and floors are measured along it.
    pub(super) up: Vec3,
    pub(super) motion: RootMotion,
    pub(super) source_floor_y: f32,
    /// `None`: the target's rest does not show where its floor is; it then keeps the source's
    /// floor clearance, scaled.
    pub(super) target_floor_y: Option<f32>,
    /// What the target's floor height is the standing height of.
    pub(super) floor_at: FloorAt,
    pub(super) reference_position: Vec3,
    /// Source bones (of `input`) at the feet: what [`RetargetPlan::measure_source_floor`] looks at.
    pub(super) contact_bones: Vec<BoneId>,
    /// (target, source) foot joint pairs for [`RetargetPlan::place_feet`].
    /// With the index of the leg (root child subtree) each belongs to, below `MAX_LEGS`.
    pub(super) contacts: Vec<(BoneId, BoneId, u8)>,
    /// Per leg, how far above the floor its lowest contact joint stands when the source's
    /// foot is down, beyond the source's clearance scaled: non-zero only for a leg whose
    /// mapped joints end well above the ground (a hoofed leg mapped down to the hock).
    pub(super) stand: [f32; MAX_LEGS],
    pub(super) foot_contact: FootContact,
}

/// What the target's floor height is measured at (see [`super::Mapping::target_floor`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FloorAt {
    /// The standing height of this joint (the lowest mapped foot joint: an ankle when the
    /// source has no toes, so the ground itself lies below it by that joint's clearance).
    Joint(BoneId),
    /// The ground itself, at height 0 of the character's own posture: its lowest mapped joints
    /// stand well above it (a hoofed leg mapped down to the hock).
    Ground,
    /// Not known (no mapped joint below the root).
    Unknown,
}

/// One skeleton in its reference posture, for build-time measurements.
#[derive(Clone, Copy)]
pub(super) struct Side<'a> {
    pub(super) skel: &'a Skeleton,
    pub(super) worlds: &'a [WorldTransform],
    pub(super) eps: f32,
    /// Bones carried at a limb's end from beside the body, with the leaf carrying each
    /// (`carried`): measured as if they hung from it.
    pub(super) carried: &'a [(BoneId, BoneId)],
}

/// Segments within about 37° of `up` count as leg (thigh, shin); the foot's slope and the hip
/// offset do not, so rigs whose ankles and toes are built differently measure alike.
const LEG_SEGMENT_COS: f32 = 0.8;

impl Side<'_> {
    /// The bone `b` hangs from: its parent, or the leaf that carries it.
    fn parent(&self, b: BoneId) -> Option<BoneId> {
        match self.carried.iter().find(|c| c.0 == b) {
            Some(&(_, by)) => Some(by),
            None => self.skel.parent(b),
        }
    }

    /// Whether `d` is `a` or hangs below it (through [`Side::parent`]).
    fn is_descendant(&self, a: BoneId, d: BoneId) -> bool {
        let mut b = Some(d);
        while let Some(x) = b {
            if x == a {
                return true;
            }
            b = self.parent(x);
        }
        false
    }

    /// The segments (joint to joint, world space) from `top` down to `low`, those longer than
    /// `eps`; empty when `low` is not below `top`.
    fn segments_down(&self, top: BoneId, low: BoneId) -> Vec<Vec3> {
        let mut path = vec![low];
        let mut b = low;
        while b != top {
            match self.parent(b) {
                Some(p) => b = p,
                None => return Vec::new(),
            }
            path.push(b);
        }
        path.windows(2)
            .map(|w| self.worlds[w[0].index()].translation - self.worlds[w[1].index()].translation)
            .filter(|d| d.length() > self.eps)
            .rev()
            .collect()
    }

    /// Hip height along a leg: from `top`'s joint down to `low`'s, the drop along `up` of the
    /// first (hip-offset) segment, full lengths of segments mostly along `up` (thigh, shin:
    /// posture does not shorten them) and the drop of mostly-horizontal ones (the foot).
    pub(super) fn leg_height(&self, top: BoneId, low: BoneId, up: Vec3) -> f32 {
        self.segments_down(top, low)
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let (drop, len) = (d.dot(up).abs(), d.length());
                if i == 0 || drop < 0.5 * len {
                    drop
                } else {
                    len
                }
            })
            .sum()
    }
}

/// Leg lengths of both rigs from the mapped upper-leg pair `top` down to the mapped foot pair
/// `low` (target, source): the legs' segments between consecutive joints mapped to each other
/// on that path (thigh, shin: those along `up` on both rigs, not the foot). Strides scale with
/// it. Compared segment for segment, like with like, whatever hip offsets, ankle heights and
/// unmapped joints the rigs have in between: a toe joint the source lacks, left unmapped between
/// the target's foot and its mapped toe tip, is not leg (counted, it lengthened a rig whose
/// toes hang down in its aligned rest by its toes' length).
fn mapped_leg_lengths(
    (src, tgt): (Side<'_>, Side<'_>),
    table: &MappingTable,
    input: u16,
    (top, low): ((BoneId, BoneId), (BoneId, BoneId)),
    up: Vec3,
) -> (f32, f32) {
    // The mapped pairs on the target's path from `low` up to `top` whose source joints lie, in
    // the same order, on the source's path between the two.
    let mut joints = vec![low];
    let mut b = low.0;
    while b != top.0 {
        let Some(p) = tgt.parent(b) else {
            return (0.0, 0.0);
        };
        b = p;
        let last = joints[joints.len() - 1].1;
        let s = if b == top.0 {
            Some(top.1)
        } else {
            primary(table, b)
                .filter(|r| r.input == input && r.bone != last)
                .map(|r| r.bone)
        };
        if let Some(s) = s.filter(|&s| {
            align::is_descendant(src.skel, top.1, s) && align::is_descendant(src.skel, s, last)
        }) {
            joints.push((b, s));
        }
    }
    let at = |side: &Side<'_>, b: BoneId| side.worlds[b.index()].translation;
    let leg = |d: Vec3| d.dot(up).abs() >= LEG_SEGMENT_COS * d.length();
    let (mut ht, mut hs) = (0.0, 0.0);
    for w in joints.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        let (dt, ds) = (
            at(&tgt, lo.0) - at(&tgt, hi.0),
            at(&src, lo.1) - at(&src, hi.1),
        );
        if leg(dt) && leg(ds) {
            ht += dt.length();
            hs += ds.length();
        }
    }
    (ht, hs)
}

/// The floor a reference posture stands on: its lowest foot joint when that is near y = 0 (a
/// character authored standing on the ground); y = 0 itself when the lowest mapped joint
/// stands above it but well below the root (`root_y`): a leg whose last segments are not
/// mapped, like a hoofed leg ending at the hock; unknown for a rest floating at the origin
/// (like CMU's, with the hips at y = 0 and the feet below).
fn floor_from_reference(lowest_y: f32, leg_height: f32, root_y: f32) -> Option<f32> {
    if lowest_y.abs() <= 0.25 * leg_height {
        Some(lowest_y)
    } else if lowest_y > 0.0 && lowest_y < 0.5 * root_y {
        Some(0.0)
    } else {
        None
    }
}

/// A contact joint standing higher above its floor than this share of the leg's height is
/// not where the leg meets the ground (see [`floor_from_reference`]).
const RAISED_CONTACT: f32 = 0.25;

impl RootPlan {
    /// Hip-height ratio from each reference posture, measured down the legs to the lowest mapped
    /// joints (averaged over both legs; falls back to the ratio of overall sizes), and floors.
    pub(super) fn new(
        src: Side<'_>,
        tgt: Side<'_>,
        tgt_own: &[WorldTransform],
        table: &MappingTable,
        rt: BoneId,
        rs: SourceRef,
        opts: &RetargetOptions,
    ) -> RootPlan {
        // Both postures are in the source's world (the target's is its aligned reference).
        let up = opts
            .source_up
            .and_then(|u| u.try_normalize())
            .unwrap_or(Vec3::Y);
        let m = Measure {
            src,
            tgt,
            tgt_own,
            table,
            rt,
            rs,
            up,
            opts,
        };
        let feet = m.feet();
        let low = feet
            .iter()
            .copied()
            .min_by(|a, b| m.y_t(a.0).total_cmp(&m.y_t(b.0)));
        let mut scale = align::extent(tgt.worlds) / align::extent(src.worlds);
        let mut floors = Floors::default();
        if let Some((tl, _)) = low {
            let first = tgt.leg_height(rt, tl, up);
            if let Some(legs) = m.leg_scale(&feet, tl, first) {
                scale = legs;
            }
            floors = m.floors(&feet, tl, first, scale);
        }
        RootPlan {
            bone: rt,
            input: rs.input,
            source_bone: rs.bone,
            scale: opts.root_scale.unwrap_or(scale),
            up,
            motion: opts.root_motion,
            source_floor_y: opts.source_floor_y.or(floors.source).unwrap_or(0.0),
            target_floor_y: opts.target_floor_y.or(floors.target),
            floor_at: floors.at,
            reference_position: tgt.worlds[rt.index()].translation,
            contact_bones: floors.contacts.iter().map(|&(_, s, _)| s).collect(),
            contacts: floors.contacts,
            stand: floors.stand,
            foot_contact: opts.foot_contact,
        }
    }
}

/// What [`RootPlan::new`] measures from: both sides in the source's world (the target's
/// posture is its aligned reference), the target's own reference, the mapping and the roots.
struct Measure<'a> {
    src: Side<'a>,
    tgt: Side<'a>,
    tgt_own: &'a [WorldTransform],
    table: &'a MappingTable,
    rt: BoneId,
    rs: SourceRef,
    up: Vec3,
    opts: &'a RetargetOptions,
}

/// The floors and the feet standing on them, as [`RootPlan`] keeps them; all unknown until
/// the target's feet are found.
struct Floors {
    contacts: Vec<(BoneId, BoneId, u8)>,
    target: Option<f32>,
    source: Option<f32>,
    stand: [f32; MAX_LEGS],
    at: FloorAt,
}

impl Default for Floors {
    fn default() -> Self {
        Floors {
            contacts: Vec::new(),
            target: None,
            source: None,
            stand: [0.0; MAX_LEGS],
            at: FloorAt::Unknown,
        }
    }
}

impl Measure<'_> {
    fn y_t(&self, b: BoneId) -> f32 {
        self.tgt.worlds[b.index()].translation.dot(self.up)
    }

    fn y_s(&self, b: BoneId) -> f32 {
        self.src.worlds[b.index()].translation.dot(self.up)
    }

    fn keeps_own(&self, t: BoneId) -> bool {
        self.opts.posture_relative.iter().any(|&(b, _)| b == t)
    }

    /// The target's feet are where the source's feet go: mapped pairs below the root whose
    /// source joint is near the source's lowest ones. A long-armed target's fingers may hang
    /// below its feet in the source's posture, and are no floor; a bone keeping its own
    /// posture is a leg only when its source joint is one, not a quadruped's front leg driven
    /// by a walker's arm.
    fn feet(&self) -> Vec<(BoneId, BoneId)> {
        let below = pairs_below(self.src, self.tgt, self.table, self.rt, self.rs);
        let lowest_src = (below.iter())
            .map(|&(_, s)| self.y_s(s))
            .fold(f32::INFINITY, f32::min);
        let near_src_feet = lowest_src + 0.25 * (self.y_s(self.rs.bone) - lowest_src).abs();
        below
            .into_iter()
            .filter(|&(_, s)| self.y_s(s) <= near_src_feet)
            .collect()
    }

    /// Target over source leg height, summed over every foot pair at the lowest level (both
    /// feet, so left/right asymmetry averages out); `None` when no pair measured.
    fn leg_scale(&self, feet: &[(BoneId, BoneId)], tl: BoneId, first: f32) -> Option<f32> {
        let (src, tgt, up) = (self.src, self.tgt, self.up);
        let (mut sum_t, mut sum_s) = (0.0, 0.0);
        for &(t, s) in feet
            .iter()
            .filter(|(t, _)| self.y_t(*t) <= self.y_t(tl) + 0.02 * first)
        {
            let (ht, hs) = match top_pair(src, tgt, self.table, self.rt, self.rs, t, s) {
                // A leg keeping its own posture (`posture_relative`) moves the body by its
                // standing height, however its bones zig-zag.
                Some((tt, st)) if self.keeps_own(t) => {
                    (self.y_t(tt) - self.y_t(t), src.leg_height(st, s, up))
                }
                Some(pair) => {
                    mapped_leg_lengths((src, tgt), self.table, self.rs.input, (pair, (t, s)), up)
                }
                None => (
                    tgt.leg_height(self.rt, t, up),
                    src.leg_height(self.rs.bone, s, up),
                ),
            };
            if ht > tgt.eps && hs > src.eps {
                sum_t += ht;
                sum_s += hs;
            }
        }
        (sum_t > 0.0 && sum_s > 0.0).then(|| sum_t / sum_s)
    }

    /// The contacts (mapped joints near the lowest foot joint `tl`: toes, ankles, both
    /// sides), both floors, and how high each leg's contact stands above the target's.
    fn floors(&self, feet: &[(BoneId, BoneId)], tl: BoneId, first: f32, scale: f32) -> Floors {
        let y_t = |b: BoneId| self.y_t(b);
        let contacts = contact_pairs(&self.tgt, feet, self.rt, y_t(tl) + 0.15 * first, &y_t);
        let lowest_s = contacts
            .iter()
            .map(|&(_, b, _)| self.y_s(b))
            .fold(f32::INFINITY, f32::min);
        // The target's floor is where its own reference stands, when that reference stands
        // along the same up (its ground is then known); a rig lying along another axis has no
        // floor in this world, and keeps the source's clearance instead. A leg keeping its
        // own posture stands as in it, whatever the source's would make of it.
        let own_y = |b: BoneId| self.tgt_own[b.index()].translation.dot(self.up);
        let standing = |y: &dyn Fn(BoneId) -> f32| y(self.rt) - y(tl);
        let own = self.keeps_own(tl) || standing(&own_y) > 0.8 * standing(&y_t);
        let y_floor: &dyn Fn(BoneId) -> f32 = if own { &own_y } else { &y_t };
        let target = floor_from_reference(y_floor(tl), first, y_floor(self.rt));
        // A floor put at the ground below raised contacts is nobody's standing height.
        let at = match target {
            Some(f) if y_floor(tl) - f > RAISED_CONTACT * first => FloorAt::Ground,
            _ => FloorAt::Joint(tl),
        };
        let source = floor_from_reference(lowest_s, first / scale, self.y_s(self.rs.bone));
        let stand = target.map_or([0.0; MAX_LEGS], |floor| {
            let clear_s = |b: BoneId| self.y_s(b) - lowest_s;
            raised_contacts(&contacts, y_floor, floor, clear_s, scale, first)
        });
        Floors {
            contacts,
            target,
            source,
            stand,
            at,
        }
    }
}

/// The mapped (target, source) pairs below the root on both sides: the legs (and whatever
/// else hangs from the hips).
fn pairs_below(
    src: Side<'_>,
    tgt: Side<'_>,
    table: &MappingTable,
    rt: BoneId,
    rs: SourceRef,
) -> Vec<(BoneId, BoneId)> {
    (tgt.skel.bone_ids())
        .filter(|&t| t != rt && tgt.is_descendant(rt, t))
        .filter_map(|t| {
            let s = primary(table, t)?;
            (s.input == rs.input
                && s.bone != rs.bone
                && align::is_descendant(src.skel, rs.bone, s.bone))
            .then_some((t, s.bone))
        })
        .collect()
}

/// The (target, source, leg) foot pairs: mapped joints below the root no higher than `near`,
/// each with the index of its leg (the root child it hangs from; more than `MAX_LEGS` share
/// the last).
fn contact_pairs(
    tgt: &Side<'_>,
    below: &[(BoneId, BoneId)],
    rt: BoneId,
    near: f32,
    y_t: &dyn Fn(BoneId) -> f32,
) -> Vec<(BoneId, BoneId, u8)> {
    let mut legs: Vec<BoneId> = Vec::new();
    below
        .iter()
        .copied()
        .filter(|(t, _)| y_t(*t) <= near)
        .map(|(t, s)| {
            // The leg: the root's child this joint hangs from.
            let mut top = t;
            while let Some(p) = tgt.parent(top).filter(|&p| p != rt) {
                top = p;
            }
            let leg = legs.iter().position(|&l| l == top).unwrap_or_else(|| {
                legs.push(top);
                legs.len() - 1
            });
            (t, s, leg.min(MAX_LEGS - 1) as u8)
        })
        .collect()
}

/// Per leg, the raised-contact offset of [`RootPlan::stand`]: the target's lowest contact joint's
/// height above `floor` (by `y_t`), less the source's matching joint's clearance in its
/// reference (`clear_s`) scaled, when the target's stands higher than [`RAISED_CONTACT`] of
/// the leg height `first`.
fn raised_contacts(
    contacts: &[(BoneId, BoneId, u8)],
    y_t: &dyn Fn(BoneId) -> f32,
    floor: f32,
    clear_s: impl Fn(BoneId) -> f32,
    scale: f32,
    first: f32,
) -> [f32; MAX_LEGS] {
    let mut lowest = [(f32::INFINITY, 0.0f32); MAX_LEGS];
    for &(t, s, leg) in contacts {
        let slot = &mut lowest[leg as usize];
        if y_t(t) < slot.0 {
            *slot = (y_t(t), clear_s(s));
        }
    }
    lowest.map(|(y, clear)| {
        let raised = y - floor;
        if y.is_finite() && raised > RAISED_CONTACT * first {
            (raised - scale * clear).max(0.0)
        } else {
            0.0
        }
    })
}

/// The topmost mapped pair on the leg above the foot pair (`t`, `s`): a target joint below
/// the root whose source joint lies on the source's path from its root down to `s` (the upper
/// legs), so both leg lengths are measured between joints mapped to each other.
fn top_pair(
    src: Side<'_>,
    tgt: Side<'_>,
    table: &MappingTable,
    rt: BoneId,
    rs: SourceRef,
    t: BoneId,
    s: BoneId,
) -> Option<(BoneId, BoneId)> {
    let mut best = None;
    let mut a = tgt.parent(t);
    while let Some(b) = a.filter(|&b| b != rt) {
        if let Some(sb) = primary(table, b).filter(|r| r.input == rs.input) {
            if sb.bone != rs.bone
                && align::is_descendant(src.skel, rs.bone, sb.bone)
                && align::is_descendant(src.skel, sb.bone, s)
            {
                best = Some((b, sb.bone));
            }
        }
        a = tgt.parent(b);
    }
    best
}

impl RetargetPlan {
    /// Moves the root vertically so the lowest foot joint stands as high above the target's
    /// floor as the source's stands above its floor (scaled): the legs' own geometry then sets
    /// the hips height, so different proportions neither float nor sink. Returns the root's
    /// move in the world (zero when it stays).
    pub(super) fn place_feet(&self, ctx: &mut RetargetContext, out: &mut Pose) -> Vec3 {
        let Some(root) = self.root.as_ref() else {
            return Vec3::ZERO;
        };
        if root.foot_contact == FootContact::Off
            || root.motion == RootMotion::Fixed
            || root.contacts.is_empty()
        {
            return Vec3::ZERO;
        }
        let dy = match (root.foot_contact, ctx.vertical_offset) {
            (FootContact::FirstFrame, Some(dy)) => dy,
            _ => {
                let dy = self.foot_offset(ctx);
                ctx.vertical_offset = Some(dy);
                dy
            }
        };
        let parent_rotation = match self.target.parent(root.bone) {
            Some(p) => ctx.scratch[p.index()].rotation,
            None => Quat::IDENTITY,
        };
        out.translations[root.bone.index()] += parent_rotation.inverse() * (root.up * dy);
        root.up * dy
    }

    /// The vertical move that puts the target's lowest foot joint at the scaled source height.
    fn foot_offset(&self, ctx: &RetargetContext) -> f32 {
        let Some(root) = self.root.as_ref() else {
            return 0.0;
        };
        let src = ctx.history[root.input as usize].get(0);
        let scale = root.scale;
        let floor_t = root.target_floor_y.unwrap_or(scale * root.source_floor_y);
        let mut lowest_s = [f32::INFINITY; MAX_LEGS];
        let mut lowest_t = [f32::INFINITY; MAX_LEGS];
        for &(t, s, leg) in &root.contacts {
            let leg = leg as usize;
            lowest_s[leg] = lowest_s[leg].min(src[s.index()].translation.dot(root.up));
            lowest_t[leg] = lowest_t[leg].min(ctx.scratch[t.index()].translation.dot(root.up));
        }
        let error = |leg: usize| {
            floor_t + root.stand[leg] + scale * (lowest_s[leg] - root.source_floor_y)
                - lowest_t[leg]
        };
        let legs = (0..MAX_LEGS).filter(|&l| lowest_t[l].is_finite());
        if root.foot_contact == FootContact::EveryFrame {
            // The lowest foot carries the weight: it decides.
            let low = legs.min_by(|&a, &b| lowest_t[a].total_cmp(&lowest_t[b]));
            low.map(error).unwrap_or(0.0)
        } else {
            // One calibration for all frames, from the feet that stand: a lifted foot's height
            // says how the legs bend, not where the floor is. Several planted feet split their
            // proportion mismatch.
            let planted_s = legs
                .clone()
                .map(|l| lowest_s[l])
                .fold(f32::INFINITY, f32::min)
                + PLANTED_M;
            let (sum, n) = legs
                .filter(|&l| lowest_s[l] <= planted_s)
                .fold((0.0, 0), |(sum, n), l| (sum + error(l), n + 1));
            if n > 0 {
                sum / n as f32
            } else {
                0.0
            }
        }
    }
}
