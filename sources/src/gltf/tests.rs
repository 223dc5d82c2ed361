#![allow(clippy::unwrap_used)]

use glam::{Quat, Vec3};
use rigcast_retarget::approx::vec_close;
use serde_json::{json, Value};

use super::*;
use crate::error::SourceError;

fn quat_close(a: Quat, b: Quat, tol_rad: f32) -> bool {
    2.0 * (a.conjugate() * b).xyz().length().min(1.0).asin() <= tol_rad
}

fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn floats(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A JSON glTF with one embedded buffer made of consecutive f32 blocks, one view per block.
fn gltf_doc(mut doc: Value, blocks: &[(&[f32], &str)]) -> Vec<u8> {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    for (data, kind) in blocks {
        let comps = match *kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len() * 4}));
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126,
            "count": data.len() / comps, "type": kind}));
        bin.extend(floats(data));
    }
    doc["asset"] = json!({"version": "2.0"});
    doc["buffers"] = json!([{"byteLength": bin.len(),
        "uri": format!("data:application/octet-stream;base64,{}", base64(&bin))}]);
    doc["bufferViews"] = json!(views);
    doc["accessors"] = json!(accessors);
    serde_json::to_vec(&doc).unwrap()
}

/// An armature node (rotated 90° about X, scaled 0.01) above a two-joint skin; the child joint
/// has a STEP rotation, the root a CUBICSPLINE translation and a LINEAR rotation.
fn hand_made() -> Vec<u8> {
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "Armature", "rotation": [0.70710677, 0.0, 0.0, 0.70710677], "scale": [0.01, 0.01, 0.01], "children": [1]},
            {"name": "hip", "translation": [0.0, 0.0, 100.0], "children": [2]},
            {"translation": [0.0, 50.0, 0.0]}
        ],
        "skins": [{"joints": [1, 2]}],
        "animations": [{
            "name": "move",
            "samplers": [
                {"input": 0, "output": 1, "interpolation": "CUBICSPLINE"},
                {"input": 0, "output": 2, "interpolation": "STEP"},
                {"input": 0, "output": 3, "interpolation": "LINEAR"}
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 1, "path": "translation"}},
                {"sampler": 1, "target": {"node": 2, "path": "rotation"}},
                {"sampler": 2, "target": {"node": 1, "path": "rotation"}}
            ]
        }]
    });
    let q1 = Quat::from_rotation_z(1.0).to_array();
    let qy = Quat::from_rotation_y(1.0).to_array();
    let id = Quat::IDENTITY.to_array();
    doc_with_blocks(doc, q1, qy, id)
}

fn doc_with_blocks(doc: Value, q1: [f32; 4], qy: [f32; 4], id: [f32; 4]) -> Vec<u8> {
    let times = [0.0f32, 2.0];
    // Cubic: key 0 (in 0, value 0, out (100,0,0)), key 1 (in 0, value (100,0,0), out 0).
    let cubic = [
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 100.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0, 0.0, 0.0f32,
    ];
    let step: Vec<f32> = id.iter().chain(q1.iter()).copied().collect();
    let linear: Vec<f32> = id.iter().chain(qy.iter()).copied().collect();
    gltf_doc(
        doc,
        &[
            (&times, "SCALAR"),
            (&cubic, "VEC3"),
            (&step, "VEC4"),
            (&linear, "VEC4"),
        ],
    )
}

fn read(bytes: &[u8], fps: Option<f64>) -> Result<GltfRead, SourceError> {
    read_gltf(
        bytes,
        None,
        "t",
        &GltfReadOptions {
            animation: None,
            sample_fps: fps,
        },
    )
}

