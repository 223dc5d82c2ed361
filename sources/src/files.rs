//! File-level entry points: pick the format from the extension, read or write whole files.

use std::path::Path;

use rigcast_retarget::Clip;

use crate::bvh::{read_bvh, write_bvh, write_bvh_onto, BvhLayout, BvhReadOptions, BvhWriteOptions};
use crate::error::SourceError;
use crate::gltf::{read_gltf, write_glb, write_glb_onto, GltfRead, GltfReadOptions, GltfTemplate};
use crate::recording::{clip_from_recording, read_recording, write_clip_recording};

/// Options for [`load_clip_with`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadOptions {
    /// BVH: metres per file unit (`None` guesses from the skeleton size).
    pub bvh_scale: Option<f32>,
    /// glTF: which animation to load, by name or decimal index (`None` = the first).
    pub animation: Option<String>,
    /// glTF: sampling rate in frames per second (`None` = the keyframe rate, or 30).
    pub sample_fps: Option<f64>,
}

pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Largest clip or character file read whole (the bound of a glTF's buffers, too): far above
/// any real file, far below what would exhaust memory.
pub const MAX_FILE_BYTES: u64 = crate::gltf::MAX_BUFFER_BYTES;

/// Reads a whole file that is a regular file of at most [`MAX_FILE_BYTES`]: a path naming a
/// device (`/dev/zero`), a FIFO (which would block its reader) or a folder is refused before it
/// is opened, and a file that grows past the bound while it is read is refused too.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, SourceError> {
    use std::io::Read;
    let io = |source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    };
    let refuse = |why: String| io(std::io::Error::new(std::io::ErrorKind::InvalidInput, why));
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(refuse(
            "not a regular file (a folder, device or FIFO is never read as a clip)".into(),
        ));
    }
    let too_large = |len: u64| {
        refuse(format!(
            "{len} bytes or more, above the {MAX_FILE_BYTES}-byte limit for a clip or character file"
        ))
    };
    if meta.len() > MAX_FILE_BYTES {
        return Err(too_large(meta.len()));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

pub(crate) fn stem(path: &Path) -> String {
    path.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("clip")
        .to_string()
}

/// Reads a glTF/GLB/VRM file, with one warning per skipped part (the file still loads).
fn read_gltf_file(path: &Path, opts: &GltfReadOptions) -> Result<GltfRead, SourceError> {
    let bytes = read_file(path)?;
    let read = read_gltf(&bytes, path.parent(), &stem(path), opts)?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    Ok(read)
}

/// Loads a clip with default options; see [`load_clip_with`].
pub fn load_clip(path: &Path) -> Result<Clip, SourceError> {
    load_clip_with(path, &LoadOptions::default())
}

/// Loads a clip from `.bvh`, `.gltf`, `.glb`, `.vrm` or `.rcr`, choosing the format by
/// extension. Errors name the file.
pub fn load_clip_with(path: &Path, opts: &LoadOptions) -> Result<Clip, SourceError> {
    load_clip_and_humanoid(path, opts).map(|c| c.clip)
}

/// A clip and what its file says of the body: a VRM's humanoid map.
#[derive(Debug, Clone)]
pub struct LoadedClip {
    /// The clip.
    pub clip: Clip,
    /// A `.vrm` file's humanoid map (human bone name → bone name), ground truth for the
    /// analysis' roles; `None` for other files.
    pub humanoid: Option<Vec<(String, String)>>,
}

/// [`load_clip_with`], with a VRM's humanoid map read from the same parse.
pub fn load_clip_and_humanoid(path: &Path, opts: &LoadOptions) -> Result<LoadedClip, SourceError> {
    let ext = extension(path);
    let mut humanoid = None;
    let result = match ext.as_str() {
        "bvh" => {
            let bytes = read_file(path)?;
            read_bvh(
                &bytes,
                &stem(path),
                &BvhReadOptions {
                    scale: opts.bvh_scale,
                },
            )
            .map(|r| r.clip)
        }
        "gltf" | "glb" | "vrm" => {
            let gltf_opts = GltfReadOptions {
                animation: opts.animation.clone(),
                sample_fps: opts.sample_fps,
            };
            read_gltf_file(path, &gltf_opts).map(|r| {
                if ext == "vrm" {
                    humanoid = r.vrm_roles.map(|m| m.into_iter().collect());
                }
                r.clip
            })
        }
        "rcr" => {
            let bytes = read_file(path)?;
            read_recording(&bytes[..]).and_then(|rec| clip_from_recording(&rec, &stem(path)))
        }
        _ => Err(SourceError::UnsupportedExtension {
            extension: ext,
            expected: ".bvh, .gltf, .glb, .vrm, .rcr",
        }),
    };
    result
        .map(|clip| LoadedClip { clip, humanoid })
        .map_err(|e| e.in_file(path))
}

/// Saves a clip as `.bvh`, `.glb` or `.rcr`, choosing the format by extension.
pub fn save_clip(path: &Path, clip: &Clip) -> Result<(), SourceError> {
    let ext = extension(path);
    let bytes: Vec<u8> = match ext.as_str() {
        "bvh" => write_bvh(clip, &BvhWriteOptions::default())
            .map_err(|e| e.in_file(path))?
            .into_bytes(),
        "glb" => write_glb(clip).map_err(|e| e.in_file(path))?,
        "rcr" => write_clip_recording(Vec::new(), clip).map_err(|e| e.in_file(path))?,
        _ => {
            return Err(SourceError::UnsupportedExtension {
                extension: ext,
                expected: ".bvh, .glb, .rcr",
            }
            .in_file(path))
        }
    };
    std::fs::write(path, bytes).map_err(|source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// A character file's own layout, kept so that motion written onto it is that file's rig again
/// (see [`save_clip_onto`]).
#[derive(Debug, Clone)]
pub enum RigLayout {
    /// A BVH file's hierarchy: joint order, End Sites, channels, offsets, units.
    Bvh(BvhLayout),
    /// A glTF file's document: nodes, names, skins, inverse bind matrices, meshes.
    Gltf(Box<GltfTemplate>),
    /// Nothing beyond the skeleton (recordings).
    Skeleton,
}

/// Loads a character: its clip (skeleton and any animation) and its file's layout.
pub fn load_rig(path: &Path) -> Result<(Clip, RigLayout), SourceError> {
    let ext = extension(path);
    let result = match ext.as_str() {
        "bvh" => {
            let bytes = read_file(path)?;
            read_bvh(&bytes, &stem(path), &BvhReadOptions::default())
                .map(|r| (r.clip, RigLayout::Bvh(r.layout)))
        }
        "gltf" | "glb" | "vrm" => read_gltf_file(path, &GltfReadOptions::default())
            .map(|r| (r.clip, RigLayout::Gltf(Box::new(r.template)))),
        _ => return load_clip(path).map(|c| (c, RigLayout::Skeleton)),
    };
    result.map_err(|e| e.in_file(path))
}

/// Saves a clip of a character loaded with [`load_rig`]. A `.bvh` output of a BVH character
/// keeps that file's hierarchy exactly; a `.glb` output of a glTF character is that file's
/// document with the clip as its animation. Any other combination is written as
/// [`save_clip`] writes it.
pub fn save_clip_onto(path: &Path, clip: &Clip, layout: &RigLayout) -> Result<(), SourceError> {
    let bytes: Vec<u8> = match (extension(path).as_str(), layout) {
        ("bvh", RigLayout::Bvh(l)) => write_bvh_onto(clip, l)
            .map_err(|e| e.in_file(path))?
            .into_bytes(),
        ("glb", RigLayout::Gltf(t)) => write_glb_onto(t, clip).map_err(|e| e.in_file(path))?,
        _ => return save_clip(path, clip),
    };
    std::fs::write(path, bytes).map_err(|source| SourceError::Io {
        path: path.to_path_buf(),
        source,
    })
}
