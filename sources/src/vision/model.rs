//! The BlazePose landmark model run through ONNX Runtime (`ort`, library loaded at run time).
//!
//! Per call: warp the ROI of the frame into the model's 256×256 RGB input (bilinear, black
//! outside the frame), run the model, and map its outputs back: landmarks from crop pixels to
//! frame pixels, world landmarks rotated by the ROI's in-plane rotation (as MediaPipe's
//! world-landmark projection does), visibility and presence through a sigmoid. The body's
//! landmarks' refinement from the model's heatmaps is read too when the model file has them
//! (the pruned models do since setup's derivation 3), as MediaPipe's pose graph refines its
//! own, and kept beside the landmarks for the output ([`Landmarks::refined`]): the lite
//! model's limbs then land nearer the 3D reference's projection on seven of eight calibrated
//! cameras, for about a tenth more work a run (`RIGCAST_NO_HEATMAP=1` reads none, to
//! compare). Several crops
//! (one per tracked person) can run in one call when the model file's batch dimension is
//! dynamic, which the pruned models made by `scripts/prune_landmark_model.py` have. Buffers
//! are allocated once in [`LandmarkModel::load`]. The crop is written in the layout the model
//! file's input declares ([`InputLayout`]): channels first for the models setup derives
//! since its derivation 5, channels last as converted.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::{Vec2, Vec3, Vec4};
use ort::environment::Environment;
use ort::session::builder::GraphOptimizationLevel;
use ort::session::Session;
use ort::value::{Tensor, ValueType};

use super::bound::{model_err, output_shape, takes_batches, BoundRun};
use super::error::VisionError;
use super::frame::RgbFrame;
use super::landmarks::{sigmoid, Landmarks, NUM_MODEL_LANDMARKS};
use super::roi::Roi;

/// Side of the model's square input, pixels.
pub const INPUT_SIZE: usize = 256;

const OUT_LANDMARKS: &str = "Identity";
const OUT_PRESENCE: &str = "Identity_1";
const OUT_WORLD: &str = "Identity_4";
const OUT_HEATMAP: &str = "Identity_3";
/// Side of the model's heatmaps (one a landmark, channels last), cells.
const HEATMAP_SIDE: usize = 64;
/// Cells either side of a landmark's cell that its heatmap refinement weighs.
const HEATMAP_REACH: i32 = 3;
/// A landmark is refined from its heatmap when the window's strongest cell is at least this
/// sure of it.
const HEATMAP_SURE: f32 = 0.5;
/// The landmarks refined from their heatmaps: the body's, shoulders to feet. Not the face's:
/// the left/right readings (`sides.rs`, and the smoothing's exchange of sides) take a
/// reading as evidence only when its ears lie the way its torso faces, and the face's
/// heatmaps can follow the face while the regression head follows the body's reading (the
/// lite model's back readings of pose2sim's cam02, a man facing the camera, refined, left
/// the guard mirrored on 29 of 100 frames). Not the crop's alignment points either: the
/// refinement reaches the output only ([`Landmarks::refined`]), the tracker follows the
/// regression head (refined, its tracks took other paths on the two-person clips).
const REFINED: std::ops::Range<usize> = 11..33;

/// How a model's input holds an image's values: as converted from TFLite the channels come
/// last (each pixel's red, green, blue together); setup's derived models take them first
/// (`scripts/planar_input.py`: one plane a channel), which spares ONNX Runtime a transpose
/// and a pad over the whole input each run for the same outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputLayout {
    /// `[batch, side, side, 3]`.
    ChannelsLast,
    /// `[batch, 3, side, side]`.
    ChannelsFirst,
}

impl InputLayout {
    /// Where value `ch` of crop pixel (`u`, `v`) lies in a `side²` crop.
    #[inline(always)]
    fn index(self, side: usize, u: usize, v: usize, ch: usize) -> usize {
        match self {
            InputLayout::ChannelsLast => (v * side + u) * 3 + ch,
            InputLayout::ChannelsFirst => (ch * side + v) * side + u,
        }
    }
}

/// How pixel values are scaled into the model's input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputRange {
    /// `v / 255` — measured to give the higher presence on real footage (see the tests).
    #[default]
    ZeroOne,
    /// `v / 127.5 − 1`.
    MinusOneOne,
}

static RUNTIME: OnceLock<Result<Environment, String>> = OnceLock::new();

/// Loads ONNX Runtime from `library` once per process and returns its environment. A missing
/// or incompatible library is an error, never a panic. Later calls reuse the first library.
pub fn runtime(library: &Path) -> Result<Environment, VisionError> {
    if !library.is_file() {
        return Err(VisionError::NotSetUp {
            path: library.to_path_buf(),
            what: "ONNX Runtime shared library",
        });
    }
    let result = RUNTIME.get_or_init(|| {
        ort::init_from(library)
            .map_err(|e| e.to_string())?
            .with_name("rigcast")
            .with_telemetry(false)
            .build()
            .map_err(|e| e.to_string())
    });
    result.clone().map_err(|message| VisionError::Runtime {
        path: library.to_path_buf(),
        message,
    })
}

/// Intra-op spinning is off unless `RIGCAST_ORT_SPIN=1` (for measuring the difference).
fn spin_enabled() -> bool {
    std::env::var("RIGCAST_ORT_SPIN").as_deref() == Ok("1")
}

/// A loaded landmark model plus its input/output buffers.
pub struct LandmarkModel {
    path: PathBuf,
    session: Session,
    /// Buffers by batch size: `batches[k - 1]` runs `k` crops in one call. Only one entry
    /// unless the model takes batches (its input's first dimension is dynamic).
    batches: Vec<Batch>,
    range: InputRange,
    layout: InputLayout,
}

