//! One source bone scored for one target bone: what the mapper ranks and assigns, and what
//! the confidence is measured on.

use crate::skeleton::BoneId;

/// One source bone scored for one target bone.
pub(super) struct Candidate {
    /// Which source skeleton.
    pub(super) input: u16,
    /// The source bone.
    pub(super) bone: BoneId,
    /// Its total score for the target bone.
    pub(super) score: f32,
    /// The evidence that scored, for people.
    pub(super) evidence: Vec<String>,
}
