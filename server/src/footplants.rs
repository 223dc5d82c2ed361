//! Samples every target's foot-lock state at [`CHECK_HZ`], off the tick, and broadcasts a
//! `footplants` event on a change (the comparison and the report are the engine's
//! `FootplantSampler`).

use std::sync::Arc;
use std::time::Duration;

use rigcast_engine::footplants::FootplantSampler;
use tokio::sync::{broadcast, watch};

use crate::events::Event;
use crate::subject::Subject;

/// How often the planted flags are compared with the last message (plants change a few times
/// a second while walking; 30 Hz keeps the marker within two display frames of the lock).
pub const CHECK_HZ: f64 = 30.0;

/// Broadcasts `footplants` for every target subject whose foot-lock state changed.
pub async fn run(
    subjects: Arc<Vec<Arc<Subject>>>,
    events: broadcast::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut sampler = FootplantSampler::new(&subjects);
    if sampler.is_empty() {
        return;
    }
    let mut interval = tokio::time::interval(Duration::from_secs_f64(1.0 / CHECK_HZ));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = shutdown.changed() => break,
        }
        // Sending fails only while no client listens; the subject keeps the report too.
        sampler.sample(|event| {
            let _ = events.send(event);
        });
    }
}
