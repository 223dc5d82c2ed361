//! Frame features: what "two frames look alike" means for the graph.
//!
//! Following Kovar, Gleicher and Pighin (2002), a frame is judged together with its
//! neighbourhood in time, as a point cloud of body points over a short window, after aligning
//! both windows on the floor (a rotation about up and a horizontal shift). Here the alignment
//! is the centre frame's heading (see [`super::body::Planar`]) rather than the least-squares
//! optimum, so every frame's window can be written down once as a vector and a frame distance
//! is a plain Euclidean distance between two vectors — which is what makes the pruned search
//! in [`super::search`] possible. The vector of frame `i` holds:
//!
//! - the body points of frames `i − h`, `i` and `i + h` (`h` = half the window), in frame
//!   `i`'s heading frame: posture plus the root's path over the window;
//! - the points' velocities at `i` (central difference), in the same frame, times
//!   [`super::GraphSettings::velocity_weight_secs`], so that two poses passing each other in
//!   opposite directions are far apart;
//!
//! all in leg lengths, heights above the clip's own floor (its lowest foot), along the body's
//! own axes (left, up, forward), so clips of different rigs and captures compare, whichever
//! way their files point up and forward.

use glam::Vec3;

use super::body::{BodyPoints, Planar, NUM_POINTS};
use crate::fk::WorldTransform;
use crate::pose::Pose;
use crate::skeleton::Skeleton;

/// What the frame vectors hold, for caches of graphs built from them: 2 since they are written
/// along the body's axes rather than the file's.
pub const FEATURES_VERSION: u32 = 2;

/// Taps of the window: before, centre, after.
const TAPS: usize = 3;
/// Values per block (one tap's points, or the velocities), padded with zeros to a multiple
/// of [`LANES`] so the distance runs on whole SIMD registers.
pub const BLOCK: usize = (NUM_POINTS * 3).div_ceil(LANES) * LANES;
/// Values per frame vector.
pub const DIM: usize = (TAPS + 1) * BLOCK;
/// Independent partial sums in the distance loop (the compiler keeps them in vector registers;
/// one running sum would be a chain of dependent adds it may not reorder).
pub const LANES: usize = 8;

/// Body points and headings of every frame of one clip (world space of its rig).
#[derive(Debug, Clone)]
pub struct ClipTrack {
    /// Points per frame.
    pub points: Vec<[Vec3; NUM_POINTS]>,
    /// Heading frame per frame.
    pub headings: Vec<Planar>,
    /// The clip's floor: its lowest foot height along up.
    pub floor: f32,
    /// The rig's up axis.
    pub up: Vec3,
    /// The rig's forward and left (the analysis'): a frame's vector is written along the
    /// body's own axes, so rigs built along other axes (Z-up, facing −Z) compare.
    pub forward: Vec3,
    /// The rig's left.
    pub left: Vec3,
    /// Leg length, metres.
    pub leg: f32,
}

