//! glTF / GLB / VRM reader: skeleton from the first skin (or VRM humanoid bones), rest from node
//! transforms, animations sampled at a fixed rate.
//!
//! Which nodes become bones: the skin's joints plus the non-joint nodes *between* joints (so the
//! tree stays connected). Nodes above the topmost joints are not bones; their transform (e.g. an
//! armature's axis conversion or 0.01 scale) is folded into the top bones so world positions
//! stay right. Uniform scale is baked into translations (non-uniform scale is averaged;
//! animated scale is ignored), because rigcast transforms carry no scale.

use std::collections::{BTreeMap, HashSet};
use std::path::Path;
use std::sync::Arc;

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::{Interpolation as GltfInterpolation, Property};
use ::gltf::{Accessor, Document};
use glam::{Quat, Vec3, Vec4};
use rigcast_retarget::{Clip, Pose, RawSkeleton, Skeleton, Transform};

use super::sample::{Interpolation, Track};
use super::tolerate::{skip_undecodable_mesh_data, summarise_validation};
use super::vrm::{vrm_human_bones, HumanBones, VrmVersion};
use crate::error::SourceError;

/// Default sampling rate when the keyframes are not evenly spaced.
pub const DEFAULT_SAMPLE_FPS: f64 = 30.0;

/// Options for reading glTF.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfReadOptions {
    /// Animation to load, by exact name or decimal index (`None` = the first, if any).
    pub animation: Option<String>,
    /// Sampling rate (`None` = the keyframe rate when evenly spaced, else 30 fps).
    pub sample_fps: Option<f64>,
}

/// Name and length of one animation in a file.
#[derive(Debug, Clone, PartialEq)]
pub struct AnimationInfo {
    /// Animation name (`animation_<index>` when unnamed).
    pub name: String,
    /// Time of its last key, seconds.
    pub duration_secs: f64,
}

/// Where the skeleton came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SkeletonOrigin {
    /// The first skin's joints.
    Skin,
    /// VRM humanoid bone nodes (file without a skin).
    VrmHumanoid(VrmVersion),
}

/// A decoded glTF file.
#[derive(Debug, Clone)]
pub struct GltfRead {
    /// Skeleton and the selected animation's frames (no frames when the file has none).
    pub clip: Clip,
    /// Every animation in the file.
    pub animations: Vec<AnimationInfo>,
    /// Index of the sampled animation.
    pub selected_animation: Option<usize>,
    /// Number of skin joints (or VRM bones) among the bones.
    pub num_joints: usize,
    /// Where the skeleton came from.
    pub origin: SkeletonOrigin,
    /// VRM humanoid role (e.g. `"leftUpperArm"`) → bone name, when the file is a VRM.
    pub vrm_roles: Option<BTreeMap<String, String>>,
    /// What was skipped to read the file (mesh data in extensions the reader cannot decode).
    pub warnings: Vec<String>,
    /// The file's document, for writing motion back onto this rig.
    pub template: GltfTemplate,
}

fn gltf_err(e: ::gltf::Error) -> SourceError {
    let message = match e {
        ::gltf::Error::Validation(errors) => summarise_validation(
            &errors
                .iter()
                .map(|(path, error)| (path.to_string(), error.to_string()))
                .collect::<Vec<_>>(),
        ),
        other => other.to_string(),
    };
    SourceError::Gltf { message }
}

/// The document and GLB binary chunk, with mesh-only extensions the reader cannot decode
/// skipped (see [`super::tolerate`]); the warning says what was skipped.
type Parsed = (Document, Option<Vec<u8>>, Option<String>, serde_json::Value);

/// A GLB file's header: magic, version, total length.
const GLB_HEADER_BYTES: u32 = 12;

