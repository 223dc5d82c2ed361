//! Automatic mapping: seed 004's weighted metrics plus name and section-graph evidence.
//!
//! ```text
//!   analyze(source…), analyze(target)                 roles, sides, sections
//!   for every target bone (parents first), every source bone of every input:
//!       score = side 30 + type 50 | similar 15 + bone count 10 + orientation ≤15
//!             + sequence 16 (same role, else by position along the section)
//!             + name ≤20 + section-graph structure ≤10 + continuity 5 + preference 10
//!   best candidate ≥ threshold → entry (score + the evidence that decided it)
//!   duplicate removal: a source bone drives at most one target bone (the best-scoring;
//!   positions along sections are length ratios, so the survivors keep their order)
//! ```
//!
//! Helper roles (twist, end joints, mechanism bones) only ever map onto the same role, so a
//! twist bone is never driven by a full limb rotation on top of its parent's, and only onto a
//! helper that hangs alike: above the hips (an armature root carries the whole body) or in a
//! section of the same kind (a toe's end never drives a finger's).
//! Everything is polynomial: O(target × source) scoring, and the section graph comparison runs
//! on sections (tens of nodes), never on bones, so no NP-hard graph edit distance is needed.

use std::collections::BTreeMap;

use glam::Vec3;
use petgraph::graph::{DiGraph, NodeIndex};
use petgraph::visit::Dfs;
use serde::{Deserialize, Serialize};

use super::candidate::Candidate;
use super::table::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use crate::analysis::{analyze, names, Analysis, Role, SectionKind, Side, SkeletonView};
use crate::skeleton::{BoneId, Skeleton};

/// Weights of the metrics (seed 004 table 1 defaults, plus name and structure).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Weights {
    /// Same body side.
    pub side: f32,
    /// Same section type.
    pub same_type: f32,
    /// Similar section type (arm/leg, hand/foot, arm/wing, spine/tail).
    pub similar_type: f32,
    /// Equal number of bones in the two sections.
    pub bone_count: f32,
    /// Bone orientation (quadratic falloff to 0 at `orientation_max_deg`).
    pub orientation: f32,
    /// Angle (degrees) where the orientation metric reaches zero.
    pub orientation_max_deg: f32,
    /// Same position within the section (by length ratio).
    pub sequence: f32,
    /// Same anatomical role from the analysis (hand = hand); the analysis folds structure,
    /// geometry and proportions into it, so it is the strongest single piece of evidence.
    pub role: f32,
    /// Multi-source: same input as the parent bone's match.
    pub continuity: f32,
    /// Multi-source: the preferred input.
    pub preference: f32,
    /// Name token similarity (0..1) times this.
    pub name: f32,
    /// Section-graph structure agreement (path of section kinds from the root, child count).
    pub structure: f32,
}

impl Default for Weights {
    fn default() -> Self {
        Weights {
            side: 30.0,
            same_type: 50.0,
            similar_type: 15.0,
            bone_count: 10.0,
            orientation: 15.0,
            orientation_max_deg: 15.0,
            sequence: 16.0,
            role: 30.0,
            continuity: 5.0,
            preference: 10.0,
            name: 20.0,
            structure: 10.0,
        }
    }
}

/// Options of the automatic mapper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MapOptions {
    /// Minimum total score for a match. The default maps same-type sections and leaves
    /// similar-type ones (wings ← arms, tail ← spine) unmapped, as in seed 004.
    pub threshold: f32,
    /// A source bone drives at most one target bone (seed 004's duplicate-bone removal).
    pub remove_duplicates: bool,
    /// Flip the sides of every second limb pair of multi-legged targets (diagonal gaits).
    pub mirror: bool,
    /// Metric weights.
    pub weights: Weights,
    /// Multi-source: input that gets the preference bonus.
    pub preferred_source: Option<u16>,
    /// Multi-source: also blend in other inputs whose best candidate scores within
    /// `blend_margin` of the winner (many-to-one, equal weights).
    pub blend_sources: bool,
    /// Score margin for `blend_sources`.
    pub blend_margin: f32,
    /// Per target bone (by name): delay / reverse / weight applied to its entry.
    pub bone_options: BTreeMap<String, BoneOptions>,
}

