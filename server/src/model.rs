//! Target characters' model files, served to the viewer at `GET /v1/subjects/{id}/model.glb`
//! so it can draw the skinned mesh the performer drives.
//!
//! Only files the operator configured as a performer's target are served, and only as what
//! they are: a binary glTF container (`.glb`, or `.vrm`, which is a GLB with the VRM
//! extension). A `.gltf` target (JSON with external buffers) has no single file to send, so the
//! viewer keeps drawing its skeleton; so do BVH targets and built-in characters. The path is
//! never taken from the request: the request names a subject id, the server looks up its file.

use std::path::{Path, PathBuf};

/// The first bytes of every binary glTF file.
const GLB_MAGIC: &[u8; 4] = b"glTF";

/// Largest model the server serves.
pub const MAX_MODEL_BYTES: u64 = 512 * 1024 * 1024;

/// Bytes of a model held in memory per request while it streams (the rest stays on disk), so
/// clients that ask for a model and do not read cost this each, not the file's size.
pub const MODEL_CHUNK_BYTES: usize = 64 * 1024;

/// A target's servable model file (plain data the engine keeps with the subject).
use rigcast_engine::subject::ModelFile;

/// Finding and opening a target's model file (the host's side of [`ModelFile`]).
#[allow(async_fn_in_trait)] // only called within this crate, on a tokio runtime
pub trait ServedModel: Sized {
    /// The model of a target loaded from `path`, when it is a binary glTF container.
    fn for_target(path: &Path) -> Option<Self>;
    /// The file opened now (it may have been replaced or removed since the server started),
    /// checked to be a GLB within [`MAX_MODEL_BYTES`], at its start, with its length: to be
    /// streamed in [`MODEL_CHUNK_BYTES`] pieces rather than read whole.
    async fn open(&self) -> Result<(tokio::fs::File, u64), ModelError>;
}

impl ServedModel for ModelFile {
    fn for_target(path: &Path) -> Option<ModelFile> {
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        let format = match ext.as_str() {
            "glb" => "glb",
            "vrm" => "vrm",
            _ => return None,
        };
        // The loader has already read it as glTF; this only rules out a renamed .gltf text file.
        let mut magic = [0u8; 4];
        use std::io::Read;
        std::fs::File::open(path)
            .ok()?
            .read_exact(&mut magic)
            .ok()?;
        (&magic == GLB_MAGIC).then(|| ModelFile {
            path: path.to_path_buf(),
            format,
        })
    }

    async fn open(&self) -> Result<(tokio::fs::File, u64), ModelError> {
        use tokio::io::{AsyncReadExt, AsyncSeekExt};
        let unreadable = |e: std::io::Error| ModelError::Unreadable {
            path: self.path.clone(),
            reason: e.to_string(),
        };
        let mut file = tokio::fs::File::open(&self.path)
            .await
            .map_err(unreadable)?;
        let len = file.metadata().await.map_err(unreadable)?.len();
        if len > MAX_MODEL_BYTES {
            return Err(ModelError::TooLarge {
                path: self.path.clone(),
                bytes: len,
            });
        }
        let mut magic = [0u8; 4];
        let is_glb = file.read_exact(&mut magic).await.is_ok() && &magic == GLB_MAGIC;
        if !is_glb {
            return Err(ModelError::NoLongerGlb {
                path: self.path.clone(),
            });
        }
        file.rewind().await.map_err(unreadable)?;
        Ok((file, len))
    }
}

/// Why a model request gets no model (answered 404 with this text).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModelError {
    /// The request path's subject id is not a number.
    #[error("subject id {0:?} is not a number")]
    BadSubjectId(String),
    /// The configured file cannot be read now.
    #[error("model file {}: {reason}", path.display())]
    Unreadable {
        /// The configured path.
        path: PathBuf,
        /// What the file system said.
        reason: String,
    },
    /// The file grew beyond [`MAX_MODEL_BYTES`].
    #[error("model file {} is {bytes} bytes, more than the {MAX_MODEL_BYTES} served", path.display())]
    TooLarge {
        /// The configured path.
        path: PathBuf,
        /// Its size now.
        bytes: u64,
    },
    /// The file was replaced by something that is not a binary glTF container.
    #[error("model file {} is no longer a binary glTF file", path.display())]
    NoLongerGlb {
        /// The configured path.
        path: PathBuf,
    },
}

/// The subject id in a model request path (`/v1/subjects/{id}/model.glb`), or None when the
/// path is not one.
pub fn model_request(path: &str) -> Option<Result<u32, ModelError>> {
    let rest = path.strip_prefix("/v1/subjects/")?;
    let id = rest.strip_suffix("/model.glb")?;
    Some(id.parse::<u32>().map_err(|_| {
        ModelError::BadSubjectId(rigcast_protocol::control::short_prefix(id).into_owned())
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block_on<F: std::future::Future>(f: F) -> F::Output {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(f)
    }

    #[test]
    fn request_paths() {
        assert_eq!(model_request("/v1/subjects/3/model.glb"), Some(Ok(3)));
        assert!(matches!(
            model_request("/v1/subjects/x/model.glb"),
            Some(Err(_))
        ));
        assert!(matches!(
            model_request("/v1/subjects//model.glb"),
            Some(Err(_))
        ));
        assert_eq!(model_request("/v1/subjects/3/model.gltf"), None);
        assert_eq!(model_request("/v1/status"), None);
    }

    #[test]
    fn only_binary_gltf_containers_are_models() {
        let dir = std::env::temp_dir().join(format!("rigcast-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let glb = dir.join("a.glb");
        std::fs::write(&glb, b"glTF\x02\x00\x00\x00rest").unwrap();
        let vrm = dir.join("a.VRM");
        std::fs::write(&vrm, b"glTF\x02\x00\x00\x00rest").unwrap();
        let text = dir.join("b.glb");
        std::fs::write(&text, b"{\"asset\":{}}").unwrap();
        let gltf = dir.join("c.gltf");
        std::fs::write(&gltf, b"glTF").unwrap();
        assert_eq!(ModelFile::for_target(&glb).unwrap().format, "glb");
        assert_eq!(ModelFile::for_target(&vrm).unwrap().format, "vrm");
        assert_eq!(ModelFile::for_target(&text), None);
        assert_eq!(ModelFile::for_target(&gltf), None);
        assert_eq!(ModelFile::for_target(&dir.join("missing.glb")), None);
        let model = ModelFile::for_target(&glb).unwrap();
        assert!(block_on(model.open()).is_ok());
        std::fs::remove_file(&glb).unwrap();
        assert!(block_on(model.open())
            .unwrap_err()
            .to_string()
            .contains("a.glb"));
        // Cleanup only: a leftover temp directory does not change what the test proved.
        let _ = std::fs::remove_dir_all(&dir);
    }
}