fn parse_tolerantly(bytes: &[u8]) -> Result<Parsed, SourceError> {
    let (json_bytes, blob) = if bytes.starts_with(b"glTF") {
        // The header's total length (bytes 8..12) must cover the 12-byte header itself: gltf
        // 1.4 subtracts the header from it unchecked (found by fuzzing: a debug build panics,
        // a release build wraps). Shorter input is refused by gltf's own header read.
        if let Some(len) = bytes.get(8..12) {
            let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]);
            if len < GLB_HEADER_BYTES {
                return Err(SourceError::Gltf {
                    message: format!(
                        "GLB header declares {len} bytes in all, fewer than the header's {GLB_HEADER_BYTES}"
                    ),
                });
            }
        }
        let glb = ::gltf::binary::Glb::from_slice(bytes).map_err(gltf_err)?;
        (glb.json.into_owned(), glb.bin.map(|b| b.into_owned()))
    } else {
        (bytes.to_vec(), None)
    };
    let mut value: serde_json::Value =
        serde_json::from_slice(&json_bytes).map_err(|e| SourceError::Gltf {
            message: format!("invalid glTF JSON: {e}"),
        })?;
    let original = value.clone();
    let warning = skip_undecodable_mesh_data(&mut value);
    let root: ::gltf::json::Root =
        serde_json::from_value(value).map_err(|e| SourceError::Gltf {
            message: format!("invalid glTF JSON: {e}"),
        })?;
    check_position_accessors(&root)?;
    let document = Document::from_json(root).map_err(gltf_err)?;
    Ok((document, blob, warning, original))
}

/// gltf-json 1.4's validation reads a primitive's `POSITION` accessor before it checks that
/// the index exists (found by fuzzing: an index past the accessors panics, in release builds
/// too), so that one index is checked here first; every other index its validation checks.
fn check_position_accessors(root: &::gltf::json::Root) -> Result<(), SourceError> {
    use ::gltf::json::mesh::Semantic;
    use ::gltf::json::validation::Checked;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&Checked::Valid(Semantic::Positions));
            if let Some(index) = position.filter(|i| i.value() >= root.accessors.len()) {
                return Err(SourceError::Gltf {
                    message: format!(
                        "meshes[{m}].primitives[{p}]: POSITION names accessor {} of {}",
                        index.value(),
                        root.accessors.len()
                    ),
                });
            }
        }
    }
    Ok(())
}

/// A node's local transform as (translation, rotation, uniform scale).
fn node_trs(node: &::gltf::Node<'_>) -> (Vec3, Quat, f32) {
    let (t, r, s) = node.transform().decomposed();
    let scale = (s[0].abs() + s[1].abs() + s[2].abs()) / 3.0;
    let rot = Quat::from_array(r);
    let rot = if rot.is_finite() && rot.length_squared() > 0.0 {
        rot.normalize()
    } else {
        Quat::IDENTITY
    };
    (Vec3::from_array(t), rot, scale)
}

/// Per bone: how a node-local (t, r) becomes the bone's local transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BoneFrame {
    pub(crate) node: usize,
    /// Product of the uniform scales of all strict ancestors.
    translation_scale: f32,
    /// For top bones: the world transform of the parent chain above them.
    above: Option<(Vec3, Quat)>,
}

impl BoneFrame {
    fn apply(&self, t: Vec3, r: Quat) -> (Vec3, Quat) {
        let t = t * self.translation_scale;
        match self.above {
            Some((at, ar)) => (at + ar * t, ar * r),
            None => (t, r),
        }
    }

    /// The inverse of [`BoneFrame::apply`]: a bone-local (t, r) as the node's own TRS.
    pub(crate) fn unapply(&self, t: Vec3, r: Quat) -> (Vec3, Quat) {
        let (t, r) = match self.above {
            Some((at, ar)) => {
                let inv = ar.inverse();
                (inv * (t - at), (inv * r).normalize())
            }
            None => (t, r),
        };
        let s = if self.translation_scale.abs() > f32::EPSILON {
            self.translation_scale
        } else {
            1.0
        };
        (t / s, r)
    }
}

/// A glTF file's own document, kept so motion written onto its skeleton keeps everything else
/// (nodes, names, skins, inverse bind matrices, meshes): see [`super::write_glb_onto`].
#[derive(Debug, Clone, Default)]
pub struct GltfTemplate {
    /// The JSON as read (before any tolerance step).
    pub(crate) json: serde_json::Value,
    /// Every buffer's bytes, in buffer order.
    pub(crate) buffers: Vec<Vec<u8>>,
    /// Node and frame of each skeleton bone, in bone order.
    pub(crate) frames: Vec<BoneFrame>,
}

