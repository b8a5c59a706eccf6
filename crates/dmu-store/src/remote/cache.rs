//! The read-through cache of remote objects on local disk: one file per
//! block (`objects/KEY/N.blk`), the block's bytes after their xxh3-64, under
//! a key made of the object's address, version and length. Least recently
//! used blocks (by file time, touched on every hit) are removed when the
//! cache passes its budget, down to three quarters of it.
//!
//! A block is written to a temporary name and renamed into place, but not
//! synced: a block torn by a crash fails its checksum on the next read and
//! is fetched again ([`Damaged`]), so the cache never needs the cost of a
//! sync per block; it holds nothing that is not also on the server.

use std::collections::HashSet;
use std::fs::File;
use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex, PoisonError};
use std::time::SystemTime;

use xxhash_rust::xxh3::{xxh3_64, xxh3_128};

/// A cached block whose bytes do not match their checksum (it has been
/// removed).
#[derive(Debug)]
pub(crate) struct Damaged;

/// The blocks of one object version.
#[derive(Debug)]
pub(crate) struct BlockCache {
    /// This object's folder.
    dir: PathBuf,
    /// The cache's `objects` folder (all objects: the budget is shared).
    objects: PathBuf,
    budget: u64,
    /// Bytes in the cache as this process last counted them, plus what it
    /// wrote since.
    used: AtomicU64,
    evicting: Mutex<()>,
    /// Blocks a reader of this process is fetching ([`BlockCache::claim`]).
    claims: Mutex<HashSet<u64>>,
    released: Condvar,
}

/// Blocks claimed for fetching by one reader; released (and waiting
/// readers woken) on drop.
pub(crate) struct Claim<'a> {
    cache: &'a BlockCache,
    blocks: Vec<u64>,
}