impl Default for MapOptions {
    fn default() -> Self {
        MapOptions {
            threshold: 70.0,
            remove_duplicates: true,
            mirror: false,
            weights: Weights::default(),
            preferred_source: None,
            blend_sources: false,
            blend_margin: 10.0,
            bone_options: BTreeMap::new(),
        }
    }
}

impl MapOptions {
    /// Stable hash of the options (cache key part). Uses the TOML text of the options, so it
    /// is stable across runs and Rust versions.
    pub fn stable_hash(&self) -> u64 {
        let text = toml::to_string(self).unwrap_or_default();
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in text.bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        h
    }

    /// Highest score a match can reach with these weights (used to normalise to 0..1).
    pub fn max_score(&self) -> f32 {
        let w = &self.weights;
        w.side
            + w.same_type
            + w.bone_count
            + w.orientation
            + w.sequence
            + w.role
            + w.name
            + w.structure
    }
}

/// Maps one source skeleton onto a target.
pub fn auto_map(
    source: &SkeletonView<'_>,
    target: &SkeletonView<'_>,
    opts: &MapOptions,
) -> MappingTable {
    auto_map_many(std::slice::from_ref(source), target, opts)
}

/// Maps several source skeletons onto one target (many-to-one; `SourceRef::input` indexes
/// `sources`).
pub fn auto_map_many(
    sources: &[SkeletonView<'_>],
    target: &SkeletonView<'_>,
    opts: &MapOptions,
) -> MappingTable {
    let analyses: Vec<Analysis> = sources.iter().map(analyze).collect();
    let ta = analyze(target);
    let src: Vec<(&Skeleton, &Analysis)> = sources
        .iter()
        .zip(&analyses)
        .map(|(v, a)| (v.skeleton, a))
        .collect();
    map_analyzed(&src, (target.skeleton, &ta), opts)
}

/// Section signature for structural evidence: kinds on the path from the root section and the
/// number of child sections, computed on a petgraph section graph.
struct SectionGraph {
    kind_path: Vec<Vec<SectionKind>>,
    num_children: Vec<usize>,
}

impl SectionGraph {
    fn new(a: &Analysis) -> SectionGraph {
        let mut g: DiGraph<SectionKind, ()> = DiGraph::new();
        let nodes: Vec<NodeIndex> = a.sections.iter().map(|s| g.add_node(s.kind)).collect();
        for (i, s) in a.sections.iter().enumerate() {
            if let Some(p) = s.parent {
                g.add_edge(nodes[p], nodes[i], ());
            }
        }
        let n = a.sections.len();
        let mut kind_path: Vec<Vec<SectionKind>> = vec![Vec::new(); n];
        for (i, s) in a.sections.iter().enumerate() {
            if s.parent.is_some() {
                continue;
            }
            let mut dfs = Dfs::new(&g, nodes[i]);
            kind_path[i] = vec![s.kind];
            while let Some(nx) = dfs.next(&g) {
                let idx = nx.index();
                for c in g.neighbors(nx) {
                    let mut p = kind_path[idx].clone();
                    p.push(g[c]);
                    kind_path[c.index()] = p;
                }
            }
        }
        let num_children = nodes.iter().map(|&nx| g.neighbors(nx).count()).collect();
        SectionGraph {
            kind_path,
            num_children,
        }
    }
}

fn family(r: Role) -> u8 {
    match r {
        Role::Hips | Role::Spine | Role::SpineMid | Role::Chest => 1,
        Role::Neck(_) | Role::Head => 2,
        Role::Tail(_) => 3,
        Role::Finger { .. } => 4,
        _ => 0,
    }
}

/// Maps already-analysed skeletons (lets callers reuse analyses).
pub fn map_analyzed(
    sources: &[(&Skeleton, &Analysis)],
    target: (&Skeleton, &Analysis),
    opts: &MapOptions,
) -> MappingTable {
    let (tskel, ta) = target;
    let scorer = Scorer::new(sources, target, opts);
    let mut table = MappingTable::empty(tskel.num_bones());
    let mut chosen_input: Vec<Option<u16>> = vec![None; tskel.num_bones()];
    let mut per_target: Vec<Vec<Candidate>> = (0..tskel.num_bones()).map(|_| Vec::new()).collect();
    for t in tskel.bone_ids() {
        if ta.roles[t.index()].role == Role::Unknown {
            continue;
        }
        let parent_input = tskel.parent(t).and_then(|p| chosen_input[p.index()]);
        let cands = scorer.candidates(t, parent_input);
        chosen_input[t.index()] = cands.first().map(|c| c.input);
        per_target[t.index()] = cands;
    }
    let picked = assign(&per_target, opts.remove_duplicates);
    fill_table(&mut table, tskel, &per_target, &picked, opts);
    super::confidence::assess(&mut table, &per_target, &picked, sources, target);
    table
}

/// What scoring a (target bone, source bone) pair looks at, computed once per mapping: the
/// skeletons, their analyses, section graphs and body directions.
struct Scorer<'a> {
    sources: &'a [(&'a Skeleton, &'a Analysis)],
    ta: &'a Analysis,
    opts: &'a MapOptions,
    tgraph: SectionGraph,
    sgraphs: Vec<SectionGraph>,
    tdirs: Vec<Vec3>,
    sdirs: Vec<Vec<Vec3>>,
    /// More than two ground limbs: a quadruped's (or insect's) legs, whose sides may mirror.
    multi_legged: bool,
    /// The orientation term's cut-off angle, radians.
    max_angle: f32,
    /// Per bone of the target and of each source: whether it hangs above the hips
    /// ([`above_hips`]).
    t_above: Vec<bool>,
    s_above: Vec<Vec<bool>>,
}

