//! A review session under Xvfb: clash tints, the recorded session replayed by
//! `dmu collide`, hover, rotation, view presets and the occlusion setting.

use std::collections::BTreeSet;
use std::path::Path;

use dmu_render::RendererOptions;
use dmu_scene::{PartId, Scene};
use glam::{DAffine3, DQuat, DVec3};
use serde_json::{Value, json};

use dmu_testkit::image_path;

use crate::support::{Palette, Viewport, count_pixels, dmu_status, with_viewer};
use crate::xvfb::{
    PLANT, first_look, no_overlays, path_str, plant_200k, run_script, run_script_on, step,
};

/// Colours of the scene's materials.
fn palette(scene: &Scene) -> Palette {
    Palette::new(
        scene
            .materials()
            .iter()
            .map(|m| m.base_color.map(f64::from))
            .map(|c| [c[0], c[1], c[2]]),
    )
}

/// Pixels of `view` showing a material with the tint `tint` and not plain.
fn tinted_pixels(image: &Path, view: Viewport, scene: &Scene, tint: [f32; 4]) -> usize {
    let plain = palette(scene);
    let tinted = plain.highlighted(tint);
    let image = image::open(image).expect("screenshot").to_rgba8();
    count_pixels(&image, view, |p| {
        tinted.explains(p, 3.0) && !plain.explains(p, 3.0)
    })
}

/// One clash as a comparable key: the two part ids, the kind.
type ClashKey = (u64, u64, String);

fn clash_keys(list: &Value) -> BTreeSet<ClashKey> {
    list.as_array()
        .expect("a list of clashes")
        .iter()
        .map(|c| {
            let id = |k: &str| c[k].as_u64().expect("part id");
            (id("a"), id("b"), c["kind"].as_str().unwrap().to_owned())
        })
        .collect()
}

/// Drags a box of the grid into its neighbour while recording, then undoes:
/// the neighbour lights up in the clash colour, and `dmu collide --record`
/// replaying the file finds at every step the clashes the viewer reported.
#[test]
fn recorded_drag_replays_to_the_same_clashes_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let scene = dmu_samples::grid(2, 10.0, 4.0, 2048);
        let glb = dir.path().join("grid.glb");
        dmu_scene::export_gltf(&scene, &glb).unwrap();
        let record = dir.path().join("session.jsonl");
        let (before_png, clash_png) = (
            image_path("viewer-record-before.png"),
            image_path("viewer-record-clash.png"),
        );
        let clearance = 1.5;
        let steps = 10;
        let report = run_script_on(
            dir.path(),
            &[path_str(&glb)],
            &json!([
                no_overlays(),
                {"select": "box_0_0_0"},
                {"clearance": clearance},
                {"screenshot": before_png},
                {"record": record},
                {"drag": {"by": [8.5, 0.0, 0.0], "steps": steps}},
                {"screenshot": clash_png},
                "undo",
                {"record": null},
            ]),
        );

        // What the viewer saw at each recorded step: the drag's frames, then the undo.
        let seen: Vec<BTreeSet<ClashKey>> = report["frames"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["action"] == "drag" || f["action"] == "undo")
            .map(|f| clash_keys(&f["clashes"]))
            .collect();
        assert_eq!(seen.len(), steps + 1);
        let kinds: BTreeSet<&str> = seen.iter().flatten().map(|k| k.2.as_str()).collect();
        assert!(
            kinds.contains("hard") && kinds.contains("soft"),
            "the drag goes through soft into hard clashes: {seen:?}"
        );
        assert!(seen[steps].is_empty(), "the undo clears the clashes");

        // The replay by the command line, step by step, checked where each step
        // ends as the viewer checks it (by default the command line would also
        // sweep the undo's jump home, longer than the box, from inside the
        // neighbour: an impact at time 0).
        let lines = std::fs::read_to_string(&record).unwrap();
        assert_eq!(lines.lines().count(), steps + 1, "one line per placement");
        let (status, replay) = dmu_status(&[
            "collide",
            path_str(&glb),
            "--record",
            path_str(&record),
            "--clearance",
            &clearance.to_string(),
            "--discrete",
            "--json",
        ]);
        assert_eq!(status, Some(1), "the replay finds clashes: {replay}");
        assert_eq!(replay["summary"]["steps"], steps + 1);
        let mut replayed = vec![BTreeSet::new(); steps + 1];
        for c in replay["clashes"].as_array().unwrap() {
            let i = c["step"].as_u64().unwrap() as usize;
            let key = (
                c["a_id"].as_u64().unwrap(),
                c["b_id"].as_u64().unwrap(),
                c["kind"].as_str().unwrap().to_owned(),
            );
            replayed[i].insert(key);
        }
        assert_eq!(replayed, seen, "dmu collide --record vs the viewer");

        // The neighbour lights up in the clash colour while the box sits in it.
        let view = Viewport::from_json(&report["viewport"]);
        let clash_tint = RendererOptions::default().clash_highlight;
        let before = tinted_pixels(&before_png, view, &scene, clash_tint);
        let during = tinted_pixels(&clash_png, view, &scene, clash_tint);
        assert!(
            during >= before + 50,
            "clash-tinted pixels: {before} before, {during} in the clash"
        );
    });
}