impl Drop for Claim<'_> {
    fn drop(&mut self) {
        let mut claims = self
            .cache
            .claims
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        for b in &self.blocks {
            claims.remove(b);
        }
        self.cache.released.notify_all();
    }
}

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl BlockCache {
    /// The cache in `root` for the object `identity` names (address,
    /// version and length).
    pub fn open(root: &Path, budget: u64, identity: &str) -> std::io::Result<Self> {
        let objects = root.join("objects");
        let dir = objects.join(format!("{:032x}", xxh3_128(identity.as_bytes())));
        std::fs::create_dir_all(&dir).map_err(|e| {
            std::io::Error::new(e.kind(), format!("the cache folder {}: {e}", dir.display()))
        })?;
        let cache = Self {
            dir,
            objects,
            budget,
            used: AtomicU64::new(0),
            evicting: Mutex::new(()),
            claims: Mutex::new(HashSet::new()),
            released: Condvar::new(),
        };
        let used = cache.blocks().iter().map(|b| b.1).sum();
        cache.used.store(used, Ordering::Relaxed);
        // A smaller budget than the cache was filled under holds from now.
        if used > budget {
            cache.evict();
        }
        Ok(cache)
    }

    fn path(&self, block: u64) -> PathBuf {
        self.dir.join(format!("{block}.blk"))
    }

    /// Block `block` if cached with all its `len` bytes intact; a damaged
    /// one is removed.
    pub fn get(&self, block: u64, len: u64) -> Result<Option<Vec<u8>>, Damaged> {
        let path = self.path(block);
        let Ok(mut file) = File::open(&path) else {
            return Ok(None);
        };
        let mut bytes = Vec::new();
        let intact = file.read_to_end(&mut bytes).is_ok()
            && bytes.len() as u64 == len + 8
            && bytes[..8] == xxh3_64(&bytes[8..]).to_le_bytes();
        if !intact {
            if std::fs::remove_file(&path).is_ok() {
                let size = bytes.len() as u64;
                let _ = self
                    .used
                    .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |u| {
                        Some(u.saturating_sub(size))
                    });
            }
            return Err(Damaged);
        }
        // Used now: the last to be evicted.
        let _ = file.set_modified(SystemTime::now());
        bytes.drain(..8);
        Ok(Some(bytes))
    }

    /// Claims `blocks` for fetching, first waiting while another reader
    /// fetches any of them (so a block is fetched once however many loaders
    /// want it at once); look in the cache again after.
    pub fn claim(&self, blocks: Vec<u64>) -> Claim<'_> {
        let mut claims = self.claims.lock().unwrap_or_else(PoisonError::into_inner);
        while blocks.iter().any(|b| claims.contains(b)) {
            claims = self
                .released
                .wait(claims)
                .unwrap_or_else(PoisonError::into_inner);
        }
        claims.extend(&blocks);
        Claim {
            cache: self,
            blocks,
        }
    }

    /// Keeps `bytes` as block `block`. A failure to write (a full disk) is
    /// not an error: the block is simply not cached.
    pub fn put(&self, block: u64, bytes: &[u8]) {
        let temp = self.dir.join(format!(
            ".{block}.tmp{}-{}",
            std::process::id(),
            TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let written = File::create(&temp).and_then(|mut f| {
            f.write_all(&xxh3_64(bytes).to_le_bytes())?;
            f.write_all(bytes)
        });
        if written
            .and_then(|()| std::fs::rename(&temp, self.path(block)))
            .is_err()
        {
            let _ = std::fs::remove_file(&temp);
            return;
        }
        let used = self
            .used
            .fetch_add(bytes.len() as u64 + 8, Ordering::Relaxed);
        if used + bytes.len() as u64 > self.budget {
            self.evict();
        }
    }

    /// Every block file in the cache (all objects): path, bytes, last use.
    fn blocks(&self) -> Vec<(PathBuf, u64, SystemTime)> {
        let mut out = Vec::new();
        let Ok(objects) = std::fs::read_dir(&self.objects) else {
            return out;
        };
        for object in objects.flatten() {
            let Ok(files) = std::fs::read_dir(object.path()) else {
                continue;
            };
            for file in files.flatten() {
                if let Ok(meta) = file.metadata()
                    && meta.is_file()
                {
                    let used = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
                    out.push((file.path(), meta.len(), used));
                }
            }
        }
        out
    }

    /// Removes the least recently used blocks until the cache holds three
    /// quarters of its budget.
    fn evict(&self) {
        let Ok(_one_at_a_time) = self.evicting.try_lock() else {
            return;
        };
        let mut blocks = self.blocks();
        let mut used: u64 = blocks.iter().map(|b| b.1).sum();
        blocks.sort_by_key(|b| b.2);
        let target = self.budget / 4 * 3;
        for (path, bytes, _) in blocks {
            if used <= target {
                break;
            }
            if std::fs::remove_file(&path).is_ok() {
                used -= bytes;
            }
        }
        self.used.store(used, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_round_trip_are_checked_and_the_least_recent_go_first() {
        let root = tempfile::tempdir().unwrap();
        let cache = BlockCache::open(root.path(), 4000, "s3://b/k\n\"e1\"\n9999").unwrap();
        assert!(cache.get(0, 1000).unwrap().is_none());
        cache.put(0, &[1; 1000]);
        assert_eq!(cache.get(0, 1000).unwrap().unwrap(), vec![1; 1000]);
        // Another version of the object is another key: nothing mixes.
        let other = BlockCache::open(root.path(), 4000, "s3://b/k\n\"e2\"\n9999").unwrap();
        assert!(other.get(0, 1000).unwrap().is_none());

        // A flipped byte is found, and the block is dropped.
        let path = cache.path(0);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[500] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert!(cache.get(0, 1000).is_err());
        assert!(!path.exists());
        // A block of the wrong length likewise.
        cache.put(1, &[2; 10]);
        assert!(cache.get(1, 1000).is_err());

        // Over budget: the least recently used go, the one just read stays.
        for b in 2..5 {
            cache.put(b, &[b as u8; 1000]);
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(cache.get(2, 1000).unwrap().is_some());
        cache.put(5, &[5; 1000]);
        let kept: Vec<u64> = (2..6)
            .filter(|&b| cache.get(b, 1000).unwrap().is_some())
            .collect();
        assert!(kept.contains(&2) && kept.contains(&5), "{kept:?}");
        assert!(kept.len() <= 3, "{kept:?}");
        assert!(cache.used.load(Ordering::Relaxed) <= 3000);
    }
}
