//! The `footplants` side message: each target's foot-lock state (which feet are planted, and
//! where they are), reported when it changes, so the viewer can draw a marker under a planted
//! foot and the Blender add-on can expose it, without polling `/v1/status`.
//!
//! The tick only stores a bitmask per target (`SubjectStats::feet_locked`, no allocation); a
//! [`FootplantSampler`] compares it off the tick (the host calls [`FootplantSampler::sample`]
//! at its own rate) and on a change takes the feet's positions from forward kinematics of the
//! target's latest published frame. The latest report per target is kept on the subject for
//! clients that connect later.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use rigcast_protocol::FootState;
use rigcast_retarget::{forward_kinematics, WorldTransform};

use crate::events::Event;
use crate::reports::FootplantReport;
use crate::subject::Subject;

/// What was last sent for one target.
#[derive(Default)]
struct Sent {
    bits: u32,
    feet: Vec<String>,
    sent: bool,
}

/// Compares every target's foot-lock state with what was last reported.
pub struct FootplantSampler {
    targets: Vec<Arc<Subject>>,
    sent: Vec<Sent>,
    worlds: Vec<WorldTransform>,
}

impl FootplantSampler {
    /// A sampler over the target subjects among `subjects`.
    pub fn new(subjects: &[Arc<Subject>]) -> FootplantSampler {
        let targets: Vec<Arc<Subject>> =
            subjects.iter().filter(|s| s.is_target()).cloned().collect();
        FootplantSampler {
            sent: targets.iter().map(|_| Sent::default()).collect(),
            targets,
            worlds: Vec::new(),
        }
    }

    /// Whether there is no target to watch.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Reports (through `tell`, and on the subject) every target whose foot-lock state
    /// changed since the last call.
    pub fn sample(&mut self, mut tell: impl FnMut(Event)) {
        for (target, last) in self.targets.iter().zip(self.sent.iter_mut()) {
            let bits = target.stats.feet_locked.load(Ordering::Relaxed);
            let feet = match target.stats.locked_feet.lock() {
                Ok(names) => {
                    if last.sent && bits == last.bits && *names == last.feet {
                        continue;
                    }
                    names.clone()
                }
                Err(_) => continue,
            };
            let report = Arc::new(report(target, &feet, bits, &mut self.worlds));
            target.set_footplants(report.clone());
            *last = Sent {
                bits,
                feet,
                sent: true,
            };
            tell(Event::Footplants(report));
        }
    }
}

/// The foot-plant report of `target` for the foot bones `feet` (bit `i` = foot `i` planted).
fn report(
    target: &Subject,
    feet: &[String],
    bits: u32,
    worlds: &mut Vec<WorldTransform>,
) -> FootplantReport {
    let skeleton = target.skeleton();
    let frame = target.latest.borrow().clone();
    worlds.resize(skeleton.num_bones(), WorldTransform::IDENTITY);
    // A frame of another skeleton (a rebuild in flight) has no meaningful positions.
    let fits = frame.pose.num_bones() == skeleton.num_bones();
    if fits {
        forward_kinematics(&skeleton, &frame.pose, worlds);
    }
    let feet = feet
        .iter()
        .enumerate()
        .filter_map(|(i, name)| {
            let bone = skeleton.bone(name)?;
            let p = if fits {
                worlds[bone.index()].translation
            } else {
                glam::Vec3::ZERO
            };
            Some(FootState {
                bone: name.clone(),
                planted: i < 32 && bits & (1 << i) != 0,
                position: p.to_array(),
            })
        })
        .collect();
    FootplantReport {
        subject: target.id,
        seq: frame.seq,
        feet,
    }
}
