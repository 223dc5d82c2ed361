//! A subject's latest frame: one writer (its source's task or thread, or the tick for a
//! target), any number of readers. The latest frame wins and nothing queues; a reader copies
//! what it needs out of the guard and lets go. A plain lock, not a channel: nobody waits for
//! a frame (the tick reads whatever is there when it runs), so the engine needs no async
//! runtime for it.

use std::sync::{Arc, RwLock, RwLockReadGuard};

use rigcast_retarget::Frame;

/// Writes a subject's latest frame (held by its source, or by the performer of a target).
#[derive(Debug)]
pub struct FrameWriter {
    slot: Arc<RwLock<Frame>>,
}

/// Reads a subject's latest frame.
#[derive(Debug, Clone)]
pub struct FrameReader {
    slot: Arc<RwLock<Frame>>,
}

/// A slot holding `initial`: its writer and a reader.
pub fn frame_slot(initial: Frame) -> (FrameWriter, FrameReader) {
    let slot = Arc::new(RwLock::new(initial));
    (FrameWriter { slot: slot.clone() }, FrameReader { slot })
}

/// The latest frame while it is read (readers hold it briefly: the writer waits meanwhile).
pub type FrameRef<'a> = RwLockReadGuard<'a, Frame>;

/// A guard whatever a panicking holder left (a frame is whole between writes: `modify`
/// changes it field by field, and a reader only ever sees it between writes).
#[inline]
fn read(slot: &RwLock<Frame>) -> FrameRef<'_> {
    slot.read().unwrap_or_else(|p| p.into_inner())
}

impl FrameWriter {
    /// Changes the frame in place (no allocation when `modify` makes none).
    #[inline]
    pub fn send_modify(&self, modify: impl FnOnce(&mut Frame)) {
        let mut frame = self.slot.write().unwrap_or_else(|p| p.into_inner());
        modify(&mut frame);
    }

    /// The frame now.
    #[inline]
    pub fn borrow(&self) -> FrameRef<'_> {
        read(&self.slot)
    }

    /// Another reader of this slot.
    pub fn subscribe(&self) -> FrameReader {
        FrameReader {
            slot: self.slot.clone(),
        }
    }
}

impl FrameReader {
    /// The frame now.
    #[inline]
    pub fn borrow(&self) -> FrameRef<'_> {
        read(&self.slot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_retarget::Pose;

    #[test]
    fn readers_see_the_latest_write() {
        let frame = Frame {
            seq: 0,
            capture_nanos: 0,
            source_id: 3,
            pose: Pose {
                rotations: Vec::new(),
                translations: Vec::new(),
            },
        };
        let (tx, rx) = frame_slot(frame);
        let other = tx.subscribe();
        for seq in 1..=3 {
            tx.send_modify(|f| f.seq = seq);
        }
        assert_eq!(
            (rx.borrow().seq, other.borrow().seq, tx.borrow().seq),
            (3, 3, 3)
        );
        assert_eq!(rx.borrow().source_id, 3);
    }
}
