//! Finding and tracking up to N people: a person detector (or, without one, a candidate-crop
//! search) to start or recover, ROI tracking from each person's auxiliary landmarks of the
//! previous frame, stable identities, and a guard against left/right label swaps.
//!
//! Per frame the landmark model runs once per tracked person, on the ROI its own last
//! landmarks gave (all tracked people's crops in one batch): no search while tracking holds.
//! The finder runs every frame while nobody is tracked or someone established was lost within
//! the last second, else every `find_every_frames` frames while fewer than `max_people` are
//! tracked; looking for more people while nobody was lost is one detector pass (see
//! `DETECTOR_REGIONS`), so one person in view costs about what `max_people: 1` costs whatever
//! `max_people` is. With nobody tracked, the person found takes the lowest free slot once
//! nobody was lost for a few frames (`ALONE_WAIT_FRAMES`): the one person in the picture is the
//! performer, not a bystander while they are hidden.
//!
//! Identities are slots (`#0`, `#1`, …). A person found again shortly after being lost takes
//! back the slot whose last position is nearest (within half its ROI) rather than any free
//! one, so two performers crossing do not trade names; two tracks that converge on one body
//! (joint by joint) are one person twice, and the one that jumped further is dropped. Before
//! that, a result that lies on (or near) another tracked person's body is not taken: the
//! crop is moved away from that person, a step at a time, until the model shows a body of the
//! tracked person's own (someone crossing in front of another with their back to the camera
//! otherwise slides onto the other's face).
//!
//! [`Finder::Search`] is the fallback without the detector model: the landmark model itself
//! reports a pose presence, so running it over a handful of crops (the whole frame
//! letterboxed, centred squares, a coarse grid) and keeping the most present one finds a
//! person, and refinement passes with the ROI from that result's auxiliary landmarks centre
//! and scale the crop.

use glam::{Vec2, Vec3};

use super::detector::{Detection, PersonDetector};
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::{idx, Landmarks, NUM_LANDMARKS};
use super::model::{Disc, LandmarkModel};
use super::roi::Roi;
/// How the tracker finds people it does not track yet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Finder {
    /// The BlazePose person detector over the whole frame (one run finds everyone).
    #[default]
    Detector,
    /// The landmark model over a fixed set of candidate crops (one person per search).
    Search,
}

/// Tracker settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// Minimum pose presence for a result to count as a new person.
    pub presence_threshold: f32,
    /// Minimum pose presence to keep tracking a person (lower than the above: someone
    /// half-hidden behind another performer is still the same person).
    pub keep_presence_threshold: f32,
    /// Refinement passes after a [`Finder::Search`] hit (each one model run).
    pub refine_passes: usize,
    /// Undo the model's facing/away reading flips (left/right label swaps) by matching the
    /// torso against recent frames.
    pub swap_guard: bool,
    /// People tracked at once (identities `#0` … `#max_people-1`).
    pub max_people: usize,
    /// How new people are found.
    pub finder: Finder,
    /// While fewer than `max_people` are tracked, look for more this often (frames).
    pub find_every_frames: u32,
    /// Minimum detector score.
    pub min_detection_score: f32,
    /// For this many frames after losing a person, their slot only takes someone found near
    /// where they were last seen.
    pub reacquire_frames: u32,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            presence_threshold: 0.5,
            keep_presence_threshold: 0.3,
            refine_passes: 2,
            swap_guard: true,
            max_people: 2,
            finder: Finder::Detector,
            find_every_frames: 10,
            min_detection_score: 0.3,
            reacquire_frames: 60,
        }
    }
}

/// Left/right landmark pairs used by the swap guard (and swapped together).
const LR_PAIRS: [(usize, usize); 16] = [
    (1, 4),
    (2, 5),
    (3, 6),
    (7, 8),
    (9, 10),
    (11, 12),
    (13, 14),
    (15, 16),
    (17, 18),
    (19, 20),
    (21, 22),
    (23, 24),
    (25, 26),
    (27, 28),
    (29, 30),
    (31, 32),
];

