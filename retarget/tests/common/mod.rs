//! Helpers shared by the integration tests that score analysis/mapping against the corpus'
//! ground-truth labels (`left_upper_arm`, `hips`, ...).
//!
//! Each test file includes this with `mod common;`; not every file uses every helper.
#![allow(dead_code)]

/// The side-less roles every humanoid-like corpus entry is scored on: the ones a retargeted
/// body cannot do without. Fingers, twist and end bones are left out on purpose.
pub const CORE: &[&str] = &[
    "hips",
    "spine",
    "chest",
    "neck",
    "head",
    "clavicle",
    "upper_arm",
    "lower_arm",
    "hand",
    "upper_leg",
    "lower_leg",
    "foot",
    "toes",
];

/// Splits a corpus label into its side-less role and its side (`"left"`/`"right"`), if any.
pub fn strip_side(label: &str) -> (&str, Option<&str>) {
    if let Some(r) = label.strip_prefix("left_") {
        (r, Some("left"))
    } else if let Some(r) = label.strip_prefix("right_") {
        (r, Some("right"))
    } else {
        (label, None)
    }
}

/// Whether a corpus label names one of the [`CORE`] roles (on either side).
pub fn is_core(label: &str) -> bool {
    CORE.contains(&strip_side(label).0)
}
