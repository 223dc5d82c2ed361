//! A streamed subject: a source (replay or live input) or a target (a character retargeted from
//! source subjects). Its skeleton can change while the server runs (a VMC sender's skeleton is
//! learnt from its packets), so the skeleton and everything derived from it live in one
//! immutable [`SubjectShape`] that is swapped as a whole.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, RwLock};

use rigcast_protocol::control::{SourceHealth, SubjectInfo, SubjectKind};
use rigcast_protocol::status::SourceStatus;
use rigcast_protocol::{SourceKind, SourceState};
use rigcast_retarget::analysis::{analyze_with_truth, humanoid_roles, Analysis, SkeletonView};
use rigcast_retarget::{Frame, Pose, Skeleton};

use crate::clock::TickTime;
use crate::reports::{FootplantReport, HealthReport, MappingReport};
use crate::settings::VmcBoneNames;
use crate::slot::{frame_slot, FrameReader, FrameWriter};
use crate::stats::SubjectStats;
use crate::translated::{translated_bones, MovingBones};

/// Which bones go out over VMC and under which names.
#[derive(Debug, Clone, Default)]
pub struct VmcPlan {
    /// (name sent, bone index, index of the nearest sent ancestor). When the ancestor is not
    /// the bone's direct parent the local transform is recomputed from world transforms.
    pub bones: Vec<(String, usize, Option<usize>)>,
    /// True when the bones' own local transforms are sent as they are (the skeleton's own
    /// names); false for humanoid role names, sent normalised (see [`crate::vmc_pose`]).
    pub direct: bool,
    /// Per skeleton bone, the normaliser of its world rotation (identity when not sent).
    pub norm: Vec<glam::Quat>,
}

impl VmcPlan {
    /// Humanoid role names when `names` asks for them and the skeleton is humanoid; else every
    /// bone under its own name.
    pub fn new(skeleton: &Skeleton, names: VmcBoneNames) -> VmcPlan {
        Self::with_truth(skeleton, names, None)
    }

    /// [`VmcPlan::new`] with a file's own humanoid map (VRM: human bone name → bone name) as
    /// ground truth for the roles, so a VRM's bones go out under the roles its author gave.
    pub fn with_truth(
        skeleton: &Skeleton,
        names: VmcBoneNames,
        truth: Option<&[(String, String)]>,
    ) -> VmcPlan {
        let analysis = analyze_with_truth(&SkeletonView::rest(skeleton), truth);
        Self::from_analysis(skeleton, names, &analysis, truth)
    }

    /// [`VmcPlan::with_truth`] on an analysis already made.
    fn from_analysis(
        skeleton: &Skeleton,
        names: VmcBoneNames,
        analysis: &Analysis,
        truth: Option<&[(String, String)]>,
    ) -> VmcPlan {
        let roles = match names {
            VmcBoneNames::Humanoid => humanoid_roles(skeleton, analysis, truth),
            VmcBoneNames::Skeleton => Vec::new(),
        };
        if roles.is_empty() {
            return VmcPlan {
                bones: skeleton
                    .bone_ids()
                    .map(|b| {
                        (
                            skeleton.name(b).to_string(),
                            b.index(),
                            skeleton.parent(b).map(|p| p.index()),
                        )
                    })
                    .collect(),
                direct: true,
                norm: Vec::new(),
            };
        }
        let mut role_of: Vec<Option<&'static str>> = vec![None; skeleton.num_bones()];
        for (h, b) in &roles {
            role_of[b.index()] = Some(h.unity_name());
        }
        let mut bones = Vec::new();
        for b in skeleton.bone_ids() {
            let Some(name) = role_of[b.index()] else {
                continue;
            };
            let mut anc = skeleton.parent(b);
            while let Some(a) = anc {
                if role_of[a.index()].is_some() {
                    break;
                }
                anc = skeleton.parent(a);
            }
            bones.push((name.to_string(), b.index(), anc.map(|a| a.index())));
        }
        let sent: Vec<(String, usize)> = bones.iter().map(|(n, b, _)| (n.clone(), *b)).collect();
        let norm = crate::vmc_pose::normalisers(skeleton, &sent, analysis.forward);
        VmcPlan {
            bones,
            direct: false,
            norm,
        }
    }
}

