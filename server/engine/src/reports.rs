//! What the server reports about its subjects besides frames, as plain data: a target's
//! mapping, its planted feet, the sources' health. The subjects keep the latest of each for
//! clients that connect later; the engine's events (`events::Event`) carry them as they happen; only
//! the host's transport edge (`wire`) turns them into protocol messages.

use rigcast_protocol::control::{MappingEntry, SourceHealth};
use rigcast_protocol::{FootState, TargetHealth};

/// A target's built mapping: which source bone each of its bones follows, how sure it is.
#[derive(Debug, Clone, PartialEq)]
pub struct MappingReport {
    /// The target subject.
    pub subject: u32,
    /// The source subject it is retargeted from (its first input).
    pub source_subject: u32,
    /// One entry per target bone.
    pub entries: Vec<MappingEntry>,
    /// What the skeleton analysis overruled or doubted on either side.
    pub warnings: Vec<String>,
}

/// A target's foot-lock state: which feet are planted and where they are.
#[derive(Debug, Clone, PartialEq)]
pub struct FootplantReport {
    /// The target subject.
    pub subject: u32,
    /// The `seq` of the target's frame the positions were taken from.
    pub seq: u64,
    /// One entry per locked foot, in the foot lock's order.
    pub feet: Vec<FootState>,
}

/// The sources' health and the targets' motion and faults, as read at one moment.
#[derive(Debug, Clone, PartialEq)]
pub struct HealthReport {
    /// One entry per source subject.
    pub sources: Vec<SourceHealth>,
    /// One entry per target subject.
    pub targets: Vec<TargetHealth>,
}
