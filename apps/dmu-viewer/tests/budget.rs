//! `--memory-budget`: the viewer on a store's skeleton, its chunks streamed
//! through the residency manager, stand-ins for what is not loaded yet, picks
//! and checks loading the meshes they read; and a store damaged on disk.

use std::process::Command;

use serde_json::{Value, json};

use crate::support::{dmu, viewer, with_viewer};
use crate::xvfb::{PLANT, path_str, step};

/// A store of the tests' plant in `dir`.
fn plant_store(dir: &std::path::Path) -> std::path::PathBuf {
    let store = dir.join("plant.dmu");
    dmu(&[
        "generate",
        "plant",
        "--triangles",
        PLANT,
        "-o",
        path_str(&store),
        "--json",
    ]);
    store
}

/// Runs `script` on `store` with `extra` viewer arguments.
fn run(dir: &std::path::Path, store: &std::path::Path, extra: &[&str], script: &Value) -> Value {
    let file = dir.join("script.json");
    std::fs::write(&file, serde_json::to_vec(script).unwrap()).unwrap();
    let mut args = vec![path_str(store), "--script", path_str(&file)];
    args.extend(extra);
    viewer(&args)
}

/// A walk, a pick in the middle of the view and a drag of what it picked.
fn walk_pick_drag() -> Value {
    let mut actions = vec![json!({"frames": 20})];
    actions.push(json!({"pick": [340.0, 363.0]}));
    actions.push(json!({"drag": {"by": [0.0, 0.0, 500.0], "steps": 5}}));
    actions.push(json!({"frames": 40}));
    json!(actions)
}

#[test]
fn a_budgeted_run_picks_like_a_loaded_one_and_counts_stand_ins_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = plant_store(dir.path());
        let script = walk_pick_drag();
        let loaded = run(dir.path(), &store, &[], &script);
        let boxes = run(dir.path(), &store, &["--memory-budget", "4GiB"], &script);
        let holes = run(
            dir.path(),
            &store,
            &["--memory-budget", "4GiB", "--stand-ins", "none"],
            &script,
        );
        let pick = |r: &Value| step(r, 1, "pick")["hit"].clone();
        assert!(
            pick(&loaded)["part_id"].is_u64(),
            "the pick hits: {}",
            pick(&loaded)
        );
        // The oracle: the whole model loaded; the budgeted pick loads meshes
        // along the ray until the hit is exact.
        assert_eq!(pick(&boxes), pick(&loaded));
        assert_eq!(pick(&holes), pick(&loaded));
        assert_eq!(boxes["moved_parts"], loaded["moved_parts"]);
        for (r, name) in [(&boxes, "box"), (&holes, "none")] {
            let memory = &r["memory"];
            let residency = &memory["residency"];
            // The budget property: resident plus loading bytes never passed it.
            assert!(
                residency["peak_bytes"].as_u64().unwrap()
                    <= memory["residency_budget_bytes"].as_u64().unwrap(),
                "{name}: {memory}"
            );
            assert!(residency["loads"].as_u64().unwrap() > 0, "{name}: {memory}");
            assert!(r["tool_geometry"]["mesh_loads"].as_u64().unwrap() > 0);
            assert!(r["peak_rss_bytes"].as_u64().unwrap() > 0);
            assert!(r["first_frame_ms"].as_f64().unwrap() > 0.0);
            // A faithful frame (nothing drawn coarser than the LOD bound
            // asks) is a complete one.
            if let Some(faithful) = r["first_faithful_frame_ms"].as_f64() {
                assert!(faithful >= r["first_complete_frame_ms"].as_f64().unwrap());
            }
            assert!(
                r["frames_lod_coarse"].as_u64().unwrap() <= r["frames_drawn"].as_u64().unwrap()
            );
        }
        // The first frame has nothing resident: boxes stand in, or holes show.
        assert_eq!(boxes["frames_with_hole"], 0, "{}", boxes["memory"]);
        assert!(boxes["frames_with_standin"].as_u64().unwrap() > 0);
        assert!(holes["frames_with_hole"].as_u64().unwrap() > 0);
        assert_eq!(holes["frames_with_standin"], 0);
        // With everything fitting, the last frames stand nothing in.
        let frames = boxes["frames_drawn"].as_u64().unwrap();
        assert!(
            boxes["frames_with_standin"].as_u64().unwrap() < frames,
            "{}",
            boxes["memory"]
        );
    });
}

#[test]
fn a_store_damaged_on_disk_gives_a_one_line_error_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = plant_store(dir.path());
        // The first segment after the 64-byte header is a chunk's: opening
        // checks the header, the table of contents and the skeleton, not it.
        let mut bytes = std::fs::read(&store).unwrap();
        bytes[64 + 40] ^= 0xff;
        std::fs::write(&store, &bytes).unwrap();
        let _one = crate::support::xvfb_lock();
        let out = Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1600x1000x24"])
            .arg(env!("CARGO_BIN_EXE_dmu-viewer"))
            .args([
                path_str(&store),
                "--memory-budget",
                "4GiB",
                "--frames",
                "30",
            ])
            .env("WGPU_BACKEND", "vulkan")
            .env("VK_ICD_FILENAMES", crate::support::LVP_ICD)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
        assert_eq!(errors.len(), 1, "{stderr}");
        assert!(
            errors[0].starts_with("dmu-viewer: error: ")
                && errors[0].contains("plant.dmu")
                && errors[0].contains("chunk"),
            "{stderr}"
        );
    });
}
