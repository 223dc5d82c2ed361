//! The mapper's cache of mapping tables, bounded in memory and on disk (least recently used
//! entries go first), so a sender churning skeletons cannot grow either without limit.
//!
//! ```text
//!  get: memory (LRU) ─miss─▶ DIR/KEY.json (decoded, mtime touched) ─miss─▶ None
//!  put: memory (evict LRU) ─▶ DIR/KEY.json only when its content changes
//!                           ─▶ more than max files in DIR? delete the oldest by mtime
//! ```

use std::path::PathBuf;
use std::sync::Arc;
use std::time::SystemTime;

use rigcast_retarget::mapping::{cache, CacheKey, MappingTable};

/// Default bound on cached tables (memory and disk each).
pub const DEFAULT_MAX_ENTRIES: usize = 128;

/// LRU-bounded mapping tables.
#[derive(Debug)]
pub struct MappingStore {
    /// (key, table, last use); linear scans are fine at this size and run off the tick.
    memory: Vec<(CacheKey, Arc<MappingTable>, u64)>,
    clock: u64,
    max_entries: usize,
    disk: Option<PathBuf>,
}

impl MappingStore {
    /// A store holding at most `max_entries` tables in memory and files in `disk`.
    pub fn new(disk: Option<PathBuf>, max_entries: usize) -> MappingStore {
        MappingStore {
            memory: Vec::new(),
            clock: 0,
            max_entries: max_entries.max(1),
            disk,
        }
    }

    /// Hands over the disk folder (to rebuild the store with another bound).
    pub fn take_disk(&mut self) -> Option<PathBuf> {
        self.disk.take()
    }

    /// Tables in memory.
    pub fn len_in_memory(&self) -> usize {
        self.memory.len()
    }

    fn path(&self, key: &CacheKey) -> Option<PathBuf> {
        self.disk
            .as_ref()
            .map(|d| d.join(format!("{}.json", key.file_stem())))
    }

    fn touch(&mut self) -> u64 {
        self.clock += 1;
        self.clock
    }

    /// The cached table for `key`, from memory or disk.
    pub fn get(&mut self, key: &CacheKey) -> Option<MappingTable> {
        let now = self.touch();
        if let Some(entry) = self.memory.iter_mut().find(|(k, _, _)| k == key) {
            entry.2 = now;
            return Some((*entry.1).clone());
        }
        let path = self.path(key)?;
        let table = cache::decode(&std::fs::read_to_string(&path).ok()?, key)?;
        // Recently used on disk too, so pruning keeps it.
        let _ = std::fs::File::options()
            .write(true)
            .open(&path)
            .and_then(|f| f.set_modified(SystemTime::now()));
        self.remember(key.clone(), Arc::new(table.clone()));
        Some(table)
    }

    /// Stores `table` under `key`. Disk errors only cost a re-map later.
    pub fn put(&mut self, key: CacheKey, table: MappingTable) {
        let unchanged = self
            .memory
            .iter()
            .any(|(k, t, _)| *k == key && **t == table);
        self.remember(key.clone(), Arc::new(table.clone()));
        let Some(path) = self.path(&key) else {
            return;
        };
        let text = cache::encode(&key, &table);
        if unchanged && std::fs::read_to_string(&path).is_ok_and(|old| old == text) {
            return;
        }
        let written = path
            .parent()
            .map(std::fs::create_dir_all)
            .transpose()
            .and_then(|_| std::fs::write(&path, text));
        if written.is_ok() {
            self.prune_disk();
        }
    }

    fn remember(&mut self, key: CacheKey, table: Arc<MappingTable>) {
        let now = self.touch();
        if let Some(entry) = self.memory.iter_mut().find(|(k, _, _)| *k == key) {
            *entry = (key, table, now);
            return;
        }
        if self.memory.len() >= self.max_entries {
            if let Some(oldest) = self
                .memory
                .iter()
                .enumerate()
                .min_by_key(|(_, (_, _, used))| *used)
                .map(|(i, _)| i)
            {
                self.memory.swap_remove(oldest);
            }
        }
        self.memory.push((key, table, now));
    }

    /// Deletes the least recently used cache files beyond the bound.
    fn prune_disk(&self) {
        let Some(dir) = &self.disk else { return };
        let Ok(read) = std::fs::read_dir(dir) else {
            return;
        };
        let mut files: Vec<(SystemTime, PathBuf)> = read
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
            .collect();
        if files.len() <= self.max_entries {
            return;
        }
        files.sort();
        for (_, p) in &files[..files.len() - self.max_entries] {
            // Nothing there to remove is fine.
            let _ = std::fs::remove_file(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_retarget::mapping::MapOptions;
    use rigcast_retarget::{RawSkeleton, Skeleton, Transform};

    fn skeleton(n: usize) -> Skeleton {
        let mut raw = RawSkeleton::default();
        let mut parent = None;
        for i in 0..n {
            parent = Some(raw.add(
                format!("b{i}"),
                parent,
                Transform::from_translation(glam::Vec3::Y * 0.1),
            ));
        }
        Skeleton::build(&raw).unwrap()
    }

    #[test]
    fn bounded_in_memory_and_on_disk() {
        let dir = std::env::temp_dir().join(format!("rigcast-store-{}", std::process::id()));
        // Nothing there to remove is fine.
        let _ = std::fs::remove_dir_all(&dir);
        let mut store = MappingStore::new(Some(dir.clone()), 3);
        let target = skeleton(2);
        let keys: Vec<CacheKey> = (1..=6)
            .map(|n| CacheKey::new(&[&skeleton(n)], &target, &MapOptions::default()))
            .collect();
        let table = MappingTable::empty;
        for (i, k) in keys.iter().enumerate() {
            store.put(k.clone(), table(i + 1));
            // Distinct modification times for the pruning order.
            std::thread::sleep(std::time::Duration::from_millis(15));
        }
        assert_eq!(store.len_in_memory(), 3);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 3);
        // The newest survive, the oldest are gone from both.
        assert_eq!(store.get(&keys[5]), Some(table(6)));
        let mut fresh = MappingStore::new(Some(dir.clone()), 3);
        assert!(fresh.get(&keys[0]).is_none());
        assert_eq!(fresh.get(&keys[3]), Some(table(4)));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
