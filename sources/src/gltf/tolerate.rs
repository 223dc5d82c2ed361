//! What the reader tolerates in real files, and how it reports what it refuses.
//!
//! rigcast reads skeletons, skins and animations; it never decodes meshes or textures. A file
//! whose meshes use an extension the `gltf` crate cannot decode (Draco, meshopt) or whose
//! textures use one (Basis, WebP, AVIF) is still a perfectly good skeleton: those extensions
//! are dropped from `extensionsRequired`, the meshes, materials and textures are left out, and
//! one warning says so. Validation errors are summarised one line per distinct problem with a
//! count, so a file with hundreds of bad accessors gives a short message, not kilobytes.

use std::collections::BTreeMap;

use serde_json::Value;

/// Extensions that only concern mesh or texture data, which the reader does not need.
pub const MESH_ONLY_EXTENSIONS: [&str; 8] = [
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_mesh_quantization",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "KHR_texture_transform",
];

/// Top-level arrays holding only mesh and texture data.
const MESH_DATA: [&str; 5] = ["meshes", "materials", "textures", "images", "samplers"];

/// Longest error message [`summarise_validation`] produces (characters, about).
pub const MAX_ERROR_CHARS: usize = 600;
/// Distinct problems listed before the rest are only counted.
const MAX_PROBLEM_LINES: usize = 6;