/// The input and bound outputs of runs on a fixed number of crops.
struct Batch {
    run: Outputs,
    input: Tensor<f32>,
}

/// The outputs fetched: landmarks, presence and world landmarks, and the heatmaps when the
/// model has them (the segmentation mask is never needed; a model pruned before the heatmaps
/// were kept runs without them, unrefined).
enum Outputs {
    Three(BoundRun<3>),
    Four(BoundRun<4>, HeatChannels),
}

/// Which landmarks a model's heatmap channels hold, in order from `first`: all 39 (setup's
/// derivation 3), or only the [`REFINED`] ones (derivation 4 on: the prune script keeps only
/// their channels of the heatmap head's last convolution, whose channels are computed
/// independently, so the values read are the same for less work a run).
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeatChannels {
    count: usize,
    first: usize,
}

/// One crop's heatmaps: 64×64 cells, `channels.count` logits a cell (channels last).
#[derive(Clone, Copy)]
struct Heat<'a> {
    cells: &'a [f32],
    channels: HeatChannels,
}

impl Outputs {
    fn run(&mut self, session: &mut Session, input: &Tensor<f32>) -> Result<(), VisionError> {
        match self {
            Outputs::Three(r) => r.run(session, input),
            Outputs::Four(r, _) => r.run(session, input),
        }
    }

    fn output(&self, i: usize) -> &[f32] {
        match self {
            Outputs::Three(r) => r.output(i),
            Outputs::Four(r, _) => r.output(i),
        }
    }

    /// Crop `i`'s heatmaps from the last run, when fetched.
    fn heatmaps(&self, i: usize) -> Option<Heat<'_>> {
        match self {
            Outputs::Three(_) => None,
            Outputs::Four(r, channels) => {
                let n = HEATMAP_SIDE * HEATMAP_SIDE * channels.count;
                let cells = &r.output(3)[i * n..(i + 1) * n];
                Some(Heat {
                    cells,
                    channels: *channels,
                })
            }
        }
    }
}

debug_fields!(LandmarkModel { path, range });

impl LandmarkModel {
    /// Loads `model` with the runtime in `library`, running inference on `threads` threads,
    /// with buffers for runs on up to `max_batch` crops at once when the model takes batches
    /// (see [`Self::max_batch`]).
    pub fn load(
        library: &Path,
        model: &Path,
        threads: usize,
        max_batch: usize,
    ) -> Result<LandmarkModel, VisionError> {
        let (session, input, layout) =
            open_model(library, model, "landmark model", threads, INPUT_SIZE)?;
        let max_batch = if takes_batches(&session) {
            max_batch.max(1)
        } else {
            1
        };
        let mut batches = Vec::with_capacity(max_batch);
        batches.push(Batch {
            run: landmark_outputs(&session, model, 1)?,
            input,
        });
        for k in 2..=max_batch {
            batches.push(Batch {
                run: landmark_outputs(&session, model, k)?,
                input: input_tensor(model, k, INPUT_SIZE, layout)?,
            });
        }
        let mut model = LandmarkModel {
            path: model.to_path_buf(),
            session,
            batches,
            range: InputRange::default(),
            layout,
        };
        model.warm_up()?;
        Ok(model)
    }

    /// One run of every batch size on the zeroed inputs. A session's first run of a shape
    /// sizes its memory arena and caches its kernels' plans, several times a later run's
    /// cost; done here it overlaps the decoder's start instead of delaying the first frame.
    fn warm_up(&mut self) -> Result<(), VisionError> {
        for batch in &mut self.batches {
            batch.run.run(&mut self.session, &batch.input)?;
        }
        Ok(())
    }

    /// Most crops one [`Self::infer_batch`] call runs together: 1 for a model whose batch
    /// dimension is fixed (pruned models made before batching was added).
    pub fn max_batch(&self) -> usize {
        self.batches.len()
    }

