//! Humanoid fixtures in the naming conventions of REFERENCE.md §2.
//!
//! One parametric body (metres, T-pose, facing +Z, the character's left at +X) is emitted with
//! each convention's names and structural quirks: Mixamo end joints, UE twist bones and ground
//! root, Rigify DEF segments with ORG/MCH helpers, CMU zero-length helper joints, SMPL's
//! "left_shoulder = upper arm", MediaPipe landmarks, VRoid names.

use glam::{vec3, Vec3};

use super::builder::Builder;

/// Naming convention / structure of a generated humanoid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// mixamorig:Hips …, with fingers and end joints.
    Mixamo,
    /// UE mannequin: root, pelvis, spine_01…, twist bones, clavicle_l.
    Unreal,
    /// Rigify DEF- chain with .001 segments and ORG-/MCH- helpers.
    Rigify,
    /// CMU (cgspeed names) with zero-length LHipJoint / LowerBack / Neck / LeftShoulder.
    CmuCgspeed,
    /// CMU 3dsMax-friendly names: LeftCollar / LeftShoulder(=upper arm) / LeftElbow …
    CmuMax,
    /// SMPL 24 joints.
    Smpl,
    /// Skeleton derived from MediaPipe's 33 pose landmarks.
    MediaPipe,
    /// VRM (VRoid `J_Bip_*` names) with eyes.
    Vrm,
    /// Unity-style `_L/_R` names, bones along local X.
    UnityX,
    /// rigcast's demo layout: `neck` → `head` → `head_top`, a leaf at the top of the skull
    /// whose name does not say "end", and no toe end joints (so no exporter-wide end sites).
    HeadTop,
}

fn side_name(style: Style, key: &str, left: bool) -> String {
    let (l, lw, lower) = if left {
        ("L", "Left", "left")
    } else {
        ("R", "Right", "right")
    };
    let s = l.to_lowercase();
    match style {
        Style::Mixamo => format!("mixamorig:{lw}{key}"),
        Style::Unreal => format!("{key}_{s}"),
        Style::Rigify => format!("DEF-{key}.{l}"),
        Style::CmuCgspeed | Style::CmuMax => format!("{lw}{key}"),
        Style::Smpl | Style::MediaPipe => format!("{lower}_{key}"),
        Style::Vrm => format!("J_Bip_{l}_{key}"),
        Style::UnityX => format!("{key}_{l}"),
        Style::HeadTop => format!("{key}_{s}"),
    }
}

struct Body {
    b: Builder,
}

impl Body {
    fn add(&mut self, name: &str, parent: Option<usize>, pos: Vec3, label: &str) -> usize {
        self.b.add(name, parent, pos, label)
    }

    /// The twist bones `style` gives the limb bone `bone` (named `name`, from `span.0` to
    /// `span.1`): Rigify's `NAME.001` halfway, in the chain, returned as the next bone's
    /// parent; Unreal's `unreal.0` beside it, `unreal.1` of the way along. Else none, and
    /// `bone` is the next bone's parent.
    fn twist(
        &mut self,
        style: Style,
        left: bool,
        (bone, name): (usize, &str),
        span: (Vec3, Vec3),
        unreal: (&str, f32),
    ) -> usize {
        match style {
            Style::Rigify => self.add(
                &format!("{name}.001"),
                Some(bone),
                (span.0 + span.1) * 0.5,
                &lab(left, "twist"),
            ),
            Style::Unreal => {
                self.add(
                    &side_name(style, unreal.0, left),
                    Some(bone),
                    span.0.lerp(span.1, unreal.1),
                    &lab(left, "twist"),
                );
                bone
            }
            _ => bone,
        }
    }
}

fn mirror(p: Vec3, left: bool) -> Vec3 {
    if left {
        p
    } else {
        vec3(-p.x, p.y, p.z)
    }
}

fn lab(left: bool, role: &str) -> String {
    format!("{}_{role}", if left { "left" } else { "right" })
}

