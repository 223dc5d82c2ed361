//! Roles from names alone, for rigs whose geometry cannot be read (offsets shifted a level,
//! joints stacked on each other, all-zero motion: such files exist and must still map).
//!
//! Each bone's canonical tokens give it a part (`thigh`, `forearm`, `clavicle`…) and its side
//! marker a side; two conventions are then told apart along each limb:
//!
//! - *segment* naming (Mixamo `LeftArm` → `LeftForeArm` → `LeftHand`) names the bone;
//! - *joint* naming (Kinect `ShoulderLeft` → `ElbowLeft` → `WristLeft`, CMU's 3ds Max names
//!   `LeftCollar` → `LeftShoulder` → `LeftElbow`) names the joint the bone starts at, so the
//!   "shoulder" right above the elbow is the upper arm, and a second "foot" below the ankle is
//!   the toes.
//!
//! The pelvis is the bone named so, else the common parent of the thighs; the chest is the
//! common parent of the arms. The result is a humanoid map (Unity bone name → bone name) used
//! as ground truth only when it is complete.

use super::names::NameInfo;
use super::{HumanBone, Side};
use crate::skeleton::{BoneId, Skeleton};
use glam::Vec3;

/// A body part a name can say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    Pelvis,
    Spine,
    Chest,
    Neck,
    Head,
    Clavicle,
    UpperArm,
    LowerArm,
    Hand,
    UpperLeg,
    LowerLeg,
    Foot,
    Toes,
}

const PARTS: &[(&str, Part)] = &[
    ("pelvis", Part::Pelvis),
    ("spine", Part::Spine),
    ("chest", Part::Chest),
    ("neck", Part::Neck),
    ("head", Part::Head),
    ("clavicle", Part::Clavicle),
    ("upperarm", Part::UpperArm),
    ("forearm", Part::LowerArm),
    ("hand", Part::Hand),
    ("thigh", Part::UpperLeg),
    ("shin", Part::LowerLeg),
    ("foot", Part::Foot),
    ("toe", Part::Toes),
];

const DIGITS: &[&str] = &["thumb", "index", "middle", "ring", "little", "finger"];

fn part(nm: &NameInfo) -> Option<Part> {
    if nm.helper || nm.tokens.iter().any(|t| DIGITS.contains(&t.as_str())) {
        return None;
    }
    nm.tokens
        .iter()
        .find_map(|t| PARTS.iter().find(|(w, _)| w == t).map(|(_, p)| *p))
}

/// The humanoid map the names describe (Unity bone name, bone name), or `None` unless it has
/// the trunk (hips, spine, chest, neck, head) and both arms and legs down to hands and feet.
pub(crate) fn humanoid_from_names(
    skel: &Skeleton,
    names: &[NameInfo],
) -> Option<Vec<(String, String)>> {
    let parts = parts(skel, names);
    let mut map: Vec<(HumanBone, BoneId)> = Vec::new();
    for side in [Side::Left, Side::Right] {
        for (p, h) in limb_bones(side) {
            let first = skel
                .bone_ids()
                .find(|b| parts[b.index()] == Some(p) && names[b.index()].side == Some(side));
            if let Some(b) = first {
                map.push((h, b));
            }
        }
    }
    let find = |h: HumanBone| map.iter().find(|(x, _)| *x == h).map(|(_, b)| *b);
    let thighs = [
        find(HumanBone::LeftUpperLeg)?,
        find(HumanBone::RightUpperLeg)?,
    ];
    let arms = [
        find(HumanBone::LeftUpperArm)?,
        find(HumanBone::RightUpperArm)?,
    ];
    let hips = skel
        .bone_ids()
        .find(|b| parts[b.index()] == Some(Part::Pelvis))
        .or_else(|| common_parent(skel, thighs))?;
    let chest = common_parent(skel, arms)?;
    let center = |p: Part| {
        skel.bone_ids()
            .find(|b| parts[b.index()] == Some(p) && names[b.index()].side.is_none())
    };
    let (neck, head) = (center(Part::Neck)?, center(Part::Head)?);
    // The spine: the first bone on the way from the hips up to the chest.
    let mut spine = chest;
    while let Some(p) = skel.parent(spine).filter(|&p| p != hips) {
        spine = p;
    }
    if spine == hips || skel.parent(spine) != Some(hips) || spine == chest {
        return None;
    }
    map.extend([
        (HumanBone::Hips, hips),
        (HumanBone::Spine, spine),
        (HumanBone::Chest, chest),
        (HumanBone::Neck, neck),
        (HumanBone::Head, head),
    ]);
    let required = 5 + 2 * 6;
    let core = map
        .iter()
        .filter(|(h, _)| !matches!(h, HumanBone::LeftShoulder | HumanBone::RightShoulder))
        .filter(|(h, _)| !matches!(h, HumanBone::LeftToes | HumanBone::RightToes))
        .count();
    (core >= required).then(|| {
        map.into_iter()
            .map(|(h, b)| (h.unity_name().to_string(), skel.name(b).to_string()))
            .collect()
    })
}

