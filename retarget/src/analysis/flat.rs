//! Flat joint sets: skeletons whose joints are all roots (WebXR / OpenXR hand models list
//! their 25 joints side by side, with no parent links), so structure says nothing.
//!
//! Such a rig is read by its joint names (`wrist`, `index-finger-phalanx-proximal`,
//! `thumb-metacarpal`, …) and its geometry decides what names cannot: which hand it is. A hand
//! is left or right by its chirality: with `f` the direction from the wrist to the middle
//! knuckle and `t` across the knuckles from the little finger to the index, the thumb stands
//! out of that plane on the palm side, along `f × t` for a left hand and against it for a right
//! one.

use glam::Vec3;

use super::names::NameInfo;
use super::vocabulary::Role;
use super::Side;

/// Whether the skeleton is a flat set: at least three joints, every one a root.
pub(crate) fn is_flat(num_bones: usize, num_roots: usize) -> bool {
    num_bones >= 3 && num_roots == num_bones
}

const DIGITS: [&str; 5] = ["thumb", "index", "middle", "ring", "little"];

/// Role of one joint of a flat hand from its name, `None` when the name says nothing.
fn hand_role(nm: &NameInfo) -> Option<Role> {
    let has = |w: &str| nm.tokens.iter().any(|t| t == w);
    if has("hand") && nm.tokens.len() == 1 {
        return Some(Role::Hand);
    }
    let digit = DIGITS.iter().position(|d| has(d))? as u8;
    let joint = if has("metacarpal") {
        0
    } else if has("proximal") {
        1
    } else if has("intermediate") {
        2
    } else if has("distal") {
        3
    } else if has("tip") {
        return Some(Role::Helper);
    } else {
        return None;
    };
    // The thumb has no intermediate phalanx: metacarpal, proximal, distal are its 3 joints;
    // the fingers' metacarpals are palm bones.
    match (digit, joint) {
        (0, j) => Some(Role::Finger {
            digit: 0,
            joint: j.min(2),
        }),
        (_, 0) => Some(Role::Helper),
        (d, j) => Some(Role::Finger {
            digit: d,
            joint: j - 1,
        }),
    }
}

/// Roles of a flat hand (`None` for joints the names do not place), and its side.
pub(crate) fn hand_roles(names: &[NameInfo], pos: &[Vec3]) -> Option<(Vec<Option<Role>>, Side)> {
    let roles: Vec<Option<Role>> = names.iter().map(hand_role).collect();
    let hand = roles.iter().position(|r| *r == Some(Role::Hand))?;
    let find = |digit: u8, joint: u8| {
        roles
            .iter()
            .position(|r| *r == Some(Role::Finger { digit, joint }))
    };
    let side = chirality(pos, hand, &find).unwrap_or(Side::Center);
    Some((roles, side))
}

fn chirality(pos: &[Vec3], hand: usize, find: &dyn Fn(u8, u8) -> Option<usize>) -> Option<Side> {
    let (index, middle, little) = (find(1, 0)?, find(2, 0)?, find(4, 0).or(find(3, 0))?);
    let thumb = find(0, 2).or(find(0, 1))?;
    let wrist = pos[hand];
    let f = (pos[middle] - wrist).try_normalize()?;
    let across = pos[index] - pos[little];
    let t = (across - f * across.dot(f)).try_normalize()?;
    // The thumb stands out of the knuckles' plane on the palm side.
    let to_thumb = pos[thumb] - wrist;
    let c = to_thumb.dot(f.cross(t)) / to_thumb.length().max(1e-9);
    if c.abs() < 0.05 {
        return None;
    }
    Some(if c > 0.0 { Side::Left } else { Side::Right })
}

/// The analysis of a flat hand, or `None` when the joints are not a hand by their names.
pub(crate) fn analyze_flat_hand(
    skel: &crate::skeleton::Skeleton,
    pos: Vec<Vec3>,
    names: Vec<NameInfo>,
) -> Option<super::Analysis> {
    use super::{BoneRole, Section, SectionKind};
    let (roles_by_name, side) = hand_roles(&names, &pos)?;
    let n = skel.num_bones();
    let mut roles = vec![
        BoneRole {
            role: Role::Helper,
            side,
            section: None,
            limb: 0,
            position: 0.0,
            confidence: 0.3,
        };
        n
    ];
    let mut sections: Vec<Section> = Vec::new();
    let hand = roles_by_name.iter().position(|r| *r == Some(Role::Hand))?;
    sections.push(Section {
        kind: SectionKind::Hand,
        side,
        limb: 0,
        bones: vec![crate::skeleton::BoneId(hand as u16)],
        length: 0.0,
        parent: None,
        ground: false,
    });
    roles[hand] = BoneRole {
        role: Role::Hand,
        section: Some(0),
        confidence: 0.8,
        ..roles[hand]
    };
    for digit in 0..5u8 {
        let si = sections.len() as u16;
        if let Some(section) = digit_section(&roles_by_name, digit, (side, si), &mut roles) {
            sections.push(section);
        }
    }
    Some(flat_analysis(pos, names, (sections, roles), side))
}

