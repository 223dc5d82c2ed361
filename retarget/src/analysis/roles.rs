//! Roles and sections: the analysis pipeline over one posture (see the module diagram in
//! `analysis`). Each phase lives in its own file:
//!
//! ```text
//!   posture      which joint positions to read (rest, or frames of the motion)
//!   flat         joint sets without hierarchy (WebXR hands), read by names
//!   detached     the body root; control bones beside the body; feet they stand for
//!   frame        up and lateral axes
//!   centerline   central tree, limbs hanging off it, its longest path
//!   forward      facing (feet, bends, thumbs, lean), geometry over names
//!   sections     legs / arms / wings / appendages; spine, tail, head sections
//!   extremities  one limb: clavicle | upper | lower | hand or foot | digits
//!   roles        this pipeline, the limbs' order, helpers and controls
//! ```

use glam::Vec3;

use super::centerline::{centerline, central_and_limbs, oriented};
use super::context::{Builder, Ctx, Limb, LimbKind};
use super::detached::{self, BodyRoot};
use super::extremities::{limb_roles, LimbMember};
use super::names::{self, NameInfo};
use super::posture::{self, Posture};
use super::sections::{classify, trunk, Layout};
use super::topology::Topology;
use super::vocabulary::{Role, SectionKind};
use super::{flat, forward, frame, Analysis, BoneRole, Doubt, Section, SkeletonView};
use crate::skeleton::BoneId;

/// Analyses every candidate posture of the view and keeps the one that reads as the most
/// complete body (the first on ties: the rest pose, or the motion's medoid frame). A first
/// posture that reads as a two-legged, two-armed body is kept outright: a frame of the motion
/// can show a body a folded rest hides, but it is no better evidence than a rest that shows
/// one, and a mid-stride frame can read an extra bone where there is none (an end joint as a
/// head over a neck).
pub(crate) fn analyze_impl(view: &SkeletonView<'_>) -> Analysis {
    let mut best: Option<(usize, Analysis)> = None;
    for p in posture::candidates(view) {
        if best.as_ref().is_some_and(|(_, a)| a.humanoid) {
            break;
        }
        let a = analyze_posture(view, p);
        let score = coherence(&a);
        if best.as_ref().is_none_or(|(s, _)| score > *s) {
            best = Some((score, a));
        }
    }
    match best {
        Some((_, a)) => a,
        None => analyze_posture(view, posture::choose(view)),
    }
}

/// How completely an analysis reads as a body: the core roles found. Being read as a humanoid
/// earns nothing by itself: one frame of a quadruped's run can read as a standing biped with no
/// more roles than its rest reads as four legs, and the rest must then win the tie.
fn coherence(a: &Analysis) -> usize {
    a.roles.iter().filter(|r| r.role.is_core()).count()
}

/// The pipeline on one posture.
fn analyze_posture(view: &SkeletonView<'_>, posture: Posture) -> Analysis {
    let skel = view.skeleton;
    let pos = posture.positions.clone();
    let names: Vec<NameInfo> = skel.names().iter().map(|s| names::normalize(s)).collect();
    if flat::is_flat(skel.num_bones(), skel.roots().count()) {
        if let Some(a) = flat::analyze_flat_hand(skel, pos.clone(), names.clone()) {
            return a;
        }
    }
    let topo = Topology::build(skel, &pos);
    let body = detached::find(skel, &topo);
    let size = extent(&pos);
    let (up, lat) = frame::up_and_lateral(skel, &topo, &pos, &body, size);
    let extension = detached::extensions(skel, &pos, &body, up);
    let moving = posture::moving_bones(view);
    let ctx = Ctx {
        skel,
        extension: &extension,
        detached: &body.detached,
        pos: &pos,
        topo: &topo,
        names: &names,
        moving: moving.as_deref(),
        samples: &posture.samples,
        up,
        forward: Vec3::Z,
        size,
    };
    let read = read_body(ctx, &body, lat);
    let (facing, out) = (read.facing, read.out);
    Analysis {
        up,
        forward: facing.forward,
        left: up.cross(facing.forward).normalize_or_zero(),
        positions: pos,
        used_pose: posture.used_pose,
        posture_frame: posture.frame,
        size,
        lengths: topo.length.clone(),
        sections: out.sections,
        roles: out.roles,
        names,
        humanoid: read.humanoid,
        main_child: topo.main.clone(),
        warnings: facing.warnings,
        doubts: out.doubts,
    }
}

/// What one posture's body reads as: its facing and its roles.
struct BodyReading {
    facing: forward::Facing,
    out: Builder,
    humanoid: bool,
}

