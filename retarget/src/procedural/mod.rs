//! Skeletons built from code rather than read from files: a world-space builder and one
//! parametric humanoid emitted in each common rig convention's names and structure. The
//! server's built-in characters are made from it, so it ships in every build; the labelled
//! test corpus (`corpus`, behind its feature) builds on it too.

mod builder;
pub mod creatures;
mod humanoid;

pub use builder::Builder;
pub use humanoid::{humanoid, Style};
