//! The mapping plan: analyze → map → overrides → posture, written once for every caller.

use rigcast_retarget::analysis::{analyze_with_truth, standing_posture, Analysis, SkeletonView};
use rigcast_retarget::mapping::{
    apply_overrides, map_analyzed, posture_relative, CacheKey, MapOptions, MappingFile,
    MappingTable,
};
use rigcast_retarget::{BoneId, Clip, Follow, Pose, RetargetOptions, RootMotion, Skeleton};

use super::OfflineError;

/// A ground-truth humanoid map (VRM human bone name → bone name), when the file has one.
pub type HumanoidTruth<'a> = Option<&'a [(String, String)]>;

/// What [`plan_mapping`] decides.
#[derive(Debug, Clone)]
pub struct MappingPlan {
    /// Target bone → source bone(s).
    pub table: MappingTable,
    /// A representative source pose when the source's rest pose is degenerate (no posture).
    pub source_reference: Option<Pose>,
    /// The same for the target (from its own animation, used for alignment only).
    pub target_reference: Option<Pose>,
    /// The source's up direction, as its analysis found it (Z-up captures exist).
    pub source_up: glam::Vec3,
    /// The source skeleton's analysis (its legs drive foot locking).
    pub source_analysis: Analysis,
    /// The target skeleton's analysis.
    pub target_analysis: Analysis,
    /// Target bones that keep their own posture and follow the source's motion from its
    /// standing posture (`mapping::posture_relative`: a walker driving a quadruped).
    pub posture_relative: Vec<(BoneId, Follow)>,
    /// The source's standing posture those bones' motion is measured from (its clip's mean
    /// posture), when there are such bones.
    pub source_standing: Option<Pose>,
}

impl MappingPlan {
    /// Options to retarget `source` (the clip this plan was made for) with this plan: its
    /// frame time, both reference postures and the source's up, with `root_motion`.
    pub fn retarget_options(&self, source: &Clip, root_motion: RootMotion) -> RetargetOptions {
        RetargetOptions {
            frame_time_secs: source.frame_time_secs as f32,
            root_motion,
            source_reference: vec![self.source_reference.clone()],
            target_reference: self.target_reference.clone(),
            posture_relative: self.posture_relative.clone(),
            source_standing: vec![self.source_standing.clone()],
            source_up: Some(self.source_up),
            ..RetargetOptions::default()
        }
    }
}

/// Where automatic tables are kept between runs (`rigcast map`'s folder; none offline).
pub trait TableCache {
    /// The table stored under `key`, if any.
    fn get(&mut self, key: &CacheKey) -> Option<MappingTable>;
    /// Stores a freshly computed automatic table.
    fn put(&mut self, key: &CacheKey, table: &MappingTable);
}

/// One source clip mapped onto one target clip: [`map_pair`]'s result.
#[derive(Debug, Clone)]
pub struct MappedPair {
    /// Target bone → source bone(s), overrides applied.
    pub table: MappingTable,
    /// The source skeleton's analysis.
    pub source_analysis: Analysis,
    /// The target skeleton's analysis.
    pub target_analysis: Analysis,
    /// Whether the automatic table came from the cache.
    pub from_cache: bool,
}

/// Analyses both clips (a ground-truth humanoid map overrides the inferred roles of the bones
/// it names; rests without a posture are read on a representative frame), maps them with
/// the automatic mapper, or takes the cached table, and applies `overrides`. A table made
/// with ground truth neither comes from nor goes into the cache: its key knows only the
/// skeletons and options.
pub fn map_pair(
    source: &Clip,
    target: &Clip,
    truth: (HumanoidTruth<'_>, HumanoidTruth<'_>),
    opts: &MapOptions,
    cache: Option<&mut dyn TableCache>,
    overrides: Option<&MappingFile>,
) -> Result<MappedPair, OfflineError> {
    let (ss, ts) = (&*source.skeleton, &*target.skeleton);
    let sa = analyze_with_truth(&SkeletonView::from_clip(ss, &source.poses), truth.0);
    let ta = analyze_with_truth(&SkeletonView::from_clip(ts, &target.poses), truth.1);
    let cache = cache.filter(|_| truth.0.is_none() && truth.1.is_none());
    let (mut table, from_cache) = table_for(&[(ss, &sa)], (ts, &ta), opts, cache);
    if let Some(file) = overrides {
        apply_overrides(&mut table, file, &[ss], ts).map_err(OfflineError::Overrides)?;
    }
    Ok(MappedPair {
        table,
        source_analysis: sa,
        target_analysis: ta,
        from_cache,
    })
}

