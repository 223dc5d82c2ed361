//! Whether the picture changed outside the people tracked: a look for a new person that costs
//! no model run.
//!
//! A person comes into view by moving into the picture, or by the camera moving onto them.
//! While the camera holds still and nobody enters, the picture outside the tracked people's
//! bodies stays what it was at the finder's last pass, which found nobody new in it, and a
//! detector pass on it would find nobody new again. The picture is summed up as a coarse grid
//! of cells, each the mean brightness of a few pixels (a few thousand pixel reads a frame:
//! microseconds, against milliseconds for a detector pass); a cell counts as changed when its
//! brightness moved by more than a compressed video's noise. Cells a tracked body covers now
//! or covered at the reference are not compared: the person moves, and uncovers what was
//! behind them.

use glam::Vec2;

use super::frame::RgbFrame;

/// Cells along the picture's longer side (the shorter side gets as many as keep them about
/// square): a cell of a 512 × 288 frame is 16 pixels across, smaller than a person the
/// detector finds in the whole frame.
const CELLS_LONG: usize = 32;
/// Most cells of a grid (the shorter side has at most as many as the longer).
const MAX_CELLS: usize = CELLS_LONG * CELLS_LONG;
/// Pixels read along each side of a cell (their mean is the cell's brightness).
const SAMPLES: usize = 4;
/// A cell's mean brightness (0-255) moving more than this is a change in the picture: a mean
/// of 16 pixels of compressed video wanders by a level or two from frame to frame, and a
/// body stepping into a cell changes it by tens.
const CHANGED_LEVELS: u16 = 12;
/// The picture changed when more than this share of the cells compared did (and at least
/// [`MIN_CHANGED_CELLS`]): a person anywhere in view covers a few cells at least.
const CHANGED_SHARE: f32 = 0.01;
/// See [`CHANGED_SHARE`]: one cell alone is a flicker, a moving leaf.
const MIN_CHANGED_CELLS: usize = 2;
/// Tracked bodies are widened by this fraction of their size on each side before the cells
/// they cover are left out: the body box of the landmarks misses loose clothes, hair, what a
/// hand holds and the shadow.
const BODY_MARGIN: f32 = 0.25;

/// One look's picture: the brightness grid the finder last looked at in one place, and the
/// cells the people tracked then covered.
#[derive(Debug, Clone)]
struct Reference {
    /// Cell brightness sums (of [`SAMPLES`]² pixels each).
    cells: [u16; MAX_CELLS],
    covered: [bool; MAX_CELLS],
    /// The frame size it was taken at (a new size starts afresh).
    size: (u32, u32),
    taken: bool,
}

/// The brightness grid of the frame measured last, and the picture at the finder's last look
/// in each of its places (the detector's regions take turns; each looks at its own part of
/// the picture, so each is compared with what it saw last).
#[derive(Debug, Clone)]
pub struct PictureWatch {
    cols: usize,
    rows: usize,
    /// The size of the frame measured last.
    measured: (u32, u32),
    /// Cell brightness sums of the frame measured last.
    current: [u16; MAX_CELLS],
    references: Vec<Reference>,
}

impl PictureWatch {
    /// A watch over `places` places the finder looks in, with no reference yet (the first
    /// look in each place is always due). Allocates here only.
    pub fn new(places: usize) -> PictureWatch {
        let empty = Reference {
            cells: [0; MAX_CELLS],
            covered: [false; MAX_CELLS],
            size: (0, 0),
            taken: false,
        };
        PictureWatch {
            cols: 0,
            rows: 0,
            measured: (0, 0),
            current: [0; MAX_CELLS],
            references: vec![empty; places.max(1)],
        }
    }

    /// Forgets every reference: every place's next look is due.
    pub fn reset(&mut self) {
        for r in &mut self.references {
            r.taken = false;
        }
    }

    /// Takes `frame` as place `place`'s reference, with `bodies` (centre, size in frame
    /// pixels) the tracked people's body boxes in it: what the finder's look there saw.
    pub fn take_reference(&mut self, place: usize, frame: &RgbFrame, bodies: &[(Vec2, Vec2)]) {
        self.measure(frame);
        let cells = self.cols * self.rows;
        let Some(r) = self.references.get_mut(place) else {
            return;
        };
        r.cells = self.current;
        r.size = (frame.width, frame.height);
        r.taken = true;
        for cell in 0..cells {
            self.references[place].covered[cell] = self.covered(cell, bodies);
        }
    }

    /// Whether `frame` differs from place `place`'s reference outside `bodies` (the tracked
    /// people's body boxes now) and outside what they covered then. True without a reference,
    /// or when the frame's size changed.
    pub fn changed(&mut self, place: usize, frame: &RgbFrame, bodies: &[(Vec2, Vec2)]) -> bool {
        let size = (frame.width, frame.height);
        if self
            .references
            .get(place)
            .is_none_or(|r| !r.taken || r.size != size)
        {
            return true;
        }
        self.measure(frame);
        let r = &self.references[place];
        let limit = CHANGED_LEVELS * (SAMPLES * SAMPLES) as u16;
        let (mut compared, mut changed) = (0usize, 0usize);
        for cell in 0..self.cols * self.rows {
            if r.covered[cell] || self.covered(cell, bodies) {
                continue;
            }
            compared += 1;
            if self.current[cell].abs_diff(r.cells[cell]) > limit {
                changed += 1;
            }
        }
        changed >= MIN_CHANGED_CELLS && changed as f32 > CHANGED_SHARE * compared as f32
    }

