//! Mapping cache: keys and (de)serialisation only — no IO here (the CLI and server own the
//! directory). Also an in-memory cache for reconnecting sources.
//!
//! A key combines every source skeleton's fingerprint, the target's fingerprint, the options'
//! stable hash and a format version, so a changed skeleton or option simply misses. A cached
//! entry embeds its key, so a renamed or stale file is detected on decode.

use std::collections::HashMap;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::auto::MapOptions;
use super::table::MappingTable;
use crate::skeleton::Skeleton;

/// Bumped whenever the mapper's behaviour changes, so old cache entries miss.
/// 2: a skull-top leaf (`head_top`) is the head's end marker, not the head (issue 3).
/// 3: names as evidence, the facing vote's strength, confidences and flags (issue 31).
/// 4: a helper above the hips maps only onto a helper above the other rig's hips (issue 35).
pub const CACHE_FORMAT: u32 = 4;

/// Identity of one mapping computation.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CacheKey {
    /// Fingerprints of the source skeletons, in input order.
    pub sources: Vec<u64>,
    /// Fingerprint of the target skeleton.
    pub target: u64,
    /// [`MapOptions::stable_hash`].
    pub options: u64,
    /// [`CACHE_FORMAT`].
    pub format: u32,
}

impl CacheKey {
    /// The key for mapping `sources` onto `target` with `opts`.
    pub fn new(sources: &[&Skeleton], target: &Skeleton, opts: &MapOptions) -> CacheKey {
        CacheKey {
            sources: sources.iter().map(|s| s.fingerprint()).collect(),
            target: target.fingerprint(),
            options: opts.stable_hash(),
            format: CACHE_FORMAT,
        }
    }

    /// A file-name-safe form, e.g. `v1-1a2b…_3c4d…-to-5e6f…-o7a8b…`.
    pub fn file_stem(&self) -> String {
        let src: Vec<String> = self.sources.iter().map(|f| format!("{f:016x}")).collect();
        format!(
            "v{}-{}-to-{:016x}-o{:016x}",
            self.format,
            src.join("_"),
            self.target,
            self.options
        )
    }
}

#[derive(Serialize, Deserialize)]
struct CacheFile {
    key: CacheKey,
    table: MappingTable,
}

/// Serialises a table with its key (JSON).
pub fn encode(key: &CacheKey, table: &MappingTable) -> String {
    serde_json::to_string(&CacheFile {
        key: key.clone(),
        table: table.clone(),
    })
    .unwrap_or_default()
}

/// Decodes a cache entry; `None` when it is unreadable or was made for a different key.
pub fn decode(text: &str, expected: &CacheKey) -> Option<MappingTable> {
    let f: CacheFile = serde_json::from_str(text).ok()?;
    (f.key == *expected).then_some(f.table)
}

/// In-memory cache of mapping tables (what a server keeps for reconnecting sources).
#[derive(Debug, Default)]
pub struct MappingCache {
    tables: HashMap<CacheKey, Arc<MappingTable>>,
}

impl MappingCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The cached table for `key`, if any.
    pub fn get(&self, key: &CacheKey) -> Option<Arc<MappingTable>> {
        self.tables.get(key).cloned()
    }

    /// Stores a table.
    pub fn insert(&mut self, key: CacheKey, table: MappingTable) -> Arc<MappingTable> {
        let t = Arc::new(table);
        self.tables.insert(key, t.clone());
        t
    }

    /// The cached table, or computes it with `compute` and caches it.
    pub fn get_or_insert_with(
        &mut self,
        key: CacheKey,
        compute: impl FnOnce() -> MappingTable,
    ) -> Arc<MappingTable> {
        if let Some(t) = self.tables.get(&key) {
            return t.clone();
        }
        self.insert(key, compute())
    }

    /// Number of cached tables.
    pub fn len(&self) -> usize {
        self.tables.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.tables.is_empty()
    }
}