#[test]
fn hand_made_accessors_sample_to_known_values() {
    let r = read(&hand_made(), Some(2.0)).unwrap();
    let s = &r.clip.skeleton;
    // The unnamed joint gets a stable name; the armature is folded in, not a bone.
    assert_eq!(s.names(), &["hip", "joint_2"]);
    assert_eq!(r.origin, SkeletonOrigin::Skin);
    assert_eq!(
        r.animations,
        vec![AnimationInfo {
            name: "move".into(),
            duration_secs: 2.0
        }]
    );
    // Rest: hip at armature·(0,0,100)·0.01 → rotated 90° about X → (0,-1,0).
    let rest = s.rest();
    assert!(
        vec_close(rest[0].translation, Vec3::new(0.0, -1.0, 0.0), 1e-5),
        "{:?}",
        rest[0]
    );
    assert!(vec_close(
        rest[1].translation,
        Vec3::new(0.0, 0.5, 0.0),
        1e-6
    ));
    assert!(quat_close(
        rest[0].rotation,
        Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
        1e-5
    ));
    // 2 s at 2 fps → 5 frames.
    assert_eq!(r.clip.num_frames(), 5);
    assert!((r.clip.frame_time_secs - 0.5).abs() < 1e-12);
    let armature = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    // Cubic at t = 1 (s = 0.5, dt = 2): 0 + (s³-2s²+s)·dt·100 + (-2s³+3s²)·100 = 25 + 50 = 75
    // (file units) → 0.75 m along the armature's x.
    let p = &r.clip.poses[2];
    assert!(
        vec_close(
            p.translations[0],
            armature * Vec3::new(0.75, 0.0, 0.0),
            1e-5
        ),
        "{:?}",
        p.translations[0]
    );
    // LINEAR rotation at t=1 is halfway: 0.5 rad about Y, after the armature rotation.
    assert!(quat_close(
        p.rotations[0],
        armature * Quat::from_rotation_y(0.5),
        1e-5
    ));
    // STEP holds the first key until t = 2.
    assert!(quat_close(
        r.clip.poses[3].rotations[1],
        Quat::IDENTITY,
        1e-6
    ));
    assert!(quat_close(
        r.clip.poses[4].rotations[1],
        Quat::from_rotation_z(1.0),
        1e-6
    ));
    // At 1.5 s (s = 0.75): (s³-2s²+s)·2·100 = 9.375, (-2s³+3s²)·100 = 84.375; total 93.75.
    let p = &r.clip.poses[3];
    assert!(vec_close(
        p.translations[0],
        armature * Vec3::new(0.9375, 0.0, 0.0),
        1e-5
    ));
}

