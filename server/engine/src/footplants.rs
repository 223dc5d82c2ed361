//! The `footplants` side message: each target's foot-lock state (which feet are planted, and
//! where they are), reported when it changes, so the viewer can draw a marker under a planted
//! foot and the Blender add-on can expose it, without polling `/v1/status`.
//!
//! The tick only stores a bitmask per target (`SubjectStats::feet_locked`, no allocation); a
//! [`FootplantSampler`] compares it off the tick (the host calls [`FootplantSampler::sample`]
//! at its own rate) and on a change takes the feet's positions from forward kinematics of the
//! target's latest published frame. A planted foot is reported again when it has moved
//! ([`MOVED_SHARE_OF_LEG`]): the lock turns a planted foot with the performer about the joint
//! it stands on (a pivot on the ball carries the ankle round it), so the position taken at the
//! landing would no longer say where the foot is. The latest report per target is kept on the
//! subject for clients that connect later.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use glam::Vec3;
use rigcast_protocol::FootState;
use rigcast_retarget::{forward_kinematics, Skeleton, WorldTransform};

use crate::events::Event;
use crate::reports::FootplantReport;
use crate::subject::Subject;

/// A planted foot is reported again once its joint has moved this share of its leg's length
/// (thigh and shin at rest) from where the last report put it: about 2 cm on a human.
pub const MOVED_SHARE_OF_LEG: f32 = 0.02;

/// What was last sent for one target.
#[derive(Default)]
struct Sent {
    bits: u32,
    feet: Vec<String>,
    /// Each foot's reported position (as in `feet`).
    positions: Vec<Vec3>,
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
                    let same = last.sent && bits == last.bits && *names == last.feet;
                    if same && !planted_moved(target, last, &mut self.worlds) {
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
                positions: report.feet.iter().map(|f| f.position.into()).collect(),
                sent: true,
            };
            tell(Event::Footplants(report));
        }
    }
}

/// Whether a foot `last` reported planted now stands farther than [`MOVED_SHARE_OF_LEG`] of
/// its leg from where it was reported, in `target`'s latest frame. No allocation; nothing to
/// compute while no foot is planted.
fn planted_moved(target: &Subject, last: &Sent, worlds: &mut Vec<WorldTransform>) -> bool {
    if last.bits == 0 {
        return false;
    }
    let skeleton = target.skeleton();
    let frame = target.latest.borrow();
    if frame.pose.num_bones() != skeleton.num_bones() {
        return false;
    }
    worlds.resize(skeleton.num_bones(), WorldTransform::IDENTITY);
    forward_kinematics(&skeleton, &frame.pose, worlds);
    drop(frame);
    let planted = (last.feet.iter().zip(&last.positions).enumerate())
        .filter(|(i, _)| *i < 32 && last.bits & (1 << i) != 0);
    for (_, (name, &reported)) in planted {
        let Some(bone) = skeleton.bone(name) else {
            continue;
        };
        let moved = worlds[bone.index()].translation.distance(reported);
        if moved > MOVED_SHARE_OF_LEG * leg_length(&skeleton, bone) {
            return true;
        }
    }
    false
}

/// Thigh and shin at rest above foot bone `foot`: its own and its parent's offsets.
fn leg_length(skeleton: &Skeleton, foot: rigcast_retarget::BoneId) -> f32 {
    let offset = |b: rigcast_retarget::BoneId| skeleton.rest()[b.index()].translation.length();
    let knee = skeleton.parent(foot);
    offset(foot) + knee.map_or(0.0, offset)
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