/// Pairs whose positions decide whether the reading flipped: the torso corners, which move
/// least and are seen best (arms legitimately move a lot between frames).
const GUARD_PAIRS: [(usize, usize); 2] = [
    (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
    (idx::LEFT_HIP, idx::RIGHT_HIP),
];

/// How fast the flip guard's reference follows accepted frames (fraction per frame).
const REFERENCE_RATE: f32 = 0.3;

/// A detection whose hips lie within this fraction of a tracked person's height from that
/// person's hips is that person.
const TRACKED_HIPS: f32 = 0.25;

/// A tracking result whose body points lie within this many body heights of another tracked
/// person's (mean distance, see [`body_distance`]) has slid onto that person: with one face
/// in the crop (the other person's; this one turned away from the camera) the landmark model
/// draws the body that face belongs to, or a blend of the two. A blend is not the other body
/// exactly, so this is wider than [`same_body`]'s tenth: in the pose2sim two-person crossing
/// (camera 3) blends lay 0.05–0.17 from the other person, the person themself mostly 0.2 and
/// further. At 0.17 a blend at 0.171 was taken (full model); camera 3 passes from 0.18 to 0.20
/// with either model, since a person whose beside crops all slide is looked for once more with
/// the other's face hidden (`look_with_face_hidden`).
const ON_OTHER_BODY: f32 = 0.19;

/// Crops tried beside a person whose result slid onto someone else, in this order: shifted
/// away from the other person's hips by these fractions of the crop's size. Further from the
/// other person's face, the model reads the person the crop is for.
const SIDE_STEPS: [f32; 3] = [0.1, 0.2, 0.3];
/// Beside crops also go straight sideways when the way away from the other person is more
/// than this far from horizontal (the sine of ~12°).
const SIDEWAYS_ALSO: f32 = 0.2;
/// Shifts of the upright crops with the other person's face hidden, tried when every beside
/// crop still slid (see `look_with_face_hidden`), in crop sizes away from them.
const MASKED_STEPS: [f32; 4] = [0.0, 0.1, 0.2, 0.3];

/// While a person lost this recently is not found again, the finder runs every frame.
const EAGER_FIND_FRAMES: u32 = 30;

/// A track held this many frames is someone: losing them makes the finder eager and keeps their
/// slot for them. A track lost sooner was a passing misreading (a poster, a reflection, the
/// same person read twice) and frees its slot at once.
const ESTABLISHED_FRAMES: u32 = 5;

/// With nobody tracked, someone found away from where a person was lost waits this many
/// frames for the slot (they may be someone else: a cut, a second person walking in), then
/// takes the lowest free slot: with nobody else in view the one person in the picture is the
/// performer. Longer than the identity judge's span, shorter than anyone notices.
const ALONE_WAIT_FRAMES: u32 = 5;

/// Detector regions, taking turns: the whole frame, then the three squares of the short side
/// along the long one (a small or far person the whole-frame pass misses appears up to twice
/// as large there).
const DETECTOR_REGIONS: usize = 4;

/// Counters for diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrackerStats {
    /// Crops the landmark model ran on (a batch of two counts two).
    pub inferences: u64,
    /// Candidate-crop searches started.
    pub searches: u64,
    /// Person detector runs.
    pub detections: u64,
    /// Left/right label swaps undone.
    pub swaps_fixed: u64,
    /// People who started being tracked.
    pub tracks_started: u64,
    /// Tracked people lost (presence below the threshold).
    pub tracks_lost: u64,
    /// Tracks dropped because they converged on someone already tracked.
    pub duplicates_dropped: u64,
    /// Tracking results that lay on another tracked person (crops beside them were tried).
    pub slides_caught: u64,
    /// Time spent finding people (detector or search, with its landmark runs), nanoseconds:
    /// the "detect" stage of the latency figures.
    pub find_nanos: u64,
}

/// One identity slot.
#[derive(Debug, Clone, Copy)]
struct Track {
    /// The crop for the next frame, while tracked.
    roi: Option<Roi>,
    /// The last crop that showed the person (kept after losing them, to look there again).
    last_roi: Option<Roi>,
    /// Accepted this frame.
    seen: bool,
    /// The last accepted landmarks (frame pixels).
    landmarks: Landmarks,
    reference: Option<[Vec3; 2]>,
    /// Body box (centre, size) of the last and the one before accepted frames.
    place: Option<(Vec2, Vec2)>,
    previous_place: Option<(Vec2, Vec2)>,
    /// Frames since the person was lost (0 while tracked).
    lost_frames: u32,
    /// Frames the person in this slot has been tracked (kept after losing them and counted on
    /// when they are taken back; a new person in the slot starts at 0).
    held_frames: u32,
}

impl Track {
    const EMPTY: Track = Track {
        roi: None,
        last_roi: None,
        seen: false,
        landmarks: Landmarks::ZERO,
        reference: None,
        place: None,
        previous_place: None,
        lost_frames: 0,
        held_frames: 0,
    };

    fn tracked(&self) -> bool {
        self.roi.is_some()
    }

    /// True for a person lost within `frames` frames after being held long enough to be
    /// someone (see [`ESTABLISHED_FRAMES`]), not a passing misreading.
    fn recently_lost(&self, frames: u32) -> bool {
        !self.tracked()
            && self.place.is_some()
            && self.lost_frames <= frames
            && self.held_frames >= ESTABLISHED_FRAMES
    }

    fn lose(&mut self) {
        self.roi = None;
        self.seen = false;
        self.reference = None;
        self.lost_frames = 1;
    }
}

