//! The crate's one error enum.

use thiserror::Error;

/// Errors raised when building or validating core types. Per-frame calls never return errors:
/// everything they need is validated when their inputs are built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RetargetError {
    /// A [`crate::RetargetContext`] used with a plan it was not made for.
    #[error("retarget context was made for another plan (use RetargetPlan::new_context)")]
    ForeignContext,
    /// A skeleton needs at least one bone.
    #[error("skeleton has no bones")]
    EmptySkeleton,
    /// More bones than a [`crate::BoneId`] can address.
    #[error("skeleton has {num_bones} bones; at most {max} are supported")]
    TooManyBones {
        /// bones given
        num_bones: usize,
        /// the limit
        max: usize,
    },
    /// Two bones share a name; names must be unique so they can be resolved to ids once.
    #[error("bone name {name:?} is used by bones {first} and {second}")]
    DuplicateBoneName {
        /// the repeated name
        name: String,
        /// index of the first bone with it
        first: usize,
        /// index of the second bone with it
        second: usize,
    },
    /// A parent index points outside the bone list.
    #[error(
        "bone {bone} ({name:?}) has parent index {parent}, but there are only {num_bones} bones"
    )]
    ParentOutOfRange {
        /// index of the bone
        bone: usize,
        /// its name
        name: String,
        /// the bad parent index
        parent: usize,
        /// number of bones
        num_bones: usize,
    },
    /// The parent links contain a cycle.
    #[error("bone {bone} ({name:?}) is part of a parent cycle")]
    ParentCycle {
        /// index of a bone on the cycle
        bone: usize,
        /// its name
        name: String,
    },
    /// A rest transform contains NaN or infinity.
    #[error("bone {bone} ({name:?}) has a non-finite rest transform")]
    NonFiniteRest {
        /// index of the bone
        bone: usize,
        /// its name
        name: String,
    },
    /// A rest translation beyond [`crate::bounds::MAX_TRANSLATION_M`] (finite values that
    /// overflow once summed along a chain).
    #[error("bone {bone} ({name:?}) has a rest offset beyond 10 km")]
    RestOutOfRange {
        /// index of the bone
        bone: usize,
        /// its name
        name: String,
    },
    /// A frame of a clip holds a pose that is not one (see [`crate::pose::Pose::check_values`]).
    #[error("frame {frame}, bone {bone}: {fault}")]
    BadPose {
        /// index of the frame
        frame: usize,
        /// index of the bone
        bone: usize,
        /// what is wrong
        fault: crate::bounds::PoseFault,
    },
    /// A derived clip would hold more bone samples than its input allows (see
    /// [`crate::bounds::sample_budget`]).
    #[error("{num_frames} frames of {num_bones} bones is beyond the limit of {max_samples} bone samples for this input")]
    TooManyFrames {
        /// frames asked for
        num_frames: f64,
        /// bones per frame
        num_bones: usize,
        /// the budget
        max_samples: u64,
    },
    /// A pose or clip does not match its skeleton.
    #[error("pose has {got} bones but the skeleton has {expected}")]
    PoseSizeMismatch {
        /// bones the skeleton has
        expected: usize,
        /// bones the pose has
        got: usize,
    },
    /// A clip needs a positive, finite frame time.
    #[error("frame time {frame_time_secs} s is not a positive finite number")]
    BadFrameTime {
        /// the bad value
        frame_time_secs: f64,
    },
    /// A mapping refers to a bone that does not exist, or is otherwise inconsistent.
    #[error("mapping is invalid: {reason}")]
    InvalidMapping {
        /// what is wrong
        reason: String,
    },
}
