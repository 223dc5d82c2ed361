//! Footplants and foot locking (seed 002): when a foot stands on the ground, and keeping the
//! target's foot there while it does.
//!
//! ```text
//!  Analysis roles ─▶ rig::find_legs      hind legs (thigh, shin, foot, toes) and a
//!                                        quadruped's front legs, by side and pair; a
//!                                        lone IK foot beside the body is carried at
//!                                        its shin's end (a source's: find_contact_legs,
//!                                        feet hanging from anywhere)
//!  source motion ─▶ detect               heel or ball near its ground AND slow, relative
//!                                        to the leg's length and the body's speed;
//!                                        hysteresis; causal
//!                                        (PlantDetector) or two-sided (detect_clip,
//!                                        with each foot's height above its ground;
//!                                        an in-place clip's feet judged against the
//!                                        belt they slide on: treadmill)
//!  target pose   ─▶ lock (FootLock)      carry the root onto the held feet, over the
//!                                        ground and up (stride: stride warping and
//!                                        pelvis height from the legs' reach:
//!                                        pelvis), pin planted feet
//!                                        (position + heading), lower the
//!                                        hips when out of reach, ik::solve_two_bone,
//!                                        blend switches, keep feet above the floor
//! ```

pub mod detect;
pub mod ik;
pub mod lock;
mod pelvis;
pub mod rig;
mod search;
pub mod spring;
mod stride;
mod treadmill;

pub use detect::{detect_clip, Contact, PlantDetector, PlantSettings, PlantTrack};
pub use ik::{solve_two_bone, TwoBoneSolution};
pub use lock::{FootLock, LockSettings};
pub use rig::{find_contact_legs, find_legs, Leg, LegKind, MAX_FEET};
