//! `dmu walk --render --compare`: every culling mode over the same frames,
//! each image against the unculled one, the occlusion modes' chunks against
//! the exactly visible ones; and `dmu walk --render` within a memory budget.
//! Included from `tests.rs`.

use serde_json::Value;

use super::{generated_plant, on_gpu};

/// With LODs off, `hzb` draws the unculled image at every frame of the walk,
/// misses no exactly visible chunk, and the report carries its ratios.
#[test]
fn walk_compare_reports_hzb_beside_the_other_modes_exact_at_every_frame() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let store = generated_plant(dir.path(), "100k");
        let args = [
            store.as_str(),
            "--render",
            "--compare",
            "--range",
            "300..308",
            "--width",
            "320",
            "--height",
            "180",
            "--lod-error-px",
            "0",
            "--json",
        ];
        let out = on_gpu("walk", &args);
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
        assert_eq!(names, ["none", "frustum", "chc", "hzb"]);
        let hzb = &v["totals"][3];
        assert_eq!(hzb["frames_with_differing_pixels"], 0, "{hzb:#}");
        assert!(hzb["median_frame_ms"].as_f64().unwrap() > 0.0);
        assert!(v["chc_over_hzb_frame_time"].as_f64().unwrap() > 0.0);
        assert_eq!(v["hzb_chunks_more_than_one_frame_late"], 0);
        for (i, f) in v["per_frame"].as_array().unwrap().iter().enumerate() {
            assert_eq!(f["hzb_missing_chunks"], 0, "frame {i}");
            assert_eq!(f["modes"][3]["culling"], "hzb", "frame {i}");
        }
    });
}

/// `dmu walk --render` within a memory budget on the 100k plant: from a cold
/// start (`--opening-frames 0`) the first frames want chunks that are not
/// resident. Without stand-ins they are holes; with them (the default) no
/// frame has a hole and the cold frames draw boxes instead, while the
/// residency keeps to its budget. The prediction (on by default) draws two
/// more views every frame but the first: 100 ms ahead and the next frame's.
/// With the opening frames (the default), the walk starts from a first view
/// that misses nothing.
#[test]
fn walk_within_a_budget_draws_stand_ins_not_holes() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let store = generated_plant(dir.path(), "100k");
        let run = |budget: &str, extra: &[&str]| -> Value {
            let mut args = vec![
                store.as_str(),
                "--render",
                "--memory-budget",
                budget,
                "--range",
                "300..330",
                "--warmup-frames",
                "0",
                "--width",
                "320",
                "--height",
                "180",
                "--json",
            ];
            args.extend_from_slice(extra);
            let out = on_gpu("walk", &args);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            serde_json::from_slice(&out.stdout).unwrap()
        };
        let holes = run(
            "20%",
            &[
                "--stand-ins",
                "none",
                "--predict-ms",
                "0",
                "--no-predict-next",
                "--opening-frames",
                "0",
            ],
        );
        let boxes = run("20%", &["--opening-frames", "0"]);
        // The first view fits in half the geometry, not in a fifth.
        let cold = run("50%", &["--opening-frames", "0"]);
        let opened = run("50%", &[]);
        let (h, b) = (&holes["render"], &boxes["render"]);
        // Without stand-ins the cold start shows holes, and nothing stands in.
        assert!(h["frames_with_hole"].as_u64().unwrap() > 0, "{h:#}");
        assert_eq!(h["frames_with_standin"], 0);
        assert_eq!(h["prediction"]["median_frame_ms"], Value::Null);
        // With them, no hole in any frame; the first frame (nothing resident)
        // draws boxes only.
        assert_eq!(b["frames_with_hole"], 0, "{b:#}");
        assert_eq!(b["holes"], 0);
        let frames = b["per_frame_residency"].as_array().unwrap();
        assert_eq!(frames.len(), 30);
        assert!(frames.iter().all(|f| f["holes"] == 0));
        let first_drawn = b["per_frame"][0]["chunks_drawn"].as_u64().unwrap();
        assert!(first_drawn > 0);
        assert_eq!(frames[0]["stand_ins"].as_u64(), Some(first_drawn));
        assert!(b["frames_with_standin"].as_u64().unwrap() >= 1);
        // A miss is a hole or a stand-in: the walk counts either.
        let missing: u64 = boxes["walk"]["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["missing_chunks"].as_u64().unwrap())
            .sum();
        assert_eq!(missing, b["stand_ins_drawn"].as_u64().unwrap());
        // The predicted views (100 ms ahead and the next frame's, the
        // defaults) ran on every frame after the first.
        assert_eq!(b["prediction"]["ahead_ms"], 100.0);
        assert_eq!(b["prediction"]["next_frame"], true);
        assert_eq!(frames[0]["ahead_ms"], Value::Null);
        assert!(
            frames[1..]
                .iter()
                .all(|f| f["ahead_ms"].as_f64().unwrap() > 0.0)
        );
        assert_eq!(boxes["walk"]["opening"]["frames"], 0);
        // Opened: frames at the first view until one missed nothing, not counted
        // among the walk's; its first frame, seen from there, misses nothing.
        let opening = &opened["walk"]["opening"];
        let n = opening["frames"].as_u64().unwrap();
        assert!(n >= 1, "{opening:#}");
        assert_eq!(opening["missing_chunks"], 0, "{opening:#}");
        assert!(opening["loaded_bytes"].as_u64().unwrap() > 0);
        let o = &opened["render"];
        assert_eq!(o["per_frame_residency"].as_array().unwrap().len(), 30);
        assert_eq!(o["per_frame_residency"][0]["stand_ins"], 0, "{o:#}");
        assert_eq!(o["frames_with_hole"], 0);
        let c = &cold["render"];
        assert!(c["per_frame_residency"][0]["stand_ins"].as_u64().unwrap() > 0);
        assert!(
            o["frames_with_standin"].as_u64().unwrap() < c["frames_with_standin"].as_u64().unwrap(),
            "opened {} against {}",
            o["frames_with_standin"],
            c["frames_with_standin"]
        );
        for walk in [
            &holes["walk"]["total"],
            &boxes["walk"]["total"],
            &cold["walk"]["total"],
            &opened["walk"]["total"],
        ] {
            assert!(
                walk["peak_resident_bytes"].as_u64().unwrap()
                    <= walk["budget_bytes"].as_u64().unwrap()
            );
        }
    });
}