/// Parses a glTF (JSON) or GLB file. `base_dir` resolves external buffer files.
pub fn read_gltf(
    bytes: &[u8],
    base_dir: Option<&Path>,
    name: &str,
    opts: &GltfReadOptions,
) -> Result<GltfRead, SourceError> {
    let (document, blob, warning, json) = parse_tolerantly(bytes)?;
    super::buffers::check_buffer_sources(&document, base_dir)?;
    let data = ::gltf::import_buffers(&document, base_dir, blob).map_err(gltf_err)?;
    let buffers: Vec<&[u8]> = data.iter().map(|b| &b.0[..]).collect();
    let mut read = read_document(&document, &buffers, name, opts)?;
    read.warnings.extend(warning);
    read.template.json = json;
    read.template.buffers = data.into_iter().map(|b| b.0).collect();
    Ok(read)
}

/// The `gltf` crate's validation skips animation channel targets, and its accessors
/// (`Target::node`, `Target::property`) panic on a bad node index or an unknown path; check
/// them here so such a file is an error.
fn check_channel_targets(doc: &Document) -> Result<(), SourceError> {
    let json = doc.as_json();
    for (a, anim) in json.animations.iter().enumerate() {
        for (c, channel) in anim.channels.iter().enumerate() {
            let target = &channel.target;
            let problem = if target.node.value() >= json.nodes.len() {
                format!(
                    "node {} does not exist ({} nodes)",
                    target.node.value(),
                    json.nodes.len()
                )
            } else if matches!(target.path, ::gltf::json::validation::Checked::Invalid) {
                "path is not translation, rotation, scale or weights".to_string()
            } else {
                continue;
            };
            return Err(SourceError::Gltf {
                message: format!("animations[{a}].channels[{c}].target: {problem}"),
            });
        }
    }
    Ok(())
}

fn read_document(
    doc: &Document,
    buffers: &[&[u8]],
    name: &str,
    opts: &GltfReadOptions,
) -> Result<GltfRead, SourceError> {
    check_channel_targets(doc)?;
    let num_nodes = doc.nodes().len();
    let parent = node_parents(doc)?;
    let vrm = vrm_human_bones(doc, num_nodes)?;
    let (joints, origin) = skeleton_joints(doc, vrm.as_ref())?;
    let included = needed_nodes(&joints, &parent);
    let nodes: Vec<::gltf::Node<'_>> = doc.nodes().collect();
    let trs: Vec<(Vec3, Quat, f32)> = nodes.iter().map(node_trs).collect();

    // Bone order: node index order; Skeleton::build makes it depth-first.
    let bone_nodes: Vec<usize> = (0..num_nodes).filter(|i| included.contains(i)).collect();
    let mut frames = Vec::with_capacity(bone_nodes.len());
    for &n in &bone_nodes {
        frames.push(bone_frame(n, &parent, &included, &trs));
    }
    let names = unique_names(&bone_nodes, &nodes);
    let bone_of_node: BTreeMap<usize, usize> = bone_nodes
        .iter()
        .enumerate()
        .map(|(b, &n)| (n, b))
        .collect();
    let raw = raw_skeleton(&frames, names, (&parent, &bone_of_node), &trs);
    let skeleton = Arc::new(Skeleton::build(&raw)?);
    let bone_frames = frames_in_skeleton_order(&skeleton, &raw, &frames)?;

    let (animations, selected, poses, frame_time) =
        read_animation(doc, buffers, opts, &skeleton, &bone_frames, &trs)?;
    let clip_name = match selected {
        Some(i) => animations[i].name.clone(),
        None => name.to_string(),
    };
    let vrm_roles = vrm.map(|(_, bones)| {
        bones
            .iter()
            .filter_map(|(role, node)| {
                let b = bone_of_node.get(node)?;
                Some((role.clone(), raw.bones[*b].name.clone()))
            })
            .collect()
    });
    Ok(GltfRead {
        clip: Clip::new(clip_name, skeleton, poses, frame_time)?,
        animations,
        selected_animation: selected,
        num_joints: joints.len(),
        origin,
        vrm_roles,
        warnings: Vec::new(),
        template: GltfTemplate {
            frames: bone_frames,
            ..GltfTemplate::default()
        },
    })
}

