//! `dmu farfield build` and `dmu walk --render --compare --far-field`: far
//! fields written into a store, read back by a walk that reports each
//! frame's pixels against the exact image. Included from `tests.rs`.

use serde_json::Value;

use super::{generated_plant, on_gpu};

/// `dmu farfield build`'s options in these tests: the cells along frames
/// 300..306 of the built-in walk, small cells, small cull boxes and captures.
const BUILD: [&str; 9] = [
    "--along-walk",
    "--range",
    "300..306",
    "--cell-size",
    "4000",
    "--triangle-budget",
    "20k",
    "--resolution",
    "128",
];

/// Far fields built along a stretch of the built-in walk are stored (the
/// store still opens, with its far fields counted), a walk over that
/// stretch draws them in every frame with fewer chunk triangles than
/// without, and reports its pixels against the exact image; a store
/// without far fields is refused by `--far-field on` with the command that
/// makes them.
#[test]
fn far_fields_are_built_into_the_store_and_drawn_by_a_walk() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let store = generated_plant(dir.path(), "200k");
        let walk = [
            store.as_str(),
            "--render",
            "--compare",
            "--far-field",
            "on",
            "--culling",
            "frustum",
            "--range",
            "300..306",
            "--width",
            "320",
            "--height",
            "180",
            "--json",
        ];
        let out = on_gpu("walk", &walk);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("dmu farfield build"), "{err}");

        let mut build = vec!["build", store.as_str()];
        build.extend(BUILD);
        build.push("--json");
        let out = on_gpu("farfield", &build);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let built: Value = serde_json::from_slice(&out.stdout).unwrap();
        let cells = built["cells"].as_u64().unwrap();
        assert!(cells >= 1, "{built:#}");
        for c in built["per_cell"].as_array().unwrap() {
            assert!(c["near_triangles"].as_u64().unwrap() <= 20_000, "{c:#}");
            assert!(c["far_triangles"].as_u64().unwrap() > 0, "{c:#}");
        }

        let out = on_gpu("walk", &walk);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let names: Vec<&str> = v["totals"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["culling"].as_str().unwrap())
            .collect();
        assert_eq!(names, ["frustum", "frustum", "frustum+far"]);
        let far = &v["far_field"];
        assert_eq!(far["cells"].as_u64(), Some(cells));
        let mode = &far["modes"][0];
        assert_eq!(mode["frames_with_far_field"], 6, "{far:#}");
        let worst = mode["far_field_differing_pixels_worst"].as_f64().unwrap();
        assert!(worst > 0.0 && worst < 0.5 * 320.0 * 180.0, "{far:#}");
        assert!(mode["median_frame_ms"].as_f64().unwrap() > 0.0);
        for (i, f) in v["per_frame"].as_array().unwrap().iter().enumerate() {
            let (without, with) = (&f["modes"][1], &f["modes"][2]);
            assert_eq!(with["far_field"], true, "frame {i}");
            assert!(
                with["triangles_drawn"].as_u64() < without["triangles_drawn"].as_u64(),
                "frame {i}: {f:#}"
            );
        }

        // The reference drawn on every third frame only: the other modes are
        // still timed on all six, and compared on frames 0 and 3 with the same
        // counts as when the reference is drawn on every frame.
        let sampled: Vec<&str> = walk
            .iter()
            .copied()
            .chain(["--reference-every", "3"])
            .collect();
        let out = on_gpu("walk", &sampled);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let s: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(s["reference_every"], 3);
        assert_eq!(v["reference_every"], 1);
        let (all, some) = (
            v["per_frame"].as_array().unwrap(),
            s["per_frame"].as_array().unwrap(),
        );
        assert_eq!(all.len(), 6);
        assert_eq!(some.len(), 6);
        let mut compared_differing = 0;
        for (i, (a, f)) in all.iter().zip(some).enumerate() {
            assert_eq!(f["modes"][0].is_null(), i % 3 != 0, "frame {i}: {f:#}");
            assert_eq!(f["modes"][2]["far_field"], true, "frame {i}");
            let expected = if i % 3 == 0 {
                compared_differing +=
                    u64::from(a["modes"][2]["differing_pixels"].as_u64() > Some(0));
                a["modes"][2]["differing_pixels"].clone()
            } else {
                Value::Null
            };
            assert_eq!(f["modes"][2]["differing_pixels"], expected, "frame {i}");
        }
        assert_eq!(
            s["totals"][2]["frames_with_differing_pixels"].as_u64(),
            Some(compared_differing)
        );
        // The reference's name is the culling's here: the far field's speed-up
        // is taken against the culling without far fields (all six frames; the
        // report's median is the value at rank round(5 / 2)), not the reference.
        let median = |m: usize| {
            let mut ms: Vec<f64> = some
                .iter()
                .map(|f| f["modes"][m]["frame_ms"].as_f64().unwrap())
                .collect();
            ms.sort_by(f64::total_cmp);
            ms[3]
        };
        let speedup = s["far_field"]["modes"][0]["without_over_with_median_frame_time"]
            .as_f64()
            .unwrap();
        assert!(
            (speedup - median(1) / median(2)).abs() <= 1e-9 * speedup,
            "{speedup} against {}",
            median(1) / median(2)
        );

        // Auto: the six frames are its probe (three without, three with, the
        // first of each untimed); it says what it chose and the times behind it.
        let auto: Vec<&str> = walk
            .iter()
            .map(|&a| if a == "on" { "auto" } else { a })
            .chain(["--explain"])
            .collect();
        let out = on_gpu("walk", &auto);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["totals"][2]["culling"], "frustum+far-auto");
        let explain: Vec<&str> = v["explain"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|l| l.as_str())
            .filter(|l| l.contains("far field"))
            .collect();
        assert_eq!(explain.len(), 1, "{:#}", v["explain"]);
        assert!(explain[0].contains("ms a frame with it"), "{}", explain[0]);
        let with: Vec<bool> = v["per_frame"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["modes"][2]["far_field"].as_bool().unwrap())
            .collect();
        assert_eq!(with, [false, false, false, true, true, true]);
    });
}

/// Cells built by shards (`--shard K/N --cells-out`) are written by
/// `--cells-from` only into the model they were built from: after a part
/// moved, the folder is refused in one line naming the shard's record.
#[test]
fn shard_cells_of_another_model_version_are_refused() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let store = generated_plant(dir.path(), "200k");
        let cells = dir.path().join("cells").to_string_lossy().into_owned();
        let run = |extra: &[&str]| {
            let mut args = vec!["build", store.as_str()];
            args.extend(BUILD);
            args.extend(extra);
            on_gpu("farfield", &args)
        };
        let out = run(&["--shard", "0/1", "--cells-out", &cells]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );

        let out = super::dmu(&[
            "move",
            &store,
            "--part",
            "#0",
            "--translate",
            "10,0,0",
            "-o",
            &store,
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = run(&["--cells-from", &cells]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success()
                && err.contains("shard-0.json")
                && err.contains("another version")
                && err.lines().count() == 1,
            "{err}"
        );
    });
}