/// Finds and tracks up to [`TrackerConfig::max_people`] people.
#[derive(Debug)]
pub struct PoseTracker {
    model: LandmarkModel,
    detector: Option<PersonDetector>,
    config: TrackerConfig,
    tracks: Vec<Track>,
    candidates: Vec<Roi>,
    detections: Vec<Detection>,
    scratch: Landmarks,
    /// This frame's first landmark run of every tracked person, made in one batch: their
    /// crops, and the results by slot.
    batch_rois: Vec<Roi>,
    batch_results: Vec<Landmarks>,
    frames_since_find: u32,
    /// Someone was lost in this frame's [`Self::track`] (the finder is due in its `find`).
    lost_now: bool,
    /// The detector region the next finder pass looks at (see [`DETECTOR_REGIONS`]).
    next_region: usize,
    stats: TrackerStats,
}

impl PoseTracker {
    /// A tracker with nobody yet. `detector` is required for [`Finder::Detector`]; without
    /// one the tracker searches.
    pub fn new(
        model: LandmarkModel,
        detector: Option<PersonDetector>,
        config: TrackerConfig,
    ) -> PoseTracker {
        let config = TrackerConfig {
            max_people: config.max_people.max(1),
            finder: if detector.is_some() {
                config.finder
            } else {
                Finder::Search
            },
            ..config
        };
        PoseTracker {
            model,
            detector,
            config,
            tracks: vec![Track::EMPTY; config.max_people],
            candidates: Vec::with_capacity(16),
            detections: Vec::with_capacity(super::detector::MAX_DETECTIONS),
            scratch: Landmarks::default(),
            batch_rois: Vec::with_capacity(config.max_people),
            batch_results: vec![Landmarks::default(); config.max_people],
            frames_since_find: 0,
            lost_now: false,
            next_region: 0,
            stats: TrackerStats::default(),
        }
    }

    /// The model (e.g. to change its input range).
    pub fn model_mut(&mut self) -> &mut LandmarkModel {
        &mut self.model
    }

    /// The settings in force (the finder falls back to search without a detector).
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Counters since creation.
    pub fn stats(&self) -> TrackerStats {
        self.stats
    }

    /// Identity slots.
    pub fn max_people(&self) -> usize {
        self.tracks.len()
    }

    /// Landmarks of person `slot` in the last frame (frame pixels), if seen in it.
    pub fn person(&self, slot: usize) -> Option<&Landmarks> {
        self.tracks
            .get(slot)
            .filter(|t| t.seen)
            .map(|t| &t.landmarks)
    }

    /// The ROI that person `slot` will be cropped with next frame, if tracked.
    pub fn roi(&self, slot: usize) -> Option<Roi> {
        self.tracks.get(slot).and_then(|t| t.roi)
    }

    /// Forgets everyone; the next frame looks for people afresh.
    pub fn reset(&mut self) {
        self.tracks.fill(Track::EMPTY);
    }

    /// Processes one frame: every tracked person once ([`Self::track`]), then the finder when
    /// it is due ([`Self::find`]). Afterwards [`Self::person`] tells who was seen.
    pub fn process_frame(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.track(frame)?;
        self.find(frame)
    }

    /// The first half of [`Self::process_frame`]: every tracked person once. Afterwards
    /// [`Self::person`] tells who was followed; [`Self::find`] must run next on the same frame
    /// (it may add people and keeps the frame counts). A live camera publishes these people's
    /// poses in between, so that a finder pass never holds them up.
    pub fn track(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.run_tracked_crops(frame)?;
        let mut lost_now = false;
        let mut batched = 0;
        for slot in 0..self.tracks.len() {
            self.tracks[slot].seen = false;
            let Some(roi) = self.tracks[slot].roi else {
                continue;
            };
            self.scratch = self.batch_results[batched];
            batched += 1;
            if self.follow(frame, slot, roi)? {
                let found = self.scratch;
                self.accept(slot, &found);
            } else {
                self.tracks[slot].lose();
                self.stats.tracks_lost += 1;
                lost_now = true;
            }
        }
        lost_now |= self.drop_duplicates();
        self.lost_now = lost_now;
        Ok(())
    }

    /// The second half of [`Self::process_frame`], after [`Self::track`] on the same frame:
    /// looks for people when the finder is due (those found are seen in this frame too).
    pub fn find(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        let num_tracked = self.tracks.iter().filter(|t| t.tracked()).count();
        self.frames_since_find = self.frames_since_find.saturating_add(1);
        let recently_lost = self
            .tracks
            .iter()
            .any(|t| t.recently_lost(EAGER_FIND_FRAMES));
        let due = std::mem::take(&mut self.lost_now)
            || recently_lost
            || num_tracked == 0
            || self.frames_since_find >= self.config.find_every_frames;
        if num_tracked < self.tracks.len() && due {
            self.frames_since_find = 0;
            let started = std::time::Instant::now();
            self.look_where_lost(frame)?;
            match self.config.finder {
                Finder::Detector => self.find_by_detector(frame)?,
                Finder::Search => self.find_by_search(frame)?,
            }
            self.stats.find_nanos += started.elapsed().as_nanos() as u64;
        }
        for t in self.tracks.iter_mut() {
            if t.tracked() {
                t.held_frames = t.held_frames.saturating_add(1);
            } else {
                t.lost_frames = t.lost_frames.saturating_add(1);
            }
        }
        Ok(())
    }