/// The part each bone's name says, joint naming resolved.
fn parts(skel: &Skeleton, names: &[NameInfo]) -> Vec<Option<Part>> {
    let mut parts: Vec<Option<Part>> = names.iter().map(part).collect();
    for side in [Side::Left, Side::Right] {
        joint_naming(skel, names, &mut parts, side);
    }
    parts
}

/// Per bone: its name says a part that no other bone with the same side marker also says
/// (CMU's `LHipJoint` and `LeftHip` both say "hip": neither is clear evidence).
pub(crate) fn unambiguous(skel: &Skeleton, names: &[NameInfo]) -> Vec<bool> {
    let parts = parts(skel, names);
    skel.bone_ids()
        .map(|b| {
            let i = b.index();
            parts[i].is_some()
                && !skel.bone_ids().any(|o| {
                    o != b && parts[o.index()] == parts[i] && names[o.index()].side == names[i].side
                })
        })
        .collect()
}

fn limb_bones(side: Side) -> [(Part, HumanBone); 8] {
    use HumanBone as H;
    let left = side == Side::Left;
    let pick = |l: H, r: H| if left { l } else { r };
    [
        (Part::Clavicle, pick(H::LeftShoulder, H::RightShoulder)),
        (Part::UpperArm, pick(H::LeftUpperArm, H::RightUpperArm)),
        (Part::LowerArm, pick(H::LeftLowerArm, H::RightLowerArm)),
        (Part::Hand, pick(H::LeftHand, H::RightHand)),
        (Part::UpperLeg, pick(H::LeftUpperLeg, H::RightUpperLeg)),
        (Part::LowerLeg, pick(H::LeftLowerLeg, H::RightLowerLeg)),
        (Part::Foot, pick(H::LeftFoot, H::RightFoot)),
        (Part::Toes, pick(H::LeftToes, H::RightToes)),
    ]
}

/// Joint naming on one side: without a bone named as the upper arm, the nearest "shoulder"
/// (clavicle token) above the forearm is the upper arm; a "foot" below another foot is the
/// toes.
fn joint_naming(skel: &Skeleton, names: &[NameInfo], parts: &mut [Option<Part>], side: Side) {
    let on_side = |b: BoneId| names[b.index()].side == Some(side);
    let has = |parts: &[Option<Part>], p: Part| {
        skel.bone_ids()
            .any(|b| on_side(b) && parts[b.index()] == Some(p))
    };
    if !has(parts, Part::UpperArm) {
        let forearm = skel
            .bone_ids()
            .find(|&b| on_side(b) && parts[b.index()] == Some(Part::LowerArm));
        let mut a = forearm.and_then(|f| skel.parent(f));
        while let Some(b) = a {
            if parts[b.index()] == Some(Part::Clavicle) {
                parts[b.index()] = Some(Part::UpperArm);
                break;
            }
            a = skel.parent(b);
        }
    }
    for b in skel.bone_ids().filter(|&b| on_side(b)) {
        let below_foot = skel
            .parent(b)
            .is_some_and(|p| parts[p.index()] == Some(Part::Foot));
        if parts[b.index()] == Some(Part::Foot) && below_foot {
            parts[b.index()] = Some(Part::Toes);
        }
    }
}

/// The deepest bone both `a` and `b` hang from.
fn common_parent(skel: &Skeleton, [a, b]: [BoneId; 2]) -> Option<BoneId> {
    let mut up = Vec::new();
    let mut x = skel.parent(a);
    while let Some(p) = x {
        up.push(p);
        x = skel.parent(p);
    }
    let mut y = skel.parent(b);
    while let Some(p) = y {
        if up.contains(&p) {
            return Some(p);
        }
        y = skel.parent(p);
    }
    None
}

/// Sections rebuilt from the roles alone (after the names replaced a reading of broken
/// geometry): spine, head, and per side arm, hand, leg and foot, bones in hierarchy order.
/// Legs stand on the ground; arms do where the posture hangs them down to it (a quadruped
/// named like a humanoid, as the MANN dogs are, stands on its arms; a body whose geometry
/// lies flat, as kinect2's rest does, says nothing of where its ground is).
pub(crate) fn sections_from_roles(skel: &Skeleton, a: &mut super::Analysis) {
    use super::{Role, Section, SectionKind};
    let kind_of = |r: Role| match r {
        Role::Hips | Role::Spine | Role::SpineMid | Role::Chest => Some(SectionKind::Spine),
        Role::Neck(_) | Role::Head => Some(SectionKind::Head),
        Role::Clavicle | Role::UpperArm | Role::LowerArm => Some(SectionKind::Arm),
        Role::Hand => Some(SectionKind::Hand),
        Role::PelvisSide | Role::UpperLeg | Role::LowerLeg => Some(SectionKind::Leg),
        Role::Foot | Role::Toes => Some(SectionKind::Foot),
        _ => None,
    };
    let mut sections: Vec<Section> = Vec::new();
    for r in a.roles.iter_mut() {
        r.section = None;
    }
    for b in skel.bone_ids() {
        let r = a.roles[b.index()];
        let Some(kind) = kind_of(r.role) else {
            continue;
        };
        let idx = match sections
            .iter()
            .position(|s| s.kind == kind && s.side == r.side)
        {
            Some(i) => i,
            None => {
                let ground = matches!(kind, SectionKind::Leg | SectionKind::Foot);
                sections.push(Section {
                    kind,
                    side: r.side,
                    limb: 0,
                    bones: Vec::new(),
                    length: 0.0,
                    parent: None,
                    ground,
                });
                sections.len() - 1
            }
        };
        sections[idx].bones.push(b);
        a.roles[b.index()].section = Some(idx as u16);
        a.roles[b.index()].limb = 0;
    }
    for s in &sections {
        let n = s.bones.len().max(1) as f32;
        for (j, b) in s.bones.iter().enumerate() {
            a.roles[b.index()].position = j as f32 / n;
        }
    }
    for s in sections.iter_mut().filter(|s| s.kind == SectionKind::Arm) {
        s.ground = reaches_ground(skel, &a.positions, a.up, &s.bones);
    }
    a.sections = sections;
}

