//! Pick, move, drag, undo, save and the highlight, end to end: the viewer runs
//! under Xvfb on lavapipe, and its results are checked against the `dmu` command
//! line, the saved file read back, and the colours the renderer can produce.

use std::path::Path;

use dmu_samples::{PlantOptions, plant};
use dmu_scene::{PartId, Scene};
use glam::{DAffine3, DVec3};
use serde_json::{Value, json};

use dmu_testkit::image_path;

use crate::support::{Palette, Viewport, count_pixels, dmu, rgb, solid_pixel, viewer, with_viewer};

/// The plant of these tests, as `--plant-triangles 200k` builds it.
pub const PLANT: &str = "200k";

pub fn plant_200k() -> Scene {
    plant(&PlantOptions {
        triangles: 200_000,
        ..PlantOptions::default()
    })
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
}

fn assert_transform_close(got: DAffine3, want: DAffine3, what: &str) {
    let (g, w) = (got.to_cols_array(), want.to_cols_array());
    assert!(
        g.iter().zip(&w).all(|(a, b)| close(*a, *b)),
        "{what}: transform {g:?}, expected {w:?}"
    );
}

pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temp path")
}

/// Overlays off: screenshots show the model alone.
pub fn no_overlays() -> Value {
    json!({"overlays": {"stats": false, "clashes": false, "tools": false}})
}

/// Runs `script` (a JSON list of actions) on the plant and returns the report.
pub fn run_script(dir: &Path, script: &Value) -> Value {
    run_script_on(dir, &["--plant-triangles", PLANT], script)
}

/// Runs `script` on the model `model` names (viewer arguments).
pub fn run_script_on(dir: &Path, model: &[&str], script: &Value) -> Value {
    let file = dir.join("script.json");
    std::fs::write(&file, serde_json::to_vec(script).unwrap()).unwrap();
    let mut args = model.to_vec();
    args.extend(["--script", path_str(&file)]);
    viewer(&args)
}

/// Opens the plant as the viewer shows it at start, and finds a pixel of the
/// 3D view that shows a part. Returns the view, the pixel and the screenshot.
pub fn first_look(dir: &Path, name: &str) -> (Viewport, (u32, u32), image::RgbaImage) {
    let png = image_path(&format!("{name}-start.png"));
    let report = run_script(dir, &json!([no_overlays(), {"screenshot": png}]));
    assert_eq!(report["model"]["triangles"], plant_200k().triangle_count());
    let view = Viewport::from_json(&report["viewport"]);
    let image = image::open(&png).expect("start screenshot").to_rgba8();
    (view, solid_pixel(&image, view), image)
}

/// The step of `report` for the `index`-th action, which must be `action`.
pub fn step<'a>(report: &'a Value, index: usize, action: &str) -> &'a Value {
    let s = &report["steps"][index];
    assert_eq!(s["action"], action, "step {index}: {s}");
    s
}

/// `ox,oy,oz,dx,dy,dz` of a reported ray, each number in Rust's shortest
/// round-trip form, so `dmu pick` receives the very same f64 ray.
fn ray_arg(ray: &Value) -> String {
    let nums: Vec<String> = ["origin", "dir"]
        .iter()
        .flat_map(|k| ray[k].as_array().expect("3 numbers").clone())
        .map(|v| v.as_f64().expect("number").to_string())
        .collect();
    nums.join(",")
}

/// Every part of `saved` (read back from glTF) sits where `expected` says.
fn assert_saved(saved: &Path, expected: &Scene, what: &str) {
    let (back, _) = dmu_scene::import_gltf(saved, &Default::default()).expect("re-import");
    assert_eq!(back.parts().len(), expected.parts().len());
    for part in expected.part_ids() {
        let path = expected.part_path(part);
        let id = if back.part_path(part) == path {
            part
        } else {
            back.find_part(&path)
                .expect("the saved file has every part")
        };
        assert_transform_close(
            back.part_world(id),
            expected.part_world(part),
            &format!("{what}: {path}"),
        );
    }
}