    /// Changes the input scaling (for the empirical range check).
    pub fn set_input_range(&mut self, range: InputRange) {
        self.range = range;
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Runs the model on `roi` of `frame` and writes the result into `out`.
    pub fn infer(
        &mut self,
        frame: &RgbFrame,
        roi: &Roi,
        out: &mut Landmarks,
    ) -> Result<(), VisionError> {
        self.infer_batch(frame, std::slice::from_ref(roi), std::slice::from_mut(out))
    }

    /// Runs the model on each of `rois` of `frame` (at most [`Self::max_batch`] at once; more
    /// run in several calls) and writes result `i` into `outs[i]`. One call on two crops costs
    /// about 0.8 of two single runs on two threads (each layer has twice the work to share).
    pub fn infer_batch(
        &mut self,
        frame: &RgbFrame,
        rois: &[Roi],
        outs: &mut [Landmarks],
    ) -> Result<(), VisionError> {
        debug_assert_eq!(rois.len(), outs.len());
        let (scale, offset) = self.range.scale_offset();
        let max = self.batches.len();
        for (rois, outs) in rois.chunks(max).zip(outs.chunks_mut(max)) {
            let batch = &mut self.batches[rois.len() - 1];
            let (_, data) = batch.input.extract_tensor_mut();
            let per_crop = INPUT_SIZE * INPUT_SIZE * 3;
            for (roi, crop) in rois.iter().zip(data.chunks_exact_mut(per_crop)) {
                warp_crop(frame, roi, INPUT_SIZE, scale, offset, self.layout, crop);
            }
            self.run_filled(rois, outs)?;
        }
        Ok(())
    }

    /// [`Self::infer`] with `disc` (frame pixels) painted mid-grey in the crop: someone
    /// else's face hidden, so that a model drawn to the one face in a crop reads the person
    /// the crop is for (a person seen from behind has no face of their own to offer).
    pub fn infer_masked(
        &mut self,
        frame: &RgbFrame,
        roi: &Roi,
        disc: Disc,
        out: &mut Landmarks,
    ) -> Result<(), VisionError> {
        let (scale, offset) = self.range.scale_offset();
        let (_, data) = self.batches[0].input.extract_tensor_mut();
        warp_crop(frame, roi, INPUT_SIZE, scale, offset, self.layout, data);
        let grey = 127.5 * scale + offset;
        fill_disc(roi, disc, INPUT_SIZE, grey, self.layout, data);
        self.run_filled(std::slice::from_ref(roi), std::slice::from_mut(out))
    }

    /// Runs the batch of `rois.len()` crops whose input is already filled and decodes result
    /// `i` into `outs[i]`.
    fn run_filled(&mut self, rois: &[Roi], outs: &mut [Landmarks]) -> Result<(), VisionError> {
        let batch = &mut self.batches[rois.len() - 1];
        batch.run.run(&mut self.session, &batch.input)?;
        // Lengths were checked against the model when the outputs were bound.
        let (lm, presence, world) = (
            batch.run.output(0),
            batch.run.output(1),
            batch.run.output(2),
        );
        let (n_lm, n_world) = (NUM_MODEL_LANDMARKS * 5, NUM_MODEL_LANDMARKS * 3);
        for (i, (roi, out)) in rois.iter().zip(outs.iter_mut()).enumerate() {
            let lm = &lm[i * n_lm..(i + 1) * n_lm];
            let world = &world[i * n_world..(i + 1) * n_world];
            decode(lm, world, presence[i], batch.run.heatmaps(i), roi, out);
        }
        Ok(())
    }
}

impl InputRange {
    /// The `(scale, offset)` taking a byte `v` to the model's input, `v · scale + offset`.
    fn scale_offset(self) -> (f32, f32) {
        match self {
            InputRange::ZeroOne => (1.0 / 255.0, 0.0),
            InputRange::MinusOneOne => (1.0 / 127.5, -1.0),
        }
    }
}

/// A disc in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    /// Centre, pixels.
    pub center: Vec2,
    /// Radius, pixels.
    pub radius: f32,
}

/// Sets every value of the pixels of the `side²` crop of `roi` (as [`warp_crop`] made it)
/// whose centre lies in `disc` to `value`.
fn fill_disc(roi: &Roi, disc: Disc, side: usize, value: f32, layout: InputLayout, out: &mut [f32]) {
    let n = side as f32;
    let (s, c) = roi.rotation.sin_cos();
    // Frame → crop: undo the rotation, then scale to crop pixels.
    let d = disc.center - roi.center;
    let centre = Vec2::new(c * d.x + s * d.y, -s * d.x + c * d.y) * (n / roi.size) + n * 0.5;
    let r = disc.radius * n / roi.size;
    let lo = |v: f32| ((v - r).floor().max(0.0) as usize).min(side);
    let hi = |v: f32| ((v + r).ceil().max(0.0) as usize).min(side);
    for v in lo(centre.y)..hi(centre.y) {
        for u in lo(centre.x)..hi(centre.x) {
            let p = Vec2::new(u as f32 + 0.5, v as f32 + 0.5);
            if p.distance_squared(centre) <= r * r {
                for ch in 0..3 {
                    out[layout.index(side, u, v, ch)] = value;
                }
            }
        }
    }
}

/// The landmark model's bound outputs for runs on `batch` crops.
fn landmark_outputs(session: &Session, model: &Path, batch: usize) -> Result<Outputs, VisionError> {
    let heat_channels = output_shape(session, OUT_HEATMAP, batch)
        .filter(|_| std::env::var_os("RIGCAST_NO_HEATMAP").is_none())
        .map(|shape| heat_channels(*shape.last().unwrap_or(&0)))
        .transpose()
        .map_err(|e| model_err(model, e))?;
    if let Some(channels) = heat_channels {
        let run = BoundRun::new(
            session,
            model,
            [OUT_LANDMARKS, OUT_PRESENCE, OUT_WORLD, OUT_HEATMAP],
            [
                NUM_MODEL_LANDMARKS * 5,
                1,
                NUM_MODEL_LANDMARKS * 3,
                HEATMAP_SIDE * HEATMAP_SIDE * channels.count,
            ],
            batch,
        )?;
        return Ok(Outputs::Four(run, channels));
    }
    Ok(Outputs::Three(BoundRun::new(
        session,
        model,
        [OUT_LANDMARKS, OUT_PRESENCE, OUT_WORLD],
        [NUM_MODEL_LANDMARKS * 5, 1, NUM_MODEL_LANDMARKS * 3],
        batch,
    )?))
}

/// A zeroed input of `batch` square RGB images of `size` pixels in `layout`.
fn input_tensor(
    model: &Path,
    batch: usize,
    size: usize,
    layout: InputLayout,
) -> Result<Tensor<f32>, VisionError> {
    let shape = match layout {
        InputLayout::ChannelsLast => [batch, size, size, 3],
        InputLayout::ChannelsFirst => [batch, 3, size, size],
    };
    Tensor::from_array((shape, vec![0.0f32; batch * size * size * 3]))
        .map_err(|e| model_err(model, e))
}

/// The layout of `session`'s first input, which must be square RGB images of `size` pixels.
fn input_layout(session: &Session, model: &Path, size: usize) -> Result<InputLayout, VisionError> {
    let shape = session
        .inputs()
        .first()
        .and_then(|input| match input.dtype() {
            ValueType::Tensor { shape, .. } => Some(shape.iter().copied().collect::<Vec<i64>>()),
            _ => None,
        });
    let s = size as i64;
    match shape.as_deref() {
        Some([_, h, w, 3]) if (*h, *w) == (s, s) => Ok(InputLayout::ChannelsLast),
        Some([_, 3, h, w]) if (*h, *w) == (s, s) => Ok(InputLayout::ChannelsFirst),
        other => Err(model_err(
            model,
            format!("input shape {other:?}: expected {size}x{size} RGB, channels first or last"),
        )),
    }
}