/// The raw skeleton of the bones' `frames` (in node order, named `names`): each bone's rest
/// from its node's transform through its frame, its parent the nearest included node above.
fn raw_skeleton(
    frames: &[BoneFrame],
    mut names: Vec<String>,
    (parent, bone_of_node): (&[Option<usize>], &BTreeMap<usize, usize>),
    trs: &[(Vec3, Quat, f32)],
) -> RawSkeleton {
    let mut raw = RawSkeleton::default();
    for (b, f) in frames.iter().enumerate() {
        let (t, r, _) = trs[f.node];
        let (t, r) = f.apply(t, r);
        let p = parent[f.node].and_then(|p| bone_of_node.get(&p).copied());
        raw.add(
            std::mem::take(&mut names[b]),
            p,
            Transform {
                translation: t,
                rotation: r,
            },
        );
    }
    raw
}

/// The bones' frames (node order, as in `raw`) in the built skeleton's order, for sampling.
fn frames_in_skeleton_order(
    skeleton: &Skeleton,
    raw: &RawSkeleton,
    frames: &[BoneFrame],
) -> Result<Vec<BoneFrame>, SourceError> {
    skeleton
        .names()
        .iter()
        .map(|n| {
            raw.bones
                .iter()
                .position(|b| &b.name == n)
                .map(|i| frames[i])
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| SourceError::Gltf {
            message: "bone lost while ordering the skeleton".into(),
        })
}

/// The nodes the skeleton is made of: the first skin's joints, else (a VRM without a skin)
/// its humanoid bones' nodes.
fn skeleton_joints(
    doc: &Document,
    vrm: Option<&HumanBones>,
) -> Result<(Vec<usize>, SkeletonOrigin), SourceError> {
    let (joints, origin) = match doc.skins().next() {
        Some(skin) => (
            skin.joints().map(|j| j.index()).collect(),
            SkeletonOrigin::Skin,
        ),
        None => match vrm {
            Some((version, bones)) if !bones.is_empty() => {
                let mut nodes: Vec<usize> = bones.values().copied().collect();
                nodes.sort_unstable();
                nodes.dedup();
                (nodes, SkeletonOrigin::VrmHumanoid(*version))
            }
            _ => return Err(SourceError::NoSkeleton),
        },
    };
    if joints.is_empty() {
        return Err(SourceError::NoSkeleton);
    }
    Ok((joints, origin))
}

/// How bone node `n` sits in the skeleton: the scale of every ancestor, and for a top bone
/// (no ancestor in the skeleton) the world transform of the nodes above it.
fn bone_frame(
    n: usize,
    parent: &[Option<usize>],
    included: &HashSet<usize>,
    trs: &[(Vec3, Quat, f32)],
) -> BoneFrame {
    let mut scale = 1.0;
    let mut p = parent[n];
    let mut above_chain = Vec::new();
    let mut in_skeleton_parent = false;
    while let Some(pi) = p {
        scale *= trs[pi].2;
        if included.contains(&pi) {
            in_skeleton_parent = true;
        } else if !in_skeleton_parent {
            above_chain.push(pi);
        }
        p = parent[pi];
    }
    let above = if in_skeleton_parent || above_chain.is_empty() {
        None
    } else {
        // World transform of the chain above, composed root-first.
        let mut t = Vec3::ZERO;
        let mut r = Quat::IDENTITY;
        let mut s = 1.0;
        for &a in above_chain.iter().rev() {
            let (at, ar, as_) = trs[a];
            t += r * (at * s);
            r = (r * ar).normalize();
            s *= as_;
        }
        Some((t, r))
    };
    BoneFrame {
        node: n,
        translation_scale: scale,
        above,
    }
}

/// The file's animations, the one chosen by `opts` and its poses sampled onto `skeleton`
/// (none, at the default rate, when the file has no animation).
type ReadAnimation = (Vec<AnimationInfo>, Option<usize>, Vec<Pose>, f64);

/// See [`ReadAnimation`].
fn read_animation(
    doc: &Document,
    buffers: &[&[u8]],
    opts: &GltfReadOptions,
    skeleton: &Skeleton,
    bone_frames: &[BoneFrame],
    trs: &[(Vec3, Quat, f32)],
) -> Result<ReadAnimation, SourceError> {
    let animations: Vec<AnimationInfo> = doc
        .animations()
        .map(|a| AnimationInfo {
            name: animation_name(&a),
            duration_secs: a
                .channels()
                .map(|c| channel_end_secs(&c, buffers))
                .fold(0.0f64, |m, t| m.max(t as f64)),
        })
        .collect();
    let selected = select_animation(doc, &animations, opts)?;
    let (poses, frame_time) = match selected {
        Some(index) => {
            let anim =
                doc.animations()
                    .nth(index)
                    .ok_or_else(|| SourceError::AnimationNotFound {
                        requested: index.to_string(),
                        available: animations.iter().map(|a| a.name.clone()).collect(),
                    })?;
            sample_animation(&anim, buffers, skeleton, bone_frames, trs, opts)?
        }
        None => (Vec::new(), 1.0 / DEFAULT_SAMPLE_FPS),
    };
    Ok((animations, selected, poses, frame_time))
}

/// Time of a channel's last key: read from the data when the accessor is sound, else from the
/// accessor's declared `max` (required by the spec, but not trusted blindly).
fn channel_end_secs(c: &::gltf::animation::Channel<'_>, buffers: &[&[u8]]) -> f32 {
    let input = c.sampler().input();
    if check_accessor(&input, buffers, Dimensions::Scalar, &[DataType::F32]).is_ok() {
        if let Some(times) = c.reader(|b| buffers.get(b.index()).copied()).read_inputs() {
            return times.filter(|t| t.is_finite()).fold(0.0, f32::max);
        }
    }
    input.max().and_then(|m| first_f32(&m)).unwrap_or(0.0)
}

fn first_f32(v: &::gltf::json::Value) -> Option<f32> {
    v.as_array()?.first()?.as_f64().map(|x| x as f32)
}

fn animation_name(a: &::gltf::Animation<'_>) -> String {
    a.name()
        .map(str::to_string)
        .unwrap_or_else(|| format!("animation_{}", a.index()))
}

/// Each node's parent, after checking that the nodes form a forest no deeper than
/// [`crate::bvh::MAX_JOINT_DEPTH`]: every node the child of at most one node, none its own
/// ancestor (a node listed as its own child, or two nodes each other's, would make every walk
/// up the tree loop forever). One pass, no recursion.
pub(crate) fn node_parents(doc: &Document) -> Result<Vec<Option<usize>>, SourceError> {
    let num_nodes = doc.nodes().len();
    let mut parent: Vec<Option<usize>> = vec![None; num_nodes];
    for n in doc.nodes() {
        for c in n.children() {
            if let Some(first) = parent[c.index()].replace(n.index()) {
                return Err(SourceError::Gltf {
                    message: format!(
                        "node {} is a child of both node {first} and node {}",
                        c.index(),
                        n.index()
                    ),
                });
            }
        }
    }
    // Depth of each node once known; walks stop at a known node, so the whole check is linear.
    let mut depth: Vec<Option<usize>> = vec![None; num_nodes];
    let mut path = Vec::new();
    for start in 0..num_nodes {
        path.clear();
        let mut at = Some(start);
        let mut base = 0;
        while let Some(n) = at {
            if let Some(d) = depth[n] {
                base = d + 1;
                break;
            }
            if path.contains(&n) {
                return Err(SourceError::Gltf {
                    message: format!("node {n} is its own ancestor (a cycle in `children`)"),
                });
            }
            if path.len() >= MAX_NODE_DEPTH {
                break; // reported just below
            }
            path.push(n);
            at = parent[n];
        }
        if base + path.len() > MAX_NODE_DEPTH {
            return Err(SourceError::limit(
                format!("node {start}: nesting depth"),
                format!("over {}", base + path.len() - 1),
                MAX_NODE_DEPTH,
            ));
        }
        for (k, &n) in path.iter().rev().enumerate() {
            depth[n] = Some(base + k);
        }
    }
    Ok(parent)
}

/// Deepest node nesting read (see [`node_parents`]).
const MAX_NODE_DEPTH: usize = crate::bvh::MAX_JOINT_DEPTH;

/// Joints plus every node on a path from a joint up to another joint.
fn needed_nodes(joints: &[usize], parent: &[Option<usize>]) -> HashSet<usize> {
    let joint_set: HashSet<usize> = joints.iter().copied().collect();
    let mut included = joint_set.clone();
    for &j in joints {
        let mut path = Vec::new();
        let mut p = parent.get(j).copied().flatten();
        while let Some(pi) = p {
            if joint_set.contains(&pi) {
                included.extend(path.iter().copied());
                break;
            }
            path.push(pi);
            // A malformed file could contain a cycle; the validated glTF cannot, but bound it.
            if path.len() > parent.len() {
                break;
            }
            p = parent[pi];
        }
    }
    included
}

fn unique_names(bone_nodes: &[usize], nodes: &[::gltf::Node<'_>]) -> Vec<String> {
    let mut used = HashSet::new();
    bone_nodes
        .iter()
        .map(|&n| {
            let base = match nodes[n].name() {
                Some(s) if !s.is_empty() => s.to_string(),
                _ => format!("joint_{n}"),
            };
            let name = if used.contains(&base) {
                format!("{base}_{n}")
            } else {
                base
            };
            used.insert(name.clone());
            name
        })
        .collect()
}

fn select_animation(
    doc: &Document,
    animations: &[AnimationInfo],
    opts: &GltfReadOptions,
) -> Result<Option<usize>, SourceError> {
    let Some(req) = &opts.animation else {
        return Ok((doc.animations().len() > 0).then_some(0));
    };
    if let Some(i) = animations.iter().position(|a| &a.name == req) {
        return Ok(Some(i));
    }
    match req.parse::<usize>() {
        Ok(i) if i < animations.len() => Ok(Some(i)),
        _ => Err(SourceError::AnimationNotFound {
            requested: req.clone(),
            available: animations.iter().map(|a| a.name.clone()).collect(),
        }),
    }
}

/// Checks that an accessor's bytes lie inside its buffer and have the expected shape, so the
/// `gltf` crate's reader cannot hit a debug assertion or read out of range.
fn check_accessor(
    a: &Accessor<'_>,
    buffers: &[&[u8]],
    dims: Dimensions,
    types: &[DataType],
) -> Result<(), SourceError> {
    let bad = |reason: String| SourceError::BadAccessor {
        accessor: a.index(),
        reason,
    };
    if a.dimensions() != dims {
        return Err(bad(format!(
            "expected {dims:?}, found {:?}",
            a.dimensions()
        )));
    }
    if !types.contains(&a.data_type()) {
        return Err(bad(format!(
            "expected component type {types:?}, found {:?}",
            a.data_type()
        )));
    }
    if a.count() == 0 {
        return Err(bad("has no elements".into()));
    }
    if a.sparse().is_some() {
        return Err(bad(
            "sparse accessors are not supported for animation".into()
        ));
    }
    let view = a.view().ok_or_else(|| bad("has no buffer view".into()))?;
    let buffer_len = buffers
        .get(view.buffer().index())
        .map(|b| b.len())
        .ok_or_else(|| bad("buffer missing".into()))?;
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|e| e > buffer_len) {
        return Err(bad(format!(
            "buffer view {} (offset {}, length {}) exceeds buffer of {buffer_len} bytes",
            view.index(),
            view.offset(),
            view.length()
        )));
    }
    let elem = a.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(bad(format!(
            "stride {stride} is smaller than the element size {elem}"
        )));
    }
    let end = (a.count() - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(a.offset()))
        .and_then(|x| x.checked_add(elem));
    if end.is_none_or(|e| e > view.length()) {
        return Err(bad(format!(
            "{} elements at offset {} overrun buffer view {} of {} bytes",
            a.count(),
            a.offset(),
            view.index(),
            view.length()
        )));
    }
    Ok(())
}