/// Everything derived from a subject's skeleton.
#[derive(Debug)]
pub struct SubjectShape {
    /// Public description (as in `hello`).
    pub info: SubjectInfo,
    /// Skeleton of the poses.
    pub skeleton: Arc<Skeleton>,
    /// VMC output names.
    pub vmc: VmcPlan,
    /// Ascending indices of the bones whose translations version 2 frames carry (marked
    /// `translated` in the `skeleton` message).
    pub translated: Vec<u16>,
}

impl SubjectShape {
    fn new(
        info: SubjectInfo,
        skeleton: Arc<Skeleton>,
        names: VmcBoneNames,
        truth: Option<&[(String, String)]>,
        moving: &MovingBones,
    ) -> SubjectShape {
        let analysis = analyze_with_truth(&SkeletonView::rest(&skeleton), truth);
        let translated = translated_bones(&skeleton, &analysis, moving);
        SubjectShape {
            vmc: VmcPlan::from_analysis(&skeleton, names, &analysis, truth),
            info,
            skeleton,
            translated,
        }
    }
}

/// The state as stored in [`Health`]'s atomic.
fn state_from_u8(v: u8) -> SourceState {
    match v {
        0 => SourceState::Connecting,
        2 => SourceState::Lost,
        3 => SourceState::Finished,
        4 => SourceState::Failed,
        _ => SourceState::Live,
    }
}

fn state_to_u8(s: SourceState) -> u8 {
    match s {
        SourceState::Connecting => 0,
        SourceState::Live => 1,
        SourceState::Lost => 2,
        SourceState::Finished => 3,
        SourceState::Failed => 4,
    }
}

/// A source subject's health: the state (atomic) and the live source's last status report.
#[derive(Debug)]
pub struct Health {
    state: AtomicU8,
    /// Last status of a live source (`None` for replays: their counters are in the stats).
    pub live: Mutex<Option<SourceStatus>>,
    /// Why the source's task or thread stopped (see [`Health::fail`]).
    failure: Mutex<Option<String>>,
}

impl Health {
    fn new(state: SourceState) -> Health {
        Health {
            state: AtomicU8::new(state_to_u8(state)),
            live: Mutex::new(None),
            failure: Mutex::new(None),
        }
    }

    /// Current state.
    #[inline]
    pub fn state(&self) -> SourceState {
        state_from_u8(self.state.load(Ordering::Relaxed))
    }

    /// Sets the state; `Failed` stays (a source that failed is failed for good, whatever a
    /// part of it still running reports).
    pub fn set_state(&self, s: SourceState) {
        let failed = state_to_u8(SourceState::Failed);
        // Err only means the state is `Failed` already, which stays.
        let _ = self
            .state
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |now| {
                (now != failed).then_some(state_to_u8(s))
            });
    }

    /// Marks the source failed for good (its task or thread stopped), keeping why.
    pub fn fail(&self, why: String) {
        if let Ok(mut f) = self.failure.lock() {
            *f = Some(why);
        }
        self.set_state(SourceState::Failed);
    }

    /// Why the source failed, once it has.
    pub fn failure(&self) -> Option<String> {
        self.failure.lock().ok().and_then(|f| f.clone())
    }
}

/// A streamed subject: its shape, its pose slot and its counters.
#[derive(Debug)]
pub struct Subject {
    /// Subject id (= index in the subject list).
    pub id: u32,
    /// What feeds a source subject; `None` for a target (retargeted character).
    pub source_kind: Option<SourceKind>,
    shape: RwLock<Arc<SubjectShape>>,
    /// Latest frame (from the source, or the tick for targets).
    pub latest: FrameReader,
    /// Input counters.
    pub stats: SubjectStats,
    /// Source health (targets stay `Live`).
    pub health: Health,
    /// Source subjects of a target (input order of its mapping); empty for sources.
    pub inputs: Vec<u32>,
    /// A target's mapping, once built.
    mapping: Mutex<Option<Arc<MappingReport>>>,
    /// A target's planted feet as last reported.
    footplants: Mutex<Option<Arc<FootplantReport>>>,
    /// The UDP address a VMC source listens on.
    pub listen_addr: Option<SocketAddr>,
    /// Calibration of a serial IMU source (the host carries out requests through it).
    pub calibration: Option<Calibration>,
    vmc_names: VmcBoneNames,
    /// What moves besides the structural bones (see [`crate::translated`]).
    moving: MovingBones,
    /// The file's own humanoid map (VRM: human bone name → bone name), ground truth for the
    /// roles of its bones in mapping and VMC output.
    truth: Option<Arc<[(String, String)]>>,
    /// A target's character file the viewer may fetch (the host serves it).
    pub model: Option<ModelFile>,
}