/// The session of `model` (`what` names it when the file is missing) with the runtime in
/// `library`, on `threads` threads, and its input: one square RGB image of `size` pixels,
/// zeroed, in the layout the model takes.
pub(crate) fn open_model(
    library: &Path,
    model: &Path,
    what: &'static str,
    threads: usize,
    size: usize,
) -> Result<(Session, Tensor<f32>, InputLayout), VisionError> {
    let env = runtime(library)?;
    if !model.is_file() {
        return Err(VisionError::NotSetUp {
            path: model.to_path_buf(),
            what,
        });
    }
    let session = build_session(&env, model, threads)?;
    let layout = input_layout(&session, model, size)?;
    let input = input_tensor(model, 1, size, layout)?;
    Ok((session, input, layout))
}

/// An optimised session on `threads` intra-op threads (one model of the pipeline).
pub(crate) fn build_session(
    env: &Environment,
    model: &Path,
    threads: usize,
) -> Result<Session, VisionError> {
    Session::builder(env)
        .map_err(|e| model_err(model, e))?
        .with_optimization_level(GraphOptimizationLevel::Level3)
        .map_err(|e| model_err(model, e))?
        .with_intra_threads(threads.max(1))
        .map_err(|e| model_err(model, e))?
        // Spinning workers burn a core waiting for work; on a 2-core machine shared with the
        // decoder and the server that costs more than the wake-up latency it saves.
        .with_intra_op_spinning(spin_enabled())
        .map_err(|e| model_err(model, e))?
        .commit_from_file(model)
        .map_err(|e| model_err(model, e))
}

/// The heatmap channels a model with `count` of them a cell holds: every landmark's, or the
/// [`REFINED`] ones'.
fn heat_channels(count: i64) -> Result<HeatChannels, String> {
    match usize::try_from(count) {
        Ok(NUM_MODEL_LANDMARKS) => Ok(HeatChannels {
            count: NUM_MODEL_LANDMARKS,
            first: 0,
        }),
        Ok(n) if n == REFINED.len() => Ok(HeatChannels {
            count: n,
            first: REFINED.start,
        }),
        _ => Err(format!(
            "heatmaps with {count} channels (expected {NUM_MODEL_LANDMARKS} or {})",
            REFINED.len()
        )),
    }
}

/// Landmark `i`'s crop point (each in [0, 1]) refined from its heatmap (logits, `i` one of
/// [`REFINED`]): the sure-weighted mean of the cells within [`HEATMAP_REACH`]
/// of its own cell, when the surest of them reaches [`HEATMAP_SURE`]. MediaPipe's pose graph
/// refines its landmarks so; the regression head alone reads a few crop pixels off.
fn refine(p: Vec2, heat: Heat<'_>, i: usize) -> Vec2 {
    let HeatChannels { count, first } = heat.channels;
    let side = HEATMAP_SIDE as i32;
    let cell = p * HEATMAP_SIDE as f32;
    let (col, row) = (cell.x as i32, cell.y as i32);
    if !(0..side).contains(&col) || !(0..side).contains(&row) {
        return p;
    }
    let (mut sum, mut at, mut surest) = (0.0f32, Vec2::ZERO, 0.0f32);
    for r in (row - HEATMAP_REACH).max(0)..(row + HEATMAP_REACH + 1).min(side) {
        for c in (col - HEATMAP_REACH).max(0)..(col + HEATMAP_REACH + 1).min(side) {
            let sure = sigmoid(heat.cells[(r * side + c) as usize * count + i - first]);
            sum += sure;
            at += Vec2::new(c as f32, r as f32) * sure;
            surest = surest.max(sure);
        }
    }
    if surest >= HEATMAP_SURE && sum > 0.0 {
        at / (sum * HEATMAP_SIDE as f32)
    } else {
        p
    }
}

/// Maps raw model outputs to frame pixels / metres.
fn decode(
    raw: &[f32],
    raw_world: &[f32],
    presence: f32,
    heat: Option<Heat<'_>>,
    roi: &Roi,
    out: &mut Landmarks,
) {
    let inv = 1.0 / INPUT_SIZE as f32;
    for i in 0..NUM_MODEL_LANDMARKS {
        let r = &raw[i * 5..i * 5 + 5];
        let read = Vec2::new(r[0], r[1]) * inv;
        let p = roi.to_frame(read - 0.5);
        out.refined[i] = match heat.filter(|_| REFINED.contains(&i)) {
            Some(heat) => roi.to_frame(refine(read, heat, i) - 0.5) - p,
            None => Vec2::ZERO,
        };
        // z shares x's crop-pixel scale.
        let z = r[2] * inv * roi.size;
        out.image[i] = Vec4::new(p.x, p.y, z, sigmoid(r[3]));
        let w = &raw_world[i * 3..i * 3 + 3];
        let xy = roi.rotate(Vec2::new(w[0], w[1]));
        out.world[i] = Vec3::new(xy.x, xy.y, w[2]);
    }
    // The converted model ends in a sigmoid already when the value lies in [0, 1]; a logit
    // otherwise.
    out.presence = if (0.0..=1.0).contains(&presence) {
        presence
    } else {
        sigmoid(presence)
    };
}

