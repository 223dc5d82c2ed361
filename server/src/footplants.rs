//! The `footplants` side message: each target's foot-lock state (which feet are planted, and
//! where they are) pushed to clients when it changes, so the viewer can draw a marker under a
//! planted foot and the Blender add-on can expose it, without polling `/v1/status`.
//!
//! The tick only stores a bitmask per target (`SubjectStats::feet_locked`, no allocation);
//! this task samples it at [`CHECK_HZ`], off the tick, and on a change takes the feet's
//! positions from forward kinematics of the target's latest published frame. The latest
//! report per target is kept on the subject for clients that connect later
//! (see `wire::state_messages`).

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use rigcast_protocol::FootState;
use rigcast_retarget::{forward_kinematics, WorldTransform};
use tokio::sync::{broadcast, watch};

use crate::events::Event;
use crate::reports::FootplantReport;
use crate::subject::Subject;

/// How often the planted flags are compared with the last message (plants change a few times
/// a second while walking; 30 Hz keeps the marker within two display frames of the lock).
pub const CHECK_HZ: f64 = 30.0;

/// What was last sent for one target.
#[derive(Default)]
struct Sent {
    bits: u32,
    feet: Vec<String>,
    sent: bool,
}

/// Broadcasts `footplants` for every target subject whose foot-lock state changed.
pub async fn run(
    subjects: Arc<Vec<Arc<Subject>>>,
    events: broadcast::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
) {
    let targets: Vec<Arc<Subject>> = subjects.iter().filter(|s| s.is_target()).cloned().collect();
    if targets.is_empty() {
        return;
    }
    let mut sent: Vec<Sent> = targets.iter().map(|_| Sent::default()).collect();
    let mut worlds: Vec<WorldTransform> = Vec::new();
    let mut interval = tokio::time::interval(Duration::from_secs_f64(1.0 / CHECK_HZ));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        for (target, last) in targets.iter().zip(sent.iter_mut()) {
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
            let report = Arc::new(report(target, &feet, bits, &mut worlds));
            target.set_footplants(report.clone());
            *last = Sent {
                bits,
                feet,
                sent: true,
            };
            // Sending fails only while no client listens; the subject keeps the report too.
            let _ = events.send(Event::Footplants(report));
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
