//! Options for building a [`super::Mapping`].

pub use crate::mapping::Follow;
use glam::Vec3;

use crate::pose::Pose;
use crate::skeleton::BoneId;

/// What the target's root (the shallowest mapped target bone, normally the hips) does with the
/// source's translation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RootMotion {
    /// Hips translation scaled by the leg-length ratio, both horizontally and vertically
    /// (heights measured from each side's floor: where its lowest foot joint sits when
    /// planted), so strides fit the target's legs and feet neither float nor sink.
    #[default]
    Scaled,
    /// Like `Scaled` vertically, but the hips stay over the target's reference position
    /// horizontally (the character walks on the spot).
    InPlace,
    /// The root keeps its reference translation (only rotations are transferred).
    Fixed,
}

/// Vertical correction of the root so the lowest foot joint stands as high above the target's
/// floor as the source's stands above its own (scaled).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FootContact {
    /// No correction: the hips height is the source's, scaled, measured from each floor.
    Off,
    /// Measure the correction on the first frame after build or [`super::Mapping::reset`] and
    /// keep it: hips displacement stays exactly the source's scaled, feet start on the floor.
    #[default]
    FirstFrame,
    /// Correct every frame (feet heights follow the source's exactly, hips height follows the
    /// target's own leg geometry).
    EveryFrame,
}

/// Options for [`super::Mapping::build`]. `Default` suits a live source at 60 Hz.
#[derive(Debug, Clone, PartialEq)]
pub struct RetargetOptions {
    /// Per source input, a representative pose to use instead of that skeleton's rest pose as
    /// the reference posture for alignment (for rigs whose zero pose is not a posture, e.g. all
    /// bones folded together, or a capture whose rest is meaningless). `None` or a missing entry
    /// uses the rest pose.
    pub source_reference: Vec<Option<Pose>>,
    /// Reference posture of the target, instead of its rest pose.
    pub target_reference: Option<Pose>,
    /// Target bones that keep their own reference posture and take their source bone's world
    /// rotation relative to the source's standing posture (`source_standing`), without rest
    /// alignment or direction fix, whole or only its turn about up ([`Follow`]): bones whose
    /// reference posture means something else on the source, like a walker's hanging arms
    /// driving a quadruped's front legs, or its upright trunk a level one (see
    /// `mapping::posture_relative`). Empty: every bone is aligned.
    pub posture_relative: Vec<(BoneId, Follow)>,
    /// Per source input, the standing posture the motion of `posture_relative` bones is
    /// measured from (a frame of the source's motion); `None` or a missing entry uses that
    /// input's reference posture. Its facing is turned onto the reference's.
    pub source_standing: Vec<Option<Pose>>,
    /// Align rest postures (T-pose vs A-pose vs any posture). Turning it off gives the plain
    /// rest-normalised transfer, which assumes both rests show the same posture.
    pub align_rest: bool,
    /// Correct each mapped bone's direction towards the source segment between the joints its
    /// own segment ends map to, so chains of different lengths still point the same way.
    pub match_directions: bool,
    /// Spread a mapped bone's bend over the unmapped bones between it and its mapped end (a
    /// target spine of four bones driven by two) instead of bending the chain rigidly. Off by
    /// default because it moves unmapped bones, which mapping files promise to hold at rest.
    pub distribute_chains: bool,
    /// Root translation handling.
    pub root_motion: RootMotion,
    /// How the hips height is corrected so the feet neither float nor sink with different leg
    /// proportions.
    pub foot_contact: FootContact,
    /// Overrides the automatically measured leg-length ratio (target / source).
    pub root_scale: Option<f32>,
    /// The up direction of the root motion's source in its own world (the skeleton analysis
    /// finds it); `None` is +Y. Heights, floors and "horizontal" are measured along it, so a
    /// Z-up capture keeps its feet on its floor.
    pub source_up: Option<Vec3>,
    /// Height of the source's lowest foot joint when the foot is planted (its "floor"), in the
    /// source's world. `None`: taken from the reference posture when it stands near y = 0,
    /// else 0. Offline, measure it over the clip with [`super::Mapping::measure_source_floor`].
    pub source_floor_y: Option<f32>,
    /// The same for the target; `None`: from its reference posture when it stands near y = 0,
    /// else the source's floor scaled (the target keeps the source's clearance).
    pub target_floor_y: Option<f32>,
    /// Seconds between [`super::Mapping::apply`] calls; converts per-bone delays into frames.
    pub frame_time_secs: f32,
    /// Longest per-bone delay honoured, seconds (bounds the history buffer).
    pub max_delay_secs: f32,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        RetargetOptions {
            source_reference: Vec::new(),
            target_reference: None,
            posture_relative: Vec::new(),
            source_standing: Vec::new(),
            align_rest: true,
            match_directions: true,
            distribute_chains: false,
            root_motion: RootMotion::Scaled,
            foot_contact: FootContact::FirstFrame,
            root_scale: None,
            source_up: None,
            source_floor_y: None,
            target_floor_y: None,
            frame_time_secs: 1.0 / 60.0,
            max_delay_secs: 5.0,
        }
    }
}