/// Reads the body from its centre line out: the central tree and the limbs off it, which way
/// it faces (the limbs' sides turned with it), the trunk's sections, then the limbs' roles,
/// helpers and the bones beside the body.
fn read_body(ctx: Ctx<'_>, body: &BodyRoot, lat: Vec3) -> BodyReading {
    let (ground, hext) = vertical_span(ctx.pos, ctx.up);
    let (central, mut limbs) = central_and_limbs(&ctx, body.root, lat, ground, hext);
    let path = centerline(&ctx, &central, &limbs);
    let facing = forward::facing(&ctx, &limbs, &path, ctx.samples, lat, (ground, hext));
    if facing.flipped {
        for m in limbs.iter_mut().flat_map(|l| l.members.iter_mut()) {
            m.1 = m.1.flipped();
        }
    }
    let ctx = Ctx {
        forward: facing.forward,
        ..ctx
    };
    let path = oriented(&ctx, path);
    let layout = classify(&ctx, &limbs, &path);
    let mut out = Builder::new(ctx.topo.length.clone());
    let head_sec = trunk(
        &ctx,
        &mut out,
        &path,
        &layout,
        &central,
        &limbs,
        (ground, hext),
    );
    let humanoid = place_limbs(&ctx, &mut out, &limbs, &layout, &path, head_sec);
    fill_helpers(&ctx, &mut out, &limbs);
    attach_detached(&ctx, body, &mut out);
    if let Some(doubt) = facing.doubt {
        push_facing_doubt(&ctx, &mut out, doubt);
    }
    BodyReading {
        facing,
        out,
        humanoid,
    }
}

/// A doubt on every sided bone: the facing vote (`cue`, of `strength`) was weak and no names
/// said which side is which.
fn push_facing_doubt(ctx: &Ctx<'_>, out: &mut Builder, (cue, strength): (f32, f32)) {
    let sided = ctx
        .skel
        .bone_ids()
        .filter(|b| out.roles[b.index()].side != super::Side::Center)
        .collect();
    out.doubts.push(Doubt {
        reason: format!(
            "its side rests on a weak facing vote ({cue:.2}; 2 is clear) and no names say it"
        ),
        strength,
        bones: sided,
    });
}

/// The lowest joint's height along `up` (the ground) and the joints' extent along it.
fn vertical_span(pos: &[Vec3], up: Vec3) -> (f32, f32) {
    let ground = pos.iter().map(|p| p.dot(up)).fold(f32::MAX, f32::min);
    let top = pos.iter().map(|p| p.dot(up)).fold(f32::MIN, f32::max);
    (ground, (top - ground).max(1e-3))
}

/// Largest extent of the joints' bounding box (the scale for tolerances).
fn extent(pos: &[Vec3]) -> f32 {
    let (lo, hi) = pos.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    (hi - lo).max_element().max(1e-3)
}

/// Sections and roles of every limb, pairs numbered upper / front-most first. Returns whether
/// the body is a humanoid: one pair of legs and one pair of arms that do not reach the ground.
fn place_limbs(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    limbs: &[Limb],
    layout: &Layout,
    path: &[BoneId],
    head_sec: Option<usize>,
) -> bool {
    let order = limb_order(limbs, path);
    // Where the legs hang from the midline, which an upright body's shoulders are no nearer to.
    let hips = limbs
        .iter()
        .zip(&layout.kinds)
        .filter(|(l, k)| **k == LimbKind::Leg && l.members.len() == 2)
        .find_map(|(l, _)| super::extremities::hips_offset(ctx, l.parent, &l.members));
    let mut counters = [0u8; 4];
    let mut humanoid_arms = 0;
    let mut humanoid_legs = 0;
    for &li in &order {
        let l = &limbs[li];
        let kind = layout.kinds[li];
        let slot = kind as usize;
        let limb_index = counters[slot];
        counters[slot] = counters[slot].saturating_add(1);
        match kind {
            // Arms that reach the ground are a quadruped's front legs.
            LimbKind::Arm if l.ground => humanoid_arms += 10,
            LimbKind::Arm => humanoid_arms += 1,
            LimbKind::Leg => humanoid_legs += 1,
            _ => {}
        }
        let parent_sec = out.section_of(l.parent);
        for &(m, side) in &l.members {
            if kind == LimbKind::Appendage {
                let at_head = head_sec.is_some() && out.roles[l.parent.index()].role == Role::Head;
                place_appendage(ctx, out, (l, m, side), parent_sec, at_head);
                continue;
            }
            limb_roles(
                ctx,
                out,
                LimbMember {
                    root: m,
                    side,
                    kind,
                    limb_index,
                    ground: l.ground,
                    parent_sec,
                    hips_offset: hips.filter(|_| kind == LimbKind::Arm && !l.ground),
                },
            );
        }
    }
    humanoid_legs == 1 && humanoid_arms == 1
}

