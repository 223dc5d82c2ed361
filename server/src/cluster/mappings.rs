//! The mapping cache shared through the cluster: the automatic mapper's table for a
//! (sources, target, options) key, computed once on whichever node first needs it, is put in
//! the KV bucket `{ns}_mappings` under the same key as the on-disk cache's file name, and any
//! other node building the same pair takes it from there instead of recomputing.
//!
//! ```text
//!  mapper: memory ▸ disk ▸ KV {ns}_mappings/KEY ▸ automatic mapper ─▶ KV put
//! ```
//!
//! The mapper runs on its own thread off the tick, so it waits for NATS here (at most
//! [`KV_TIMEOUT`] per call); an unreachable bucket costs a local computation, never an error.
//! Only automatic tables are shared: mapping files and `set_mapping` overrides stay with the
//! node whose performer they belong to.

use crate::stats::MappingShareCounts;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use async_nats::jetstream::kv;
use rigcast_retarget::mapping::{cache, CacheKey, MappingTable};

/// Longest one bucket read or write may hold the mapper.
pub const KV_TIMEOUT: Duration = Duration::from_secs(1);

/// The mapper's handle on the shared cache.
pub struct SharedMappings {
    kv: kv::Store,
    runtime: tokio::runtime::Handle,
    counts: Arc<MappingShareCounts>,
}

impl SharedMappings {
    /// The cache in bucket `kv`, reached through `runtime` from the mapper's thread.
    pub fn new(
        kv: kv::Store,
        runtime: tokio::runtime::Handle,
        counts: Arc<MappingShareCounts>,
    ) -> SharedMappings {
        SharedMappings {
            kv,
            runtime,
            counts,
        }
    }

    /// The table another node computed for `key`, if any (call off the async runtime).
    pub fn get(&self, key: &CacheKey) -> Option<MappingTable> {
        // The timeout is made inside `block_on`: its timer needs the runtime's context, which
        // the mapper's own thread does not have.
        let read = async { tokio::time::timeout(KV_TIMEOUT, self.kv.get(key.file_stem())).await };
        let bytes = self.runtime.block_on(read).ok()?.ok()??;
        let table = cache::decode(std::str::from_utf8(&bytes).ok()?, key)?;
        self.counts.fetched.fetch_add(1, Ordering::Relaxed);
        Some(table)
    }

    /// Offers `table`, computed here for `key`, to the other nodes (call off the runtime).
    pub fn put(&self, key: &CacheKey, table: &MappingTable) {
        let value = cache::encode(key, table).into_bytes();
        let write = async {
            tokio::time::timeout(KV_TIMEOUT, self.kv.put(key.file_stem(), value.into())).await
        };
        if let Ok(Ok(_)) = self.runtime.block_on(write) {
            self.counts.shared.fetch_add(1, Ordering::Relaxed);
        }
    }
}