/// Bilinear warp of `roi` into a `side²` RGB float buffer (`v · scale + offset`) in `layout`,
/// black outside the frame. Writes every value of `out`, so a model's input tensor is filled
/// in place and never reallocated.
pub fn warp_crop(
    frame: &RgbFrame,
    roi: &Roi,
    side: usize,
    scale: f32,
    offset: f32,
    layout: InputLayout,
    out: &mut [f32],
) {
    debug_assert_eq!(out.len(), side * side * 3);
    let weights = Weights { scale, offset };
    // One loop a layout, chosen here rather than at each pixel.
    match layout {
        InputLayout::ChannelsLast => warp_into(frame, roi, side, weights, Interleaved(out)),
        InputLayout::ChannelsFirst => {
            let (r, rest) = out.split_at_mut(side * side);
            let (g, b) = rest.split_at_mut(side * side);
            warp_into(frame, roi, side, weights, Planar([r, g, b]))
        }
    }
}

/// A crop's buffer, taking each pixel's three values.
trait Crop {
    /// Writes `value` to crop pixel `at` (`v · side + u`).
    fn put(&mut self, at: usize, value: [f32; 3]);
}

/// A channels-last crop.
struct Interleaved<'a>(&'a mut [f32]);

impl Crop for Interleaved<'_> {
    #[inline(always)]
    fn put(&mut self, at: usize, value: [f32; 3]) {
        if let Some(pixel) = self.0.get_mut(at * 3..at * 3 + 3) {
            for (o, value) in pixel.iter_mut().zip(value) {
                *o = value;
            }
        }
    }
}

/// A channels-first crop: one plane a channel.
struct Planar<'a>([&'a mut [f32]; 3]);

impl Crop for Planar<'_> {
    #[inline(always)]
    fn put(&mut self, at: usize, value: [f32; 3]) {
        for (plane, value) in self.0.iter_mut().zip(value) {
            plane[at] = value;
        }
    }
}

/// [`warp_crop`]'s sampling into `out`.
#[inline(always)]
fn warp_into(frame: &RgbFrame, roi: &Roi, side: usize, weights: Weights, mut out: impl Crop) {
    let n = side as f32;
    let (s, c) = roi.rotation.sin_cos();
    let step = roi.size / n;
    // Frame position of crop pixel (u, v) centre: origin + u·du + v·dv.
    let du = Vec2::new(c, s) * step;
    let dv = Vec2::new(-s, c) * step;
    let origin = roi.to_frame(Vec2::new(0.5 / n - 0.5, 0.5 / n - 0.5)) - Vec2::splat(0.5);
    let (w, h) = (frame.width as i32, frame.height as i32);
    // Whether all four neighbours of `p` lie inside the frame (for `p` ≥ 0 the truncation
    // is the floor).
    let inside = |p: Vec2| p.x >= 0.0 && p.y >= 0.0 && (p.x as i32) + 1 < w && (p.y as i32) + 1 < h;
    for v in 0..side {
        let row = origin + dv * v as f32;
        let at = |u: usize| row + du * u as f32;
        // A row's positions move monotonically with `u`, so the pixels whose neighbours are
        // all inside form one run: find its ends, and read the run without checking each
        // pixel against the frame's edges.
        let mut first = 0;
        while first < side && !inside(at(first)) {
            first += 1;
        }
        let mut end = side;
        while end > first && !inside(at(end - 1)) {
            end -= 1;
        }
        for u in (0..first).chain(end..side) {
            out.put(v * side + u, weights.sample_edge(frame, at(u)));
        }
        for u in first..end {
            out.put(v * side + u, weights.sample_inside(frame, at(u)));
        }
    }
}

/// Byte values as floats, read from a table rather than converted: with the runs read
/// without edge checks, a crop inside the frame took 0.45-0.65 ms of CPU instead of
/// 0.75-0.9 (a 256-pixel crop of a 512 × 910 frame, one core); the values are the same.
static BYTE_VALUES: [f32; 256] = {
    let mut table = [0.0; 256];
    let mut i = 0;
    while i < 256 {
        table[i] = i as f32;
        i += 1;
    }
    table
};

/// The scaling of one crop's values ([`warp_crop`]).
#[derive(Clone, Copy)]
struct Weights {
    scale: f32,
    offset: f32,
}

impl Weights {
    /// The bilinear value at `p`, whose four neighbours all lie inside the frame.
    #[inline(always)]
    fn sample_inside(self, frame: &RgbFrame, p: Vec2) -> [f32; 3] {
        let (x0, y0) = (p.x as i32, p.y as i32);
        let (fx, fy) = (p.x - x0 as f32, p.y - y0 as f32);
        let stride = frame.width as usize * 3;
        let i00 = y0 as usize * stride + x0 as usize * 3;
        let top = &frame.data[i00..i00 + 6];
        let bot = &frame.data[i00 + stride..i00 + stride + 6];
        let f = |b: u8| BYTE_VALUES[b as usize];
        std::array::from_fn(|ch| {
            let t = f(top[ch]) * (1.0 - fx) + f(top[ch + 3]) * fx;
            let b = f(bot[ch]) * (1.0 - fx) + f(bot[ch + 3]) * fx;
            (t * (1.0 - fy) + b * fy) * self.scale + self.offset
        })
    }

    /// The bilinear value at `p`, neighbours outside the frame black.
    #[inline(always)]
    fn sample_edge(self, frame: &RgbFrame, p: Vec2) -> [f32; 3] {
        let x0 = floor(p.x);
        let y0 = floor(p.y);
        let (fx, fy) = (p.x - x0, p.y - y0);
        let (x0, y0) = (x0 as i32, y0 as i32);
        let p00 = frame.pixel(x0, y0);
        let p10 = frame.pixel(x0 + 1, y0);
        let p01 = frame.pixel(x0, y0 + 1);
        let p11 = frame.pixel(x0 + 1, y0 + 1);
        std::array::from_fn(|ch| {
            let top = p00[ch] as f32 * (1.0 - fx) + p10[ch] as f32 * fx;
            let bot = p01[ch] as f32 * (1.0 - fx) + p11[ch] as f32 * fx;
            (top * (1.0 - fy) + bot * fy) * self.scale + self.offset
        })
    }
}