/// Limb indices in numbering order: upper / front-most first (by where along the centre line
/// each hangs, then by height, then by parent for a stable order).
fn limb_order(limbs: &[Limb], path: &[BoneId]) -> Vec<usize> {
    let k_of = |b: BoneId| path.iter().position(|&x| x == b);
    let mut order: Vec<usize> = (0..limbs.len()).collect();
    order.sort_by(|&a, &b| {
        let ka = k_of(limbs[a].parent).unwrap_or(0);
        let kb = k_of(limbs[b].parent).unwrap_or(0);
        kb.cmp(&ka)
            .then(limbs[b].height.total_cmp(&limbs[a].height))
            .then(limbs[a].parent.cmp(&limbs[b].parent))
    });
    order
}

/// An appendage member `m` (of limb `l`, on `side`): its section, and its bones' roles; a small
/// pair hanging from the head (`on_head`) are eyes.
fn place_appendage(
    ctx: &Ctx<'_>,
    out: &mut Builder,
    (l, m, side): (&Limb, BoneId, super::Side),
    parent_sec: Option<usize>,
    on_head: bool,
) {
    let bones: Vec<BoneId> = ctx.subtree(m).collect();
    out.add_section(
        SectionKind::Appendage,
        side,
        0,
        bones.clone(),
        parent_sec,
        false,
    );
    let eye = on_head
        && ctx.topo.size[m.index()] <= 3
        && l.members.len() == 2
        && !ctx.names[m.index()].helper;
    for &b in &bones {
        out.set(b, Role::Appendage, 0.5);
    }
    if eye {
        out.set(m, Role::Eye, 0.6);
    }
}

/// Everything not placed yet: helpers (twist bones inside limbs), with the side of where they
/// hang.
fn fill_helpers(ctx: &Ctx<'_>, out: &mut Builder, limbs: &[Limb]) {
    let mut in_limb = vec![false; ctx.skel.num_bones()];
    for &(m, _) in limbs.iter().flat_map(|l| l.members.iter()) {
        for b in ctx.subtree(m) {
            in_limb[b.index()] = true;
        }
    }
    for b in ctx.skel.bone_ids() {
        let i = b.index();
        if out.roles[i].role != Role::Unknown {
            continue;
        }
        if let Some(p) = ctx.skel.parent(b) {
            let pr = out.roles[p.index()];
            out.roles[i] = BoneRole {
                role: if ctx.is_twist(b) && in_limb[i] {
                    Role::Twist
                } else {
                    Role::Helper
                },
                confidence: 0.3,
                ..pr
            };
        } else {
            out.roles[i].role = Role::Helper;
            out.roles[i].confidence = 0.3;
        }
    }
}

/// Detached bones that continue a leg ending without its foot (an IK foot under the root at
/// the end of a shin) take the foot's role; the other detached bones are controls, carriers
/// helpers.
fn attach_detached(ctx: &Ctx<'_>, body: &BodyRoot, out: &mut Builder) {
    let Builder {
        roles, sections, ..
    } = out;
    for l in ctx.skel.bone_ids() {
        let Some(b) = ctx.extension[l.index()] else {
            continue;
        };
        let lr = roles[l.index()];
        // Only feet: IK foot targets carry the foot's motion; hand controls are handles.
        let (role, kind) = match lr.role {
            Role::LowerLeg => (Role::Foot, SectionKind::Foot),
            _ => continue,
        };
        let parent = lr.section.map(|s| s as usize);
        let ground = parent.is_some_and(|p| sections[p].ground);
        roles[b.index()] = BoneRole {
            role,
            section: Some(sections.len() as u16),
            position: 0.0,
            confidence: lr.confidence * 0.8,
            ..lr
        };
        sections.push(Section {
            kind,
            side: lr.side,
            limb: lr.limb,
            bones: vec![b],
            length: 0.0,
            parent,
            ground,
        });
    }
    // Which bones some limb extends to, marked once (a search per bone is quadratic in wide rigs).
    let mut extended = vec![false; ctx.skel.num_bones()];
    for e in ctx.extension.iter().flatten() {
        extended[e.index()] = true;
    }
    for b in ctx.skel.bone_ids() {
        let attached = extended[b.index()] && roles[b.index()].role == Role::Foot;
        if ctx.detached[b.index()] && !attached {
            roles[b.index()].role = Role::Control;
            roles[b.index()].confidence = 0.5;
        }
    }
    // Carriers (an armature node, UE's `root`) carry the root motion of some rigs: helpers,
    // which map onto the other rig's carrier.
    for &c in &body.carriers {
        roles[c.index()].role = Role::Helper;
        roles[c.index()].confidence = 0.5;
    }
}
