//! The vocabulary of the analysis: section kinds and bone roles, with their labels.

use serde::{Deserialize, Serialize};

/// Kind of body section (seed 004's body types, plus digits, wings and appendages).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SectionKind {
    /// Hips and spine up to where the front-most limbs attach.
    Spine,
    /// Neck and head, beyond the front-most limbs.
    Head,
    /// Behind the rear-most legs.
    Tail,
    /// Clavicle, upper and lower arm (also a quadruped's front legs).
    Arm,
    /// Hand (and finger joints when the hand has a single digit chain).
    Hand,
    /// Pelvis helper, thigh and shin.
    Leg,
    /// Foot and toes.
    Foot,
    /// One finger or toe chain.
    Digit,
    /// A wing (an arm-like limb much longer than the arms).
    Wing,
    /// Eyes, ears, horns, props: small or head-mounted side chains.
    Appendage,
}

impl SectionKind {
    /// Seed 004's "similar body type": limbs with limbs, extremities with extremities.
    pub fn similar(self, other: SectionKind) -> bool {
        use SectionKind::*;
        matches!(
            (self, other),
            (Arm, Leg)
                | (Leg, Arm)
                | (Arm, Wing)
                | (Wing, Arm)
                | (Hand, Foot)
                | (Foot, Hand)
                | (Spine, Tail)
                | (Tail, Spine)
                | (Spine, Head)
                | (Head, Spine)
        )
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        use SectionKind::*;
        match self {
            Spine => "spine",
            Head => "head",
            Tail => "tail",
            Arm => "arm",
            Hand => "hand",
            Leg => "leg",
            Foot => "foot",
            Digit => "digit",
            Wing => "wing",
            Appendage => "appendage",
        }
    }
}

/// What one bone is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Pelvis: where the rear-most legs attach.
    Hips,
    /// First spine bone above the hips.
    Spine,
    /// Spine bones between the first and the chest.
    SpineMid,
    /// Last spine bone: where the front-most limbs (clavicles) attach.
    Chest,
    /// Neck bone, 0 = lowest.
    Neck(u8),
    /// Head.
    Head,
    /// End joint above the head.
    HeadEnd,
    /// Jaw.
    Jaw,
    /// Eye.
    Eye,
    /// Ear, horn, prop or other side chain.
    Appendage,
    /// Clavicle / shoulder blade.
    Clavicle,
    /// Upper arm (humerus; also front-leg upper segment, wing humerus).
    UpperArm,
    /// Forearm.
    LowerArm,
    /// Hand / wrist.
    Hand,
    /// Finger (or claw) joint: digit 0 = thumb … 4 = little; joint 0 = proximal.
    Finger {
        /// which digit
        digit: u8,
        /// which joint along it
        joint: u8,
    },
    /// Pelvis-side helper between the hips and the thigh (CMU `LHipJoint`).
    PelvisSide,
    /// Thigh.
    UpperLeg,
    /// Shin.
    LowerLeg,
    /// Foot / ankle.
    Foot,
    /// Toes / ball.
    Toes,
    /// End joint past the toes.
    ToeEnd,
    /// Tail bone, 0 = at the base.
    Tail(u8),
    /// Twist or segment bone that shares its parent's motion.
    Twist,
    /// Helper / mechanism / end joint with no anatomical role.
    Helper,
    /// Control bone beside the body (IK target, pole target, orient handle): never a body
    /// part, and drives or is driven by nothing.
    Control,
    /// Not recognised.
    Unknown,
}

const DIGITS: [&str; 5] = ["thumb", "index", "middle", "ring", "little"];

impl Role {
    /// Part of a paired limb (gets a side and limb index in labels).
    pub fn is_limb(self) -> bool {
        use Role::*;
        matches!(
            self,
            Clavicle
                | UpperArm
                | LowerArm
                | Hand
                | Finger { .. }
                | PelvisSide
                | UpperLeg
                | LowerLeg
                | Foot
                | Toes
                | ToeEnd
        )
    }

    /// The roles the acceptance criteria count: hips, spine ends, neck, head, clavicles,
    /// upper/lower arms, hands, upper/lower legs, feet, toes.
    pub fn is_core(self) -> bool {
        use Role::*;
        matches!(
            self,
            Hips | Spine
                | Chest
                | Neck(0)
                | Head
                | Clavicle
                | UpperArm
                | LowerArm
                | Hand
                | UpperLeg
                | LowerLeg
                | Foot
                | Toes
        )
    }

    /// Helper-like roles that only map onto the same role.
    pub fn is_helper(self) -> bool {
        matches!(
            self,
            Role::Twist
                | Role::Helper
                | Role::Control
                | Role::HeadEnd
                | Role::ToeEnd
                | Role::Unknown
        )
    }

    /// snake_case name used in labels.
    pub fn name(self) -> String {
        use Role::*;
        match self {
            Hips => "hips".into(),
            Spine => "spine".into(),
            SpineMid => "spine_mid".into(),
            Chest => "chest".into(),
            Neck(0) => "neck".into(),
            // Widened: the 256th bone of a long neck or tail is `255`, and 255 + 1 overflows u8.
            Neck(k) => format!("neck_{}", u16::from(k) + 1),
            Head => "head".into(),
            HeadEnd => "head_end".into(),
            Jaw => "jaw".into(),
            Eye => "eye".into(),
            Appendage => "appendage".into(),
            Clavicle => "clavicle".into(),
            UpperArm => "upper_arm".into(),
            LowerArm => "lower_arm".into(),
            Hand => "hand".into(),
            Finger { digit, joint } => match DIGITS.get(digit as usize) {
                Some(d) => format!("{d}_{}", joint + 1),
                None => format!("digit{}_{}", digit + 1, joint + 1),
            },
            PelvisSide => "pelvis_side".into(),
            UpperLeg => "upper_leg".into(),
            LowerLeg => "lower_leg".into(),
            Foot => "foot".into(),
            Toes => "toes".into(),
            ToeEnd => "toe_end".into(),
            Tail(k) => format!("tail_{}", u16::from(k) + 1),
            Twist => "twist".into(),
            Helper => "helper".into(),
            Control => "control".into(),
            Unknown => "unknown".into(),
        }
    }
}
