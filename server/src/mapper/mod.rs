//! The mapper: builds each performer's [`Mapping`] off the tick path, on its own thread.
//!
//! ```text
//!  start / set_mapping / source skeleton changed
//!        │
//!        ▼
//!  table = memory cache ▸ disk cache (~/.cache/rigcast/mappings/KEY.json)
//!          ▸ cluster mode: the nodes' shared cache (crate::cluster::SharedMappings) ▸ auto_map_many
//!        + overrides file (TOML) + the session's set_mapping overrides
//!        ──▶ cache (memory + disk, LRU-bounded, written only when changed: mapping_store.rs)
//!        ──▶ Mapping::build ──▶ the engine's inbox (Input::Mapping; the tick takes it)
//!                                                   └──▶ `mapping` message to clients
//! ```
//!
//! Cache keys are both skeletons' fingerprints plus the mapper options' hash, so a
//! reconnecting source (same skeleton) maps without re-running the automatic mapper.
//! Subjects loaded from a VRM carry its humanoid map as ground truth for their roles
//! ([`Subject::truth`]); the key does not cover it, so such mappings bypass both caches.

mod graft;

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use rigcast_protocol::control::MappingEntry;
use rigcast_retarget::analysis::{analyze_with_truth, Analysis, SkeletonView};
use rigcast_retarget::footplant::{find_legs, FootLock, LegKind, LockSettings};
use rigcast_retarget::mapping::{
    apply_overrides, mapping_colors, CacheKey, MapOptions, MappingFile, MappingTable, SourceRef,
    TargetEntry, UNMAPPED,
};
use rigcast_retarget::{BoneId, Follow, Mapping, Pose, RetargetOptions, RootMotion, Skeleton};
use tokio::sync::broadcast;

use crate::changes::find_source_bone;
use crate::mapping_store::{MappingStore, DEFAULT_MAX_ENTRIES};
use crate::offline::TableCache;
use rigcast_engine::graft_live::LowerInput;
use rigcast_engine::inbox::Inbox;
use rigcast_engine::performer::BuiltMapping;
use rigcast_engine::reports::MappingReport;
use rigcast_engine::subject::Subject;
use rigcast_engine::tick::EngineCommand;

/// What the mapper knows about one performer.
pub struct PerformerPlan {
    /// The target subject (its `inputs` are the source subjects).
    pub target: Arc<Subject>,
    /// A representative pose of the character (its file's animation), for alignment when its
    /// rest pose has no posture.
    pub target_reference: Option<Pose>,
    /// The character file's own animation (empty without one): the analysis reads its sides
    /// from the knees' and elbows' bends there, evidence one pose cannot give.
    pub target_motion: Arc<[Pose]>,
    /// Overrides from the performer's mapping file.
    pub overrides_file: Option<MappingFile>,
    /// Overrides received with `set_mapping` this session (target bone → source bone).
    pub session: BTreeMap<String, Option<String>>,
    /// Root motion.
    pub root_motion: RootMotion,
    /// Foot locking: `Some(on)` as configured, `None` for on when the character is a humanoid
    /// or a quadruped.
    pub foot_lock: Option<bool>,
    /// A graft's lower body (`None`: not a graft; the upper body is input 0).
    pub graft: Option<LowerInput>,
}

/// Extra knowledge about a replayed source: a representative pose and the clip's poses (for
/// the floor height).
#[derive(Debug, Clone, Default)]
pub struct SourceExtra {
    /// Middle frame of the clip.
    pub reference: Option<Pose>,
    /// The clip's poses.
    pub poses: Arc<Vec<Pose>>,
}

