//! Skeleton analysis: what every bone *is*, from structure, geometry and (weakly) names.
//!
//! ```text
//!   Skeleton (+ optional representative Pose when the rest pose is degenerate)
//!     │ geometry::joint_positions     world joint positions, body size
//!     │ topology                      main child, reach, order-free subtree hashes, twins
//!     │ frame                         lateral axis from mirror twins, up (checked against the
//!     │                               legs, never assumed), forward from feet / head cues
//!     │ centerline                    central tree → its longest path, oriented tail → head
//!     │ sections                      limb pairs on the path: legs (rearmost ground pair),
//!     │                               arms, wings, head appendages; spine / neck / tail
//!     ▼ limbs::fit_chain              clavicle? | upper | lower | hand/foot | digits
//!   Analysis { up, forward, left, positions, sections, roles[bone] }
//! ```
//!
//! Files: `posture` (rest pose or the motion's medoid frame), `detached` (control and IK bones
//! beside the body, and the limbs they continue), `forward` (facing from feet, joint bends over
//! the motion, thumbs; geometry beats names), `topology` (order-free structure), `roles`
//! (up, centerline, limbs, sections),
//! `limbs` (chain splitting), `names` (name normalisation), `vocabulary` (roles and kinds),
//! `humanoid` (Unity / VRM role map), `truth` (a file's own humanoid map overriding roles).
//!
//! Nothing here assumes a facing direction: the character's forward is where its feet (toes)
//! point, the way its knees and elbows bend and its thumbs sit; side markers in names break the
//! tie only when geometry gives no clear cue, and a clear cue that disagrees with the names is
//! reported in `Analysis::warnings`.

mod byname;
mod centerline;
mod context;
mod detached;
mod extremities;
mod flat;
mod forward;
mod frame;
pub mod humanoid;
mod limbs;
pub mod names;
mod posture;
mod roles;
mod sections;
mod topology;
pub mod truth;
mod vocabulary;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::pose::Pose;
use crate::skeleton::{BoneId, Skeleton};

pub use humanoid::{humanoid_roles, HumanBone};
pub use vocabulary::{Role, SectionKind};

/// Which side of the body a bone is on, from the character's own point of view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// On the centerline (spine, neck, head, tail, jaw).
    Center,
    /// The character's left.
    Left,
    /// The character's right.
    Right,
}

impl Side {
    /// The other side (center stays center).
    pub fn flipped(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
            Side::Center => Side::Center,
        }
    }
}

/// A skeleton plus an optional representative pose, the input of [`analyze`] and the mapper.
#[derive(Debug, Clone, Copy)]
pub struct SkeletonView<'a> {
    /// The skeleton.
    pub skeleton: &'a Skeleton,
    /// A representative frame of its animation, used for geometry when the rest pose is not a
    /// posture (see `posture`). Ignored when `motion` has frames.
    pub pose: Option<&'a Pose>,
    /// Frames of the skeleton's animation (may be empty). The analysis samples them for a
    /// posture and for the up axis when the rest pose cannot be trusted.
    pub motion: &'a [Pose],
}

impl<'a> SkeletonView<'a> {
    /// A view of the rest pose only.
    pub fn rest(skeleton: &'a Skeleton) -> Self {
        SkeletonView {
            skeleton,
            pose: None,
            motion: &[],
        }
    }

    /// A view of a skeleton with its animation frames.
    pub fn from_clip(skeleton: &'a Skeleton, motion: &'a [Pose]) -> Self {
        SkeletonView {
            skeleton,
            pose: None,
            motion,
        }
    }

    /// A view with one representative pose (live sources: the latest frame).
    pub fn with_pose(skeleton: &'a Skeleton, pose: Option<&'a Pose>) -> Self {
        SkeletonView {
            skeleton,
            pose,
            motion: &[],
        }
    }
}

/// A group of bones playing one part (an arm, a tail, the spine…).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Section {
    /// What kind of section.
    pub kind: SectionKind,
    /// Its side.
    pub side: Side,
    /// Which pair of limbs of this kind (0 = the upper / front-most pair).
    pub limb: u8,
    /// Bones in hierarchical order, from the body outwards.
    pub bones: Vec<BoneId>,
    /// Sum of bone lengths, metres.
    pub length: f32,
    /// The section this one hangs from.
    pub parent: Option<usize>,
    /// The limb reaches the ground (legs, and the front legs of quadrupeds).
    pub ground: bool,
}