/// Builds a T-pose humanoid in one style. `fingers`: add five three-joint fingers (+ tips for
/// Mixamo) where the style has them.
pub fn humanoid(style: Style, fingers: bool) -> Builder {
    let mut body = Body {
        b: Builder::default(),
    };
    let hips_pos = vec3(0.0, 0.95, 0.0);
    let ground_root = if style == Style::Unreal {
        Some(body.add("root", None, Vec3::ZERO, "helper"))
    } else {
        None
    };
    let hips_name = hips_name(style);
    let hips = body.add(hips_name, ground_root, hips_pos, "hips");
    if style == Style::Rigify {
        body.add("ORG-spine", Some(hips), hips_pos, "helper");
    }
    let spine = spine_chain(style);
    let mut parent = hips;
    for (name, y, label) in &spine {
        parent = body.add(name, Some(parent), vec3(0.0, *y, 0.0), label);
    }
    let chest = parent;
    let chest_y = body.b.world_pos[chest].y;
    let neck_chain = neck_chain(style, chest_y);
    let mut p = chest;
    let mut head = chest;
    for (name, pos, label) in &neck_chain {
        p = body.add(name, Some(p), *pos, label);
        if *label == "head" {
            head = p;
        }
    }
    face(&mut body, style, head);
    for left in [true, false] {
        arm(&mut body, style, chest, left, fingers);
        leg(&mut body, style, hips, left);
    }
    if style == Style::UnityX {
        body.b.bones_along_x();
    }
    body.b
}

/// The hips bone's name in `style`.
fn hips_name(style: Style) -> &'static str {
    match style {
        Style::Mixamo => "mixamorig:Hips",
        Style::Unreal => "pelvis",
        Style::Rigify => "DEF-spine",
        Style::CmuCgspeed | Style::CmuMax => "Hips",
        Style::Smpl => "pelvis",
        Style::MediaPipe => "hip_center",
        Style::Vrm => "J_Bip_C_Hips",
        Style::UnityX => "Hips",
        Style::HeadTop => "pelvis",
    }
}

/// The spine above the hips in `style`: (name, height, label); zero-length helpers repeat the
/// previous height.
fn spine_chain(style: Style) -> Vec<(&'static str, f32, &'static str)> {
    match style {
        Style::Mixamo => vec![
            ("mixamorig:Spine", 1.05, "spine"),
            ("mixamorig:Spine1", 1.17, "spine_mid"),
            ("mixamorig:Spine2", 1.30, "chest"),
        ],
        Style::Unreal => vec![
            ("spine_01", 1.05, "spine"),
            ("spine_02", 1.17, "spine_mid"),
            ("spine_03", 1.30, "chest"),
        ],
        Style::Rigify => vec![
            ("DEF-spine.001", 1.05, "spine"),
            ("DEF-spine.002", 1.17, "spine_mid"),
            ("DEF-spine.003", 1.30, "chest"),
        ],
        Style::CmuCgspeed => vec![
            ("LowerBack", 0.95, "spine"),
            ("Spine", 1.09, "spine_mid"),
            ("Spine1", 1.23, "chest"),
        ],
        Style::CmuMax => vec![
            ("lowerback", 0.95, "spine"),
            ("Chest", 1.09, "spine_mid"),
            ("Chest2", 1.23, "chest"),
        ],
        Style::Smpl => vec![
            ("spine1", 1.06, "spine"),
            ("spine2", 1.18, "spine_mid"),
            ("spine3", 1.30, "chest"),
        ],
        Style::MediaPipe => vec![
            ("spine_mid", 1.12, "spine"),
            ("shoulder_center", 1.40, "chest"),
        ],
        Style::Vrm => vec![
            ("J_Bip_C_Spine", 1.05, "spine"),
            ("J_Bip_C_Chest", 1.17, "spine_mid"),
            ("J_Bip_C_UpperChest", 1.30, "chest"),
        ],
        Style::UnityX => vec![("Spine", 1.07, "spine"), ("Chest", 1.28, "chest")],
        Style::HeadTop => vec![
            ("spine_lower", 1.05, "spine"),
            ("spine_upper", 1.17, "spine_mid"),
            ("chest", 1.31, "chest"),
        ],
    }
}