/// Builds and rebuilds mappings.
pub struct Mapper {
    subjects: Arc<Vec<Arc<Subject>>>,
    performers: Vec<PerformerPlan>,
    extras: HashMap<u32, SourceExtra>,
    store: MappingStore,
    /// Cluster mode: automatic tables shared with the other nodes.
    shared: Option<crate::cluster::SharedMappings>,
    frame_time_secs: f32,
    events: broadcast::Sender<rigcast_engine::events::Event>,
    /// Where built mappings go, and whom the mapper tells it took a command.
    engine: Inbox,
    options: MapOptions,
}

impl Mapper {
    /// A mapper over `subjects` (sources and targets) for `performers`.
    pub fn new(
        subjects: Arc<Vec<Arc<Subject>>>,
        performers: Vec<PerformerPlan>,
        extras: HashMap<u32, SourceExtra>,
        disk: Option<PathBuf>,
        rate_hz: f64,
        events: broadcast::Sender<rigcast_engine::events::Event>,
        engine: Inbox,
    ) -> Mapper {
        Mapper {
            subjects,
            performers,
            extras,
            store: MappingStore::new(disk, DEFAULT_MAX_ENTRIES),
            shared: None,
            frame_time_secs: (1.0 / rate_hz) as f32,
            events,
            engine,
            options: MapOptions::default(),
        }
    }

    /// Bounds the mapping cache (memory and disk) to `max_entries` tables.
    pub fn with_max_cache_entries(mut self, max_entries: usize) -> Mapper {
        let disk = self.store.take_disk();
        self.store = MappingStore::new(disk, max_entries);
        self
    }

    /// Looks up (and offers) automatic tables in the cluster's shared cache too.
    pub fn with_shared(mut self, shared: Option<crate::cluster::SharedMappings>) -> Mapper {
        self.shared = shared;
        self
    }

    /// Builds every performer's mapping; failures are reported and leave that target at rest.
    pub fn build_all(&mut self) {
        for i in 0..self.performers.len() {
            if let Err(e) = self.build(i) {
                tracing::error!(
                    "cannot map {}: {e:#}",
                    self.performers[i].target.info().name
                );
            }
        }
    }

    /// Builds performer `i`'s mapping and hands it to the tick.
    pub fn build(&mut self, i: usize) -> anyhow::Result<()> {
        if self.performers[i].graft.is_some() {
            return self.build_graft(i);
        }
        let p = &self.performers[i];
        let target = p.target.skeleton();
        let src = read_sources(&self.subjects, &self.extras, &p.target.inputs);
        let ta = analyze_with_truth(&target_view(&target, p), p.target.truth());
        // The cache key knows the skeletons, not the truth: a truth-driven table must neither
        // come from nor go into the cache.
        let use_cache = p.target.truth().is_none() && src.truths.iter().all(|t| t.is_none());
        let mut caches = Caches {
            store: &mut self.store,
            shared: self.shared.as_ref(),
        };
        let cache = use_cache.then_some(&mut caches);
        let table = performer_table(p, &src, (&target, &ta), &self.options, cache)?;
        let opts = self.retarget_options(p, &src, &table, &ta);
        let mut mapping = Mapping::build(&src.refs(), &target, &table, &opts)
            .context("cannot build the retargeting mapping")?;
        if let Some(extra) = p.target.inputs.first().and_then(|id| self.extras.get(id)) {
            if let Some(floor) = mapping.measure_source_floor(&extra.poses) {
                mapping.set_source_floor_y(floor);
            }
        }
        let warnings: Vec<String> = (src.analyses.iter())
            .flat_map(|a| a.warnings.iter().map(|w| format!("source: {w}")))
            .chain(ta.warnings.iter().map(|w| format!("target: {w}")))
            .collect();
        let report = mapping_report(
            &p.target,
            &src.skeletons,
            &target,
            &ta,
            &table,
            &self.options,
            warnings,
        );
        let foot_lock = build_foot_lock(&mapping, &src.analyses, &ta, p.foot_lock);
        self.hand_over(
            i,
            BuiltMapping {
                mapping,
                foot_lock,
                graft: None,
            },
            report,
        );
        Ok(())
    }

