//! BVH (Biovision hierarchy) reading and writing.
//!
//! ```text
//!  .bvh text ──read_bvh──▶ BvhRead { clip (metres), scale, channels }
//!  Clip ──write_bvh──▶ .bvh text (ZXY rotations, positions where they move)
//!  Clip + BvhLayout ──write_bvh_onto──▶ .bvh text with that file's exact hierarchy
//! ```
//!
//! End Sites become leaf bones named `<parent>_end` so their offsets survive; the writer turns
//! such leaves back into End Sites.
//!
//! Why a hand-written parser rather than `bvh_anim`: that crate is unmaintained, panics on some
//! malformed input and mangles leaves without End Sites; the grammar is small enough that our
//! own parser can report every error with its line and never panic.

mod layout;
mod parse;
mod units;
mod write;

pub use layout::{write_bvh_onto, BvhLayout, LayoutJoint};
pub use parse::{read_bvh, BvhRead, BvhReadOptions, FRAME_TIME_RANGE_SECS, MAX_JOINT_DEPTH};
pub use units::{guess_unit, parse_unit, UnitGuess, UNIT_CANDIDATES};
pub use write::{write_bvh, BvhWriteOptions};

/// One BVH channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Channel {
    /// translation along X
    Xposition,
    /// translation along Y
    Yposition,
    /// translation along Z
    Zposition,
    /// rotation about X
    Xrotation,
    /// rotation about Y
    Yrotation,
    /// rotation about Z
    Zrotation,
}

impl Channel {
    /// Parses a channel name (case-insensitive).
    pub fn from_name(name: &str) -> Option<Channel> {
        Some(match name.to_ascii_lowercase().as_str() {
            "xposition" => Channel::Xposition,
            "yposition" => Channel::Yposition,
            "zposition" => Channel::Zposition,
            "xrotation" => Channel::Xrotation,
            "yrotation" => Channel::Yrotation,
            "zrotation" => Channel::Zrotation,
            _ => return None,
        })
    }

    /// The channel's name as BVH spells it.
    pub fn name(self) -> &'static str {
        match self {
            Channel::Xposition => "Xposition",
            Channel::Yposition => "Yposition",
            Channel::Zposition => "Zposition",
            Channel::Xrotation => "Xrotation",
            Channel::Yrotation => "Yrotation",
            Channel::Zrotation => "Zrotation",
        }
    }
}

#[cfg(test)]
mod tests;