fn read_track(
    channel: &::gltf::animation::Channel<'_>,
    buffers: &[&[u8]],
) -> Result<Option<(Property, Track)>, SourceError> {
    let sampler = channel.sampler();
    let property = channel.target().property();
    let (dims, types): (Dimensions, &[DataType]) = match property {
        Property::Translation | Property::Scale => (Dimensions::Vec3, &[DataType::F32]),
        Property::Rotation => (
            Dimensions::Vec4,
            &[
                DataType::F32,
                DataType::I8,
                DataType::U8,
                DataType::I16,
                DataType::U16,
            ],
        ),
        Property::MorphTargetWeights => return Ok(None),
    };
    check_accessor(
        &sampler.input(),
        buffers,
        Dimensions::Scalar,
        &[DataType::F32],
    )?;
    check_accessor(&sampler.output(), buffers, dims, types)?;
    let reader = channel.reader(|b| buffers.get(b.index()).copied());
    let times: Vec<f32> = reader
        .read_inputs()
        .ok_or_else(|| SourceError::BadAccessor {
            accessor: sampler.input().index(),
            reason: "cannot read key times".into(),
        })?
        .collect();
    let out_err = || SourceError::BadAccessor {
        accessor: sampler.output().index(),
        reason: "cannot read output values".into(),
    };
    let values: Vec<Vec4> = match reader.read_outputs().ok_or_else(out_err)? {
        ::gltf::animation::util::ReadOutputs::Translations(it)
        | ::gltf::animation::util::ReadOutputs::Scales(it) => {
            it.map(|v| Vec3::from_array(v).extend(0.0)).collect()
        }
        ::gltf::animation::util::ReadOutputs::Rotations(r) => {
            r.into_f32().map(Vec4::from_array).collect()
        }
        ::gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => return Ok(None),
    };
    let interpolation = match sampler.interpolation() {
        GltfInterpolation::Linear => Interpolation::Linear,
        GltfInterpolation::Step => Interpolation::Step,
        GltfInterpolation::CubicSpline => Interpolation::CubicSpline,
    };
    let track = Track {
        times,
        values,
        interpolation,
    };
    if track.values.iter().any(|v| !v.is_finite()) {
        return Err(SourceError::BadAccessor {
            accessor: sampler.output().index(),
            reason: "contains NaN or infinite values".into(),
        });
    }
    track.validate().map_err(|e| SourceError::BadAccessor {
        accessor: sampler.output().index(),
        reason: e.to_string(),
    })?;
    Ok(Some((property, track)))
}

