//! OSC address mapping: which OSC messages carry which bone's position/rotation.
//!
//! VMC is one such mapping ([`OscMapping::vmc`]); other OSC senders get their own, written in
//! TOML or JSON, e.g.
//!
//! ```toml
//! [[rules]]
//! address = "/tracker/{bone}/quat"   # `{bone}` captures a path segment as the bone name
//! args = ["qw", "qx", "qy", "qz"]     # argument layout, one field per OSC argument
//! space = "internal"                  # values already right-handed +Y up
//!
//! [[rules]]
//! address = "/frame"
//! frame_end = true                    # marks the end of one frame
//!
//! [bone_names]                        # sender's names → HumanBodyBones
//! pelvis = "Hips"
//! ```
//!
//! A bone is named by a `{bone}` segment, a `bone` argument, or a fixed `bone = "..."`; the
//! special name `root` addresses the root transform (VMC's `/VMC/Ext/Root/Pos`). A `*` segment
//! matches any one segment. Extra arguments beyond the layout are ignored (the VMC spec says
//! so); fewer arguments, wrong types, NaN or infinity drop the message.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::SourceError;
use crate::live::humanoid::human_bone_index;

/// A complete OSC → bone mapping.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OscMapping {
    /// Rules, tried in order; the first whose address matches handles a message.
    pub rules: Vec<OscRule>,
    /// Renames sender bone names to Unity `HumanBodyBones` names.
    #[serde(default)]
    pub bone_names: BTreeMap<String, String>,
}

/// One address rule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OscRule {
    /// Address pattern: literal segments, `*` (any one segment), `{bone}` (the bone name).
    pub address: String,
    /// Fixed target bone (a `HumanBodyBones` name, a `bone_names` key, or `root`).
    #[serde(default)]
    pub bone: Option<String>,
    /// Argument layout.
    #[serde(default)]
    pub args: Vec<ArgField>,
    /// Coordinate convention of the values.
    #[serde(default)]
    pub space: CoordSpace,
    /// A message matching this rule ends a frame (like VMC's `/VMC/Ext/T`).
    #[serde(default)]
    pub frame_end: bool,
}

/// Meaning of one OSC argument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArgField {
    /// String: the bone name.
    Bone,
    /// Float: position x / y / z, metres.
    Px,
    /// Float: position y.
    Py,
    /// Float: position z.
    Pz,
    /// Float: quaternion x.
    Qx,
    /// Float: quaternion y.
    Qy,
    /// Float: quaternion z.
    Qz,
    /// Float: quaternion w.
    Qw,
    /// Float: sender time in seconds (used to detect reordered datagrams).
    Time,
    /// String: a blend shape name.
    BlendName,
    /// Float: a blend shape value.
    BlendValue,
    /// Any one argument, ignored.
    Skip,
}

/// Coordinate convention of incoming values.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoordSpace {
    /// Unity: left-handed, +Y up (VMC).
    #[default]
    Unity,
    /// Already internal: right-handed, +Y up.
    Internal,
}

impl OscMapping {
    /// The VMC (Performer → Marionette) protocol.
    pub fn vmc() -> OscMapping {
        use ArgField::*;
        let pose = vec![Bone, Px, Py, Pz, Qx, Qy, Qz, Qw];
        let rule = |address: &str, bone: Option<&str>, args: Vec<ArgField>, frame_end| OscRule {
            address: address.into(),
            bone: bone.map(Into::into),
            args,
            space: CoordSpace::Unity,
            frame_end,
        };
        let mut root = pose.clone();
        root[0] = Skip;
        OscMapping {
            rules: vec![
                rule("/VMC/Ext/Root/Pos", Some("root"), root, false),
                rule("/VMC/Ext/Bone/Pos", None, pose, false),
                rule("/VMC/Ext/T", None, vec![Time], true),
                rule(
                    "/VMC/Ext/Blend/Val",
                    None,
                    vec![BlendName, BlendValue],
                    false,
                ),
            ],
            bone_names: BTreeMap::new(),
        }
    }