/// Drops mesh-only extensions and the mesh data they apply to from a glTF JSON document.
/// Returns the warning to show, or `None` when the file declares none of them (`json` is then
/// untouched).
pub fn skip_undecodable_mesh_data(json: &mut Value) -> Option<String> {
    let declared = |key: &str, json: &Value| -> Vec<String> {
        json.get(key)
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(Value::as_str)
                    .filter(|e| MESH_ONLY_EXTENSIONS.contains(e))
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut skipped = declared("extensionsRequired", json);
    for e in declared("extensionsUsed", json) {
        if !skipped.contains(&e) {
            skipped.push(e);
        }
    }
    if skipped.is_empty() {
        return None;
    }
    let root = json.as_object_mut()?;
    for key in ["extensionsRequired", "extensionsUsed"] {
        if let Some(Value::Array(list)) = root.get_mut(key) {
            list.retain(|e| {
                !e.as_str()
                    .is_some_and(|e| MESH_ONLY_EXTENSIONS.contains(&e))
            });
        }
    }
    for key in MESH_DATA {
        root.remove(key);
    }
    if let Some(Value::Array(nodes)) = root.get_mut("nodes") {
        for node in nodes.iter_mut().filter_map(Value::as_object_mut) {
            node.remove("mesh");
            node.remove("weights");
        }
    }
    stub_compressed_accessors(root);
    // meshopt's fallback buffers have no data at all; nothing the reader uses lives in them.
    if let Some(Value::Array(buffers)) = root.get_mut("buffers") {
        for buffer in buffers.iter_mut().filter_map(Value::as_object_mut) {
            let fallback = buffer
                .get("extensions")
                .and_then(|e| {
                    e.get("EXT_meshopt_compression")
                        .or(e.get("KHR_meshopt_compression"))
                })
                .and_then(|m| m.get("fallback"))
                .and_then(Value::as_bool)
                == Some(true);
            if fallback && !buffer.contains_key("uri") {
                buffer.insert(
                    "uri".into(),
                    Value::from("data:application/octet-stream;base64,"),
                );
                buffer.insert("byteLength".into(), Value::from(0));
            }
        }
    }
    Some(format!(
        "meshes and textures skipped: the file uses {} (the skeleton, skin and animations load)",
        skipped.join(", ")
    ))
}

/// Compressed meshes' accessors have no buffer view (their data is in the compressed stream),
/// which the `gltf` crate refuses. The meshes are gone, so nothing reads them: point them at
/// one stub view instead of renumbering every accessor (animations refer to them by index).
fn stub_compressed_accessors(root: &mut serde_json::Map<String, Value>) {
    let has_buffer = root
        .get("buffers")
        .and_then(Value::as_array)
        .is_some_and(|b| !b.is_empty());
    let Some(Value::Array(accessors)) = root.get("accessors") else {
        return;
    };
    let viewless: Vec<usize> = accessors
        .iter()
        .enumerate()
        .filter(|(_, a)| a.get("bufferView").is_none() && a.get("sparse").is_none())
        .map(|(i, _)| i)
        .collect();
    if viewless.is_empty() || !has_buffer {
        return;
    }
    let views = root
        .entry("bufferViews")
        .or_insert_with(|| Value::Array(Vec::new()));
    let Some(list) = views.as_array_mut() else {
        return;
    };
    list.push(serde_json::json!({"buffer": 0, "byteLength": 1}));
    let stub = list.len() - 1;
    if let Some(Value::Array(accessors)) = root.get_mut("accessors") {
        for i in viewless {
            if let Some(a) = accessors.get_mut(i).and_then(Value::as_object_mut) {
                a.insert("bufferView".into(), Value::from(stub));
            }
        }
    }
}

/// One line per distinct problem (path with indices folded, and the error), with a count,
/// bounded to about [`MAX_ERROR_CHARS`].
pub fn summarise_validation(errors: &[(String, String)]) -> String {
    let mut problems: BTreeMap<(String, String), usize> = BTreeMap::new();
    for (path, error) in errors {
        *problems
            .entry((fold_indices(path), error.clone()))
            .or_default() += 1;
    }
    let mut lines: Vec<String> = problems
        .iter()
        .take(MAX_PROBLEM_LINES)
        .map(|((path, error), n)| match n {
            1 => format!("{path}: {error}"),
            n => format!("{path}: {error} (×{n})"),
        })
        .collect();
    if problems.len() > MAX_PROBLEM_LINES {
        lines.push(format!(
            "… and {} more kinds of problem",
            problems.len() - MAX_PROBLEM_LINES
        ));
    }
    let mut text = format!(
        "invalid glTF ({} problems): {}",
        errors.len(),
        lines.join("; ")
    );
    if text.chars().count() > MAX_ERROR_CHARS {
        text = text.chars().take(MAX_ERROR_CHARS - 1).collect();
        text.push('…');
    }
    text
}

/// `accessors[12].bufferView` → `accessors[*].bufferView`.
fn fold_indices(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => {
                in_index = true;
                out.push_str("[*");
            }
            ']' => {
                in_index = false;
                out.push(']');
            }
            _ if in_index => {}
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folds_repeated_problems_into_one_counted_line() {
        let errors: Vec<(String, String)> = (0..300)
            .map(|i| {
                (
                    format!("accessors[{i}].bufferView"),
                    "Missing data".to_string(),
                )
            })
            .chain([(
                "nodes[3].mesh".to_string(),
                "Index out of range".to_string(),
            )])
            .collect();
        let text = summarise_validation(&errors);
        assert_eq!(
            text,
            "invalid glTF (301 problems): accessors[*].bufferView: Missing data (×300); \
             nodes[*].mesh: Index out of range"
        );
    }

    #[test]
    fn many_kinds_of_problem_stay_short() {
        let errors: Vec<(String, String)> = (0..500)
            .map(|i| {
                (
                    format!("p{i}.{}", "x".repeat(80)),
                    format!("error kind {i}"),
                )
            })
            .collect();
        let text = summarise_validation(&errors);
        assert!(
            text.chars().count() <= MAX_ERROR_CHARS,
            "{} chars",
            text.len()
        );
        assert!(text.contains("more kinds of problem") || text.ends_with('…'));
    }

    #[test]
    fn files_without_mesh_only_extensions_are_untouched() {
        let mut json =
            serde_json::json!({"extensionsRequired": ["KHR_materials_variants"], "meshes": [{}]});
        let before = json.clone();
        assert_eq!(skip_undecodable_mesh_data(&mut json), None);
        assert_eq!(json, before);
    }
}
