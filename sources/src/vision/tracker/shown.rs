//! What each identity slot last showed, and whether it may show this frame's reading.
//!
//! A slot is an identity to whoever reads the tracker: the pose it shows is one person's
//! from frame to frame. The tracker's continuity keeps a followed person's readings together,
//! but a slot also changes body when it is given someone: a person found right after a track
//! was lost (a misreading held a frame, then the performer found elsewhere), a lost person
//! taken back within their reach as a reading elsewhere in them or of someone else, a
//! misreading's identity handed to the upright body it lay in. Shown at once, the new body
//! is the old identity moving across the picture in a frame: the identity jump (hips
//! moving more than 15 % of the frame between frames at most [`IDENTITY_SPAN`] apart), and
//! a consumer's smoothing and limb lengths carried from one body onto another. So a track
//! started since the slot last showed a body, within the last [`IDENTITY_SPAN`] frames, is
//! shown only when its reading continues that body (the tracker's test: hips within reach of
//! where that body's were, measured by what the picture shows of it); else it is tracked but
//! not shown until that many frames have passed since: the slot shows nobody in between, a
//! loss and a new start, and the pipeline starts the new body's smoothing afresh. What the
//! tracker decides is unchanged.

/// Frames within which a slot's shown body may only be followed by one that continues it (the
/// identity judge's span: frames at most two apart).
pub(super) const IDENTITY_SPAN: u32 = 2;

/// One slot's output state, over the tracker's readings `T`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Shown<T> {
    /// The reading the slot showed last, and which start of a track it came from.
    last: Option<(T, u64)>,
    /// Frames since that frame (0 in it).
    age: u32,
    /// Whether this frame's reading was decided on, and shown.
    decided: bool,
    now: bool,
}

impl<T: Copy> Shown<T> {
    pub(super) const fn new() -> Self {
        Shown {
            last: None,
            age: 0,
            decided: false,
            now: false,
        }
    }

    /// Starts a frame: nothing shown in it yet.
    pub(super) fn begin_frame(&mut self) {
        self.age = self.age.saturating_add(1);
        self.decided = false;
        self.now = false;
    }

    /// Decides, once a frame, whether the slot shows `reading`, from the `start`th start of a
    /// track: yes unless the slot showed a reading of another start within the last
    /// [`IDENTITY_SPAN`] frames that `reading` does not continue (`continues(last, reading)`).
    /// Readings of the start shown last came through the track's own continuity tests. Returns
    /// whether the reading was held back by this call.
    pub(super) fn decide(
        &mut self,
        reading: &T,
        start: u64,
        continues: impl FnOnce(&T, &T) -> bool,
    ) -> bool {
        if self.decided {
            return false;
        }
        self.decided = true;
        let other_body = self.last.is_some_and(|(last, last_start)| {
            last_start != start && self.age <= IDENTITY_SPAN && !continues(&last, reading)
        });
        self.now = !other_body;
        if self.now {
            self.last = Some((*reading, start));
            self.age = 0;
        }
        other_body
    }

    /// Whether the slot shows its reading in this frame.
    pub(super) fn now(&self) -> bool {
        self.now
    }
}
