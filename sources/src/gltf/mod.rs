//! glTF 2.0 / GLB / VRM reading and GLB writing.
//!
//! ```text
//!  .gltf/.glb/.vrm ──read_gltf──▶ GltfRead { clip, animations, vrm_roles }
//!        first skin's joints (or VRM humanoid nodes) → Skeleton (depth-first)
//!        node TRS → rest; channels sampled at a fixed rate → poses
//!  Clip ──write_glb──▶ .glb (nodes + skin + one LINEAR animation)
//!  Clip + GltfTemplate ──write_glb_onto──▶ the character's own document, new animation
//! ```

mod buffers;
mod onto;
mod read;
mod sample;
mod tolerate;
mod vrm;
mod write;

pub use buffers::MAX_BUFFER_BYTES;
pub use onto::write_glb_onto;
pub use read::{
    read_gltf, AnimationInfo, GltfRead, GltfReadOptions, GltfTemplate, SkeletonOrigin,
    DEFAULT_SAMPLE_FPS,
};
pub use sample::{Interpolation, Track};
pub use tolerate::{MAX_ERROR_CHARS, MESH_ONLY_EXTENSIONS};
pub use vrm::VrmVersion;
pub use write::write_glb;

#[cfg(test)]
mod tests;
