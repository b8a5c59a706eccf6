//! `--far-field on|auto`: a store's far fields (`dmu farfield build`) drawn
//! in the main view, captured again after a move once the view is calm,
//! `auto`'s probe, and the one-line errors where there are none to draw.

use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use crate::support::{dmu, dmu_on_lavapipe, viewer_fails, with_viewer};
use crate::xvfb::{PLANT, path_str, run_script_on};

/// A part of the tests' plant in the far field of the built cell: a
/// cladding wall of unit U03 about 48 m ahead of the eye.
const FAR_PART: &str = "U03-L1-CLAD-0004";

/// A store of the tests' plant in `dir`, without far fields.
fn plant_store(dir: &Path, name: &str) -> PathBuf {
    let store = dir.join(name);
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

/// Builds the far field of one cell, the one frame 300 of the built-in walk
/// stands in (cells 4 m wide, a cull box of at most 20k triangles, faces of
/// 128 pixels), and returns the cell's centre: where it was captured from.
fn build_one_cell(store: &Path) -> [f64; 3] {
    let built = dmu_on_lavapipe(&[
        "farfield",
        "build",
        path_str(store),
        "--along-walk",
        "--range",
        "300..301",
        "--cell-size",
        "4000",
        "--triangle-budget",
        "20k",
        "--resolution",
        "128",
        "--json",
    ]);
    assert_eq!(built["cells"], 1, "{built:#}");
    // A cull box is a cube around its cell's centre.
    let b = &built["per_cell"][0]["near_box"];
    let corner = |i: usize, k: usize| b[i][k].as_f64().expect("a box corner");
    [0, 1, 2].map(|k| 0.5 * (corner(0, k) + corner(1, k)))
}

/// The far field of each frame record of `report`.
fn far_frames(report: &Value) -> Vec<&Value> {
    report["frames"]
        .as_array()
        .expect("frame records")
        .iter()
        .map(|f| &f["far_field"])
        .collect()
}

/// The eye in the built cell draws its far field once loaded; moving a part
/// it shows makes it stale, and the next calm frame captures it again (in
/// memory) and draws it with the part as geometry.
#[test]
fn a_far_field_is_drawn_and_captured_again_after_a_move_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = plant_store(dir.path(), "p.dmu");
        let eye = build_one_cell(&store);
        let settle = 8;
        let report = run_script_on(
            dir.path(),
            &[path_str(&store), "--far-field", "on"],
            &json!([
                {"camera": {"eye": eye, "forward": [1.0, 0.0, 0.0]}},
                {"frames": settle},
                {"select": FAR_PART},
                {"move": [0.0, 0.0, 3000.0]},
                {"frames": 6},
            ]),
        );
        let frames = far_frames(&report);
        let records = report["frames"].as_array().unwrap();
        let of = |action: &str| {
            records
                .iter()
                .position(|f| f["action"] == action)
                .unwrap_or_else(|| panic!("no {action} frame"))
        };
        let (select, moved) = (of("select"), of("move"));
        // Loaded within the settling frames, then drawn in each.
        let before = &frames[..select];
        assert!(
            before.iter().any(|f| f["drawn"] == true),
            "never drawn: {before:#?}"
        );
        let first = before.iter().position(|f| f["drawn"] == true).unwrap();
        for f in &before[..first] {
            assert_eq!(f["why"], "loading", "{f}");
        }
        for f in &frames[first..=moved] {
            assert_eq!(f["drawn"], true, "{f}");
            assert!(f["triangles"].as_u64().unwrap() > 0, "{f}");
        }
        assert_eq!(frames[select]["stale"], 0);
        assert_eq!(frames[select]["moved_parts"], 0);
        // The move's frame: the part is drawn as geometry and the far field
        // showing it is stale, not yet captured again (the edit has to settle).
        let at_move = frames[moved];
        assert_eq!(at_move["moved_parts"], 1, "{at_move}");
        assert_eq!(at_move["stale"], 1, "{at_move}");
        assert_eq!(at_move["rebuilds"], 0, "{at_move}");
        // Some frames later: captured again, nothing stale, still drawn.
        let last = frames.last().unwrap();
        assert_eq!(last["stale"], 0, "{last}");
        assert_eq!(last["rebuilds"], 1, "{last}");
        assert!(last["last_rebuild_ms"].as_f64().unwrap() > 0.0, "{last}");
        assert_eq!(last["drawn"], true, "{last}");
        assert_eq!(last["moved_parts"], 1, "{last}");
        let far = &report["far_field"];
        assert_eq!(far["mode"], "on");
        assert_eq!(far["cells"], 1);
        assert_eq!(far["rebuilds"], 1);
        assert_eq!(far["stale"], 0);
        assert!(far["frames_with_far_field"].as_u64().unwrap() >= 6, "{far}");
    });
}