    /// The retarget options of a performer: its root motion, the quadruped posture plan, and
    /// the references its analyses used.
    fn retarget_options(
        &self,
        p: &PerformerPlan,
        src: &Sources<'_>,
        table: &MappingTable,
        ta: &Analysis,
    ) -> RetargetOptions {
        let (relative, source_standing) =
            self.posture_plan(&p.target.inputs, &src.refs(), &src.analyses, table, ta);
        RetargetOptions {
            frame_time_secs: self.frame_time_secs,
            root_motion: p.root_motion,
            posture_relative: relative,
            source_standing,
            source_reference: (src.references.iter())
                .zip(&src.analyses)
                .map(|(r, a)| r.filter(|_| a.used_pose).cloned())
                .collect(),
            target_reference: p.target_reference.clone().filter(|_| ta.used_pose),
            source_up: src.analyses.first().map(|a| a.up),
            ..RetargetOptions::default()
        }
    }

    /// A walker driving a quadruped: the target's extra ground limbs keep their own posture
    /// and follow the source's motion from the source clip's standing posture
    /// (`offline::posture_plan`); a live source without a clip measures from its reference.
    fn posture_plan(
        &self,
        inputs: &[u32],
        sources: &[&Skeleton],
        analyses: &[Analysis],
        table: &MappingTable,
        ta: &Analysis,
    ) -> (Vec<(BoneId, Follow)>, Vec<Option<Pose>>) {
        let with_clips: Vec<(&Skeleton, &Analysis, Option<&[Pose]>)> = (inputs.iter())
            .zip(sources)
            .zip(analyses)
            .map(|((id, s), a)| (*s, a, self.extras.get(id).map(|e| &e.poses[..])))
            .collect();
        crate::offline::posture_plan(table, &with_clips, ta)
    }

    /// Publishes performer `i`'s built mapping: the locked feet for the status, the engine,
    /// the `mapping` message.
    fn hand_over(&self, i: usize, built: BuiltMapping, report: MappingReport) {
        let p = &self.performers[i];
        let target = p.target.skeleton();
        if let Ok(mut feet) = p.target.stats.locked_feet.lock() {
            *feet = built
                .foot_lock
                .iter()
                .flat_map(|l| l.target_legs())
                .map(|leg| target.name(leg.foot).to_string())
                .collect();
        }
        p.target
            .stats
            .feet_locked
            .store(0, std::sync::atomic::Ordering::Relaxed);
        self.engine.mapping(p.target.id, built);
        let report = Arc::new(report);
        p.target.set_mapping(report.clone());
        // Err only means no client is listening right now.
        let _ = self
            .events
            .send(rigcast_engine::events::Event::Mapping(report));
    }

    /// Handles one command.
    pub fn handle(&mut self, cmd: EngineCommand) {
        match cmd {
            EngineCommand::SetMapping { subject, overrides } => {
                let Some(i) = self.performers.iter().position(|p| p.target.id == subject) else {
                    return;
                };
                self.performers[i].session.extend(overrides);
                if let Err(e) = self.build(i) {
                    tracing::error!("set_mapping for subject {subject}: {e:#}");
                }
            }
            EngineCommand::SetPerformer { subject, foot_lock } => {
                let Some(i) = self.performers.iter().position(|p| p.target.id == subject) else {
                    return;
                };
                if foot_lock.is_some() {
                    self.performers[i].foot_lock = foot_lock;
                }
                if let Err(e) = self.build(i) {
                    tracing::error!("set_performer for subject {subject}: {e:#}");
                }
            }
            EngineCommand::SkeletonChanged { subject } => {
                for i in 0..self.performers.len() {
                    if self.performers[i].target.inputs.contains(&subject) {
                        // The old reference pose belongs to the old skeleton.
                        self.extras.remove(&subject);
                        if let Err(e) = self.build(i) {
                            tracing::error!("re-mapping after a skeleton change: {e:#}");
                        }
                    }
                }
            }
            EngineCommand::Shutdown => {}
        }
    }