/// The keyframe rate when keys are evenly spaced (to 1 %), rounded to an integer rate.
fn keyframe_fps(times: &[f32]) -> Option<f64> {
    if times.len() < 3 {
        return None;
    }
    let dt = (times[1] - times[0]) as f64;
    if dt <= 0.0 {
        return None;
    }
    let even = times
        .windows(2)
        .all(|w| ((w[1] - w[0]) as f64 - dt).abs() <= 0.01 * dt);
    let fps = 1.0 / dt;
    (even && (5.0..=240.0).contains(&fps)).then(|| {
        let r = fps.round();
        if (fps - r).abs() < 0.05 {
            r
        } else {
            fps
        }
    })
}

fn sample_animation(
    anim: &::gltf::Animation<'_>,
    buffers: &[&[u8]],
    skeleton: &Skeleton,
    frames: &[BoneFrame],
    trs: &[(Vec3, Quat, f32)],
    opts: &GltfReadOptions,
) -> Result<(Vec<Pose>, f64), SourceError> {
    let tracks = BoneTracks::read(anim, buffers, frames)?;
    let keyed_fps = tracks.first_times.as_deref().and_then(keyframe_fps);
    let fps = match opts.sample_fps {
        Some(f) if f.is_finite() && f > 0.0 && f <= 10_000.0 => f,
        Some(f) => {
            return Err(SourceError::InvalidOption {
                reason: format!("sample rate must be in (0, 10000] fps, got {f}"),
            })
        }
        None => keyed_fps.unwrap_or(DEFAULT_SAMPLE_FPS),
    };
    // Sampling at the keys' own (rounded) rate: one frame per key. Rounding matters because
    // writers often store a truncated frame time (BVH's 0.008333 for 120 fps), which puts the
    // last key a fraction of a frame short of `n / fps` and would drop it under `floor`.
    let on_keys = opts.sample_fps.is_none() && keyed_fps.is_some();
    let end_secs = tracks.end_secs;
    let wanted = if on_keys {
        (end_secs as f64 * fps).round() + 1.0
    } else {
        (end_secs as f64 * fps + 1e-3).floor() + 1.0
    };
    let num_frames = tracks.frames_within_budget(wanted, skeleton, || {
        format!(
            "animation {:?}: {} s at {fps} fps makes {wanted} frames of {} bones;",
            animation_name(anim),
            end_secs,
            skeleton.num_bones()
        )
    })?;
    // On keys, sample at the keys themselves: a truncated frame time drifts from k / fps by
    // a fraction of a frame over a long clip, which would interpolate between keys.
    let key_times = (tracks.first_times.as_deref()).filter(|t| on_keys && t.len() == num_frames);
    let mut poses = Vec::with_capacity(num_frames);
    for k in 0..num_frames {
        let t = match key_times {
            Some(times) => times[k],
            None => (k as f64 / fps) as f32,
        };
        poses.push(tracks.pose_at(t, skeleton, frames, trs));
    }
    Ok((poses, 1.0 / fps))
}