/// `auto` times frames without the far field, then with it, and keeps the
/// faster way; each frame says why it drew none.
#[test]
fn auto_times_frames_with_and_without_the_far_field_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = plant_store(dir.path(), "p.dmu");
        let eye = build_one_cell(&store);
        let report = run_script_on(
            dir.path(),
            &[path_str(&store), "--far-field", "auto"],
            &json!([
                {"camera": {"eye": eye, "forward": [1.0, 0.0, 0.0]}},
                {"frames": 12},
            ]),
        );
        let frames = far_frames(&report);
        // Loaded, the first three frames of the probe go without.
        let loaded = frames
            .iter()
            .position(|f| f["why"] != "loading")
            .expect("loaded");
        for f in &frames[loaded..loaded + 3] {
            assert_eq!(f["drawn"], false, "{f}");
            assert!(f["why"].as_str().unwrap().contains("auto"), "{f}");
        }
        for f in &frames[loaded + 3..loaded + 6] {
            assert_eq!(f["drawn"], true, "{f}");
        }
        let changes = report["far_field"]["auto_changes"].as_array().unwrap();
        assert_eq!(changes.len(), 1, "{:#}", report["far_field"]);
        assert!(
            changes[0].as_str().unwrap().contains("ms a frame with it"),
            "{changes:?}"
        );
        // After the probe every frame follows its choice.
        let on = changes[0].as_str().unwrap().contains("far field on");
        for f in &frames[loaded + 6..] {
            assert_eq!(f["drawn"], on, "{f}");
        }
    });
}

/// `--far-field on|auto` where no far field can be drawn: one line naming
/// the file and what makes them; the run never starts.
#[test]
fn far_fields_missing_or_impossible_give_a_one_line_error_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = plant_store(dir.path(), "bare.dmu");
        let one_error = |args: &[&str], wants: &[&str]| {
            let stderr = viewer_fails(args);
            let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
            assert_eq!(errors.len(), 1, "{args:?}: {stderr}");
            assert!(
                errors[0].starts_with("dmu-viewer: error: --far-field "),
                "{stderr}"
            );
            for w in wants {
                assert!(errors[0].contains(w), "{args:?}: {w:?} missing in {stderr}");
            }
        };
        let bare = path_str(&store);
        one_error(
            &[bare, "--far-field", "on", "--frames", "2"],
            &["bare.dmu", "dmu farfield build"],
        );
        one_error(
            &[bare, "--far-field", "auto", "--frames", "2"],
            &["bare.dmu", "dmu farfield build"],
        );
        one_error(
            &["--far-field", "on", "--frames", "2"],
            &["built-in plant", "dmu farfield build"],
        );
        one_error(
            &[
                bare,
                "--far-field",
                "on",
                "--memory-budget",
                "1GiB",
                "--frames",
                "2",
            ],
            &["--memory-budget"],
        );
        // Off is the default, and plain: the store opens as it always did.
        let report = crate::support::viewer(&[bare, "--far-field", "off", "--frames", "3"]);
        assert!(report.get("far_field").is_none(), "{report:#}");
    });
}