    /// Fills `self.current` with `frame`'s cell brightness (and sizes the grid to it).
    fn measure(&mut self, frame: &RgbFrame) {
        let (w, h) = (frame.width as usize, frame.height as usize);
        self.measured = (frame.width, frame.height);
        let long = w.max(h).max(1);
        let cells_short = (CELLS_LONG * w.min(h)).div_ceil(long).clamp(1, CELLS_LONG);
        (self.cols, self.rows) = if w >= h {
            (CELLS_LONG, cells_short)
        } else {
            (cells_short, CELLS_LONG)
        };
        if frame.data.len() < w * h * 3 || w == 0 || h == 0 {
            self.current.fill(0);
            return;
        }
        for row in 0..self.rows {
            for col in 0..self.cols {
                let mut sum = 0u16;
                for sy in 0..SAMPLES {
                    // Sample points at the centres of a SAMPLES × SAMPLES split of the cell.
                    let y = ((row * SAMPLES + sy) * 2 + 1) * h / (self.rows * SAMPLES * 2);
                    for sx in 0..SAMPLES {
                        let x = ((col * SAMPLES + sx) * 2 + 1) * w / (self.cols * SAMPLES * 2);
                        let p = (y * w + x) * 3;
                        let px = &frame.data[p..p + 3];
                        // Rec. 601 luma in integers (weights sum to 256): at most 255.
                        let luma = (77 * u32::from(px[0])
                            + 150 * u32::from(px[1])
                            + 29 * u32::from(px[2]))
                            >> 8;
                        sum += luma as u16;
                    }
                }
                self.current[row * self.cols + col] = sum;
            }
        }
    }

    /// Whether cell `cell` of the frame measured last overlaps one of `bodies`, each widened
    /// by [`BODY_MARGIN`] of its size on every side.
    fn covered(&self, cell: usize, bodies: &[(Vec2, Vec2)]) -> bool {
        let (col, row) = (cell % self.cols, cell / self.cols);
        let cell_w = self.measured.0 as f32 / self.cols as f32;
        let cell_h = self.measured.1 as f32 / self.rows as f32;
        let lo = Vec2::new(col as f32 * cell_w, row as f32 * cell_h);
        let hi = lo + Vec2::new(cell_w, cell_h);
        bodies.iter().any(|&(centre, size)| {
            let half = size * (0.5 + BODY_MARGIN);
            let (blo, bhi) = (centre - half, centre + half);
            blo.x < hi.x && bhi.x > lo.x && blo.y < hi.y && bhi.y > lo.y
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 512 × 288 frame of a left-to-right grey ramp (a wall with some texture).
    fn wall() -> RgbFrame {
        let mut f = RgbFrame::new(512, 288);
        for (i, px) in f.data.chunks_exact_mut(3).enumerate() {
            let x = (i % 512) as u8 / 4;
            px.copy_from_slice(&[60 + x, 60 + x, 60 + x]);
        }
        f
    }

    /// `frame` with a bright upright block (a person's size) centred at `centre`.
    fn with_person(mut frame: RgbFrame, centre: Vec2) -> RgbFrame {
        let (w, h) = (frame.width as usize, frame.height as usize);
        for y in 0..h {
            for x in 0..w {
                let d = Vec2::new(x as f32, y as f32) - centre;
                if d.x.abs() < 20.0 && d.y.abs() < 60.0 {
                    frame.data[(y * w + x) * 3..][..3].copy_from_slice(&[230, 200, 180]);
                }
            }
        }
        frame
    }

    const BODY: Vec2 = Vec2::new(40.0, 120.0);

    #[test]
    fn a_still_picture_is_unchanged_and_a_newcomer_is_a_change() {
        let mut watch = PictureWatch::new(2);
        let frame = wall();
        assert!(watch.changed(0, &frame, &[]), "no reference yet");
        watch.take_reference(0, &frame, &[]);
        assert!(!watch.changed(0, &frame, &[]));
        assert!(
            watch.changed(1, &frame, &[]),
            "each place has its own reference"
        );
        let newcomer = with_person(wall(), Vec2::new(400.0, 150.0));
        assert!(watch.changed(0, &newcomer, &[]));
        // A slight, even change of light is no newcomer.
        let mut brighter = wall();
        brighter.data.iter_mut().for_each(|v| *v += 4);
        assert!(!watch.changed(0, &brighter, &[]));
        watch.reset();
        assert!(watch.changed(0, &frame, &[]));
    }

    #[test]
    fn the_tracked_people_moving_is_no_change() {
        let mut watch = PictureWatch::new(1);
        let here = Vec2::new(100.0, 150.0);
        watch.take_reference(0, &with_person(wall(), here), &[(here, BODY)]);
        // The person walked on: where they were and where they are are left out.
        let there = Vec2::new(250.0, 150.0);
        let moved = with_person(wall(), there);
        assert!(!watch.changed(0, &moved, &[(there, BODY)]));
        // Someone else came in beside them.
        let two = with_person(moved, Vec2::new(420.0, 150.0));
        assert!(watch.changed(0, &two, &[(there, BODY)]));
    }

    #[test]
    fn a_new_frame_size_or_an_empty_frame_is_a_change_not_a_panic() {
        let mut watch = PictureWatch::new(1);
        watch.take_reference(0, &wall(), &[]);
        assert!(watch.changed(0, &RgbFrame::new(256, 144), &[]));
        let mut empty = PictureWatch::new(1);
        empty.take_reference(0, &RgbFrame::new(0, 0), &[]);
        // Nothing to compare: no change, and no panic.
        assert!(!empty.changed(0, &RgbFrame::new(0, 0), &[]));
        let mut tall = PictureWatch::new(1);
        let portrait = RgbFrame::new(288, 512);
        tall.take_reference(0, &portrait, &[]);
        assert!(!tall.changed(0, &portrait, &[]));
    }
}