/// A target's character file the viewer may fetch: a binary glTF container the host has
/// checked (the host's `model` module finds and serves it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelFile {
    /// The configured path.
    pub path: PathBuf,
    /// `glb` or `vrm` (announced in the subject list as `model`).
    pub format: &'static str,
}

/// What outcome a calibration request had: attempts finished so far and the last one's
/// result (`None` before the first; `Err` says why it failed).
pub type CalibrationOutcome = (u64, Option<Result<(), String>>);

/// A live source that can be calibrated (a serial IMU suit), as the host reaches its thread.
/// The engine only carries it with the subject; the host implements it over the source's own
/// handle and makes the requests.
pub trait Calibrator: Send + Sync + std::fmt::Debug {
    /// Asks for a calibration against the rest pose (a T-pose).
    fn request(&self);
    /// Asks for a calibration against `pose`, held by the performer.
    fn request_pose(&self, pose: Pose);
    /// Attempts finished so far and the last one's result.
    fn outcome(&self) -> CalibrationOutcome;
}

/// A calibratable source's handle and the server's account of its calibration.
#[derive(Debug)]
pub struct Calibration {
    /// Reaches the source's thread.
    pub handle: Box<dyn Calibrator>,
    /// `calibrating …`, `calibrated (T-pose)`, `calibration failed: …`; empty before the
    /// first request.
    pub text: Mutex<String>,
    /// Bumped per request, so a superseded request's outcome is not reported.
    pub generation: AtomicU64,
}

impl Calibration {
    /// The current text (empty before any request).
    pub fn text(&self) -> String {
        match self.text.lock() {
            Ok(g) => g.clone(),
            Err(p) => p.into_inner().clone(),
        }
    }

    /// Replaces the text.
    pub fn set_text(&self, text: String) {
        match self.text.lock() {
            Ok(mut g) => *g = text,
            Err(p) => *p.into_inner() = text,
        }
    }
}

impl Subject {
    /// Builds a source subject and the writer its source writes its frames to.
    pub fn new(id: u32, name: String, skeleton: Arc<Skeleton>) -> (Subject, FrameWriter) {
        Self::with_kind(
            id,
            name,
            skeleton,
            Some(SourceKind::Replay),
            Vec::new(),
            VmcBoneNames::default(),
        )
    }

    /// Builds a subject of any kind. `inputs` non-empty makes it a target retargeted from
    /// those subjects.
    pub fn with_kind(
        id: u32,
        name: String,
        skeleton: Arc<Skeleton>,
        source_kind: Option<SourceKind>,
        inputs: Vec<u32>,
        vmc_names: VmcBoneNames,
    ) -> (Subject, FrameWriter) {
        let info = SubjectInfo {
            id,
            name,
            kind: if inputs.is_empty() {
                SubjectKind::Source
            } else {
                SubjectKind::Target
            },
            source: inputs.first().copied(),
            num_bones: skeleton.num_bones() as u32,
            fingerprint: skeleton.fingerprint_hex(),
            model: None,
        };
        let (tx, rx) = frame_slot(Frame {
            seq: 0,
            capture_nanos: 0,
            source_id: id,
            pose: Pose::from_rest(&skeleton),
        });
        let initial = if source_kind == Some(SourceKind::Replay) || !inputs.is_empty() {
            SourceState::Live
        } else {
            SourceState::Connecting
        };
        // Live inputs may move any bone; replays are measured once their clip is known
        // (`with_moving_bones`); targets move their root chain and hips.
        let moving = if source_kind == Some(SourceKind::Replay) || !inputs.is_empty() {
            MovingBones::Structural
        } else {
            MovingBones::All
        };
        (
            Subject {
                id,
                source_kind,
                shape: RwLock::new(Arc::new(SubjectShape::new(
                    info, skeleton, vmc_names, None, &moving,
                ))),
                latest: rx,
                stats: SubjectStats::default(),
                health: Health::new(initial),
                inputs,
                mapping: Mutex::new(None),
                footplants: Mutex::new(None),
                listen_addr: None,
                calibration: None,
                vmc_names,
                moving,
                truth: None,
                model: None,
            },
            tx,
        )
    }

    /// Sets the listen address reported for a live source.
    pub fn with_listen_addr(mut self, addr: Option<SocketAddr>) -> Subject {
        self.listen_addr = addr;
        self
    }