/// Whether the limb of `bones` (and all that hangs below them) hangs down to the ground of
/// the posture `positions`: its lowest joint within a fifth of the posture's height above
/// the lowest joint of all (the band the geometric reading gives a ground limb), and at
/// least 30 degrees below level as seen from the limb's first joint.
fn reaches_ground(skel: &Skeleton, positions: &[Vec3], up: Vec3, bones: &[BoneId]) -> bool {
    let at = |b: BoneId| positions.get(b.index()).copied().unwrap_or(Vec3::ZERO);
    let h = |b: BoneId| at(b).dot(up);
    let (ground, top) = skel
        .bone_ids()
        .map(h)
        .fold((f32::MAX, f32::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    let in_limb = |mut b: BoneId| loop {
        if bones.contains(&b) {
            return true;
        }
        match skel.parent(b) {
            Some(p) => b = p,
            None => return false,
        }
    };
    let Some(lowest) = skel
        .bone_ids()
        .filter(|&b| in_limb(b))
        .min_by(|&x, &y| h(x).total_cmp(&h(y)))
    else {
        return false;
    };
    let Some(&first) = bones.first() else {
        return false;
    };
    let down = (at(first) - at(lowest)).normalize_or_zero().dot(up);
    h(lowest) < ground + 0.2 * (top - ground).max(1e-3) && down >= 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::names::normalize;
    use crate::skeleton::{RawSkeleton, Transform};

    /// Kinect v2's joint set, all joints at the origin (no geometry at all).
    fn kinect() -> Skeleton {
        let mut raw = RawSkeleton::default();
        let mut add = |n: &str, p: Option<usize>| raw.add(n, p, Transform::IDENTITY);
        let base = add("SpineBase", None);
        let mid = add("SpineMid", Some(base));
        let top = add("SpineShoulder", Some(mid));
        let neck = add("Neck", Some(top));
        add("Head", Some(neck));
        for s in ["Left", "Right"] {
            let sh = add(&format!("Shoulder{s}"), Some(top));
            let el = add(&format!("Elbow{s}"), Some(sh));
            let wr = add(&format!("Wrist{s}"), Some(el));
            let hand = add(&format!("Hand{s}"), Some(wr));
            add(&format!("HandTip{s}"), Some(hand));
            add(&format!("Thumb{s}"), Some(wr));
            let hip = add(&format!("Hip{s}"), Some(base));
            let knee = add(&format!("Knee{s}"), Some(hip));
            let ankle = add(&format!("Ankle{s}"), Some(knee));
            add(&format!("Foot{s}"), Some(ankle));
        }
        Skeleton::build(&raw).expect("skeleton")
    }

    #[test]
    fn kinect_joint_names_make_a_humanoid() {
        let s = kinect();
        let names: Vec<NameInfo> = s.names().iter().map(|n| normalize(n)).collect();
        let map = humanoid_from_names(&s, &names).expect("complete");
        let get = |h: &str| map.iter().find(|(x, _)| x == h).map(|(_, b)| b.as_str());
        assert_eq!(get("Hips"), Some("SpineBase"));
        assert_eq!(get("Spine"), Some("SpineMid"));
        assert_eq!(get("Chest"), Some("SpineShoulder"));
        assert_eq!(get("LeftUpperArm"), Some("ShoulderLeft"));
        assert_eq!(get("LeftLowerArm"), Some("ElbowLeft"));
        assert_eq!(get("LeftHand"), Some("WristLeft"));
        assert_eq!(get("RightUpperLeg"), Some("HipRight"));
        assert_eq!(get("RightFoot"), Some("AnkleRight"));
        assert_eq!(get("RightToes"), Some("FootRight"));
    }

    #[test]
    fn meaningless_names_say_nothing() {
        let s = kinect()
            .renamed(|b, _| format!("j{}", b.0))
            .expect("rename");
        let names: Vec<NameInfo> = s.names().iter().map(|n| normalize(n)).collect();
        assert!(humanoid_from_names(&s, &names).is_none());
    }
}