/// The automatic table for analysed sources and target: the cache's, when it holds one that
/// fits these skeletons (keyed by the skeletons and `opts`), else the automatic mapper's,
/// which is then offered to the cache. Whether it came from the cache. A table made with
/// ground truth must not be looked up here: the key does not know the truth.
pub fn table_for(
    sources: &[(&Skeleton, &Analysis)],
    target: (&Skeleton, &Analysis),
    opts: &MapOptions,
    cache: Option<&mut dyn TableCache>,
) -> (MappingTable, bool) {
    let Some(cache) = cache else {
        return (map_analyzed(sources, target, opts), false);
    };
    let skeletons: Vec<&Skeleton> = sources.iter().map(|s| s.0).collect();
    let key = CacheKey::new(&skeletons, target.0, opts);
    match cache
        .get(&key)
        .filter(|t| t.validate(&skeletons, target.0).is_ok())
    {
        Some(t) => (t, true),
        None => {
            let t = map_analyzed(sources, target, opts);
            cache.put(&key, &t);
            (t, false)
        }
    }
}

/// Which target bones keep their own posture (`mapping::posture_relative`: a walker driving
/// a quadruped), and per source the standing posture their motion is measured from (from
/// that source's frames, when it has any; none when no bone keeps its posture).
pub fn posture_plan(
    table: &MappingTable,
    sources: &[(&Skeleton, &Analysis, Option<&[Pose]>)],
    target: &Analysis,
) -> (Vec<(BoneId, Follow)>, Vec<Option<Pose>>) {
    let analyses: Vec<&Analysis> = sources.iter().map(|s| s.1).collect();
    let relative = posture_relative(table, &analyses, target);
    if relative.is_empty() {
        return (relative, Vec::new());
    }
    let standing = sources
        .iter()
        .map(|(skeleton, analysis, poses)| standing_posture(skeleton, (*poses)?, analysis.up))
        .collect();
    (relative, standing)
}

/// Maps the clip's skeleton onto the target with the automatic mapper, then applies the
/// overrides of a mapping file (TOML, `retarget/MAPPING.md`) if given. Rests without a
/// posture (all joints on a line) are analysed, and aligned, on a representative frame.
pub fn plan_mapping(
    source: &Clip,
    target: &Clip,
    overrides: Option<&MappingFile>,
) -> Result<MappingPlan, OfflineError> {
    plan_mapping_with_truth(source, target, overrides, (None, None))
}

/// [`plan_mapping`] with ground-truth humanoid maps (VRM: human bone name → bone name) for the
/// source and the target, which override the inferred roles of the bones they name.
pub fn plan_mapping_with_truth(
    source: &Clip,
    target: &Clip,
    overrides: Option<&MappingFile>,
    truth: (HumanoidTruth<'_>, HumanoidTruth<'_>),
) -> Result<MappingPlan, OfflineError> {
    let pair = map_pair(
        source,
        target,
        truth,
        &MapOptions::default(),
        None,
        overrides,
    )?;
    let (sa, ta) = (pair.source_analysis, pair.target_analysis);
    let sources = [(&*source.skeleton, &sa, Some(&source.poses[..]))];
    let (relative, standing) = posture_plan(&pair.table, &sources, &ta);
    Ok(MappingPlan {
        posture_relative: relative,
        source_standing: standing.into_iter().next().flatten(),
        table: pair.table,
        source_up: sa.up,
        source_reference: sa.posture_pose(&source.poses),
        target_reference: ta.posture_pose(&target.poses),
        source_analysis: sa,
        target_analysis: ta,
    })
}