/// Per bone of `skel`: whether it is an ancestor of the bone `a` reads as the hips (an
/// armature root, a ground bone the body hangs from), all false without hips. A helper there
/// carries the whole body; one anywhere else (a head's end, a twist bone) carries nothing.
fn above_hips(skel: &Skeleton, a: &Analysis) -> Vec<bool> {
    let mut above = vec![false; skel.num_bones()];
    let hips = skel
        .bone_ids()
        .find(|b| a.roles[b.index()].role == Role::Hips);
    let mut b = hips.and_then(|h| skel.parent(h));
    while let Some(p) = b {
        above[p.index()] = true;
        b = skel.parent(p);
    }
    above
}

impl<'a> Scorer<'a> {
    fn new(
        sources: &'a [(&'a Skeleton, &'a Analysis)],
        (tskel, ta): (&'a Skeleton, &'a Analysis),
        opts: &'a MapOptions,
    ) -> Scorer<'a> {
        Scorer {
            sources,
            ta,
            opts,
            tgraph: SectionGraph::new(ta),
            sgraphs: sources.iter().map(|(_, a)| SectionGraph::new(a)).collect(),
            tdirs: tskel
                .bone_ids()
                .map(|b| ta.body_direction(tskel, b))
                .collect(),
            sdirs: sources
                .iter()
                .map(|(s, a)| s.bone_ids().map(|b| a.body_direction(s, b)).collect())
                .collect(),
            multi_legged: ta
                .sections
                .iter()
                .filter(|s| s.ground && matches!(s.kind, SectionKind::Arm | SectionKind::Leg))
                .count()
                > 2,
            max_angle: opts.weights.orientation_max_deg.to_radians(),
            t_above: above_hips(tskel, ta),
            s_above: sources.iter().map(|(s, a)| above_hips(s, a)).collect(),
        }
    }

    /// Every source's best candidates for target bone `t`, best first (at most
    /// `KEEP_PER_INPUT` per source). `parent_input`: the source chosen for `t`'s parent.
    fn candidates(&self, t: BoneId, parent_input: Option<u16>) -> Vec<Candidate> {
        let tside = self.target_side(t);
        let mut cands: Vec<Candidate> = Vec::new();
        for (input, (sskel, _)) in self.sources.iter().enumerate() {
            let mut best: Vec<Candidate> = sskel
                .bone_ids()
                .filter_map(|s| self.score(t, tside, parent_input, input, s))
                .filter(|c| c.score >= self.opts.threshold)
                .collect();
            best.sort_by(|a, b| b.score.total_cmp(&a.score));
            best.truncate(KEEP_PER_INPUT);
            cands.extend(best);
        }
        cands.sort_by(|a, b| b.score.total_cmp(&a.score));
        cands
    }

    /// The side `t` should be matched on: with `mirror` on a multi-legged target, front limbs
    /// and every second ground limb take the other side (a walker's left arm drives the right
    /// foreleg, as in a diagonal gait).
    fn target_side(&self, t: BoneId) -> Side {
        let tr = self.ta.roles[t.index()];
        let Some(sec) = tr.section.map(|s| &self.ta.sections[s as usize]) else {
            return tr.side;
        };
        if !(self.opts.mirror && self.multi_legged) {
            return tr.side;
        }
        let front = sec.ground
            && matches!(
                sec.kind,
                SectionKind::Arm | SectionKind::Hand | SectionKind::Digit
            );
        if front || (sec.ground && sec.limb % 2 == 1) {
            tr.side.flipped()
        } else {
            tr.side
        }
    }

    /// The score of source bone `s` (of source `input`) for target bone `t`, with the
    /// evidence behind it; `None` when `s` may not drive `t` at all.
    fn score(
        &self,
        t: BoneId,
        tside: Side,
        parent_input: Option<u16>,
        input: usize,
        s: BoneId,
    ) -> Option<Candidate> {
        let (w, sa) = (&self.opts.weights, self.sources[input].1);
        let (tr, sr) = (self.ta.roles[t.index()], sa.roles[s.index()]);
        if !may_drive(sr.role, tr.role) {
            return None;
        }
        if (tr.role.is_helper() || sr.role.is_helper()) && !self.hang_alike(t, input, s) {
            return None;
        }
        let mut score = 0.0;
        let mut ev = Vec::new();
        if sr.side == tside {
            score += w.side;
            ev.push(format!("side={}", side_name(tside)));
        }
        score += self.section_score(t, input, s, &mut ev);
        score += role_score(w, tr.role, sr.role, tr.position - sr.position, &mut ev);
        score += self.orientation_score(t, input, s, &mut ev);
        let ns = names::similarity(&self.ta.names[t.index()], &sa.names[s.index()]);
        if ns > 0.0 {
            score += w.name * ns;
            ev.push(format!("name:{ns:.2}"));
        }
        if parent_input == Some(input as u16) && self.sources.len() > 1 {
            score += w.continuity;
        }
        if self.opts.preferred_source == Some(input as u16) {
            score += w.preference;
            ev.push("preferred".into());
        }
        // Ties: the closer position along the section, then the closer length ratio.
        let tie = (tr.position - sr.position).abs() * 1e-3
            + (rel_len(self.ta, t) - rel_len(sa, s)).abs() * 1e-3;
        Some(Candidate {
            input: input as u16,
            bone: s,
            score: score - tie,
            evidence: ev,
        })
    }

    /// Whether target bone `t` and source bone `s` (of source `input`) hang alike: both above
    /// the hips ([`above_hips`]), or neither and in sections of the same kind (or both in
    /// none). Helpers match by role alone, so by where they hang too: a helper above the hips
    /// (an armature root) driven by one elsewhere moved the whole character with it (LaFAN1's
    /// and Xia's zero-length head ends carried the roots of Casual, both robots and the
    /// Bandai-Namco rig: their feet from 1 m under their ground to 2 m over it), and a
    /// finger's end driven by a toe's end (LaFAN1's, onto RobotExpressive) was taken for a
    /// foot: its arm's length made the legs' ratio 2.88, not 1.79.
    fn hang_alike(&self, t: BoneId, input: usize, s: BoneId) -> bool {
        let sa = self.sources[input].1;
        let above = self.t_above[t.index()];
        if above != self.s_above[input][s.index()] {
            return false;
        }
        let kind = |a: &Analysis, b: BoneId| {
            (a.roles[b.index()].section).map(|i| a.sections[i as usize].kind)
        };
        above || kind(self.ta, t) == kind(sa, s)
    }

    /// Section kind, bone count and place in the section tree of `t` and `s` alike.
    fn section_score(&self, t: BoneId, input: usize, s: BoneId, ev: &mut Vec<String>) -> f32 {
        let (w, sa) = (&self.opts.weights, self.sources[input].1);
        let (tr, sr) = (self.ta.roles[t.index()], sa.roles[s.index()]);
        let (Some(ti), Some(si)) = (tr.section, sr.section) else {
            return 0.0;
        };
        let (a, b) = (&self.ta.sections[ti as usize], &sa.sections[si as usize]);
        let mut score = 0.0;
        if a.kind == b.kind {
            let k = if a.limb == b.limb { 1.0 } else { 0.2 };
            score += w.same_type * k;
            ev.push(format!("type={}", a.kind.name()));
        } else if a.kind.similar(b.kind) {
            score += w.similar_type;
            ev.push(format!("similar={}~{}", a.kind.name(), b.kind.name()));
        }
        if a.bones.len() == b.bones.len() {
            score += w.bone_count;
        }
        let (tg, sg) = (&self.tgraph, &self.sgraphs[input]);
        let (tp, sp) = (&tg.kind_path[ti as usize], &sg.kind_path[si as usize]);
        let common = tp.iter().zip(sp).take_while(|(x, y)| x == y).count();
        let mut st = common as f32 / tp.len().max(sp.len()).max(1) as f32;
        if tg.num_children[ti as usize] == sg.num_children[si as usize] {
            st = (st + 0.25).min(1.0);
        }
        if st >= 0.99 {
            ev.push("structure".into());
        }
        score + w.structure * st
    }

    /// How closely `t` and `s` point the same way in their bodies' frames.
    fn orientation_score(&self, t: BoneId, input: usize, s: BoneId, ev: &mut Vec<String>) -> f32 {
        let (dt, ds) = (self.tdirs[t.index()], self.sdirs[input][s.index()]);
        if dt == Vec3::ZERO || ds == Vec3::ZERO {
            return 0.0;
        }
        let ang = dt.dot(ds).clamp(-1.0, 1.0).acos();
        let o = self.opts.weights.orientation * (1.0 - (ang / self.max_angle).powi(2)).max(0.0);
        if o > 0.0 {
            ev.push("orientation".into());
        }
        o
    }
}