#[test]
fn glb_round_trip_of_the_demo() {
    let clip = crate::demo::generate();
    let glb = write_glb(&clip).unwrap();
    // Minimal structure check: the gltf crate parses and validates it.
    let g = ::gltf::Gltf::from_slice(&glb).unwrap();
    assert_eq!(g.nodes().count(), 25);
    assert_eq!(g.animations().count(), 1);
    assert_eq!(&glb[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes([glb[8], glb[9], glb[10], glb[11]]) as usize,
        glb.len()
    );
    let back = read(&glb, None).unwrap();
    assert_eq!(back.clip.skeleton.names(), clip.skeleton.names());
    assert_eq!(back.clip.skeleton.parents(), clip.skeleton.parents());
    // Evenly spaced keys → the keyframe rate (60 fps) is detected.
    assert!((back.clip.fps() - 60.0).abs() < 1e-6);
    assert_eq!(back.clip.num_frames(), clip.num_frames());
    for (a, b) in clip.poses.iter().zip(&back.clip.poses) {
        for i in 0..a.num_bones() {
            assert!(quat_close(a.rotations[i], b.rotations[i], 1e-5));
            assert!(vec_close(a.translations[i], b.translations[i], 1e-6));
        }
    }
}

#[test]
fn glb_round_trip_keeps_every_frame_with_a_truncated_frame_time() {
    // BVH files store 120 fps as 0.008333 s; the last key then lands a fraction of a frame
    // before 993/120 s, and sampling at the detected 120 fps must still give all 994 frames.
    let demo = crate::demo::generate();
    let poses: Vec<_> = (0..994)
        .map(|k| demo.poses[k % demo.num_frames()].clone())
        .collect();
    let clip = rigcast_retarget::Clip::new("long", demo.skeleton.clone(), poses, 0.008333).unwrap();
    let back = read(&write_glb(&clip).unwrap(), None).unwrap();
    assert_eq!(back.clip.num_frames(), 994);
    assert!((back.clip.fps() - 120.0).abs() < 1e-6);
}

#[test]
fn vrm_without_skin_uses_humanoid_bones() {
    for (ext, version) in [
        (
            json!({"VRMC_vrm": {"specVersion": "1.0", "humanoid": {"humanBones": {
            "hips": {"node": 1}, "spine": {"node": 2}, "head": {"node": 4}}}}}),
            VrmVersion::V1,
        ),
        (
            json!({"VRM": {"humanoid": {"humanBones": [
            {"bone": "hips", "node": 1}, {"bone": "spine", "node": 2}, {"bone": "head", "node": 4}]}}}),
            VrmVersion::V0,
        ),
    ] {
        let doc = json!({
            "scenes": [{"nodes": [0]}],
            "nodes": [
                {"name": "Root", "children": [1]},
                {"name": "J_Hips", "translation": [0.0, 1.0, 0.0], "children": [2]},
                {"name": "J_Spine", "translation": [0.0, 0.1, 0.0], "children": [3]},
                {"name": "J_Neck", "translation": [0.0, 0.4, 0.0], "children": [4]},
                {"name": "J_Head", "translation": [0.0, 0.1, 0.0]}
            ],
            "extensions": ext,
        });
        let bytes = serde_json::to_vec(&json!({"asset": {"version": "2.0"}})).unwrap();
        let mut full: Value = serde_json::from_slice(&bytes).unwrap();
        for (k, v) in doc.as_object().unwrap() {
            full[k] = v.clone();
        }
        let r = read(&serde_json::to_vec(&full).unwrap(), None).unwrap();
        assert_eq!(r.origin, SkeletonOrigin::VrmHumanoid(version));
        // J_Neck is between two humanoid bones, so it is kept; Root above is not.
        assert_eq!(
            r.clip.skeleton.names(),
            &["J_Hips", "J_Spine", "J_Neck", "J_Head"]
        );
        let roles = r.vrm_roles.unwrap();
        assert_eq!(roles["hips"], "J_Hips");
        assert_eq!(roles["head"], "J_Head");
        assert_eq!(r.clip.num_frames(), 0);
    }
}

#[test]
fn malformed_gltf_gives_clear_errors() {
    // Bad JSON.
    let e = read(b"{\"asset\": {\"version\": \"2.0\"", None)
        .err()
        .unwrap();
    assert!(matches!(e, SourceError::Gltf { .. }), "{e}");
    // Valid glTF with neither skin nor VRM.
    let e = read(
        br#"{"asset":{"version":"2.0"},"nodes":[{"name":"a"}]}"#,
        None,
    )
    .err()
    .unwrap();
    assert!(matches!(e, SourceError::NoSkeleton), "{e}");
    // Accessor that overruns its buffer view.
    let e = read_edited(|doc| doc["accessors"][1]["count"] = json!(600));
    assert!(
        matches!(e, SourceError::BadAccessor { accessor: 1, .. }),
        "{e}"
    );
    // Accessor with the wrong type for its target.
    let e = read_edited(|doc| {
        doc["accessors"][2]["type"] = json!("VEC3");
        doc["accessors"][2]["count"] = json!(2);
    });
    assert!(
        matches!(e, SourceError::BadAccessor { accessor: 2, .. }),
        "{e}"
    );
    // Unknown animation name lists the available ones.
    let opts = GltfReadOptions {
        animation: Some("fly".into()),
        sample_fps: None,
    };
    let e = read_gltf(&hand_made(), None, "t", &opts).err().unwrap();
    assert!(
        matches!(&e, SourceError::AnimationNotFound { available, .. } if available == &["move"]),
        "{e}"
    );
    // Truncated GLB.
    let glb = write_glb(&crate::demo::generate()).unwrap();
    for cut in [3, 12, 40, glb.len() / 2, glb.len() - 1] {
        assert!(read(&glb[..cut], None).is_err(), "cut {cut}");
    }
    // Binary garbage.
    assert!(read(&[0xff, 0xfe, 0x00, 0x01, 0x02], None).is_err());
}

/// A GLB from a JSON document and a binary chunk (both padded as the spec asks).
fn glb_from(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    super::write::glb_container(json, Some(&b)).unwrap()
}

/// The demo as GLB, plus a skinned mesh the way Draco exporters write it: 300 attribute
/// accessors without buffer views, the compressed bytes in one view named by the primitive's
/// `KHR_draco_mesh_compression`, and the extension in `extensionsRequired`.
fn draco_demo(attribute_view: Option<usize>) -> (Vec<u8>, rigcast_retarget::Clip) {
    let clip = crate::embedded_demo().unwrap();
    let written = write_glb(&clip).unwrap();
    let glb = ::gltf::binary::Glb::from_slice(&written).unwrap();
    let mut json: Value = serde_json::from_slice(&glb.json).unwrap();
    let mut bin = glb.bin.unwrap().into_owned();
    let compressed_view = json["bufferViews"].as_array().unwrap().len();
    json["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": 64}));
    bin.extend([0x44u8; 64]); // stands in for a Draco bitstream
    json["buffers"][0]["byteLength"] = json!(bin.len());
    let first = json["accessors"].as_array().unwrap().len();
    let mut primitives = Vec::new();
    for k in 0..100 {
        let mut attrs = serde_json::Map::new();
        for (a, (name, kind)) in [
            ("POSITION", "VEC3"),
            ("NORMAL", "VEC3"),
            ("TEXCOORD_0", "VEC2"),
        ]
        .iter()
        .enumerate()
        {
            let mut acc = json!({"componentType": 5126, "count": 24, "type": kind});
            if *name == "POSITION" {
                acc["min"] = json!([-1.0, -1.0, -1.0]);
                acc["max"] = json!([1.0, 1.0, 1.0]);
            }
            if let Some(v) = attribute_view {
                acc["bufferView"] = json!(v);
            }
            json["accessors"].as_array_mut().unwrap().push(acc);
            attrs.insert(name.to_string(), json!(first + 3 * k + a));
        }
        primitives.push(json!({
            "attributes": attrs,
            "extensions": {"KHR_draco_mesh_compression": {
                "bufferView": compressed_view,
                "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}}
        }));
    }
    json["meshes"] = json!([{"primitives": primitives}]);
    let mesh_node = json["nodes"].as_array().unwrap().len();
    json["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"name": "body", "mesh": 0, "skin": 0}));
    json["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!(mesh_node));
    json["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    json["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    (glb_from(&json, &bin), clip)
}

#[test]
fn draco_compressed_meshes_are_skipped_with_one_warning_and_the_skeleton_loads() {
    let (bytes, clip) = draco_demo(None);
    // The gltf crate alone refuses the file (that is what the tolerance is for).
    assert!(::gltf::Gltf::from_slice(&bytes).is_err());
    let r = read(&bytes, None).unwrap();
    assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
    assert!(
        r.warnings[0].contains("KHR_draco_mesh_compression"),
        "{}",
        r.warnings[0]
    );
    assert_eq!(r.clip.skeleton.names(), clip.skeleton.names());
    assert_eq!(r.clip.num_frames(), clip.num_frames());
    for (a, b) in r.clip.poses.iter().zip(&clip.poses) {
        for (qa, qb) in a.rotations.iter().zip(&b.rotations) {
            assert!(quat_close(*qa, *qb, 1e-5));
        }
    }
    // A plain file has no warning.
    let plain = read(&write_glb(&clip).unwrap(), None).unwrap();
    assert!(plain.warnings.is_empty());
}

#[test]
fn hundreds_of_bad_accessors_give_a_short_summarised_error() {
    // The same file without the extension, every attribute accessor naming a missing view.
    let (bytes, _) = draco_demo(Some(9999));
    let glb = ::gltf::binary::Glb::from_slice(&bytes).unwrap();
    let mut json: Value = serde_json::from_slice(&glb.json).unwrap();
    json.as_object_mut().unwrap().remove("extensionsRequired");
    json.as_object_mut().unwrap().remove("extensionsUsed");
    let broken = glb_from(&json, &glb.bin.unwrap());
    let message = read(&broken, None).unwrap_err().to_string();
    println!("{message}");
    assert!(
        message.chars().count() <= MAX_ERROR_CHARS + 20,
        "{} chars",
        message.len()
    );
    assert!(message.contains("accessors[*].bufferView"), "{message}");
    assert!(message.contains("×300"), "{message}");
}

/// The error of reading [`hand_made`] with `edit` applied to its JSON.
fn read_edited(edit: impl FnOnce(&mut Value)) -> SourceError {
    let mut doc: Value = serde_json::from_slice(&hand_made()).unwrap();
    edit(&mut doc);
    read(&serde_json::to_vec(&doc).unwrap(), None)
        .err()
        .unwrap()
}