/// Picks at a pixel showing a part, moves it 100 mm, saves; checks the pick
/// against `dmu pick` for the same ray, the saved transforms against the
/// plant, and the highlight in the screenshots.
#[test]
fn pick_move_save_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (view, (px, py), start) = first_look(dir.path(), "viewer-pick");
        let picked_png = image_path("viewer-pick-picked.png");
        let moved_png = image_path("viewer-pick-moved.png");
        let saved = dir.path().join("moved.glb");
        let report = run_script(
            dir.path(),
            &json!([
                no_overlays(),
                {"pick": [px, py]},
                {"screenshot": picked_png},
                {"move": [100.0, 0.0, 0.0]},
                {"save": saved},
                {"screenshot": moved_png},
            ]),
        );
        assert_eq!(
            Viewport::from_json(&report["viewport"]),
            view,
            "the layout moved"
        );

        // The pick equals the command line's for the same f64 ray.
        let pick = step(&report, 1, "pick");
        assert_eq!(
            pick["pixel"],
            json!([f64::from(px) + 0.5, f64::from(py) + 0.5])
        );
        assert_eq!(pick["hit"]["hit"], true, "{pick}");
        let cli = dmu(&[
            "pick",
            "--plant-triangles",
            PLANT,
            "--ray",
            &ray_arg(&pick["ray"]),
            "--json",
        ]);
        for key in ["hit", "part_id", "part", "path", "triangle", "point"] {
            assert_eq!(
                cli[key], pick["hit"][key],
                "{key}: dmu pick {cli} vs viewer {pick}"
            );
        }
        assert!(close(
            cli["distance"].as_f64().unwrap(),
            pick["hit"]["distance"].as_f64().unwrap()
        ));

        // The saved file has the part 100 mm along x, everything else in place.
        let mut expected = plant_200k();
        let part = PartId(pick["hit"]["part_id"].as_u64().unwrap() as u32);
        assert_eq!(expected.part_path(part), pick["hit"]["path"]);
        let mut world = expected.part_world(part);
        world.translation += DVec3::new(100.0, 0.0, 0.0);
        expected.set_part_world(part, world);
        let moved = step(&report, 3, "move");
        assert_eq!(moved["part_id"], part.0);
        // To rounding of the report's JSON: serde_json (without its
        // `float_roundtrip` feature) may read a printed f64 back an ulp off.
        let t: Vec<f64> = serde_json::from_value(moved["translation"].clone()).unwrap();
        assert!(
            t.iter()
                .zip(world.translation.to_array())
                .all(|(&a, b)| close(a, b)),
            "the typed move: {t:?}, expected {}",
            world.translation
        );
        assert_eq!(step(&report, 4, "save")["format"], "gltf");
        assert_saved(&saved, &expected, "after the move");

        // The highlight. Around the picked pixel, surfaces that showed a plain
        // material at some lighting now show that material mixed with the
        // selection colour at the same lighting; and the moved part still shows it.
        let plain = Palette::new(
            expected
                .materials()
                .iter()
                .map(|m| m.base_color.map(f64::from))
                .map(|c| [c[0], c[1], c[2]]),
        );
        let tinted = plain.highlighted(dmu_render::RendererOptions::default().highlight);
        let picked = image::open(&picked_png).unwrap().to_rgba8();
        let after = image::open(&moved_png).unwrap().to_rgba8();
        let mut turned = 0;
        for y in view.y + py - 12..=view.y + py + 12 {
            for x in view.x + px - 12..=view.x + px + 12 {
                let now = rgb(&picked, x, y);
                if plain
                    .explain(rgb(&start, x, y), 2.0)
                    .iter()
                    .any(|&(m, k)| tinted.matches(m, k, now, 3.0))
                {
                    turned += 1;
                }
            }
        }
        assert!(
            turned >= 20,
            "{turned} pixels near the pick turned to the selection colour; {pick}"
        );
        let highlighted = |p: [u8; 3]| tinted.explains(p, 3.0) && !plain.explains(p, 3.0);
        let count = |image| count_pixels(image, view, highlighted);
        let (n_start, n_picked, n_after) = (count(&start), count(&picked), count(&after));
        assert!(
            n_picked >= n_start + 20 && n_after >= n_start + 20,
            "highlighted pixels: {n_start} at start, {n_picked} picked, {n_after} moved"
        );
    });
}

/// Drags the picked part along Z with the mouse (the interactive drag's code),
/// saves, undoes, saves again: the drag moves it along Z only, the tree and
/// collision run at every step, and the undo puts it back.
#[test]
fn mouse_drag_along_z_then_undo_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (_, (px, py), _) = first_look(dir.path(), "viewer-drag");
        let dragged = dir.path().join("dragged.gltf");
        let undone = dir.path().join("undone.glb");
        let steps = 6;
        let report = run_script(
            dir.path(),
            &json!([
                {"pick": [px, py]},
                {"mouse_drag": {"axis": "z", "from": [px, py], "to": [px, py - 30], "steps": steps}},
                {"save": dragged},
                "undo",
                {"save": undone},
            ]),
        );
        let plant = plant_200k();
        let part = PartId(step(&report, 0, "pick")["hit"]["part_id"].as_u64().unwrap() as u32);
        let start = plant.part_world(part);
        let drag = step(&report, 1, "mouse_drag");
        let t: Vec<f64> = serde_json::from_value(drag["translation"].clone()).unwrap();
        assert_eq!((t[0], t[1]), (start.translation.x, start.translation.y));
        assert!(
            t[2] > start.translation.z,
            "dragging the pointer up lifts the part: z {} -> {}",
            start.translation.z,
            t[2]
        );
        let frames: Vec<&Value> = report["frames"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["action"] == "mouse_drag")
            .collect();
        assert_eq!(frames.len(), steps + 1, "one frame per pointer position");
        assert!(
            frames[1..]
                .iter()
                .all(|f| f["move_us"].as_f64().unwrap() > 0.0)
        );

        let mut expected = plant.clone();
        let mut world = start;
        world.translation.z = t[2];
        expected.set_part_world(part, world);
        assert_saved(&dragged, &expected, "after the drag");
        assert_eq!(step(&report, 3, "undo")["part_id"], part.0);
        assert_saved(&undone, &plant, "after the undo");
        assert_eq!(report["moved_parts"], json!([]), "nothing left moved");
    });
}
