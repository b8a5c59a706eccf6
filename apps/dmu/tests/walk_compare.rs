//! `dmu walk --render --compare`: every culling mode over the same frames,
//! each image against the unculled one, the occlusion modes' chunks against
//! the exactly visible ones. Included from `tests.rs`.

use serde_json::Value;

use super::{dmu, on_gpu, path};

/// With LODs off, `hzb` draws the unculled image at every frame of the walk,
/// misses no exactly visible chunk, and the report carries its ratios.
#[test]
fn walk_compare_reports_hzb_beside_the_other_modes_exact_at_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let store = path(dir.path(), "p.dmu");
    let out = dmu(&["generate", "plant", "--triangles", "100k", "-o", &store]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
    let Some(out) = on_gpu("walk_compare_reports_hzb", "walk", &args) else {
        return;
    };
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
}