/// Hover tints the part under the pointer (the part a pick there finds); a
/// typed rotation turns the picked part 90° about Z through its box centre and
/// undoes; the top preset looks down; occlusion on queries, off does not.
#[test]
fn hover_rotate_presets_and_occlusion_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (view, (px, py), _) = first_look(dir.path(), "viewer-hover");
        let (plain_png, hover_png) = (
            image_path("viewer-hover-plain.png"),
            image_path("viewer-hover.png"),
        );
        let report = run_script(
            dir.path(),
            &json!([
                no_overlays(),
                {"occlusion": "on"},
                {"frames": 3},
                {"occlusion": "off"},
                {"frames": 3},
                {"screenshot": plain_png},
                {"hover": [px, py]},
                {"screenshot": hover_png},
                {"pick": [px, py]},
                {"rotate": {"axis": "z", "degrees": 90.0}},
                "undo",
                {"view": "top"},
                {"frames": 1},
            ]),
        );
        let queries = |from: usize, to: usize| -> Vec<u64> {
            report["frames"].as_array().unwrap()[from..to]
                .iter()
                .map(|f| f["queries"].as_u64().unwrap())
                .collect()
        };
        // Frames: overlays, occlusion, 3 frames, occlusion, 3 frames, ...
        assert!(
            queries(2, 5).iter().all(|&q| q > 0),
            "on: {:?}",
            queries(2, 5)
        );
        assert!(
            queries(6, 9).iter().all(|&q| q == 0),
            "off: {:?}",
            queries(6, 9)
        );

        let hovered = step(&report, 6, "hover")["part_id"].clone();
        let pick = step(&report, 8, "pick");
        assert_eq!(
            hovered, pick["hit"]["part_id"],
            "hover finds the picked part"
        );
        let plant = plant_200k();
        let hover_tint = RendererOptions::default().hover_highlight;
        let (plain, lit) = (
            tinted_pixels(&plain_png, view, &plant, hover_tint),
            tinted_pixels(&hover_png, view, &plant, hover_tint),
        );
        assert!(lit >= plain + 20, "hover-tinted pixels: {plain} -> {lit}");

        let part = PartId(hovered.as_u64().unwrap() as u32);
        let start = plant.part_world(part);
        let centre = plant.part_world_bounds(part).center();
        let want = DAffine3::from_translation(centre)
            * DAffine3::from_quat(DQuat::from_rotation_z(90f64.to_radians()))
            * DAffine3::from_translation(-centre)
            * start;
        let rotated = step(&report, 9, "rotate");
        let t: Vec<f64> = serde_json::from_value(rotated["translation"].clone()).unwrap();
        assert!(
            DVec3::from_slice(&t).abs_diff_eq(want.translation, 1e-6),
            "{t:?} vs {}",
            want.translation
        );
        let m: Vec<f64> = serde_json::from_value(rotated["matrix3"].clone()).unwrap();
        assert!(
            glam::DMat3::from_cols_slice(&m).abs_diff_eq(want.matrix3, 1e-12),
            "{m:?}"
        );
        assert_eq!(step(&report, 10, "undo")["part_id"], part.0);
        assert_eq!(report["moved_parts"], json!([]));

        let forward: Vec<f64> =
            serde_json::from_value(report["camera"]["forward"].clone()).unwrap();
        assert!(forward[2] < -0.999, "top looks down: {forward:?}");
    });
}