    /// Single-person convenience: processes the frame and copies person `#0` into `out`.
    /// Returns whether `#0` was seen.
    pub fn process(&mut self, frame: &RgbFrame, out: &mut Landmarks) -> Result<bool, VisionError> {
        self.process_frame(frame)?;
        match self.person(0) {
            Some(lm) => {
                *out = *lm;
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Runs the landmark model once on every tracked person's crop, in one batch, into
    /// `self.batch_results` (in slot order). The crops come from the last frame, so no result
    /// depends on another: what the checks after it compare is unchanged by running them
    /// together.
    fn run_tracked_crops(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.batch_rois.clear();
        self.batch_rois
            .extend(self.tracks.iter().filter_map(|t| t.roi));
        let n = self.batch_rois.len();
        if n == 0 {
            return Ok(());
        }
        self.model
            .infer_batch(frame, &self.batch_rois, &mut self.batch_results[..n])?;
        self.stats.inferences += n as u64;
        Ok(())
    }

    /// Says whether `self.scratch`, the landmark run for tracked person `slot` on `roi`,
    /// continues the track. A result that lies on another tracked person's body (see
    /// [`ON_OTHER_BODY`]) is not this person: crops shifted away from the other person
    /// ([`SIDE_STEPS`]) are tried instead, and the first that shows a body of its own
    /// continues the track.
    fn follow(&mut self, frame: &RgbFrame, slot: usize, roi: Roi) -> Result<bool, VisionError> {
        let keep = self.config.keep_presence_threshold;
        if self.shows_own_body(slot, keep) {
            return Ok(true);
        }
        self.look_beside(frame, slot, roi, keep)
    }

    /// When `self.scratch` (the result on `roi`) lies on another tracked person's body, runs
    /// the crops shifted away from that person ([`SIDE_STEPS`]) until one shows a body of
    /// `slot`'s own (presence at least `presence`); returns whether one did (its result in
    /// `self.scratch`).
    fn look_beside(
        &mut self,
        frame: &RgbFrame,
        slot: usize,
        roi: Roi,
        presence: f32,
    ) -> Result<bool, VisionError> {
        let Some(other) = self.other_body_under(slot) else {
            return Ok(false);
        };
        self.stats.slides_caught += 1;
        let away = (roi.center - hip_centre(&self.tracks[other].landmarks)).normalize_or_zero();
        // People stand on one floor, so two bodies overlapping in the picture are side by
        // side: when `away` also points up or down (one stands nearer the camera, or jumps),
        // its sideways part is tried too.
        let sideways = Vec2::new(away.x, 0.0).normalize_or_zero();
        let directions = [
            Some(away),
            (away.y.abs() > SIDEWAYS_ALSO).then_some(sideways),
        ];
        for dir in directions.into_iter().flatten() {
            for step in SIDE_STEPS {
                let crop = Roi {
                    center: roi.center + dir * step * roi.size,
                    ..roi
                };
                self.model.infer(frame, &crop, &mut self.scratch)?;
                self.stats.inferences += 1;
                if self.shows_own_body(slot, presence) {
                    return Ok(true);
                }
            }
        }
        self.look_with_face_hidden(frame, slot, roi, other, presence)
    }

    /// The last resort of [`Self::look_beside`]: upright crops at `roi` and shifted away
    /// from `other` ([`MASKED_STEPS`]), `other`'s face painted over
    /// ([`LandmarkModel::infer_masked`]). Returns whether one showed `slot`'s own body.
    ///
    /// Upright because `roi`'s rotation came from a reading that slid: tilted towards the
    /// other person, it puts more of them in the crop.
    fn look_with_face_hidden(
        &mut self,
        frame: &RgbFrame,
        slot: usize,
        roi: Roi,
        other: usize,
        presence: f32,
    ) -> Result<bool, VisionError> {
        let theirs = &self.tracks[other].landmarks;
        let Some(face) = face_disc(theirs) else {
            return Ok(false);
        };
        let away = (roi.center - hip_centre(theirs)).normalize_or_zero();
        for step in MASKED_STEPS {
            let crop = Roi {
                center: roi.center + away * step * roi.size,
                rotation: 0.0,
                ..roi
            };
            self.model
                .infer_masked(frame, &crop, face, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.shows_own_body(slot, presence) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// True when `self.scratch` can be person `slot` this frame: it continues their track
    /// and lies on nobody else's body.
    fn shows_own_body(&self, slot: usize, presence: f32) -> bool {
        self.continues_track(slot, presence) && self.other_body_under(slot).is_none()
    }

    /// True when `self.scratch` can be person `slot` this frame: present enough, and a body
    /// box that continues theirs.
    fn continues_track(&self, slot: usize, presence: f32) -> bool {
        self.scratch.presence >= presence
            && self.tracks[slot]
                .place
                .is_none_or(|p| continues(p, body_box(&self.scratch)))
    }

    /// Another tracked person whose body `self.scratch` lies on (their landmarks of this
    /// frame when already processed, else of the last).
    fn other_body_under(&self, slot: usize) -> Option<usize> {
        (0..self.tracks.len()).find(|&b| {
            let t = &self.tracks[b];
            b != slot && t.tracked() && body_distance(&self.scratch, &t.landmarks) < ON_OTHER_BODY
        })
    }

    /// Takes `lm` as person `slot`'s landmarks this frame.
    fn accept(&mut self, slot: usize, lm: &Landmarks) {
        let guard = self.config.swap_guard;
        let t = &mut self.tracks[slot];
        t.landmarks = *lm;
        if let Some(reference) = t.reference.as_ref().filter(|_| guard) {
            if labels_swapped(reference, &t.landmarks) {
                flip_interpretation(&mut t.landmarks);
                self.stats.swaps_fixed += 1;
            }
        }
        t.roi = next_roi(&t.landmarks);
        if t.roi.is_some() {
            t.last_roi = t.roi;
        }
        t.seen = true;
        t.lost_frames = 0;
        t.previous_place = t.place;
        t.place = Some(body_box(&t.landmarks));
        update_reference(&mut t.reference, &t.landmarks);
    }

    /// Drops one of every two tracks that now cover the same body: the one not yet
    /// established, else the one whose box jumped further from its previous frame (it is the
    /// one that slid onto the other person).
    /// Returns whether any was dropped.
    fn drop_duplicates(&mut self) -> bool {
        let mut dropped = false;
        for a in 0..self.tracks.len() {
            for b in a + 1..self.tracks.len() {
                let (ta, tb) = (&self.tracks[a], &self.tracks[b]);
                if !(ta.seen && tb.seen) {
                    continue;
                }
                if !same_body(&ta.landmarks, &tb.landmarks) {
                    continue;
                }
                let jump = |t: &Track| {
                    t.previous_place
                        .zip(t.place)
                        .map_or(f32::INFINITY, |(p, c)| {
                            p.0.distance(c.0) / p.1.max_element().max(1.0)
                        })
                };
                // A track not yet established is the same person found twice; else the one
                // that jumped further slid onto the other person.
                let young = |t: &Track| t.held_frames < ESTABLISHED_FRAMES;
                let loser = match (young(ta), young(tb)) {
                    (true, false) => a,
                    (false, true) => b,
                    _ if jump(ta) > jump(tb) => a,
                    _ => b,
                };
                let t = &mut self.tracks[loser];
                t.lose();
                // Remember where it was before it slid, for taking the slot back.
                t.place = t.previous_place;
                self.stats.duplicates_dropped += 1;
                dropped = true;
            }
        }
        dropped
    }

    /// True when `hips` (frame pixels) lie near a tracked person's hips: the detector's box is
    /// the face, so its hip keypoint is what says whom it found.
    fn is_tracked_at(&self, hips: Vec2) -> bool {
        self.tracks.iter().filter(|t| t.tracked()).any(|t| {
            t.place
                .is_some_and(|(_, s)| hip_centre(&t.landmarks).distance(hips) < TRACKED_HIPS * s.y)
        })
    }

    /// True when `lm` is the body of someone tracked (see [`same_body`]).
    fn is_tracked_body(&self, lm: &Landmarks) -> bool {
        self.tracks
            .iter()
            .filter(|t| t.tracked())
            .any(|t| same_body(&t.landmarks, lm))
    }

    /// One landmark run at the last crop of each recently lost person: someone hidden for a
    /// few frames usually reappears where they were, often facing away from the camera where
    /// the (face-based) detector cannot see them.
    fn look_where_lost(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        for slot in 0..self.tracks.len() {
            let t = &self.tracks[slot];
            if !t.recently_lost(EAGER_FIND_FRAMES) {
                continue;
            }
            let Some(roi) = t.last_roi else { continue };
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            let presence = self.config.presence_threshold;
            if self.shows_own_body(slot, presence)
                || self.look_beside(frame, slot, roi, presence)?
            {
                let found = self.scratch;
                self.tracks[slot].reference = None;
                self.accept(slot, &found);
            }
        }
        Ok(())
    }

    /// The detector while someone is missing. Looking for more people while nobody was lost
    /// is one pass over the next of the [`DETECTOR_REGIONS`] (they take turns), so it costs one
    /// pass however long nobody else comes. While nobody is tracked or someone established was
    /// lost within [`EAGER_FIND_FRAMES`], every region in order, as a tracker of one person
    /// does to find them again.
    fn find_by_detector(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        let searching = !self.tracks.iter().any(Track::tracked)
            || self
                .tracks
                .iter()
                .any(|t| t.recently_lost(EAGER_FIND_FRAMES));
        let regions = if searching {
            0..DETECTOR_REGIONS
        } else {
            self.next_region = (self.next_region + 1) % DETECTOR_REGIONS;
            self.next_region..self.next_region + 1
        };
        Roi::search_candidates(frame.width, frame.height, &mut self.candidates);
        for region in regions {
            if self.tracks.iter().all(Track::tracked) {
                break;
            }
            let Some(detector) = self.detector.as_mut() else {
                return Ok(());
            };
            detector.detect_in(frame, &self.candidates[region], &mut self.detections)?;
            self.stats.detections += 1;
            self.start_detected(frame)?;
        }
        Ok(())
    }

    /// Starts tracks for this detector pass's detections that are nobody tracked yet.
    fn start_detected(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        // Nearest (largest body circle) first: performers stand in front of bystanders.
        self.detections
            .sort_unstable_by(|a, b| b.body_radius().total_cmp(&a.body_radius()));
        for i in 0..self.detections.len() {
            if self.tracks.iter().all(|t| t.tracked()) {
                break;
            }
            let d = self.detections[i];
            if self.is_tracked_at(d.hip_center) {
                continue;
            }
            let Some(roi) = d.roi() else { continue };
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.scratch.presence >= self.config.presence_threshold
                && upright_as_detected(&self.scratch, &d)
            {
                let found = self.scratch;
                self.start_track(&found);
            }
        }
        Ok(())
    }

    fn find_by_search(&mut self, frame: &RgbFrame) -> Result<(), VisionError> {
        self.stats.searches += 1;
        Roi::search_candidates(frame.width, frame.height, &mut self.candidates);
        let mut best = Landmarks::default();
        let mut best_presence = -1.0;
        for i in 0..self.candidates.len() {
            let roi = self.candidates[i];
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.scratch.presence > best_presence {
                // A crop showing someone already tracked does not count.
                if !self.is_tracked_body(&self.scratch) {
                    best_presence = self.scratch.presence;
                    best = self.scratch;
                }
            }
        }
        if best_presence < self.config.presence_threshold {
            return Ok(());
        }
        // Re-crop around the person found; keep a refinement only if it is still a person.
        for _ in 0..self.config.refine_passes {
            let Some(roi) = next_roi(&best) else { break };
            self.model.infer(frame, &roi, &mut self.scratch)?;
            self.stats.inferences += 1;
            if self.scratch.presence < self.config.presence_threshold {
                break;
            }
            best = self.scratch;
        }
        self.start_track(&best);
        Ok(())
    }

    /// Gives a newly found person a slot (see [`Self::slot_for`]) and starts their track.
    fn start_track(&mut self, lm: &Landmarks) {
        if self.is_tracked_body(lm) {
            return;
        }
        let Some((slot, same_person)) = self.slot_for(lm) else {
            return;
        };
        let t = &mut self.tracks[slot];
        t.place = None;
        t.previous_place = None;
        if !same_person {
            t.held_frames = 0;
            t.reference = None;
        }
        self.accept(slot, lm);
        self.stats.tracks_started += 1;
    }

    /// The slot for a newly found person `lm`, and whether it is someone the slot held: the
    /// recently lost slot they are nearest to, else a slot nobody held recently. While someone else is tracked, a person found
    /// away from everyone recently lost is left alone for
    /// [`TrackerConfig::reacquire_frames`] (most likely a bystander while the performer is
    /// hidden); while nobody is, only for [`ALONE_WAIT_FRAMES`], and then they take the
    /// lowest free slot.
    fn slot_for(&self, lm: &Landmarks) -> Option<(usize, bool)> {
        let center = body_box(lm).0;
        let window = self.config.reacquire_frames;
        let nearest = self
            .tracks
            .iter()
            .enumerate()
            .filter(|(_, t)| t.recently_lost(window))
            .filter_map(|(i, t)| {
                let (c, s) = t.place?;
                let d = c.distance(center) / s.max_element().max(1.0);
                (d < 0.5).then_some((i, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        if let Some(slot) = nearest {
            return Some((slot, true));
        }
        let anyone_tracked = self.tracks.iter().any(Track::tracked);
        let free = if anyone_tracked {
            self.tracks
                .iter()
                .position(|t| !t.tracked() && !t.recently_lost(window))
        } else if self
            .tracks
            .iter()
            .any(|t| t.recently_lost(ALONE_WAIT_FRAMES))
        {
            None
        } else {
            Some(0)
        };
        free.map(|slot| (slot, false))
    }
}

/// The disc covering `lm`'s head: around the nose, out past the ears (at least half the
/// shoulder width, for a head seen from the side); None when no head is seen.
fn face_disc(lm: &Landmarks) -> Option<Disc> {
    let point = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let ears = point(idx::LEFT_EAR).distance(point(idx::RIGHT_EAR));
    let shoulders = point(idx::LEFT_SHOULDER).distance(point(idx::RIGHT_SHOULDER));
    let radius = (0.75 * ears).max(FACE_RADIUS * shoulders);
    (radius > 1.0).then_some(Disc {
        center: point(idx::NOSE),
        radius,
    })
}

/// Least radius of a hidden face, in shoulder widths.
const FACE_RADIUS: f32 = 0.5;

/// Landmarks compared to tell one body found twice from two bodies that overlap on screen.
const BODY_POINTS: [usize; 8] = [
    idx::LEFT_SHOULDER,
    idx::RIGHT_SHOULDER,
    idx::LEFT_HIP,
    idx::RIGHT_HIP,
    idx::LEFT_KNEE,
    idx::RIGHT_KNEE,
    idx::LEFT_ANKLE,
    idx::RIGHT_ANKLE,
];

/// True when two landmark sets are the same body: their joints lie on top of each other
/// (mean distance under a tenth of the body's height). People crossing overlap as boxes but
/// not joint by joint. Compared under both labellings: the flip guard may have exchanged one
/// track's left and right (its reference faced the other way), and the same body read with
/// swapped labels is still one body found twice.
fn same_body(a: &Landmarks, b: &Landmarks) -> bool {
    body_distance(a, b) < 0.1
}

/// How far apart two landmark sets' bodies are: the mean distance of their [`BODY_POINTS`],
/// under the closer of the two labellings, in the taller body's heights.
fn body_distance(a: &Landmarks, b: &Landmarks) -> f32 {
    let height = body_box(a).1.y.max(body_box(b).1.y).max(1.0);
    let mean = |mirrored: bool| {
        BODY_POINTS
            .iter()
            .map(|&i| {
                let j = if mirrored { mirror_index(i) } else { i };
                Vec2::new(a.image[i].x - b.image[j].x, a.image[i].y - b.image[j].y).length()
            })
            .sum::<f32>()
            / BODY_POINTS.len() as f32
    };
    mean(false).min(mean(true)) / height
}

/// The landmark of the other side for `i` (itself for the centre line).
fn mirror_index(i: usize) -> usize {
    LR_PAIRS
        .iter()
        .find_map(|&(l, r)| {
            if l == i {
                Some(r)
            } else if r == i {
                Some(l)
            } else {
                None
            }
        })
        .unwrap_or(i)
}

/// True when body box `next` can be the same person as `last` one frame later: about the
/// same height and not far away. Two people crossing differ in both (the one behind looks
/// smaller), so a crop that slides from one to the other shows up as a jump.
fn continues(last: (Vec2, Vec2), next: (Vec2, Vec2)) -> bool {
    let (h0, h1) = (last.1.y.max(1.0), next.1.y.max(1.0));
    let ratio = h1 / h0;
    (0.75..=1.33).contains(&ratio) && last.0.distance(next.0) < 0.3 * h0
}

/// Midpoint of the hips, frame pixels.
fn hip_centre(lm: &Landmarks) -> Vec2 {
    let (l, r) = (lm.image[idx::LEFT_HIP], lm.image[idx::RIGHT_HIP]);
    Vec2::new(l.x + r.x, l.y + r.y) * 0.5
}

/// The box around the 33 body landmarks (centre, size), frame pixels.
fn body_box(lm: &Landmarks) -> (Vec2, Vec2) {
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for p in &lm.image[..NUM_LANDMARKS] {
        let p = Vec2::new(p.x, p.y);
        if p.is_finite() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    if lo.x > hi.x {
        return (Vec2::ZERO, Vec2::ZERO);
    }
    ((lo + hi) * 0.5, hi - lo)
}

/// True when the reading `lm` of detection `d`'s crop stands the way the detector saw the
/// person (hips towards head within a quarter turn of the detection's): a reading upside down
/// against its own detection (a crop the model filled with the body's mirror image, the head
/// read at the feet) is nobody the two models agree on.
fn upright_as_detected(lm: &Landmarks, d: &Detection) -> bool {
    let point = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let read = point(idx::AUX_SCALE) - point(idx::AUX_CENTER);
    read.dot(d.body_scale - d.hip_center) > 0.0
}

fn next_roi(lm: &Landmarks) -> Option<Roi> {
    let c = lm.image[idx::AUX_CENTER];
    let s = lm.image[idx::AUX_SCALE];
    Roi::from_alignment(Vec2::new(c.x, c.y), Vec2::new(s.x, s.y))
}

/// Torso lines (left minus right, world) of hips and shoulders: what the flip guard compares.
fn torso_lines(lm: &Landmarks) -> [Vec3; 2] {
    GUARD_PAIRS.map(|(l, r)| lm.world[l] - lm.world[r])
}

/// The torso lines after [`flip_interpretation`]: left and right exchange (negating the line)
/// and depth is mirrored, so x and y change sign and z stays.
fn flipped_lines(lines: [Vec3; 2]) -> [Vec3; 2] {
    lines.map(|v| Vec3::new(-v.x, -v.y, v.z))
}

/// True when the current frame fits the reference better with its reading flipped.
///
/// Why: on ambiguous views (a blurred face, a side view) the model sometimes switches between
/// "facing the camera" and "facing away" — the two readings of the same image, one the other
/// mirrored in depth with left and right exchanged — often for single frames, sometimes
/// through a degenerate in-between frame. Comparing against a reference that follows the
/// accepted frames with some inertia (rather than against the last frame alone) keeps one
/// degenerate frame from deciding the labels of all that follow.
fn labels_swapped(reference: &[Vec3; 2], cur: &Landmarks) -> bool {
    let same = torso_lines(cur);
    let flipped = flipped_lines(same);
    let cost = |lines: &[Vec3; 2]| -> f32 {
        lines
            .iter()
            .zip(reference)
            .map(|(a, b)| a.distance(*b))
            .sum()
    };
    cost(&flipped) < cost(&same)
}

/// Moves the reference torso lines towards the accepted frame's.
fn update_reference(reference: &mut Option<[Vec3; 2]>, lm: &Landmarks) {
    let lines = torso_lines(lm);
    *reference = Some(match *reference {
        Some(r) => [
            r[0].lerp(lines[0], REFERENCE_RATE),
            r[1].lerp(lines[1], REFERENCE_RATE),
        ],
        None => lines,
    });
}

/// The other reading of the same image: depth mirrored, left and right labels exchanged.
/// (Two mirrors make a proper rotation, so the result is a valid body.)
fn flip_interpretation(lm: &mut Landmarks) {
    for p in lm.world.iter_mut() {
        p.z = -p.z;
    }
    for p in lm.image.iter_mut() {
        p.z = -p.z;
    }
    for &(l, r) in &LR_PAIRS {
        lm.image.swap(l, r);
        lm.world.swap(l, r);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn person(offset_x: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for &(l, r) in &LR_PAIRS {
            let y = l as f32 * 10.0;
            lm.image[l] = Vec4::new(offset_x + 50.0, y, 0.0, 1.0);
            lm.image[r] = Vec4::new(offset_x - 50.0, y, 0.0, 1.0);
            lm.world[l] = Vec3::new(0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
            lm.world[r] = Vec3::new(-0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
        }
        lm
    }

    #[test]
    fn one_body_read_with_swapped_labels_is_still_one_body() {
        let a = person(0.0);
        let mut b = person(4.0);
        flip_interpretation(&mut b);
        assert!(same_body(&a, &b), "a relabelled copy is the same body");
        // Two people side by side (apart by more than their shoulder width) are not.
        assert!(!same_body(&a, &person(300.0)));
        let mut far = person(300.0);
        flip_interpretation(&mut far);
        assert!(!same_body(&a, &far));
    }

    #[test]
    fn a_depth_flip_is_detected_and_undone() {
        let mut reference = None;
        update_reference(&mut reference, &person(0.0));
        let reference = reference.unwrap();
        let mut cur = person(3.0);
        assert!(!labels_swapped(&reference, &cur));
        flip_interpretation(&mut cur);
        assert!(labels_swapped(&reference, &cur));
        flip_interpretation(&mut cur);
        assert_eq!(cur, person(3.0));
    }

    #[test]
    fn a_flip_keeps_limb_lengths_and_mirrors_depth() {
        let mut lm = person(0.0);
        lm.world[idx::LEFT_ELBOW].z = 0.2;
        let before = lm.world[idx::LEFT_SHOULDER].distance(lm.world[idx::LEFT_ELBOW]);
        flip_interpretation(&mut lm);
        let after = lm.world[idx::RIGHT_SHOULDER].distance(lm.world[idx::RIGHT_ELBOW]);
        assert!((before - after).abs() < 1e-6);
        assert_eq!(lm.world[idx::RIGHT_ELBOW].z, -0.2);
    }

    #[test]
    fn a_reading_upside_down_against_its_detection_is_refused() {
        let mut lm = person(0.0);
        lm.image[idx::AUX_CENTER] = Vec4::new(0.0, 200.0, 0.0, 1.0);
        lm.image[idx::AUX_SCALE] = Vec4::new(0.0, 50.0, 0.0, 1.0);
        let mut d = Detection {
            score: 0.9,
            center: Vec2::new(0.0, 40.0),
            size: Vec2::splat(40.0),
            hip_center: Vec2::new(10.0, 190.0),
            body_scale: Vec2::new(30.0, 60.0),
        };
        assert!(upright_as_detected(&lm, &d));
        d.body_scale = Vec2::new(0.0, 330.0);
        assert!(!upright_as_detected(&lm, &d));
    }
}