    /// Parses a mapping from TOML text.
    pub fn from_toml(text: &str) -> Result<OscMapping, SourceError> {
        toml::from_str(text).map_err(|e| SourceError::InvalidOption {
            reason: format!("OSC mapping: {e}"),
        })
    }

    /// Checks the rules and prepares them for matching.
    pub(crate) fn compile(&self) -> Result<Vec<CompiledRule>, SourceError> {
        self.rules
            .iter()
            .enumerate()
            .map(|(i, r)| compile_rule(i, r, self))
            .collect()
    }

    /// Resolves a sender bone name to a bone target.
    pub(crate) fn resolve(&self, name: &str) -> Option<BoneTarget> {
        let name = self
            .bone_names
            .get(name)
            .map(String::as_str)
            .unwrap_or(name);
        if name == "root" {
            return Some(BoneTarget::Root);
        }
        human_bone_index(name).map(BoneTarget::Human)
    }
}

/// Where a message's transform goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BoneTarget {
    /// The root transform.
    Root,
    /// A `HumanBodyBones` index.
    Human(usize),
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Segment {
    Literal(String),
    Any,
    Bone,
}

/// A validated rule with argument positions resolved.
#[derive(Debug, Clone)]
pub(crate) struct CompiledRule {
    pub segments: Vec<Segment>,
    pub fixed_bone: Option<BoneTarget>,
    pub bone_arg: Option<usize>,
    pub position: Option<[usize; 3]>,
    pub rotation: Option<[usize; 4]>,
    pub time_arg: Option<usize>,
    pub blend: Option<(usize, usize)>,
    pub min_args: usize,
    pub space: CoordSpace,
    pub frame_end: bool,
}

fn compile_rule(
    index: usize,
    rule: &OscRule,
    mapping: &OscMapping,
) -> Result<CompiledRule, SourceError> {
    let bad = |what: String| SourceError::InvalidOption {
        reason: format!("OSC mapping rule {index} ({:?}): {what}", rule.address),
    };
    let Some(path) = rule.address.strip_prefix('/') else {
        return Err(bad("address must start with '/'".into()));
    };
    let segments = address_segments(path);
    let find = |f: ArgField| rule.args.iter().position(|a| *a == f);
    let bone_arg = find(ArgField::Bone);
    let fixed_bone = match &rule.bone {
        Some(name) => Some(
            mapping
                .resolve(name)
                .ok_or_else(|| bad(format!("unknown bone {name:?}")))?,
        ),
        None => None,
    };
    let has_bone_segment = segments.contains(&Segment::Bone);
    let sources = [fixed_bone.is_some(), bone_arg.is_some(), has_bone_segment]
        .iter()
        .filter(|b| **b)
        .count();
    let (position, rotation) = transform_args(&rule.args).map_err(|e| bad(e.into()))?;
    let carries_transform = position.is_some() || rotation.is_some();
    if carries_transform && sources != 1 {
        return Err(bad(
            "a transform rule needs exactly one bone source: `bone`, a bone argument or a {bone} segment"
                .into(),
        ));
    }
    let blend = match (find(ArgField::BlendName), find(ArgField::BlendValue)) {
        (Some(n), Some(v)) => Some((n, v)),
        (None, None) => None,
        _ => return Err(bad("blend needs both blend_name and blend_value".into())),
    };
    Ok(CompiledRule {
        segments,
        fixed_bone,
        bone_arg,
        position,
        rotation,
        time_arg: find(ArgField::Time),
        blend,
        min_args: rule.args.len(),
        space: rule.space,
        frame_end: rule.frame_end,
    })
}

/// An address's path (after its leading `/`) as segments: `*` any, `{bone}` the bone's name,
/// anything else literal.
fn address_segments(path: &str) -> Vec<Segment> {
    path.split('/')
        .map(|s| match s {
            "*" => Segment::Any,
            "{bone}" => Segment::Bone,
            lit => Segment::Literal(lit.to_string()),
        })
        .collect()
}

/// Argument positions of a position (px, py, pz) and a rotation (qx, qy, qz, qw).
type TransformArgs = (Option<[usize; 3]>, Option<[usize; 4]>);