/// Four panes, each with its own camera and view: the main one focused on a
/// part, top, the cells debug view and front. The cells the main view drew
/// are checked against its frustum on the CPU: every drawn cell meets it, and
/// every cell wholly inside it is drawn.
#[test]
fn four_panes_with_a_cells_view_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (single, (px, py), _) = first_look(dir.path(), "viewer-panes");
        let png = image_path("viewer-panes.png");
        let report = run_script(
            dir.path(),
            &json!([
                no_overlays(),
                {"pick": [px, py]},
                "focus",
                {"panes": 4},
                {"frames": 2},
                {"screenshot": png},
            ]),
        );
        let panes = report["panes"].as_array().expect("panes in the report");
        assert_eq!(panes.len(), 4);
        let kinds: Vec<&str> = panes.iter().map(|p| p["kind"].as_str().unwrap()).collect();
        assert_eq!(kinds, ["model", "model", "cells", "model"]);
        let rects: Vec<Viewport> = panes
            .iter()
            .map(|p| Viewport::from_json(&p["rect"]))
            .collect();
        assert_eq!(rects[0], Viewport::from_json(&report["viewport"]));
        for (i, a) in rects.iter().enumerate() {
            assert!(
                a.x >= single.x
                    && a.y >= single.y
                    && a.x + a.width <= single.x + single.width
                    && a.y + a.height <= single.y + single.height,
                "pane {i} {a:?} leaves the view area {single:?}"
            );
            for b in &rects[i + 1..] {
                let apart = a.x + a.width <= b.x
                    || b.x + b.width <= a.x
                    || a.y + a.height <= b.y
                    || b.y + b.height <= a.y;
                assert!(apart, "{a:?} overlaps {b:?}");
            }
        }
        for (i, p) in panes.iter().enumerate() {
            assert!(p["triangles_drawn"].as_u64().unwrap() > 0, "pane {i}: {p}");
        }
        let forward = |i: usize| -> DVec3 {
            let f: Vec<f64> =
                serde_json::from_value(panes[i]["camera"]["forward"].clone()).unwrap();
            DVec3::from_slice(&f)
        };
        assert!(forward(1).z < -0.999, "pane 1 looks down: {}", forward(1));
        assert!(
            forward(3).y > 0.999,
            "pane 3 looks along +y: {}",
            forward(3)
        );

        // The cells view against the main camera's frustum, on the CPU.
        let plant = plant_200k();
        let tree = dmu_tree::Tree::build(&plant, Default::default());
        let cells = &panes[2];
        let (drawn, culled) = (
            cells["cells_drawn"].as_u64().unwrap() as usize,
            cells["cells_culled"].as_u64().unwrap() as usize,
        );
        assert_eq!(drawn + culled, tree.cell_count());
        assert!(
            drawn > 0 && culled > 0,
            "focused: {drawn} drawn, {culled} culled"
        );
        let ids: BTreeSet<u32> = serde_json::from_value(cells["drawn_cell_ids"].clone()).unwrap();
        assert_eq!(ids.len(), drawn);
        let cam = &panes[0]["camera"];
        let eye: Vec<f64> = serde_json::from_value(cam["eye"].clone()).unwrap();
        let eye = DVec3::from_slice(&eye);
        let camera = dmu_render::Camera {
            eye,
            target: eye + forward(0) * 1e5,
            up: DVec3::Z,
            fov_y_rad: cam["fov_y_deg"].as_f64().unwrap().to_radians(),
            near: cam["near"].as_f64().unwrap(),
        };
        let frustum = camera.frustum(f64::from(rects[0].width) / f64::from(rects[0].height));
        let mut inside = 0;
        for cell in tree.cell_ids() {
            let bounds = tree.cell_bounds(cell);
            if ids.contains(&cell.0) {
                assert!(
                    frustum.intersects_aabb(&bounds),
                    "cell {} drawn outside",
                    cell.0
                );
            }
            if frustum.test_aabb(&bounds) == dmu_geom::Containment::Inside {
                inside += 1;
                assert!(
                    ids.contains(&cell.0),
                    "cell {} inside but not drawn",
                    cell.0
                );
            }
        }
        assert!(inside > 0, "some cell lies wholly in the main view");
    });
}