/// `v.floor()`, without the library call it compiles to on CPUs without SSE4.1 (a sixth of
/// the crop's time): truncation is the floor for non-negative values, which nearly all crop
/// positions are.
#[inline]
fn floor(v: f32) -> f32 {
    if v >= 0.0 {
        (v as i32) as f32
    } else {
        v.floor()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::vision::landmarks::idx;

    fn gradient_frame(w: u32, h: u32) -> RgbFrame {
        let mut f = RgbFrame::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let i = ((y * w + x) * 3) as usize;
                f.data[i] = (x % 256) as u8;
                f.data[i + 1] = (y % 256) as u8;
                f.data[i + 2] = 7;
            }
        }
        f
    }

    /// Painted exactly the crop pixels whose centres `Roi::to_frame` puts inside the disc
    /// (a band of half a pixel at its edge left out), upright and turned.
    #[test]
    fn a_hidden_disc_covers_the_crop_pixels_inside_it() {
        let side = 32;
        let disc = Disc {
            center: Vec2::new(110.0, 95.0),
            radius: 12.0,
        };
        for rotation in [0.0f32, 0.5, -2.0] {
            let roi = Roi {
                center: Vec2::new(100.0, 100.0),
                size: 64.0,
                rotation,
            };
            let mut out = vec![0.25f32; side * side * 3];
            fill_disc(&roi, disc, side, -1.0, InputLayout::ChannelsLast, &mut out);
            let pixel = roi.size / side as f32;
            let mut painted = 0;
            for v in 0..side {
                for u in 0..side {
                    let n = (Vec2::new(u as f32, v as f32) + 0.5) / side as f32 - 0.5;
                    let d = roi.to_frame(n).distance(disc.center);
                    let value = out[(v * side + u) * 3];
                    if d < disc.radius - 0.5 * pixel {
                        assert_eq!(value, -1.0, "({u}, {v}) at {d:.1} px, turned {rotation}");
                        painted += 1;
                    } else if d > disc.radius + 0.5 * pixel {
                        assert_eq!(value, 0.25, "({u}, {v}) at {d:.1} px, turned {rotation}");
                    }
                }
            }
            // About the disc's area in crop pixels (π·6²).
            assert!((90..=125).contains(&painted), "{painted}");
        }
    }

    #[test]
    fn a_disc_outside_the_crop_paints_nothing() {
        let roi = Roi::square(Vec2::new(50.0, 50.0), 40.0);
        let mut out = vec![0.5f32; 16 * 16 * 3];
        let far = Disc {
            center: Vec2::new(500.0, -300.0),
            radius: 30.0,
        };
        fill_disc(&roi, far, 16, 0.0, InputLayout::ChannelsLast, &mut out);
        assert!(out.iter().all(|&v| v == 0.5));
    }

    /// The crop read in runs inside the frame gives every value exactly as reading each
    /// pixel with the edge checks does: upright and turned, inside, across the edges, and
    /// outside the frame altogether.
    #[test]
    fn reading_runs_inside_the_frame_changes_no_value() {
        let f = gradient_frame(97, 61);
        let side = 48;
        let weights = Weights {
            scale: 1.0 / 255.0,
            offset: 0.0,
        };
        for (centre, size, rotation) in [
            (Vec2::new(48.0, 30.0), 40.0, 0.0f32),
            (Vec2::new(48.3, 30.7), 33.3, 0.3),
            (Vec2::new(10.0, 50.0), 90.0, -0.7),
            (Vec2::new(90.0, 5.0), 120.0, 2.5),
            (Vec2::new(-200.0, 30.0), 50.0, 1.0),
        ] {
            let roi = Roi {
                center: centre,
                size,
                rotation,
            };
            let mut out = vec![9.0f32; side * side * 3];
            let last = InputLayout::ChannelsLast;
            warp_crop(
                &f,
                &roi,
                side,
                weights.scale,
                weights.offset,
                last,
                &mut out,
            );
            let n = side as f32;
            let origin = roi.to_frame(Vec2::splat(0.5 / n - 0.5)) - Vec2::splat(0.5);
            let (s, c) = rotation.sin_cos();
            let (du, dv) = (Vec2::new(c, s) * (size / n), Vec2::new(-s, c) * (size / n));
            for v in 0..side {
                for u in 0..side {
                    let p = origin + dv * v as f32 + du * u as f32;
                    let want = weights.sample_edge(&f, p);
                    let i = (v * side + u) * 3;
                    for ch in 0..3 {
                        assert_eq!(
                            out[i + ch].to_bits(),
                            want[ch].to_bits(),
                            "({u}, {v}) {roi:?}"
                        );
                    }
                }
            }
        }
    }

    const LAST: InputLayout = InputLayout::ChannelsLast;

    /// What a crop costs (a benchmark, run in release: `cargo test --release -p
    /// rigcast-sources --lib crop_cost -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn crop_cost() {
        let mut f = RgbFrame::new(512, 910);
        for (i, v) in f.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 251) as u8;
        }
        let roi = Roi {
            center: Vec2::new(250.0, 460.0),
            size: 380.0,
            rotation: 0.2,
        };
        let mut out = vec![0.0f32; INPUT_SIZE * INPUT_SIZE * 3];
        // This thread's time on a CPU, ns (the first field of its schedstat).
        let cpu = || -> f64 {
            let text = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap();
            text.split_whitespace().next().unwrap().parse().unwrap()
        };
        let layouts = [LAST, InputLayout::ChannelsFirst];
        let mut times = [vec![], vec![]];
        // Alternating rounds, so that the machine's load moves both alike.
        for _round in 0..7 {
            for (layout, times) in layouts.into_iter().zip(&mut times) {
                let t = cpu();
                for _ in 0..200 {
                    warp_crop(&f, &roi, INPUT_SIZE, 1.0 / 255.0, 0.0, layout, &mut out);
                    std::hint::black_box(&out);
                }
                times.push((cpu() - t) * 1e-6 / 200.0);
            }
        }
        for (layout, mut t) in layouts.into_iter().zip(times) {
            t.sort_by(f64::total_cmp);
            println!(
                "{layout:?}: least {:.3}, median {:.3} ms of CPU a crop",
                t[0], t[3]
            );
        }
    }

    /// A crop written channels first holds every value of the crop written channels last,
    /// to the bit, at its own place (so a model taking either reads the same numbers), and
    /// a hidden disc paints the same pixels in both.
    #[test]
    fn channels_first_holds_the_same_values_as_channels_last() {
        let f = gradient_frame(97, 61);
        let side = 40;
        let disc = Disc {
            center: Vec2::new(45.0, 28.0),
            radius: 9.0,
        };
        for (centre, size, rotation) in [
            (Vec2::new(48.3, 30.7), 33.3, 0.3f32),
            (Vec2::new(10.0, 50.0), 90.0, -0.7),
        ] {
            let roi = Roi {
                center: centre,
                size,
                rotation,
            };
            let mut last = vec![9.0f32; side * side * 3];
            let mut first = vec![9.0f32; side * side * 3];
            let first_layout = InputLayout::ChannelsFirst;
            warp_crop(&f, &roi, side, 1.0 / 255.0, 0.0, LAST, &mut last);
            warp_crop(&f, &roi, side, 1.0 / 255.0, 0.0, first_layout, &mut first);
            fill_disc(&roi, disc, side, -1.0, LAST, &mut last);
            fill_disc(&roi, disc, side, -1.0, first_layout, &mut first);
            let mut painted = 0;
            for v in 0..side {
                for u in 0..side {
                    for ch in 0..3 {
                        let want = last[(v * side + u) * 3 + ch];
                        let got = first[(ch * side + v) * side + u];
                        assert_eq!(got.to_bits(), want.to_bits(), "({u}, {v}) {ch} {roi:?}");
                        painted += usize::from(want == -1.0);
                    }
                }
            }
            assert!(
                painted > 0,
                "the disc painted nothing: the test shows nothing"
            );
        }
    }

    #[test]
    fn the_crop_floor_is_the_floor() {
        for v in [
            0.0f32, 0.25, 1.0, 3.999, 511.5, -0.0, -0.25, -1.0, -1.5, -700.2,
        ] {
            assert_eq!(floor(v), v.floor(), "{v}");
        }
    }

    #[test]
    fn identity_crop_reproduces_pixels() {
        // A 256-pixel ROI over a 256×256 frame maps crop pixel (u, v) to frame pixel (u, v).
        let f = gradient_frame(256, 256);
        let roi = Roi::square(Vec2::new(128.0, 128.0), 256.0);
        let mut out = vec![0.0; INPUT_SIZE * INPUT_SIZE * 3];
        warp_crop(&f, &roi, INPUT_SIZE, 1.0, 0.0, LAST, &mut out);
        for (u, v) in [(0usize, 0usize), (10, 200), (255, 255), (128, 3)] {
            let i = (v * INPUT_SIZE + u) * 3;
            assert!((out[i] - u as f32).abs() < 1e-3, "u {u} got {}", out[i]);
            assert!((out[i + 1] - v as f32).abs() < 1e-3);
            assert!((out[i + 2] - 7.0).abs() < 1e-3);
        }
    }

    #[test]
    fn outside_the_frame_is_black_and_scaling_applies() {
        let f = gradient_frame(64, 64);
        let roi = Roi::square(Vec2::new(32.0, 32.0), 1024.0);
        let mut out = vec![9.0; INPUT_SIZE * INPUT_SIZE * 3];
        warp_crop(&f, &roi, INPUT_SIZE, 1.0 / 127.5, -1.0, LAST, &mut out);
        assert!((out[0] + 1.0).abs() < 1e-6, "corner is black → −1");
    }

    #[test]
    fn quarter_turn_crop_reads_along_the_rotated_axis() {
        let f = gradient_frame(256, 256);
        let mut roi = Roi::square(Vec2::new(128.0, 128.0), 256.0);
        roi.rotation = std::f32::consts::FRAC_PI_2;
        let mut out = vec![0.0; INPUT_SIZE * INPUT_SIZE * 3];
        warp_crop(&f, &roi, INPUT_SIZE, 1.0, 0.0, LAST, &mut out);
        // Moving right in the crop (u) moves down in the frame (y): the green channel grows.
        let g = |u: usize, v: usize| out[(v * INPUT_SIZE + u) * 3 + 1];
        assert!(g(200, 128) > g(50, 128) + 100.0);
    }

    /// Heatmaps (logits) nobody is sure of but one sure cell of landmark `i`'s.
    fn one_sure_cell(i: usize, col: usize, row: usize) -> Vec<f32> {
        let mut heat = vec![-10.0f32; HEATMAP_SIDE * HEATMAP_SIDE * NUM_MODEL_LANDMARKS];
        heat[(row * HEATMAP_SIDE + col) * NUM_MODEL_LANDMARKS + i] = 10.0;
        heat
    }

    /// `cells` as a model with every landmark's heatmap gives them.
    fn all(cells: &[f32]) -> Heat<'_> {
        let channels = heat_channels(NUM_MODEL_LANDMARKS as i64).unwrap();
        Heat { cells, channels }
    }

    #[test]
    fn heatmaps_of_the_refined_landmarks_only_refine_as_all_of_them_do() {
        // Varied logits, then each cell's channels of the refined landmarks alone (what the
        // prune script's sliced last convolution gives).
        let every: Vec<f32> = (0..HEATMAP_SIDE * HEATMAP_SIDE * NUM_MODEL_LANDMARKS)
            .map(|k| ((k * 7919) % 1013) as f32 / 101.3 - 4.0)
            .collect();
        let sliced: Vec<f32> = every
            .chunks(NUM_MODEL_LANDMARKS)
            .flat_map(|cell| cell[REFINED].iter().copied())
            .collect();
        let channels = heat_channels(REFINED.len() as i64).unwrap();
        assert_eq!(
            channels,
            HeatChannels {
                count: 22,
                first: 11
            }
        );
        let some = Heat {
            cells: &sliced,
            channels,
        };
        let mut moved = 0;
        for i in REFINED {
            for at in [
                Vec2::new(0.3, 0.7),
                Vec2::new(0.01, 0.5),
                Vec2::new(0.9, 0.99),
            ] {
                let want = refine(at, all(&every), i);
                assert_eq!(refine(at, some, i), want, "landmark {i} at {at}");
                moved += usize::from(want != at);
            }
        }
        assert!(moved > 0, "no landmark was refined: the test shows nothing");
        assert!(heat_channels(38).is_err() && heat_channels(0).is_err());
    }

    #[test]
    fn a_landmark_moves_to_its_heatmaps_sure_cell_nearby_and_only_then() {
        let cell = |c: f32, r: f32| Vec2::new(c, r) / HEATMAP_SIDE as f32;
        let at = cell(22.5, 31.5);
        // A sure cell two cells away: the landmark goes there (the other 48 cells of the
        // window weigh 2e-3 together).
        let moved = refine(at, all(&one_sure_cell(15, 20, 30)), 15);
        assert!(moved.distance(cell(20.0, 30.0)) < 0.01 / 64.0, "{moved}");
        // Beyond the window, for another landmark, or only half sure: it stays.
        assert_eq!(refine(at, all(&one_sure_cell(15, 40, 30)), 15), at);
        assert_eq!(refine(at, all(&one_sure_cell(16, 20, 30)), 15), at);
        let mut unsure = one_sure_cell(15, 20, 30);
        unsure.iter_mut().for_each(|v| *v = v.min(-0.5));
        assert_eq!(refine(at, all(&unsure), 15), at);
        // A point outside the crop is left as the regression read it.
        assert_eq!(
            refine(cell(70.0, 30.0), all(&one_sure_cell(15, 63, 30)), 15),
            cell(70.0, 30.0)
        );
    }

    #[test]
    fn decode_keeps_the_bodys_refinement_beside_the_reading_and_none_for_the_face() {
        let mut raw = [0.0f32; NUM_MODEL_LANDMARKS * 5];
        for i in [idx::NOSE, idx::LEFT_WRIST] {
            raw[i * 5] = 90.0; // crop pixel 90: heatmap cell 22.5
            raw[i * 5 + 1] = 126.0;
        }
        let mut heat = one_sure_cell(idx::LEFT_WRIST, 20, 30);
        heat[(30 * HEATMAP_SIDE + 20) * NUM_MODEL_LANDMARKS + idx::NOSE] = 10.0;
        let world = [0.0f32; NUM_MODEL_LANDMARKS * 3];
        let roi = Roi::square(Vec2::new(128.0, 128.0), 256.0);
        let mut out = Landmarks::default();
        decode(&raw, &world, 0.9, Some(all(&heat)), &roi, &mut out);
        let px = |i: usize| Vec2::new(out.image[i].x, out.image[i].y);
        // The reading itself is the regression head's (what the tracker follows).
        assert!(px(idx::LEFT_WRIST).distance(Vec2::new(90.0, 126.0)) < 1e-3);
        assert!(out.refined[idx::LEFT_WRIST].distance(Vec2::new(-10.0, -6.0)) < 0.1);
        assert_eq!(out.refined[idx::NOSE], Vec2::ZERO);
        // The output takes it, once.
        out.take_refinement();
        assert!(px_of(&out, idx::LEFT_WRIST).distance(Vec2::new(80.0, 120.0)) < 0.1);
        assert_eq!(out.refined[idx::LEFT_WRIST], Vec2::ZERO);
        assert!(px_of(&out, idx::NOSE).distance(Vec2::new(90.0, 126.0)) < 1e-3);
    }

    fn px_of(lm: &Landmarks, i: usize) -> Vec2 {
        Vec2::new(lm.image[i].x, lm.image[i].y)
    }

    #[test]
    fn decode_maps_crop_centre_to_roi_centre() {
        let mut raw = [0.0f32; NUM_MODEL_LANDMARKS * 5];
        raw[0] = 128.0;
        raw[1] = 128.0;
        raw[3] = 10.0;
        let world = [0.0f32; NUM_MODEL_LANDMARKS * 3];
        let roi = Roi::square(Vec2::new(500.0, 300.0), 400.0);
        let mut out = Landmarks::default();
        decode(&raw, &world, 0.9, None, &roi, &mut out);
        assert!((out.image[0].x - 500.0).abs() < 1e-3 && (out.image[0].y - 300.0).abs() < 1e-3);
        assert!(out.image[0].w > 0.99);
        assert!((out.presence - 0.9).abs() < 1e-6);
    }
}