/// The role of one bone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoneRole {
    /// What the bone is.
    pub role: Role,
    /// Its side.
    pub side: Side,
    /// Section it belongs to (index into [`Analysis::sections`]).
    pub section: Option<u16>,
    /// Limb pair index of its section (0 = upper / front-most pair).
    pub limb: u8,
    /// Position along its section, 0 at the body end, 1 at the far end (by length).
    pub position: f32,
    /// 0..=1, how sure the analysis is.
    pub confidence: f32,
}

impl BoneRole {
    fn unknown() -> Self {
        BoneRole {
            role: Role::Unknown,
            side: Side::Center,
            section: None,
            limb: 0,
            position: 0.0,
            confidence: 0.0,
        }
    }

    /// Readable label, e.g. `left_upper_arm`, `hips`, `tail_3`, `right_wing_hand`,
    /// `left_arm2_hand` (second pair of arms). Corpus ground truth uses the same labels.
    pub fn label(&self, kind: Option<SectionKind>) -> String {
        let side = match self.side {
            Side::Left => "left_",
            Side::Right => "right_",
            Side::Center => "",
        };
        let wing = matches!(kind, Some(SectionKind::Wing));
        let pair = if self.limb > 0 && self.role.is_limb() {
            format!("limb{}_", self.limb + 1)
        } else {
            String::new()
        };
        let wing = if wing && self.role.is_limb() {
            "wing_"
        } else {
            ""
        };
        format!("{side}{wing}{pair}{}", self.role.name())
    }
}

/// Everything [`analyze`] found out about a skeleton.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Analysis {
    /// Up axis (unit), in the skeleton's space.
    pub up: Vec3,
    /// Forward axis (unit): where the character faces.
    pub forward: Vec3,
    /// The character's left (unit), `up × forward`.
    pub left: Vec3,
    /// World joint positions the analysis used (rest, or the representative pose).
    pub positions: Vec<Vec3>,
    /// True when the rest pose was not a posture and a frame (or the representative pose) was
    /// used instead.
    pub used_pose: bool,
    /// Index into the view's `motion` of the frame the analysis read, if it read one.
    pub posture_frame: Option<usize>,
    /// Largest extent of the skeleton, metres (the scale for tolerances).
    pub size: f32,
    /// Length of each bone (distance to its main child; 0 for leaves).
    pub lengths: Vec<f32>,
    /// Sections.
    pub sections: Vec<Section>,
    /// Role of every bone, indexed by [`BoneId`].
    pub roles: Vec<BoneRole>,
    /// Normalised names, indexed by [`BoneId`].
    #[serde(skip)]
    pub names: Vec<names::NameInfo>,
    /// The skeleton has two legs and two arms (plus any tail / fingers).
    pub humanoid: bool,
    /// Child continuing each bone's chain (towards its farthest descendant).
    pub main_child: Vec<Option<BoneId>>,
    /// What the analysis overruled or doubted (names against geometry, …), for the user.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Readings it nearly made instead, and the bones they read otherwise (see [`Doubt`]).
    #[serde(default)]
    pub doubts: Vec<Doubt>,
}

/// A reading the analysis nearly made instead of its own, and the bones that reading reads
/// otherwise: the analysis' own measure of where it may be wrong, which the mapper's
/// confidence carries (a margin between source bones cannot see a wrong reading of the body).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Doubt {
    /// Why, for people.
    pub reason: String,
    /// 0..1: how close the other reading came (1: as likely as the one chosen).
    pub strength: f32,
    /// The bones it would read otherwise.
    pub bones: Vec<BoneId>,
}

impl Analysis {
    /// The strongest doubt over bone `b`'s reading, if any.
    pub fn doubt_of(&self, b: BoneId) -> Option<&Doubt> {
        self.doubts
            .iter()
            .filter(|d| d.bones.contains(&b))
            .max_by(|x, y| x.strength.total_cmp(&y.strength))
    }

    /// The pose the analysis read its geometry from, when not the rest pose: the motion frame
    /// it chose (`motion` must be the view's motion). Alignment stages use the same posture.
    pub fn posture_pose(&self, motion: &[Pose]) -> Option<Pose> {
        posture::frame_pose(motion, self.posture_frame).cloned()
    }

    /// Role label of one bone (see [`BoneRole::label`]).
    pub fn label(&self, bone: BoneId) -> String {
        let r = &self.roles[bone.index()];
        // Hands and digits of a wing are labelled as part of the wing.
        let mut sec = r.section.map(|s| s as usize);
        let mut kind = sec.map(|s| self.sections[s].kind);
        while let Some(s) = sec {
            if self.sections[s].kind == SectionKind::Wing {
                kind = Some(SectionKind::Wing);
                break;
            }
            sec = self.sections[s].parent;
        }
        r.label(kind)
    }