/// Frames composed from the panels as last painted (the default) show what a
/// whole paint of the same frame shows, pixel for pixel: after a pick (the
/// panels change), a drag (the part moves under clash markers drawn over the
/// view), a preset view and frames with only the 3D view changing. Most of
/// those frames reuse the panels; painting whole, none does. While the part
/// is dragged the panels may lag (`--panel-refresh-ms`, a minute here): the
/// drag's frames copy the panels painted at the pick though its position
/// changes, and the first frame after it shows them as they are. (One run:
/// the panels show timings, which differ from run to run.)
#[test]
fn composed_frames_equal_whole_paints_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (_, (px, py), _) = first_look(dir.path(), "viewer-compose");
        let [composed_png, whole_png] =
            ["composed", "whole"].map(|n| image_path(&format!("viewer-compose-{n}.png")));
        let report = run_script_on(
            dir.path(),
            &["--plant-triangles", PLANT, "--panel-refresh-ms", "60000"],
            &json!([
                {"overlays": {"stats": false, "clashes": true}},
                {"pick": [px, py]},
                {"drag": {"by": [0.0, 0.0, -400.0], "steps": 8}},
                {"view": "iso"},
                {"frames": 4},
                {"hover": [px, py]},
                {"frames": 2},
                {"screenshot": composed_png},
                {"paint_whole": true},
                {"frames": 2},
                {"screenshot": whole_png},
            ]),
        );
        let whole: Vec<bool> = report["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| {
                f["painted_whole"]
                    .as_bool()
                    .expect("painted_whole per frame")
            })
            .collect();
        // The 19 frames up to the first screenshot, then 4 painted whole.
        let (composing, painting) = whole.split_at(whole.len() - 4);
        assert!(painting.iter().all(|&w| w), "{whole:?}");
        let frames = report["frames"].as_array().unwrap();
        let stale: Vec<(&str, bool)> = frames
            .iter()
            .map(|f| {
                let stale = f["panels_stale"].as_bool().expect("panels_stale per frame");
                (f["action"].as_str().unwrap(), stale)
            })
            .collect();
        let drag: Vec<bool> = (stale.iter())
            .filter(|(a, _)| *a == "drag")
            .map(|&(_, s)| s)
            .collect();
        assert_eq!(drag.len(), 8, "{stale:?}");
        // The last step ends the drag, and a frame with a glyph new to egui's
        // atlas is painted whole.
        assert!(
            drag.iter().filter(|&&s| s).count() >= 4,
            "the drag's frames lag: {stale:?} {whole:?}"
        );
        let after = stale.iter().rposition(|(a, _)| *a == "drag").unwrap() + 1;
        assert!(
            stale[after..].iter().all(|&(_, s)| !s),
            "no frame after the drag lags: {stale:?}"
        );
        assert!(
            !composing.last().unwrap(),
            "the first screenshot's frame is composed: {whole:?}"
        );
        let reused = composing.iter().filter(|&&w| !w).count();
        assert!(
            reused * 2 >= composing.len(),
            "most frames reuse the panels: {whole:?}"
        );
        let composed = image::open(&composed_png).unwrap().to_rgba8();
        let painted = image::open(&whole_png).unwrap().to_rgba8();
        assert_eq!(composed.dimensions(), painted.dimensions());
        let differing: Vec<(u32, u32)> = composed
            .enumerate_pixels()
            .filter(|&(x, y, p)| p != painted.get_pixel(x, y))
            .map(|(x, y, _)| (x, y))
            .collect();
        assert!(
            differing.is_empty(),
            "composed and whole paints differ in {} pixels, from {:?} to {:?}",
            differing.len(),
            differing.iter().min(),
            differing.iter().max()
        );
    });
}

/// The stats overlay is off at start and shows at the top of the view when
/// turned on, from the top bar (script `overlays`) or with
/// `--stats`; nothing else in the window changes.
#[test]
fn the_stats_overlay_is_off_unless_asked_for_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let [plain, toggled, off, flagged] = ["plain", "toggled", "off", "flagged"]
            .map(|n| image_path(&format!("viewer-stats-{n}.png")));
        let report = run_script(
            dir.path(),
            &json!([
                {"frames": 4},
                {"screenshot": plain},
                {"overlays": {"stats": true}},
                {"frames": 2},
                {"screenshot": toggled},
                {"overlays": {"stats": false}},
                {"frames": 2},
                {"screenshot": off},
            ]),
        );
        run_script_on(
            dir.path(),
            &["--plant-triangles", PLANT, "--stats"],
            &json!([{"frames": 4}, {"screenshot": flagged}]),
        );
        let view = Viewport::from_json(&report["viewport"]);
        let plain = image::open(&plain).unwrap().to_rgba8();
        let off = image::open(&off).unwrap().to_rgba8();
        assert!(plain == off, "the start shows the overlay");
        for other in [toggled, flagged] {
            let other = image::open(&other).unwrap().to_rgba8();
            let differing: Vec<(u32, u32)> = (plain.enumerate_pixels())
                .filter(|&(x, y, p)| p != other.get_pixel(x, y))
                .map(|(x, y, _)| (x, y))
                .collect();
            assert!(differing.len() > 1000, "{} pixels differ", differing.len());
            // The box is as wide as its longest line: at 680 pixels, the view's width.
            let top = |&(x, y): &(u32, u32)| {
                (view.x..view.x + view.width).contains(&x)
                    && (view.y..view.y + view.height / 2).contains(&y)
            };
            assert!(
                differing.iter().all(top),
                "pixels outside the view's upper half differ: {:?}",
                differing.iter().find(|p| !top(p))
            );
        }
    });
}
