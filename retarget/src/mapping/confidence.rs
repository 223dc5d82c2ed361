//! How sure the mapper is of each target bone, from the margins of its own evidence (never
//! from labels).
//!
//! ```text
//!   margin     = chosen score − the best alternative, the smaller of:
//!                  the target's next candidate with another source bone, and
//!                  the best score another target bone gave the same source bone
//!   confidence = (1 − e^(−margin / MARGIN_SCALE)) × (1 − doubt)   for each analysis' doubt
//!                over the target bone's and the source bone's readings
//!   flagged    = margin confidence < FLAG_BELOW, the runner-up within CLOSE_MARGIN points,
//!                or a doubt of at least DOUBT_FLAG (helpers too: a doubted end marker may
//!                be the head);
//!                unmapped: a core target bone, a gap in a driven chain (parent and a
//!                body-part descendant driven), or a bone of a section kind whose source core bone
//!                drives nothing (the source's head unused while the target's head chain
//!                has an undriven bone)
//! ```
//!
//! The analyses' own role confidences are not used: they are rules' guesses, not measured
//! (a right leg read at 0.3), and multiplying them in made right bones look doubtful. Their
//! doubts are (`Analysis::doubts`): a competing reading and how close it came, which a margin
//! between source bones cannot see (sides resting on a weak facing vote, a limb bone that
//! another split of its chain nearly as cheap reads otherwise). A reading whose doubt is short
//! of a coin toss lowers the confidence without flagging.
//!
//! A chosen pair whose closest rival is far behind, between bones whose roles the analyses
//! are sure of, is confident; a pair that won by a point, or whose source bone another target
//! bone wanted nearly as much, is not. The scale and cut-offs are in score points, the
//! weights' own units (a name or an orientation term is worth 15–20 points).

use std::collections::HashMap;

use super::candidate::Candidate;
use super::table::{Flag, MappingTable};
use crate::analysis::{Analysis, Doubt, Role, SectionKind};
use crate::skeleton::{BoneId, Skeleton};

/// Score points over which a margin's confidence rises to 63 % (1 − 1/e).
const MARGIN_SCALE: f32 = 12.0;
/// Confidence below which a bone is flagged.
const FLAG_BELOW: f32 = 0.35;
/// A runner-up within this many points of the chosen source flags the bone.
const CLOSE_MARGIN: f32 = 4.0;
/// An analysis' doubt at least this strong over either bone's reading flags the bone.
const DOUBT_FLAG: f32 = 0.9;

/// Per (input, source bone): the two best (score, target) pairs over every target's
/// candidates.
type Rivals = HashMap<(u16, BoneId), [(f32, usize); 2]>;

fn rivals(per_target: &[Vec<Candidate>]) -> Rivals {
    let mut out: Rivals = HashMap::new();
    for (t, cs) in per_target.iter().enumerate() {
        for c in cs {
            let e = out
                .entry((c.input, c.bone))
                .or_insert([(f32::MIN, usize::MAX); 2]);
            if c.score > e[0].0 {
                e[1] = e[0];
                e[0] = (c.score, t);
            } else if c.score > e[1].0 {
                e[1] = (c.score, t);
            }
        }
    }
    out
}

/// The margin of target `t`'s chosen candidate `k` over its best alternative.
fn margin(per_target: &[Vec<Candidate>], rivals: &Rivals, t: usize, k: usize) -> f32 {
    let cs = &per_target[t];
    let top = &cs[k];
    let own = cs
        .iter()
        .filter(|c| (c.input, c.bone) != (top.input, top.bone))
        .map(|c| c.score)
        .fold(f32::MIN, f32::max);
    let other = rivals
        .get(&(top.input, top.bone))
        .map(|r| if r[0].1 == t { r[1].0 } else { r[0].0 })
        .unwrap_or(f32::MIN);
    let rival = own.max(other);
    if rival == f32::MIN {
        // No alternative at all: as sure as the score itself allows.
        MARGIN_SCALE * 4.0
    } else {
        top.score - rival
    }
}

/// Per bone: the strongest of the analysis' doubts over its reading, if any (one pass over
/// the doubts' bones, not a search per bone).
fn doubts_per_bone(a: &Analysis) -> Vec<Option<&Doubt>> {
    let mut out: Vec<Option<&Doubt>> = vec![None; a.roles.len()];
    for d in &a.doubts {
        for b in &d.bones {
            if let Some(slot) = out.get_mut(b.index()) {
                if slot.is_none_or(|s| d.strength > s.strength) {
                    *slot = Some(d);
                }
            }
        }
    }
    out
}

/// Sets every mapped entry's confidence and the table's flagged bones.
pub(super) fn assess(
    table: &mut MappingTable,
    per_target: &[Vec<Candidate>],
    picked: &[Option<usize>],
    sources: &[(&Skeleton, &Analysis)],
    (tskel, ta): (&Skeleton, &Analysis),
) {
    let rivals = rivals(per_target);
    let unused = unused_core_kinds(picked, per_target, sources);
    let below = driven_below(table, tskel, ta);
    let tdoubt = doubts_per_bone(ta);
    let sdoubt: Vec<Vec<Option<&Doubt>>> =
        sources.iter().map(|(_, a)| doubts_per_bone(a)).collect();
    table.flagged.clear();
    for t in tskel.bone_ids() {
        let tr = ta.roles[t.index()];
        let Some(k) = picked[t.index()] else {
            if let Some(reason) = unmapped_reason(table, tskel, ta, &unused, &below, t) {
                table.flagged.push(Flag {
                    bone: t,
                    confidence: 0.0,
                    reason,
                });
            }
            continue;
        };
        let m = margin(per_target, &rivals, t.index(), k);
        let chosen = &per_target[t.index()][k];
        let doubt = pair_doubts(tdoubt[t.index()], &sdoubt, chosen);
        let sure: f32 = doubt
            .iter()
            .filter_map(|(d, _)| d.map(|d| 1.0 - d.strength.clamp(0.0, 1.0)))
            .product();
        let from_margin = 1.0 - (-m.max(0.0) / MARGIN_SCALE).exp();
        let c = from_margin * sure;
        if let Some(e) = table.entries[t.index()].as_mut() {
            e.confidence = c;
        }
        // Helpers are not checked, unless the analysis nearly read the bone as a body part
        // (a head read as the skull top's end marker).
        let doubted = doubt
            .iter()
            .any(|(d, _)| d.is_some_and(|d| d.strength >= DOUBT_FLAG));
        if (tr.role.is_helper() && !doubted) || matches!(tr.role, Role::Unknown | Role::Control) {
            continue;
        }
        let Some(reason) = flag_reason(m, &doubt, from_margin, c) else {
            continue;
        };
        table.flagged.push(Flag {
            bone: t,
            confidence: c,
            reason,
        });
    }
}