    /// Gives the subject its file's humanoid map (VRM) as ground truth for its bones' roles;
    /// the VMC plan is rebuilt with it. `None` or empty leaves the roles inferred.
    pub fn with_truth(mut self, truth: Option<Vec<(String, String)>>) -> Subject {
        self.truth = truth.filter(|t| !t.is_empty()).map(Arc::from);
        self.rebuild_shape();
        self
    }

    /// Serves `model` as this target's mesh (announced as `model` in the subject list).
    pub fn with_model(mut self, model: Option<ModelFile>) -> Subject {
        let old = self.shape();
        let mut info = old.info.clone();
        info.model = model.as_ref().map(|m| m.format.to_string());
        let shape = SubjectShape::new(
            info,
            old.skeleton.clone(),
            self.vmc_names,
            self.truth.as_deref(),
            &self.moving,
        );
        self.shape = RwLock::new(Arc::new(shape));
        self.model = model;
        self
    }

    /// Marks the bones that move in a replayed clip as translated in version 2 frames.
    pub fn with_moving_bones(mut self, poses: &[Pose]) -> Subject {
        self.moving = MovingBones::measured(&self.skeleton(), poses);
        self.rebuild_shape();
        self
    }

    fn rebuild_shape(&mut self) {
        let old = self.shape();
        let shape = SubjectShape::new(
            old.info.clone(),
            old.skeleton.clone(),
            self.vmc_names,
            self.truth.as_deref(),
            &self.moving,
        );
        self.shape = RwLock::new(Arc::new(shape));
    }

    /// The file's humanoid map given by [`Subject::with_truth`], if any.
    pub fn truth(&self) -> Option<&[(String, String)]> {
        self.truth.as_deref()
    }

    /// Makes a live source calibratable through `handle`.
    pub fn with_calibration(mut self, handle: Option<Box<dyn Calibrator>>) -> Subject {
        self.calibration = handle.map(|handle| Calibration {
            handle,
            text: Mutex::new(String::new()),
            generation: AtomicU64::new(0),
        });
        self
    }

    /// The `detail` of this source's health: the server's calibration account (which
    /// supersedes the source's own `calibrated`/`not calibrated` note) and, while the device
    /// is not live, the source's detail (why it is lost).
    fn detail(&self, live_detail: String, now: std::time::Instant) -> String {
        if let Some(why) = self.health.failure() {
            return why;
        }
        if let Some(why) = (self.stats).recent_rejection(std::time::Duration::from_secs(1), now) {
            return why;
        }
        let cal = self
            .calibration
            .as_ref()
            .map(|c| c.text())
            .unwrap_or_default();
        let about_calibration = live_detail.contains("calibrat");
        if cal.is_empty() {
            live_detail
        } else if live_detail.is_empty()
            || about_calibration
            || self.health.state() == SourceState::Live
        {
            cal
        } else {
            format!("{live_detail}; {cal}")
        }
    }

    /// The current shape (cheap: an `Arc` clone).
    #[inline]
    pub fn shape(&self) -> Arc<SubjectShape> {
        match self.shape.read() {
            Ok(s) => s.clone(),
            Err(poisoned) => poisoned.into_inner().clone(),
        }
    }

    /// Public description.
    pub fn info(&self) -> SubjectInfo {
        self.shape().info.clone()
    }

    /// Current skeleton.
    pub fn skeleton(&self) -> Arc<Skeleton> {
        self.shape().skeleton.clone()
    }

    /// Checks a pose handed to the engine as a whole, in place (rotations close to unit length
    /// are renormalised): each value may be finite while their sums (root + hips, a chain in
    /// FK) are not. A refused pose is counted on the subject, with the bone and why, at `now`.
    pub fn admit(&self, pose: &mut Pose, now: std::time::Instant) -> bool {
        let Err(refusal) = pose.check_values() else {
            return true;
        };
        let shape = self.shape();
        let name = shape.skeleton.names().get(refusal.bone).map(|n| n.as_str());
        self.stats.reject_pose(refusal, name.unwrap_or("?"), now);
        false
    }