    /// Runs until `Shutdown` or every sender is gone (call on a dedicated thread): the
    /// commands the engine passes on ([`rigcast_engine::Output::Build`]).
    pub fn run(mut self, rx: std::sync::mpsc::Receiver<EngineCommand>) {
        while let Ok(cmd) = rx.recv() {
            if matches!(cmd, EngineCommand::Shutdown) {
                break;
            }
            self.engine.command_taken();
            self.handle(cmd);
        }
    }
}

/// Merges `set_mapping` overrides: target bone → source bone (searched in input order), or
/// `None` to leave the bone unmapped. Unknown names are errors (clients are checked first).
pub fn apply_session(
    table: &mut MappingTable,
    session: &BTreeMap<String, Option<String>>,
    sources: &[&Skeleton],
    target: &Skeleton,
) -> anyhow::Result<()> {
    for (tname, sname) in session {
        let t = target
            .bone(tname)
            .with_context(|| format!("unknown target bone {tname:?}"))?;
        // The user has decided this bone: it is no longer flagged.
        table.flagged.retain(|f| f.bone != t);
        let Some(sname) = sname else {
            table.entries[t.index()] = None;
            continue;
        };
        let (input, bone) = find_source_bone(sources, sname)
            .with_context(|| format!("unknown source bone {sname:?}"))?;
        let options = table.entries[t.index()]
            .as_ref()
            .map(|e| e.options)
            .unwrap_or_default();
        table.entries[t.index()] = Some(TargetEntry {
            sources: vec![SourceRef {
                input,
                bone,
                weight: 1.0,
            }],
            options,
            score: 0.0,
            evidence: vec!["set_mapping".into()],
            confidence: 1.0,
        });
    }
    Ok(())
}

/// The mapper's caches as the offline pipeline looks tables up: its own store (memory, then
/// disk), then the cluster's shared cache; a computed table goes to the shared cache only
/// (the store gets the table as used, overrides applied, once it is made).
struct Caches<'a> {
    store: &'a mut MappingStore,
    shared: Option<&'a crate::cluster::SharedMappings>,
}

impl TableCache for Caches<'_> {
    fn get(&mut self, key: &CacheKey) -> Option<MappingTable> {
        (self.store.get(key)).or_else(|| self.shared.and_then(|s| s.get(key)))
    }

    fn put(&mut self, key: &CacheKey, table: &MappingTable) {
        if let Some(s) = self.shared {
            s.put(key, table);
        }
    }
}

/// A performer's sources as the mapper reads them, in input order.
struct Sources<'a> {
    skeletons: Vec<Arc<Skeleton>>,
    /// A replayed source's representative pose.
    references: Vec<Option<&'a Pose>>,
    /// Roles known from the file (a VRM's humanoid map).
    truths: Vec<Option<&'a [(String, String)]>>,
    analyses: Vec<Analysis>,
}

impl Sources<'_> {
    fn refs(&self) -> Vec<&Skeleton> {
        self.skeletons.iter().map(|s| &**s).collect()
    }
}

/// Reads and analyses the source subjects `inputs`.
fn read_sources<'a>(
    subjects: &'a [Arc<Subject>],
    extras: &'a HashMap<u32, SourceExtra>,
    inputs: &[u32],
) -> Sources<'a> {
    let skeletons: Vec<Arc<Skeleton>> = (inputs.iter())
        .map(|id| subjects[*id as usize].skeleton())
        .collect();
    let references: Vec<Option<&Pose>> = (inputs.iter())
        .map(|id| extras.get(id).and_then(|e| e.reference.as_ref()))
        .collect();
    let truths: Vec<Option<&[(String, String)]>> = (inputs.iter())
        .map(|id| subjects[*id as usize].truth())
        .collect();
    let analyses = (skeletons.iter())
        .zip(&references)
        .zip(&truths)
        .map(|((s, r), t)| analyze_with_truth(&SkeletonView::with_pose(s, *r), *t))
        .collect();
    Sources {
        skeletons,
        references,
        truths,
        analyses,
    }
}

