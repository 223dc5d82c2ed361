//! Characters as every command loads them (`load_character`: `builtin:NAME` or a file). The
//! built-in ones are made from code in the engine (`rigcast_engine::builtin`, re-exported here).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rigcast_retarget::Clip;
use rigcast_sources::{RigLayout, SourceError};
use thiserror::Error;

use rigcast_engine::builtin::{builtin, BUILTIN_NAMES, BUILTIN_PREFIX};

/// A character as every command loads it (`serve --target`, `retarget --target`, config
/// performers): one rule for files and built-ins.
#[derive(Debug)]
pub struct LoadedCharacter {
    /// Its name: the built-in's, else the file's stem.
    pub name: String,
    /// Its skeleton and any animation in the file (none for a built-in); the animation only
    /// serves as a reference posture.
    pub clip: Clip,
    /// The file's own layout, to write motion back onto it (`Skeleton` for a built-in).
    pub layout: RigLayout,
    /// A `.vrm` file's humanoid map (human bone name → bone name): ground truth for roles.
    pub truth: Option<Vec<(String, String)>>,
    /// The file, `None` for a built-in.
    pub file: Option<PathBuf>,
}

/// Why a character could not be loaded.
#[derive(Debug, Error)]
pub enum CharacterError {
    /// `builtin:NAME` with a name that is not built in.
    #[error("unknown built-in character {name:?}; expected one of {BUILTIN_NAMES:?}")]
    UnknownBuiltin {
        /// the name asked for
        name: String,
    },
    /// The file could not be read.
    #[error(transparent)]
    File(#[from] SourceError),
}

/// Loads `builtin:NAME` or a character file (.bvh, .gltf/.glb, .vrm, .rcr).
pub fn load_character(path: &Path) -> Result<LoadedCharacter, CharacterError> {
    if let Some(name) = path.to_string_lossy().strip_prefix(BUILTIN_PREFIX) {
        let skeleton = builtin(name).ok_or_else(|| CharacterError::UnknownBuiltin {
            name: name.to_string(),
        })?;
        let clip = Clip::new(name, Arc::new(skeleton), Vec::new(), 1.0 / 30.0)
            .map_err(SourceError::from)?;
        return Ok(LoadedCharacter {
            name: name.to_string(),
            clip,
            layout: RigLayout::Skeleton,
            truth: None,
            file: None,
        });
    }
    let (clip, layout) = rigcast_sources::load_rig(path)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| clip.name.clone());
    Ok(LoadedCharacter {
        name,
        clip,
        layout,
        truth: vrm_truth(path),
        file: Some(path.to_path_buf()),
    })
}

/// A VRM file's humanoid map (human bone name → bone name): ground truth for its roles.
pub fn vrm_truth(path: &Path) -> Option<Vec<(String, String)>> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    if ext != "vrm" {
        return None;
    }
    let info = rigcast_sources::describe(path).ok()?;
    info.vrm_roles
        .map(|m| m.into_iter().collect::<Vec<(String, String)>>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mannequin_differs_from_the_demo_source() {
        let m = rigcast_engine::builtin::mannequin().unwrap();
        let demo = rigcast_sources::embedded_demo().unwrap();
        assert_ne!(m.fingerprint(), demo.skeleton.fingerprint());
        assert!(m.num_bones() > demo.skeleton.num_bones());
        assert!(m.bone("pelvis").is_some() && m.bone("upperarm_l").is_some());
        assert!(builtin("nope").is_none());
    }
}