/// Same role (and so the same place in its section), else partial credit by position along
/// the section (`position_gap`: target's minus source's, as length ratios).
fn role_score(
    w: &Weights,
    target: Role,
    source: Role,
    position_gap: f32,
    ev: &mut Vec<String>,
) -> f32 {
    if target == source {
        ev.push(format!("role={}", target.name()));
        return w.role + w.sequence;
    }
    let same_family = family(target) != 0 && family(target) == family(source);
    let finger_digit = matches!((target, source), (Role::Finger { digit: a, .. }, Role::Finger { digit: b, .. }) if a == b);
    let k = if same_family || finger_digit {
        2.0
    } else {
        4.0
    };
    0.5 * w.sequence * (1.0 - k * position_gap.abs()).max(0.0)
}

/// Whether a source bone of role `source` may drive a target bone of role `target` at all.
fn may_drive(source: Role, target: Role) -> bool {
    let (sr, tr) = (source, target);
    // Unknown bones and controls (IK / pole targets, armature roots) drive nothing:
    // a rotation copied onto an IK handle moves no limb.
    if matches!(sr, Role::Unknown | Role::Control) || tr == Role::Control {
        return false;
    }
    // Helpers only map onto the same helper role; anatomy never maps onto helpers.
    if (tr.is_helper() || sr.is_helper()) && tr != sr {
        return false;
    }
    let face = |r: Role| matches!(r, Role::Eye | Role::Jaw);
    !(face(tr) != face(sr) || (face(tr) && tr != sr))
}

