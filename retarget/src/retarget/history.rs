//! A fixed ring of past source world transforms, for per-bone delays. Sized at build time;
//! pushing a frame allocates nothing.

use crate::fk::{forward_kinematics, WorldTransform};
use crate::pose::Pose;
use crate::skeleton::Skeleton;

/// The last `capacity` frames of one source input, as world transforms.
#[derive(Debug, Clone)]
pub(crate) struct History {
    num_bones: usize,
    capacity: usize,
    head: usize,
    primed: bool,
    worlds: Vec<WorldTransform>,
}

impl History {
    pub(crate) fn new(num_bones: usize, capacity: usize) -> History {
        let capacity = capacity.max(1);
        History {
            num_bones,
            capacity,
            head: 0,
            primed: false,
            worlds: vec![WorldTransform::IDENTITY; num_bones * capacity],
        }
    }

    /// Forgets the past: the next push fills every slot, so delayed bones start from that frame
    /// instead of from stale or empty data.
    pub(crate) fn reset(&mut self) {
        self.primed = false;
    }

    /// Runs forward kinematics of `pose` into the next slot.
    pub(crate) fn push(&mut self, skeleton: &Skeleton, pose: &Pose) {
        let n = self.num_bones;
        if self.primed {
            self.head = (self.head + 1) % self.capacity;
        }
        let start = self.head * n;
        forward_kinematics(skeleton, pose, &mut self.worlds[start..start + n]);
        if !self.primed {
            for slot in 0..self.capacity {
                if slot != self.head {
                    self.worlds.copy_within(start..start + n, slot * n);
                }
            }
            self.primed = true;
        }
    }

    /// World transforms `delay_frames` pushes ago (clamped to the capacity).
    #[inline]
    pub(crate) fn get(&self, delay_frames: usize) -> &[WorldTransform] {
        let d = delay_frames.min(self.capacity - 1);
        let slot = (self.head + self.capacity - d) % self.capacity;
        &self.worlds[slot * self.num_bones..(slot + 1) * self.num_bones]
    }
}