/// The performer's table: cached or automatic, then its file's and its session's overrides.
/// With a cache, the table as used is stored, so a restart starts where the session left it
/// (the cluster shares only automatic ones).
fn performer_table(
    p: &PerformerPlan,
    src: &Sources<'_>,
    target: (&Skeleton, &Analysis),
    options: &MapOptions,
    mut caches: Option<&mut Caches<'_>>,
) -> anyhow::Result<MappingTable> {
    let src_refs = src.refs();
    let pairs: Vec<(&Skeleton, &Analysis)> = src_refs.iter().copied().zip(&src.analyses).collect();
    let cache = caches.as_mut().map(|c| &mut **c as &mut dyn TableCache);
    let (mut table, _) = crate::offline::table_for(&pairs, target, options, cache);
    if let Some(file) = &p.overrides_file {
        apply_overrides(&mut table, file, &src_refs, target.0).context("mapping file")?;
    }
    apply_session(&mut table, &p.session, &src_refs, target.0)?;
    if let Some(caches) = caches {
        let key = CacheKey::new(&src_refs, target.0, options);
        caches.store.put(key, table.clone());
    }
    Ok(table)
}

/// A target's mapping as clients are told of it.
fn mapping_report(
    subject: &Subject,
    sources: &[Arc<Skeleton>],
    target: &Skeleton,
    analysis: &Analysis,
    table: &MappingTable,
    opts: &MapOptions,
    warnings: Vec<String>,
) -> MappingReport {
    let colors = mapping_colors(target, analysis, table);
    let max = opts.max_score().max(1e-6);
    let entries = target
        .bone_ids()
        .map(|t| {
            let entry = table.get(t);
            let source = entry.and_then(|e| e.primary()).and_then(|r| {
                sources
                    .get(r.input as usize)
                    .map(|s| s.name(r.bone).to_string())
            });
            let c = colors.get(t.index()).copied().flatten();
            MappingEntry {
                target: target.name(t).to_string(),
                score: entry
                    .map(|e| (e.score / max).clamp(0.0, 1.0))
                    .unwrap_or(0.0),
                source,
                color_gradient: c.map(|c| c.gradient).unwrap_or(UNMAPPED),
                color_random: c.map(|c| c.random).unwrap_or(UNMAPPED),
                confidence: entry.map_or(0.0, |e| e.confidence),
                flagged: table.flag(t).map(|f| f.reason.clone()),
            }
        })
        .collect();
    MappingReport {
        subject: subject.id,
        source_subject: subject.inputs.first().copied().unwrap_or(0),
        entries,
        warnings,
    }
}

/// The performer's foot lock, when configured on (or, unconfigured, when the character stands
/// like a humanoid or a quadruped) and the character has legs to lock.
fn build_foot_lock(
    mapping: &Mapping,
    sources: &[Analysis],
    target: &Analysis,
    configured: Option<bool>,
) -> Option<FootLock> {
    let standing = || {
        let legs = find_legs(mapping.target(), target);
        target.humanoid || legs.iter().filter(|l| l.kind == LegKind::Front).count() >= 2
    };
    if !configured.unwrap_or_else(standing) {
        return None;
    }
    let source = sources.get(mapping.root_input()?)?;
    FootLock::new(mapping, source, target, LockSettings::default())
}

/// The character as the analysis reads it: its representative pose and its own animation.
fn target_view<'a>(target: &'a Skeleton, p: &'a PerformerPlan) -> SkeletonView<'a> {
    SkeletonView {
        skeleton: target,
        pose: p.target_reference.as_ref(),
        motion: &p.target_motion,
    }
}