/// An animation's rotation and translation tracks per bone, how long it runs, and the key
/// times of its first track (whose rate the clip is sampled at by default).
struct BoneTracks {
    rotation: Vec<Option<Track>>,
    translation: Vec<Option<Track>>,
    end_secs: f32,
    first_times: Option<Vec<f32>>,
}

impl BoneTracks {
    /// The tracks of `anim`'s channels that target one of the skeleton's bone nodes.
    fn read(
        anim: &::gltf::Animation<'_>,
        buffers: &[&[u8]],
        frames: &[BoneFrame],
    ) -> Result<Self, SourceError> {
        let bone_of_node: BTreeMap<usize, usize> = frames
            .iter()
            .enumerate()
            .map(|(b, f)| (f.node, b))
            .collect();
        let mut tracks = BoneTracks {
            rotation: vec![None; frames.len()],
            translation: vec![None; frames.len()],
            end_secs: 0.0,
            first_times: None,
        };
        for channel in anim.channels() {
            let Some(&bone) = bone_of_node.get(&channel.target().node().index()) else {
                continue;
            };
            let Some((property, track)) = read_track(&channel, buffers)? else {
                continue;
            };
            tracks.end_secs = tracks.end_secs.max(track.end_secs());
            if tracks.first_times.is_none() {
                tracks.first_times = Some(track.times.clone());
            }
            match property {
                Property::Rotation => tracks.rotation[bone] = Some(track),
                Property::Translation => tracks.translation[bone] = Some(track),
                _ => {}
            }
        }
        Ok(tracks)
    }