/// The analyses' doubts over a mapped pair's readings: the target bone's (`target`), then its
/// chosen source bone's.
fn pair_doubts<'a>(
    target: Option<&'a Doubt>,
    sources: &[Vec<Option<&'a Doubt>>],
    chosen: &Candidate,
) -> [(Option<&'a Doubt>, &'static str); 2] {
    let source = sources
        .get(chosen.input as usize)
        .and_then(|d| d.get(chosen.bone.index()).copied().flatten());
    [(target, "the target"), (source, "the source")]
}

/// Why a mapped bone is flagged, if it is: its margin `m` over the runner-up (negative when its
/// best source went elsewhere), the analyses' doubts (the target's, the source's), the
/// confidence from the margin alone and the whole confidence `c`.
fn flag_reason(
    m: f32,
    doubt: &[(Option<&Doubt>, &str); 2],
    from_margin: f32,
    c: f32,
) -> Option<String> {
    Some(if m < 0.0 {
        format!(
            "its best source bone went to another bone ({:.1} points)",
            -m
        )
    } else if m < CLOSE_MARGIN {
        format!("the runner-up is {m:.1} points behind")
    } else if let Some((d, whose)) = doubt
        .iter()
        .filter_map(|(d, w)| d.map(|d| (d, w)))
        .filter(|(d, _)| d.strength >= DOUBT_FLAG)
        .max_by(|x, y| x.0.strength.total_cmp(&y.0.strength))
    {
        format!("{whose}'s analysis doubts its reading: {}", d.reason)
    } else if from_margin < FLAG_BELOW {
        format!("low confidence {c:.2} (margin {m:.1} points)")
    } else {
        return None;
    })
}

/// Section kinds in which some source's core bone drives nothing.
fn unused_core_kinds(
    picked: &[Option<usize>],
    per_target: &[Vec<Candidate>],
    sources: &[(&Skeleton, &Analysis)],
) -> Vec<SectionKind> {
    let used: std::collections::HashSet<(u16, BoneId)> = picked
        .iter()
        .enumerate()
        .filter_map(|(t, k)| k.map(|k| &per_target[t][k]))
        .map(|c| (c.input, c.bone))
        .collect();
    let mut kinds = Vec::new();
    for (input, (skel, a)) in sources.iter().enumerate() {
        for b in skel.bone_ids() {
            let r = a.roles[b.index()];
            let Some(sec) = r.section.map(|s| a.sections[s as usize].kind) else {
                continue;
            };
            if r.role.is_core() && !used.contains(&(input as u16, b)) && !kinds.contains(&sec) {
                kinds.push(sec);
            }
        }
    }
    kinds
}

/// Per target bone: whether a driven body part (not a helper or end marker) lies anywhere
/// below it. One pass from the leaves up (parents come before their children), so a rig of
/// thousands of bones costs a walk, not a search per bone.
fn driven_below(table: &MappingTable, tskel: &Skeleton, ta: &Analysis) -> Vec<bool> {
    let mut below = vec![false; tskel.num_bones()];
    let ids: Vec<BoneId> = tskel.bone_ids().collect();
    for &d in ids.iter().rev() {
        let here = table.entries[d.index()].is_some() && !ta.roles[d.index()].role.is_helper();
        if let Some(p) = tskel.parent(d) {
            below[p.index()] |= here || below[d.index()];
        }
    }
    below
}

/// Why an unmapped target bone should be checked, if it should (`below`: [`driven_below`]).
fn unmapped_reason(
    table: &MappingTable,
    tskel: &Skeleton,
    ta: &Analysis,
    unused: &[SectionKind],
    below: &[bool],
    t: BoneId,
) -> Option<String> {
    let tr = ta.roles[t.index()];
    if tr.role == Role::Control {
        return None;
    }
    if tr.role.is_core() {
        return Some(format!(
            "no source bone drives its role ({})",
            tr.role.name()
        ));
    }
    let driven = |b: BoneId| table.entries[b.index()].is_some();
    let parent_driven = tskel.parent(t).is_some_and(driven);
    // A driven body part below (end markers and helpers below do not count).
    if parent_driven && below[t.index()] {
        return Some("undriven between driven bones".into());
    }
    let kind = tr.section.map(|s| ta.sections[s as usize].kind);
    let chain_bone = matches!(kind, Some(SectionKind::Head | SectionKind::Spine));
    (chain_bone && parent_driven && kind.is_some_and(|k| unused.contains(&k))).then(|| {
        format!(
            "undriven while a source's core {} bone drives nothing",
            kind.map_or("", |k| k.name())
        )
    })
}