impl ClipTrack {
    /// Measures every frame of `poses` (all fitting `skeleton`).
    pub fn measure(skeleton: &Skeleton, body: &BodyPoints, poses: &[Pose]) -> ClipTrack {
        let mut worlds = vec![WorldTransform::IDENTITY; skeleton.num_bones()];
        let points: Vec<_> = poses
            .iter()
            .map(|p| body.points(skeleton, p, &mut worlds))
            .collect();
        let headings = points.iter().map(|p| body.heading(p)).collect();
        let up = body.up();
        let floor = points
            .iter()
            .flat_map(|p| [p[NUM_POINTS - 2], p[NUM_POINTS - 1]])
            .map(|p| p.dot(up))
            .fold(f32::INFINITY, f32::min);
        ClipTrack {
            points,
            headings,
            floor: if floor.is_finite() { floor } else { 0.0 },
            up,
            forward: body.forward(),
            left: body.left(),
            leg: body.leg_length(),
        }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the clip has no frames.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Frame vectors of one clip: `DIM` values for each frame whose window fits in the clip
/// (frames `half .. len − half`), `None` for the others.
#[derive(Debug, Clone)]
pub struct ClipFeatures {
    /// Half window in frames (the tap distance).
    pub half: usize,
    /// Frames of the clip.
    pub len: usize,
    values: Vec<f32>,
}

impl ClipFeatures {
    /// Computes the vectors of `track` with a half window of `half` frames (≥ 1), velocities
    /// weighted by `velocity_weight_secs`, at `frame_time_secs` per frame.
    pub fn compute(
        track: &ClipTrack,
        half: usize,
        frame_time_secs: f32,
        velocity_weight_secs: f32,
    ) -> ClipFeatures {
        let half = half.max(1);
        let n = track.len();
        let valid = n.saturating_sub(2 * half);
        let mut values = vec![0.0; valid * DIM];
        let scale = 1.0 / track.leg;
        let vel_scale = scale * velocity_weight_secs / (2.0 * frame_time_secs);
        // Along the body's axes (left, up, forward), not the file's.
        let along = |v: Vec3| Vec3::new(v.dot(track.left), v.dot(track.up), v.dot(track.forward));
        for (k, out) in values.chunks_exact_mut(DIM).enumerate() {
            let i = k + half;
            let to_local = track.headings[i].inverse(track.up);
            let floor = track.up * track.floor;
            let mut blocks = out.chunks_exact_mut(BLOCK);
            for tap in [i - half, i, i + half] {
                let block = blocks.next().unwrap_or_default();
                for (slot, p) in block.chunks_exact_mut(3).zip(&track.points[tap]) {
                    let v = along(to_local.apply(track.up, *p - floor)) * scale;
                    slot.copy_from_slice(&v.to_array());
                }
            }
            let turn = to_local.rotation(track.up);
            let block = blocks.next().unwrap_or_default();
            let velocities = track.points[i + 1].iter().zip(&track.points[i - 1]);
            for (slot, (a, b)) in block.chunks_exact_mut(3).zip(velocities) {
                slot.copy_from_slice(&(along(turn * (*a - *b)) * vel_scale).to_array());
            }
        }
        ClipFeatures {
            half,
            len: n,
            values,
        }
    }

    /// The vector of frame `i`, if its window fits.
    pub fn get(&self, i: usize) -> Option<&[f32]> {
        if i < self.half || i + self.half >= self.len {
            return None;
        }
        let k = i - self.half;
        Some(&self.values[k * DIM..(k + 1) * DIM])
    }

    /// The first and one-past-last frame with a vector.
    pub fn valid_range(&self) -> std::ops::Range<usize> {
        self.half..self.len.saturating_sub(self.half).max(self.half)
    }
}

/// Squared distance between two frame vectors, giving up (returning a value above `bound`)
/// as soon as the partial sum passes `bound`: most pairs of a database are far apart, and the
/// first points (posture at the window start) already tell.
#[inline]
pub fn distance_sq_bounded(a: &[f32], b: &[f32], bound: f32) -> f32 {
    let mut sum = 0.0;
    let (blocks_a, _) = a.as_chunks::<BLOCK>();
    let (blocks_b, _) = b.as_chunks::<BLOCK>();
    for (ba, bb) in blocks_a.iter().zip(blocks_b) {
        // Fixed-size blocks and a difference array per chunk: written this way the compiler
        // uses whole 4-wide registers (a loop over slice chunks came out 2 floats at a time).
        // Each lane still sums in chunk order, so the result is the same to the bit.
        let mut lanes = [0.0f32; LANES];
        for c in 0..BLOCK / LANES {
            let mut d = [0.0f32; LANES];
            for (l, d) in d.iter_mut().enumerate() {
                *d = ba[c * LANES + l] - bb[c * LANES + l];
            }
            for (lane, d) in lanes.iter_mut().zip(d) {
                *lane += d * d;
            }
        }
        sum += lanes.iter().sum::<f32>();
        if sum > bound {
            return sum;
        }
    }
    sum
}

/// The frame distance reported everywhere (thresholds, edge costs, join checks): the RMS
/// distance per compared point, in leg lengths.
#[inline]
pub fn rms(distance_sq: f32) -> f32 {
    (distance_sq / ((TAPS + 1) * NUM_POINTS) as f32).sqrt()
}

/// The squared distance whose [`rms`] is `threshold`.
#[inline]
pub fn squared_bound(threshold: f32) -> f32 {
    threshold * threshold * ((TAPS + 1) * NUM_POINTS) as f32
}

/// The distance between two frames' vectors (full, never bounded).
pub fn frame_distance(a: &[f32], b: &[f32]) -> f32 {
    rms(distance_sq_bounded(a, b, f32::INFINITY))
}