/// Neck and head above the chest (at height `chest_y`) in `style`: (name, position, label).
fn neck_chain(style: Style, chest_y: f32) -> Vec<(&'static str, Vec3, &'static str)> {
    match style {
        Style::Mixamo => vec![
            ("mixamorig:Neck", vec3(0.0, 1.46, 0.01), "neck"),
            ("mixamorig:Head", vec3(0.0, 1.57, 0.02), "head"),
            ("mixamorig:HeadTop_End", vec3(0.0, 1.76, 0.02), "head_end"),
        ],
        Style::Unreal => vec![
            ("neck_01", vec3(0.0, 1.46, 0.01), "neck"),
            ("head", vec3(0.0, 1.57, 0.02), "head"),
        ],
        Style::Rigify => vec![
            ("DEF-spine.004", vec3(0.0, 1.46, 0.01), "neck"),
            ("DEF-spine.005", vec3(0.0, 1.51, 0.015), "neck_2"),
            ("DEF-spine.006", vec3(0.0, 1.57, 0.02), "head"),
            ("DEF-spine.006_end", vec3(0.0, 1.76, 0.02), "head_end"),
        ],
        Style::CmuCgspeed => vec![
            ("Neck", vec3(0.0, chest_y, 0.0), "neck"),
            ("Neck1", vec3(0.0, 1.46, 0.01), "neck_2"),
            ("Head", vec3(0.0, 1.57, 0.02), "head"),
        ],
        Style::CmuMax => vec![
            ("lowerneck", vec3(0.0, chest_y, 0.0), "neck"),
            ("Neck", vec3(0.0, 1.46, 0.01), "neck_2"),
            ("Head", vec3(0.0, 1.57, 0.02), "head"),
        ],
        Style::Smpl => vec![
            ("neck", vec3(0.0, 1.46, 0.01), "neck"),
            ("head", vec3(0.0, 1.56, 0.03), "head"),
        ],
        Style::MediaPipe => vec![("head", vec3(0.0, 1.60, 0.0), "head")],
        Style::Vrm => vec![
            ("J_Bip_C_Neck", vec3(0.0, 1.46, 0.01), "neck"),
            ("J_Bip_C_Head", vec3(0.0, 1.57, 0.02), "head"),
        ],
        Style::UnityX => vec![
            ("Neck", vec3(0.0, 1.46, 0.01), "neck"),
            ("Head", vec3(0.0, 1.57, 0.02), "head"),
        ],
        Style::HeadTop => vec![
            ("neck", vec3(0.0, 1.47, 0.0), "neck"),
            ("head", vec3(0.0, 1.57, 0.0), "head"),
            ("head_top", vec3(0.0, 1.75, 0.0), "head_end"),
        ],
    }
}

/// Face landmarks some styles hang from the head (MediaPipe's nose, eyes and ears; VRM's eyes).
fn face(body: &mut Body, style: Style, head: usize) {
    match style {
        Style::MediaPipe => {
            body.add("nose", Some(head), vec3(0.0, 1.62, 0.11), "head_end");
            for left in [true, false] {
                for (key, pos, role) in [
                    ("eye", vec3(0.03, 1.64, 0.09), "eye"),
                    ("ear", vec3(0.075, 1.62, 0.0), "appendage"),
                ] {
                    body.add(
                        &side_name(style, key, left),
                        Some(head),
                        mirror(pos, left),
                        &lab(left, role),
                    );
                }
            }
        }
        Style::Vrm => {
            for left in [true, false] {
                let n = if left {
                    "J_Adj_L_FaceEye"
                } else {
                    "J_Adj_R_FaceEye"
                };
                body.add(
                    n,
                    Some(head),
                    mirror(vec3(0.03, 1.64, 0.09), left),
                    &lab(left, "eye"),
                );
            }
        }
        _ => {}
    }
}

