//! Bone mapping: which source bone(s) drive each target bone.
//!
//! ```text
//!   (source Skeleton, target Skeleton, options, overrides)
//!        │  automatic mapping (analysis + weighted metrics)    [issue: automatic mapping]
//!        ▼
//!   MappingTable: per target bone → source bone(s) with weights and per-bone options
//! ```
//!
//! [`MappingTable`] is plain data: it is what mapping files and the on-disk cache store and what
//! clients display and edit. Turning a table into something that retargets poses every frame
//! (rest alignment precomputed) is the retargeting stage's job.

mod auto;
pub mod cache;
mod candidate;
mod colors;
mod confidence;
pub mod file;
mod posture;
mod table;

pub use auto::{auto_map, auto_map_many, map_analyzed, MapOptions, Weights};
pub use cache::{CacheKey, MappingCache};
pub use colors::{mapping_colors, BoneColors, UNMAPPED};
pub use file::{
    apply_overrides, parse_mapping_file, to_mapping_file, MappingFile, MappingFileError,
};
pub use posture::{posture_relative, Follow};
pub use table::{BoneOptions, Flag, MappingTable, SourceRef, TargetEntry};
