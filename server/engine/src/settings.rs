//! How the engine runs a subject, as the host's configuration chooses it (plain values; the
//! host's config schema reads them from `[server]` and `[[performers]]`).

use serde::Deserialize;

/// What a target character does while its source is lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum OnLost {
    /// Ease to the character's own rest pose over about half a second, standing where it was
    /// (`"ease"`, or `"rest"`).
    #[default]
    #[serde(alias = "rest")]
    #[cfg_attr(feature = "clap", value(alias = "rest"))]
    Ease,
    /// Hold the last pose.
    Hold,
    /// Walk on the performer's `idle_graph` from the nearest pose (`"idle"`).
    Idle,
}

/// Bone names in VMC output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VmcBoneNames {
    /// Unity `HumanBodyBones` names for humanoid subjects (others pass through).
    #[default]
    Humanoid,
    /// The subject's own bone names.
    Skeleton,
}
