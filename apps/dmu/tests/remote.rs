//! `dmu` against a real S3 server (SeaweedFS, see `dmu_testkit::weed`): an
//! import written to `s3://`, and a walk read from it that equals the local
//! file's, frame for frame, fetching nothing the second time (`--cache-dir`).

use std::process::{Command, Output};

use dmu_testkit::require;
use dmu_testkit::weed::Weed;
use serde_json::Value;

use crate::{json, path};

/// `dmu ARGS` reaching `weed`.
fn dmu_s3(weed: &Weed, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dmu"))
        .args(args)
        .env("AWS_ENDPOINT_URL", &weed.endpoint)
        .env_remove("AWS_ACCESS_KEY_ID")
        .env("DMU_CACHE_DIR", weed.cache.path().join("default"))
        .output()
        .expect("run dmu")
}

#[test]
fn an_import_to_s3_walks_as_the_local_file_and_a_second_walk_fetches_nothing() {
    require(Weed::new(), |weed| {
        let dir = tempfile::tempdir().unwrap();
        let glb = path(dir.path(), "p.glb");
        let local = path(dir.path(), "p.dmu");
        let cache = path(weed.cache.path(), "walks");
        let out = dmu_s3(
            &weed,
            &["generate", "plant", "--triangles", "150k", "-o", &glb],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = dmu_s3(&weed, &["import", &glb, "-o", "s3://models/p.dmu"]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // The same bytes as a local file: the oracle.
        std::fs::write(&local, weed.get("p.dmu")).unwrap();

        let walk = |file: &str| {
            let args = [
                "--cache-dir",
                &cache,
                "walk",
                file,
                "--memory-budget",
                "10%",
                "--range",
                "0..120",
                "--json",
            ];
            json(&dmu_s3(&weed, &args))
        };
        let frames = |report: &Value| report["walks"][0]["frames"].clone();
        let same = |a: &Value, b: &Value| {
            let (a, b) = (frames(a), frames(b));
            let differ = (0..a.as_array().unwrap().len()).find(|&i| a[i] != b[i]);
            assert!(
                differ.is_none(),
                "frame {differ:?}: {} against {}",
                a[differ.unwrap_or(0)],
                b[differ.unwrap_or(0)]
            );
        };
        let remote = |report: &Value| report["walks"][0]["remote"].clone();
        let on_disk = walk(&local);
        assert!(remote(&on_disk).is_null());
        let cold = walk("s3://models/p.dmu");
        same(&cold, &on_disk);
        assert!(remote(&cold)["bytes_fetched"].as_u64().unwrap() > 0);
        let warm = walk("s3://models/p.dmu");
        same(&warm, &on_disk);
        assert_eq!(remote(&warm)["bytes_fetched"], 0, "{}", remote(&warm));
        assert_eq!(remote(&warm)["requests"], 1);
        // The cache went where --cache-dir said, not to the default.
        assert!(std::fs::read_dir(&cache).unwrap().count() > 0);
        assert!(!weed.cache.path().join("default").join("objects").exists());

        // An http(s) address is read only: writing there is one line.
        let out = dmu_s3(
            &weed,
            &["import", &glb, "-o", "http://127.0.0.1:8888/p.dmu"],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("s3://") && err.lines().count() == 1,
            "{err}"
        );
    });
}