    /// Writes a source's checked `pose` into its slot (`writer`) as the frame handed over at
    /// `time`: captured at `capture_nanos` (0: at `time`), numbered `seq` or, if that is not
    /// more, the last number + 1; the input counters follow. No allocation unless the
    /// skeleton's size changed.
    pub fn publish_source_pose(
        &self,
        writer: &FrameWriter,
        pose: &Pose,
        time: TickTime,
        (capture_nanos, seq): (u64, u64),
    ) {
        let capture = if capture_nanos == 0 {
            time.unix_nanos
        } else {
            capture_nanos
        };
        // Before the frame: a tick that sees the new frame sees when it was handed over.
        (self.stats.published_nanos).store(time.unix_nanos, Ordering::Relaxed);
        writer.send_modify(|f| {
            if f.pose.num_bones() == pose.num_bones() {
                f.pose.copy_from(pose);
            } else {
                // Only after a skeleton change.
                f.pose = pose.clone();
            }
            f.seq = seq.max(f.seq + 1);
            f.capture_nanos = capture;
        });
        self.stats.input.tick(time.instant);
        (self.stats.last_capture_nanos).store(capture, Ordering::Relaxed);
    }

    /// Replaces the skeleton (a live source learnt a new one). Returns false when it is the
    /// same skeleton (nothing changed).
    pub fn set_skeleton(&self, skeleton: Arc<Skeleton>) -> bool {
        let old = self.shape();
        if old.skeleton.fingerprint() == skeleton.fingerprint() {
            return false;
        }
        let mut info = old.info.clone();
        info.num_bones = skeleton.num_bones() as u32;
        info.fingerprint = skeleton.fingerprint_hex();
        let shape = Arc::new(SubjectShape::new(
            info,
            skeleton,
            self.vmc_names,
            self.truth.as_deref(),
            &self.moving,
        ));
        match self.shape.write() {
            Ok(mut s) => *s = shape,
            Err(poisoned) => *poisoned.into_inner() = shape,
        }
        true
    }

    /// A target's mapping, once built.
    pub fn mapping(&self) -> Option<Arc<MappingReport>> {
        latest(&self.mapping)
    }

    /// Keeps a target's newly built mapping (for clients that connect later).
    pub fn set_mapping(&self, report: Arc<MappingReport>) {
        keep(&self.mapping, report);
    }

    /// A target's planted feet as last reported.
    pub fn footplants(&self) -> Option<Arc<FootplantReport>> {
        latest(&self.footplants)
    }

    /// Keeps a target's latest foot-plant report (for clients that connect later).
    pub fn set_footplants(&self, report: Arc<FootplantReport>) {
        keep(&self.footplants, report);
    }

    /// Whether this subject is another node's, relayed from the cluster (its frames are
    /// forwarded as received instead of being encoded by this node's tick).
    pub fn is_relayed(&self) -> bool {
        self.source_kind == Some(rigcast_protocol::SourceKind::Remote)
    }

    /// Whether this is a retargeted character.
    pub fn is_target(&self) -> bool {
        !self.inputs.is_empty()
    }

    /// Health as sent in `source_status` (sources only), at `now`.
    pub fn source_health(&self, now: std::time::Instant) -> Option<SourceHealth> {
        if self.is_target() {
            return None;
        }
        let state = self.health.state();
        let live = self.health.live.lock().ok().and_then(|g| g.clone());
        Some(match live {
            Some(s) => SourceHealth {
                subject: self.id,
                kind: self.source_kind?,
                state,
                input_fps: s.input_fps,
                latency_ms: s.latency_ms,
                frames: s.frames,
                dropped: s.dropped,
                detail: self.detail(s.detail, now),
                camera: s.camera,
            },
            None => SourceHealth {
                subject: self.id,
                kind: self.source_kind?,
                state,
                input_fps: self.stats.input.rate_hz(now) as f32,
                latency_ms: 0.0,
                frames: self.stats.input.total(),
                dropped: 0,
                detail: self.detail(String::new(), now),
                camera: None,
            },
        })
    }
}

/// What a report slot holds now (a panic elsewhere while it was held leaves a whole value).
fn latest<T>(slot: &Mutex<Option<Arc<T>>>) -> Option<Arc<T>> {
    match slot.lock() {
        Ok(s) => s.clone(),
        Err(poisoned) => poisoned.into_inner().clone(),
    }
}

/// Replaces what a report slot holds.
fn keep<T>(slot: &Mutex<Option<Arc<T>>>, report: Arc<T>) {
    match slot.lock() {
        Ok(mut s) => *s = Some(report),
        Err(poisoned) => *poisoned.into_inner() = Some(report),
    }
}