    /// First bone with the given role and side.
    pub fn find(&self, role: Role, side: Side) -> Option<BoneId> {
        self.roles
            .iter()
            .position(|r| r.role == role && r.side == side && r.limb == 0)
            .map(|i| BoneId(i as u16))
    }

    /// Section kind of a bone, if it belongs to one.
    pub fn section_kind(&self, bone: BoneId) -> Option<SectionKind> {
        self.roles[bone.index()]
            .section
            .map(|s| self.sections[s as usize].kind)
    }

    /// Direction of a bone (towards its main child) expressed in the body frame
    /// (x = left, y = up, z = forward); zero for leaves.
    pub fn body_direction(&self, skeleton: &Skeleton, bone: BoneId) -> Vec3 {
        let _ = skeleton;
        // Zero-length helpers take the direction of the first real segment below them.
        let p = self.positions[bone.index()];
        let mut c = bone;
        let mut d = Vec3::ZERO;
        while let Some(next) = self.main_child[c.index()] {
            c = next;
            d = self.positions[c.index()] - p;
            if d.length() > 1e-4 * self.size {
                break;
            }
        }
        let d = d.normalize_or_zero();
        Vec3::new(d.dot(self.left), d.dot(self.up), d.dot(self.forward))
    }
}

/// The standing posture of a skeleton's motion, even when its rest pose is a posture: the
/// motion's mean posture (per bone, the average local rotation, headings taken out about `up`),
/// for a walk standing with the arms hanging, not its T-pose. `None` without valid frames.
pub fn standing_posture(skeleton: &Skeleton, motion: &[Pose], up: Vec3) -> Option<Pose> {
    posture::mean_posture(skeleton, motion, up)
}

/// Analyses a skeleton. Never fails: an unusual skeleton just gets more `Unknown` roles and
/// lower confidences.
pub fn analyze(view: &SkeletonView<'_>) -> Analysis {
    let mut a = roles::analyze_impl(view);
    names_as_evidence(view.skeleton, &mut a);
    a
}

/// Names that describe a complete humanoid are strong evidence. When the geometry's reading
/// disagrees with them on most of their bones (offsets shifted a level, joints stacked:
/// geometry that cannot be trusted), the names' roles replace it and the analysis says so.
/// When it agrees on most, the few bones it reads otherwise take their names' roles (a
/// cartoon's big head read as neck + head, an upper arm too short for the length fit): a
/// name that says what a bone is, and that no other bone on its side also says, outweighs a
/// proportion that merely suggests otherwise. The
/// sides stay the analysis' (where clear geometry and names disagree on sides, the geometry
/// has already won in `forward`).
fn names_as_evidence(skeleton: &Skeleton, a: &mut Analysis) {
    let Some(map) = byname::humanoid_from_names(skeleton, &a.names) else {
        return;
    };
    let parsed = truth::parse_truth(skeleton, &map);
    let upper = parsed.iter().any(|(h, _)| *h == HumanBone::UpperChest);
    let wanted: Vec<(BoneId, Role, Side)> = parsed
        .iter()
        .map(|&(h, b)| {
            let (role, side) = truth::human_bone_role(h, upper);
            let have = a.roles[b.index()].side;
            (b, role, if have == Side::Center { side } else { have })
        })
        .collect();
    let agree = wanted
        .iter()
        .filter(|(b, role, _)| a.roles[b.index()].role == *role)
        .count();
    if 2 * agree >= wanted.len() {
        let clear = byname::unambiguous(skeleton, &a.names);
        let differ: Vec<(BoneId, Role, Side)> = wanted
            .into_iter()
            .filter(|(b, role, _)| clear[b.index()] && a.roles[b.index()].role != *role)
            .collect();
        truth::set_roles(a, &differ, NAMED_ROLE_CONFIDENCE);
        return;
    }
    truth::apply_truth(skeleton, a, &map);
    byname::sections_from_roles(skeleton, a);
    a.humanoid = true;
    a.warnings.push(format!(
        "the geometry does not read as the body its names describe ({agree} of {} named bones \
         agree): roles come from the names",
        map.len()
    ));
}

/// Confidence of a role a bone's name gave it over the geometry's reading.
const NAMED_ROLE_CONFIDENCE: f32 = 0.8;

/// [`analyze`], then the file's own humanoid map (VRM: human bone name → bone name) as ground
/// truth over the inferred roles and sides (see [`truth::apply_truth`]). `None` or an empty
/// map is plain [`analyze`].
pub fn analyze_with_truth(view: &SkeletonView<'_>, truth: Option<&[(String, String)]>) -> Analysis {
    let mut a = analyze(view);
    if let Some(t) = truth {
        truth::apply_truth(view.skeleton, &mut a, t);
    }
    a
}