    /// `wanted` frames of `skeleton`, if within the sample budget of what the file holds (its
    /// keys across the sampled tracks); else a limit error that `what` describes.
    fn frames_within_budget(
        &self,
        wanted: f64,
        skeleton: &Skeleton,
        what: impl FnOnce() -> String,
    ) -> Result<usize, SourceError> {
        let input_samples = (self.rotation.iter())
            .chain(&self.translation)
            .flatten()
            .map(|t| t.times.len() as u64)
            .sum::<u64>();
        let bones = skeleton.num_bones();
        rigcast_retarget::bounds::frames_within_budget(wanted, bones, input_samples).ok_or_else(
            || {
                SourceError::limit(
                    what(),
                    format!("{} bone samples", wanted * bones as f64),
                    format!(
                        "{} for this file",
                        rigcast_retarget::bounds::sample_budget(input_samples)
                    ),
                )
            },
        )
    }

    /// The pose at `t` seconds: each bone's tracks sampled (its rest where it has none), in
    /// the skeleton's bone frames.
    fn pose_at(
        &self,
        t: f32,
        skeleton: &Skeleton,
        frames: &[BoneFrame],
        trs: &[(Vec3, Quat, f32)],
    ) -> Pose {
        let mut pose = Pose::from_rest(skeleton);
        for (b, f) in frames.iter().enumerate() {
            let (rest_t, rest_r, _) = trs[f.node];
            let r = self.rotation[b]
                .as_ref()
                .map(|tr| tr.sample_quat(t))
                .unwrap_or(rest_r);
            let tt = self.translation[b]
                .as_ref()
                .map(|tr| tr.sample_vec3(t))
                .unwrap_or(rest_t);
            let (tt, r) = f.apply(tt, r);
            pose.translations[b] = tt;
            pose.rotations[b] = r;
        }
        pose
    }
}
