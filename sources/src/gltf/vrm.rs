//! VRM humanoid bone tables (VRM 0.x `extensions.VRM` and VRM 1.0 `extensions.VRMC_vrm`).

use std::collections::BTreeMap;

use ::gltf::json::Value;
use ::gltf::Document;

use crate::error::SourceError;

/// Which VRM specification a file follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VrmVersion {
    /// VRM 0.x (`extensions.VRM`).
    V0,
    /// VRM 1.0 (`extensions.VRMC_vrm`).
    V1,
}

/// A VRM file's version and its humanoid role → node index table.
pub(crate) type HumanBones = (VrmVersion, BTreeMap<String, usize>);

/// The humanoid role → node index table, when the document is a VRM.
pub(crate) fn vrm_human_bones(
    doc: &Document,
    num_nodes: usize,
) -> Result<Option<HumanBones>, SourceError> {
    let Some(ext) = doc.extensions() else {
        return Ok(None);
    };
    let bad = |reason: String| SourceError::Gltf {
        message: format!("VRM humanoid: {reason}"),
    };
    let node_of = |v: &Value, role: &str| -> Result<usize, SourceError> {
        let n = v
            .get("node")
            .and_then(Value::as_u64)
            .ok_or_else(|| bad(format!("bone {role:?} has no node index")))?;
        let n = n as usize;
        if n >= num_nodes {
            return Err(bad(format!(
                "bone {role:?} points at node {n}, but there are {num_nodes} nodes"
            )));
        }
        Ok(n)
    };
    if let Some(v1) = ext.get("VRMC_vrm") {
        let bones = human_bones(v1)
            .and_then(Value::as_object)
            .ok_or_else(|| bad("VRMC_vrm.humanoid.humanBones is missing".into()))?;
        let mut out = BTreeMap::new();
        for (role, v) in bones {
            out.insert(role.clone(), node_of(v, role)?);
        }
        return Ok(Some((VrmVersion::V1, out)));
    }
    if let Some(v0) = ext.get("VRM") {
        // VRM 0.x lists the bones as an array of `{bone, node}`.
        let bones = human_bones(v0)
            .and_then(Value::as_array)
            .ok_or_else(|| bad("VRM.humanoid.humanBones is missing".into()))?;
        let mut out = BTreeMap::new();
        for v in bones {
            let role = v
                .get("bone")
                .and_then(Value::as_str)
                .ok_or_else(|| bad("a human bone has no role name".into()))?;
            out.insert(role.to_string(), node_of(v, role)?);
        }
        return Ok(Some((VrmVersion::V0, out)));
    }
    Ok(None)
}

/// `humanoid.humanBones` of a VRM extension object (an object in 1.0, an array in 0.x).
fn human_bones(extension: &Value) -> Option<&Value> {
    extension.get("humanoid")?.get("humanBones")
}