/// The sources' health and the targets' motion and faults now (the `source_status` message's
/// content), at `now`.
pub fn health_report(subjects: &[Arc<Subject>], now: std::time::Instant) -> HealthReport {
    HealthReport {
        sources: subjects
            .iter()
            .filter_map(|s| s.source_health(now))
            .collect(),
        targets: subjects
            .iter()
            .filter(|s| s.is_target())
            .map(|s| rigcast_protocol::TargetHealth {
                subject: s.id,
                motion: s.stats.motion.load(),
                fault: s.stats.fault(),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A calibratable source that never answers (the test only reads the subject's account).
    #[derive(Debug)]
    struct NoDevice;

    impl Calibrator for NoDevice {
        fn request(&self) {}
        fn request_pose(&self, _: Pose) {}
        fn outcome(&self) -> CalibrationOutcome {
            (0, None)
        }
    }

    #[test]
    fn detail_shows_calibration_and_why_a_device_is_lost() {
        let sk = Arc::new(crate::builtin::mannequin().unwrap());
        let (s, _tx) = Subject::with_kind(
            0,
            "suit".into(),
            sk,
            Some(SourceKind::Serial),
            Vec::new(),
            VmcBoneNames::default(),
        );
        let s = s.with_calibration(Some(Box::new(NoDevice)));
        let report = |state: SourceState, detail: &str| {
            s.health.set_state(state);
            *s.health.live.lock().unwrap() = Some(SourceStatus {
                state: SourceState::Live,
                input_fps: 0.0,
                latency_ms: 0.0,
                frames: 0,
                dropped: 0,
                detail: detail.into(),
                camera: None,
            });
            s.source_health(std::time::Instant::now()).unwrap().detail
        };
        // Before any request the source's own note shows.
        assert_eq!(
            report(SourceState::Live, "not calibrated"),
            "not calibrated"
        );
        s.calibration
            .as_ref()
            .unwrap()
            .set_text("calibrated (N-pose)".into());
        // The server's account supersedes the source's own calibration note…
        assert_eq!(
            report(SourceState::Live, "calibrated"),
            "calibrated (N-pose)"
        );
        // …but a lost device still says why.
        assert_eq!(
            report(SourceState::Lost, "/dev/x: end of stream; reconnecting"),
            "/dev/x: end of stream; reconnecting; calibrated (N-pose)"
        );
        // Sources without calibration pass their detail through.
        let (v, _tx) = Subject::with_kind(
            1,
            "v".into(),
            s.skeleton(),
            Some(SourceKind::Vmc),
            Vec::new(),
            VmcBoneNames::default(),
        );
        assert_eq!(
            v.source_health(std::time::Instant::now()).unwrap().detail,
            ""
        );
    }

    #[test]
    fn vmc_plan_sends_humanoid_roles_relative_to_sent_ancestors() {
        let m = crate::builtin::mannequin().unwrap();
        let plan = VmcPlan::new(&m, VmcBoneNames::Humanoid);
        let find = |n: &str| plan.bones.iter().find(|(name, ..)| name == n).unwrap();
        assert_eq!(
            m.name(rigcast_retarget::BoneId(find("Hips").1 as u16)),
            "pelvis"
        );
        let (_, arm, arm_parent) = find("LeftUpperArm");
        assert_eq!(m.name(rigcast_retarget::BoneId(*arm as u16)), "upperarm_l");
        // Its ancestor is the shoulder role (clavicle), not a twist/helper bone.
        assert_eq!(Some(find("LeftShoulder").1), *arm_parent);
        // The mannequin's ground root has no role, so Hips has no sent ancestor.
        assert_eq!(find("Hips").2, None);
        assert!(!plan.direct);
        assert!(plan.bones.iter().all(|(n, ..)| n != "root"));
        // A file's humanoid map overrides the inferred roles (here: sides swapped).
        let truth: Vec<(String, String)> = [
            ("leftUpperArm", "upperarm_r"),
            ("rightUpperArm", "upperarm_l"),
        ]
        .iter()
        .map(|(h, b)| (h.to_string(), b.to_string()))
        .collect();
        let swapped = VmcPlan::with_truth(&m, VmcBoneNames::Humanoid, Some(&truth));
        let sent = |n: &str| {
            let b = swapped.bones.iter().find(|(name, ..)| name == n).unwrap().1;
            m.name(rigcast_retarget::BoneId(b as u16)).to_string()
        };
        assert_eq!(sent("LeftUpperArm"), "upperarm_r");
        assert_eq!(sent("RightUpperArm"), "upperarm_l");
        assert_eq!(sent("Hips"), "pelvis");
        let raw = VmcPlan::new(&m, VmcBoneNames::Skeleton);
        assert_eq!(raw.bones.len(), m.num_bones());
        assert!(raw.direct);
    }
}