fn arm(body: &mut Body, style: Style, chest: usize, left: bool, fingers: bool) {
    let y = 1.43;
    let cy = body.b.world_pos[chest].y;
    let m = |v: Vec3| mirror(v, left);
    let sn = |k: &str| side_name(style, k, left);
    let shoulder = m(vec3(0.18, y, -0.01));
    let elbow = m(vec3(0.46, y, -0.01));
    let wrist = m(vec3(0.72, y, -0.01));
    let (clav_name, up_name, lo_name, hand_name) = match style {
        Style::Mixamo => (sn("Shoulder"), sn("Arm"), sn("ForeArm"), sn("Hand")),
        Style::Unreal => (sn("clavicle"), sn("upperarm"), sn("lowerarm"), sn("hand")),
        Style::Rigify => (sn("shoulder"), sn("upper_arm"), sn("forearm"), sn("hand")),
        Style::CmuCgspeed => (sn("Shoulder"), sn("Arm"), sn("ForeArm"), sn("Hand")),
        Style::CmuMax => (sn("Collar"), sn("Shoulder"), sn("Elbow"), sn("Wrist")),
        Style::Smpl => (sn("collar"), sn("shoulder"), sn("elbow"), sn("wrist")),
        Style::MediaPipe => (String::new(), sn("shoulder"), sn("elbow"), sn("wrist")),
        Style::Vrm => (sn("Shoulder"), sn("UpperArm"), sn("LowerArm"), sn("Hand")),
        Style::UnityX => (sn("Shoulder"), sn("UpperArm"), sn("LowerArm"), sn("Hand")),
        Style::HeadTop => (sn("clavicle"), sn("arm_upper"), sn("arm_lower"), sn("hand")),
    };
    let mut parent = chest;
    if style != Style::MediaPipe {
        // CMU clavicles start at the spine joint itself (zero offset).
        let cpos = match style {
            Style::CmuCgspeed | Style::CmuMax => vec3(0.0, cy, 0.0),
            _ => m(vec3(0.03, 1.41, 0.0)),
        };
        parent = body.add(&clav_name, Some(parent), cpos, &lab(left, "clavicle"));
        if style == Style::Rigify {
            body.add(
                &format!("MCH-shoulder_parent.{}", if left { "L" } else { "R" }),
                Some(parent),
                cpos,
                &lab(left, "helper"),
            );
        }
    }
    let up = body.add(&up_name, Some(parent), shoulder, &lab(left, "upper_arm"));
    let lo_parent = body.twist(
        style,
        left,
        (up, &up_name),
        (shoulder, elbow),
        ("upperarm_twist_01", 0.5),
    );
    let lo = body.add(&lo_name, Some(lo_parent), elbow, &lab(left, "lower_arm"));
    let hand_parent = body.twist(
        style,
        left,
        (lo, &lo_name),
        (elbow, wrist),
        ("lowerarm_twist_01", 0.6),
    );
    let hand = body.add(&hand_name, Some(hand_parent), wrist, &lab(left, "hand"));
    hand_extras(body, style, hand, left, fingers);
}

/// What hangs from the hand in `style`: CMU's finger base and thumb helpers, SMPL's hand,
/// MediaPipe's three finger landmarks, else five fingers when `fingers`.
fn hand_extras(body: &mut Body, style: Style, hand: usize, left: bool, fingers: bool) {
    let y = 1.43;
    let wrist = mirror(vec3(0.72, y, -0.01), left);
    let m = |v: Vec3| mirror(v, left);
    let sn = |k: &str| side_name(style, k, left);
    match style {
        Style::CmuCgspeed => {
            let fb = body.add(&sn("FingerBase"), Some(hand), wrist, &lab(left, "helper"));
            body.add(
                &sn("HandIndex1"),
                Some(fb),
                m(vec3(0.80, y, -0.01)),
                &lab(left, "index_1"),
            );
            let t = if left { "LThumb" } else { "RThumb" };
            body.add(t, Some(hand), wrist, &lab(left, "helper"));
        }
        Style::CmuMax => {
            let hn = if left { "lhand" } else { "rhand" };
            let fb = body.add(hn, Some(hand), wrist, &lab(left, "helper"));
            let f = if left { "LFingers" } else { "RFingers" };
            body.add(f, Some(fb), m(vec3(0.80, y, -0.01)), &lab(left, "index_1"));
            let t = if left { "LThumb" } else { "RThumb" };
            body.add(t, Some(hand), wrist, &lab(left, "helper"));
        }
        Style::Smpl => {
            body.add(
                &sn("hand"),
                Some(hand),
                m(vec3(0.81, y, -0.01)),
                &lab(left, "index_1"),
            );
        }
        Style::MediaPipe => {
            for (key, pos, role) in [
                ("thumb", vec3(0.76, y - 0.01, 0.05), "thumb_1"),
                ("index", vec3(0.81, y, 0.02), "index_1"),
                ("pinky", vec3(0.80, y, -0.04), "little_1"),
            ] {
                body.add(&sn(key), Some(hand), m(pos), &lab(left, role));
            }
        }
        _ if fingers => add_fingers(body, style, hand, left, wrist),
        _ => {}
    }
}

