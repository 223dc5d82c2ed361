//! The offline pipeline as a library: the mapping plan of a clip onto a character (analysis,
//! automatic mapping, mapping-file overrides, which bones keep their own posture), whole-clip
//! retargeting with the foot lock, and grafting one clip's upper body onto another's legs.
//! `rigcast map`, `retarget` and `graft`, the server's mapper and the tests call it; it reads
//! and writes no file and prints nothing (progress goes to a callback).
//!
//! ```text
//!  source clip ─┐
//!               ├─ plan_mapping ─▶ MappingPlan ─▶ retarget_clip_locked ─▶ clip on the target
//!  target clip ─┘   (analyze → map → overrides → posture)     (Mapping + FootLock, per frame)
//! ```

mod clip;
mod graft;
mod plan;

pub use clip::{retarget_clip, retarget_clip_locked, Progress};
pub use graft::{graft_clips, plants, Grafted};
pub use plan::{
    map_pair, plan_mapping, plan_mapping_with_truth, posture_plan, table_for, HumanoidTruth,
    MappedPair, MappingPlan, TableCache,
};

use rigcast_retarget::graft::GraftError;
use rigcast_retarget::mapping::MappingFileError;
use rigcast_retarget::RetargetError;
use thiserror::Error;

/// Why an offline step failed. Each message says which step; its source says why.
#[derive(Debug, Error)]
pub enum OfflineError {
    /// The mapping file's overrides do not fit the skeletons.
    #[error("mapping file")]
    Overrides(#[source] MappingFileError),
    /// The automatic mapping found no bone to drive.
    #[error("no bone of {target} could be mapped to {source_name}")]
    NothingMapped {
        /// what the target is (for the message)
        target: &'static str,
        /// what the source is
        source_name: &'static str,
    },
    /// `Mapping::build` refused the plan.
    #[error("cannot build the retargeting mapping")]
    Build(#[source] RetargetError),
    /// A frame of the clip does not fit its own skeleton.
    #[error("frame {index} does not fit the source skeleton")]
    Frame {
        /// the frame
        index: usize,
        /// why
        #[source]
        source: RetargetError,
    },
    /// The output clip could not be made.
    #[error(transparent)]
    Clip(#[from] RetargetError),
    /// The upper clip could not be put onto the lower clip's rig.
    #[error("cannot retarget the upper clip onto the lower clip's rig")]
    GraftRetarget(#[source] Box<OfflineError>),
    /// The lower clip's rig has no waist to cut at.
    #[error("the lower clip's rig")]
    GraftRig(#[source] GraftError),
    /// Planning or synthesising the graft failed.
    #[error(transparent)]
    Graft(#[from] GraftError),
}