/// The arguments holding a position and a rotation, each all or none; otherwise what is
/// missing.
fn transform_args(args: &[ArgField]) -> Result<TransformArgs, &'static str> {
    let find = |f: ArgField| args.iter().position(|a| *a == f);
    let p = [find(ArgField::Px), find(ArgField::Py), find(ArgField::Pz)];
    let q = [
        find(ArgField::Qx),
        find(ArgField::Qy),
        find(ArgField::Qz),
        find(ArgField::Qw),
    ];
    let position = match p {
        [Some(x), Some(y), Some(z)] => Some([x, y, z]),
        [None, None, None] => None,
        _ => return Err("position needs all of px, py, pz"),
    };
    let rotation = match q {
        [Some(x), Some(y), Some(z), Some(w)] => Some([x, y, z, w]),
        [None, None, None, None] => None,
        _ => return Err("rotation needs all of qx, qy, qz, qw"),
    };
    Ok((position, rotation))
}

impl CompiledRule {
    /// Matches an address; on success returns the `{bone}` segment (or "" when none).
    pub fn matches<'a>(&self, address: &'a str) -> Option<&'a str> {
        let path = address.strip_prefix('/')?;
        let mut captured = "";
        let mut parts = path.split('/');
        for seg in &self.segments {
            let part = parts.next()?;
            match seg {
                Segment::Literal(l) if l != part => return None,
                Segment::Bone => captured = part,
                _ => {}
            }
        }
        if parts.next().is_some() {
            return None;
        }
        Some(captured)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vmc_compiles_and_matches() {
        let rules = OscMapping::vmc().compile().unwrap();
        assert_eq!(rules[1].matches("/VMC/Ext/Bone/Pos"), Some(""));
        assert_eq!(rules[1].matches("/VMC/Ext/Bone/Pos/x"), None);
        assert_eq!(rules[1].matches("/VMC/Ext/Bone"), None);
        assert_eq!(rules[0].fixed_bone, Some(BoneTarget::Root));
    }

    #[test]
    fn toml_mapping_with_captures_and_renames() {
        let m = OscMapping::from_toml(
            r#"
[bone_names]
pelvis = "Hips"

[[rules]]
space = "internal"
address = "/tracker/{bone}/quat"
args = ["qw", "qx", "qy", "qz"]
"#,
        )
        .unwrap();
        let rules = m.compile().unwrap();
        assert_eq!(rules[0].matches("/tracker/pelvis/quat"), Some("pelvis"));
        assert_eq!(rules[0].rotation, Some([1, 2, 3, 0]));
        assert_eq!(m.resolve("pelvis"), Some(BoneTarget::Human(0)));
        assert_eq!(
            m.resolve("LeftHand"),
            human_bone_index("LeftHand").map(BoneTarget::Human)
        );
        assert_eq!(m.resolve("tail"), None);
    }

    #[test]
    fn rejects_inconsistent_rules() {
        let bad = [
            ("address = \"no/slash\"", "must start with '/'"),
            (
                "address = \"/a\"\nargs = [\"qx\", \"qy\"]\nbone = \"Hips\"",
                "rotation needs all of qx, qy, qz, qw",
            ),
            (
                "address = \"/a\"\nargs = [\"px\", \"pz\"]\nbone = \"Hips\"",
                "position needs all of px, py, pz",
            ),
            (
                "address = \"/a\"\nargs = [\"qx\", \"qy\", \"qz\", \"qw\"]",
                "exactly one bone source",
            ),
            (
                "address = \"/a/{bone}\"\nargs = [\"qx\", \"qy\", \"qz\", \"qw\"]\nbone = \"Hips\"",
                "exactly one bone source",
            ),
            ("address = \"/a\"\nbone = \"Tail\"", "unknown bone \"Tail\""),
            (
                "address = \"/a\"\nargs = [\"blend_name\"]",
                "blend needs both blend_name and blend_value",
            ),
        ];
        for (rule, reason) in bad {
            let text = format!("[[rules]]\n{rule}\n");
            let m = OscMapping::from_toml(&text).unwrap();
            let e = m
                .compile()
                .err()
                .unwrap_or_else(|| panic!("accepted: {text}"));
            assert!(e.to_string().contains(reason), "{text}: {e}");
        }
    }
}