/// Which candidate each target bone takes (an index into its list, `None`: unmapped).
fn assign(per_target: &[Vec<Candidate>], remove_duplicates: bool) -> Vec<Option<usize>> {
    // Assignment. With duplicate removal every source bone drives at most one target bone:
    // a greedy matching on the global score order (the best pairs are fixed first, a loser
    // falls back to its next candidate instead of going unmapped).
    let mut used: std::collections::HashSet<(u16, BoneId)> = std::collections::HashSet::new();
    let mut picked: Vec<Option<usize>> = vec![None; per_target.len()];
    if remove_duplicates {
        let mut all: Vec<(f32, usize, usize)> = Vec::new();
        for (t, cs) in per_target.iter().enumerate() {
            for (k, c) in cs.iter().enumerate() {
                all.push((c.score, t, k));
            }
        }
        all.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for (_, t, k) in all {
            let c = &per_target[t][k];
            if picked[t].is_some() || used.contains(&(c.input, c.bone)) {
                continue;
            }
            used.insert((c.input, c.bone));
            picked[t] = Some(k);
        }
    } else {
        for (t, cs) in per_target.iter().enumerate() {
            if !cs.is_empty() {
                picked[t] = Some(0);
            }
        }
    }
    picked
}

/// The table entries of the picked candidates (with other inputs' close seconds blended in
/// when asked).
fn fill_table(
    table: &mut MappingTable,
    tskel: &Skeleton,
    per_target: &[Vec<Candidate>],
    picked: &[Option<usize>],
    opts: &MapOptions,
) {
    for t in tskel.bone_ids() {
        let Some(k) = picked[t.index()] else { continue };
        let cs = &per_target[t.index()];
        let top = &cs[k];
        let mut refs = vec![SourceRef {
            input: top.input,
            bone: top.bone,
            weight: 1.0,
        }];
        if opts.blend_sources {
            for c in cs.iter() {
                let other_input = c.input != top.input && !refs.iter().any(|r| r.input == c.input);
                if other_input && c.score >= top.score - opts.blend_margin {
                    refs.push(SourceRef {
                        input: c.input,
                        bone: c.bone,
                        weight: 1.0,
                    });
                }
            }
        }
        table.entries[t.index()] = Some(TargetEntry {
            sources: refs,
            options: opts
                .bone_options
                .get(tskel.name(t))
                .copied()
                .unwrap_or_default(),
            score: top.score,
            evidence: top.evidence.clone(),
            confidence: 1.0,
        });
    }
}

/// Candidates kept per target bone and source input (enough for duplicate fallback).
const KEEP_PER_INPUT: usize = 6;

fn rel_len(a: &Analysis, b: BoneId) -> f32 {
    let r = a.roles[b.index()];
    match r.section {
        Some(s) => {
            let sec = &a.sections[s as usize];
            if sec.length > 1e-6 {
                a.lengths[b.index()] / sec.length
            } else {
                0.0
            }
        }
        None => 0.0,
    }
}

fn side_name(s: Side) -> &'static str {
    match s {
        Side::Left => "left",
        Side::Right => "right",
        Side::Center => "center",
    }
}