fn add_fingers(body: &mut Body, style: Style, hand: usize, left: bool, wrist: Vec3) {
    let m = |v: Vec3| mirror(v, left);
    let digits = ["Thumb", "Index", "Middle", "Ring", "Pinky"];
    let label_digits = ["thumb", "index", "middle", "ring", "little"];
    let lr = if left { "L" } else { "R" };
    for (d, name) in digits.iter().enumerate() {
        let (base, dir) = if d == 0 {
            (vec3(0.025, -0.01, 0.035), vec3(0.7, -0.1, 0.7))
        } else {
            (
                vec3(0.09, 0.0, 0.03 - 0.02 * (d as f32 - 1.0)),
                vec3(1.0, 0.0, 0.0),
            )
        };
        let dir = dir.normalize_or_zero();
        let seg = [0.04, 0.028, 0.022, 0.02];
        let mut parent = hand;
        let mut pos = wrist + m(base);
        let joints = if style == Style::Mixamo { 4 } else { 3 };
        for (j, step) in seg.iter().enumerate().take(joints) {
            let label = if j < 3 {
                lab(left, &format!("{}_{}", label_digits[d], j + 1))
            } else {
                lab(left, "helper")
            };
            let n = j + 1;
            let name = match style {
                Style::Mixamo => side_name(style, &format!("Hand{name}{n}"), left),
                Style::Unreal => side_name(style, &format!("{}_0{n}", name.to_lowercase()), left),
                Style::Rigify => format!("DEF-f_{}.0{n}.{lr}", name.to_lowercase()),
                Style::Vrm => side_name(style, &format!("{name}{n}"), left),
                _ => side_name(style, &format!("{name}{n}"), left),
            };
            parent = body.add(&name, Some(parent), pos, &label);
            pos += m(dir * *step);
        }
    }
}

fn leg(body: &mut Body, style: Style, hips: usize, left: bool) {
    let m = |v: Vec3| mirror(v, left);
    let sn = |k: &str| side_name(style, k, left);
    let hip = m(vec3(0.09, 0.91, 0.0));
    let knee = m(vec3(0.09, 0.50, 0.01));
    let ankle = m(vec3(0.09, 0.08, -0.01));
    let ball = m(vec3(0.09, 0.01, 0.12));
    let tip = m(vec3(0.09, 0.01, 0.19));
    let (up, lo, foot, toe) = match style {
        Style::Mixamo => (sn("UpLeg"), sn("Leg"), sn("Foot"), sn("ToeBase")),
        Style::Unreal => (sn("thigh"), sn("calf"), sn("foot"), sn("ball")),
        Style::Rigify => (sn("thigh"), sn("shin"), sn("foot"), sn("toe")),
        Style::CmuCgspeed => (sn("UpLeg"), sn("Leg"), sn("Foot"), sn("ToeBase")),
        Style::CmuMax => (sn("Hip"), sn("Knee"), sn("Ankle"), sn("Toe")),
        Style::Smpl => (sn("hip"), sn("knee"), sn("ankle"), sn("foot")),
        Style::MediaPipe => (sn("hip"), sn("knee"), sn("ankle"), sn("foot_index")),
        Style::Vrm => (sn("UpperLeg"), sn("LowerLeg"), sn("Foot"), sn("ToeBase")),
        Style::UnityX => (sn("UpperLeg"), sn("LowerLeg"), sn("Foot"), sn("Toes")),
        Style::HeadTop => (sn("leg_upper"), sn("leg_lower"), sn("foot"), sn("toes")),
    };
    let mut parent = hips;
    if matches!(style, Style::CmuCgspeed | Style::CmuMax) {
        let n = if left { "LHipJoint" } else { "RHipJoint" };
        parent = body.add(
            n,
            Some(hips),
            body.b.world_pos[hips],
            &lab(left, "pelvis_side"),
        );
    }
    let u = body.add(&up, Some(parent), hip, &lab(left, "upper_leg"));
    let lp = body.twist(style, left, (u, &up), (hip, knee), ("thigh_twist_01", 0.5));
    let l = body.add(&lo, Some(lp), knee, &lab(left, "lower_leg"));
    let fp = body.twist(style, left, (l, &lo), (knee, ankle), ("calf_twist_01", 0.5));
    let f = body.add(&foot, Some(fp), ankle, &lab(left, "foot"));
    if style == Style::MediaPipe {
        body.add(
            &sn("heel"),
            Some(f),
            m(vec3(0.09, 0.02, -0.06)),
            &lab(left, "helper"),
        );
    }
    let t = body.add(&toe, Some(f), ball, &lab(left, "toes"));
    if matches!(style, Style::Mixamo | Style::Rigify) {
        let end = if style == Style::Mixamo {
            sn("Toe_End")
        } else {
            format!("{toe}_end")
        };
        body.add(&end, Some(t), tip, &lab(left, "toe_end"));
    }
}