/// The analysis of a flat hand from its sections and roles: the hand's own axes, no posture.
fn flat_analysis(
    pos: Vec<Vec3>,
    names: Vec<NameInfo>,
    (sections, roles): (Vec<super::Section>, Vec<super::BoneRole>),
    side: Side,
) -> super::Analysis {
    let n = roles.len();
    let (lo, hi) = pos.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let warnings = if side == super::Side::Center {
        vec!["a hand whose side the joints do not tell (no thumb out of the palm plane)".into()]
    } else {
        Vec::new()
    };
    super::Analysis {
        up: Vec3::Y,
        forward: Vec3::Z,
        left: Vec3::X,
        positions: pos,
        used_pose: false,
        posture_frame: None,
        size: (hi - lo).max_element().max(1e-3),
        lengths: vec![0.0; n],
        sections,
        roles,
        names,
        humanoid: false,
        main_child: vec![None; n],
        warnings,
        doubts: Vec::new(),
    }
}

/// The section of one digit (bones named for it, in joint order) as section `si`, its bones'
/// roles set; `None` when no bone is named for it.
fn digit_section(
    roles_by_name: &[Option<Role>],
    digit: u8,
    (side, si): (super::Side, u16),
    roles: &mut [super::BoneRole],
) -> Option<super::Section> {
    let mut bones: Vec<(u8, usize)> = roles_by_name
        .iter()
        .enumerate()
        .filter_map(|(i, r)| match r {
            Some(Role::Finger { digit: d, joint }) if *d == digit => Some((*joint, i)),
            _ => None,
        })
        .collect();
    if bones.is_empty() {
        return None;
    }
    bones.sort_unstable();
    let k = bones.len() as f32;
    for (j, &(joint, i)) in bones.iter().enumerate() {
        roles[i] = super::BoneRole {
            role: Role::Finger { digit, joint },
            section: Some(si),
            position: j as f32 / k,
            confidence: 0.7,
            ..roles[i]
        };
    }
    Some(super::Section {
        kind: super::SectionKind::Digit,
        side,
        limb: 0,
        bones: bones
            .iter()
            .map(|&(_, i)| crate::skeleton::BoneId(i as u16))
            .collect(),
        length: 0.0,
        parent: Some(0),
        ground: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::names::normalize;

    /// A flat left hand: fingers along -Y, knuckles across Z (index at -Z), the thumb standing
    /// out towards +X (the palm side), as WebXR's generic left hand is built.
    fn hand(mirror: f32) -> (Vec<NameInfo>, Vec<Vec3>) {
        let mut names = vec!["wrist".to_string()];
        let mut pos = vec![Vec3::new(0.0, 0.05, 0.0)];
        for (d, z) in [
            ("index", -0.02),
            ("middle", 0.0),
            ("ring", 0.02),
            ("pinky", 0.04),
        ] {
            for (j, y) in [
                ("proximal", -0.03),
                ("intermediate", -0.07),
                ("distal", -0.09),
            ] {
                names.push(format!("{d}-finger-phalanx-{j}"));
                pos.push(Vec3::new(0.0, y, z));
            }
        }
        for (j, p) in [
            ("metacarpal", Vec3::new(0.01, 0.02, -0.02)),
            ("phalanx-proximal", Vec3::new(0.02, 0.0, -0.04)),
            ("phalanx-distal", Vec3::new(0.03, -0.02, -0.06)),
        ] {
            names.push(format!("thumb-{j}"));
            pos.push(p);
        }
        let pos = pos
            .into_iter()
            .map(|p| Vec3::new(p.x * mirror, p.y, p.z))
            .collect();
        (names.iter().map(|n| normalize(n)).collect(), pos)
    }

    #[test]
    fn joints_by_name_and_the_side_by_chirality() {
        let (names, pos) = hand(1.0);
        let (roles, side) = hand_roles(&names, &pos).expect("a hand");
        assert_eq!(side, Side::Left);
        assert_eq!(roles[0], Some(Role::Hand));
        assert_eq!(roles[1], Some(Role::Finger { digit: 1, joint: 0 }));
        // Mirrored through the palm plane it is a right hand.
        let (names, pos) = hand(-1.0);
        assert_eq!(hand_roles(&names, &pos).expect("a hand").1, Side::Right);
        assert!(is_flat(25, 25) && !is_flat(25, 1));
    }
}
