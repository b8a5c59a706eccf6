//! The design-review tools under Xvfb: the gizmo with snapping and undo, a
//! section plane through the 2M plant, measurement against `dmu collide`, and
//! the clash list.

use dmu_geom::Camera;
use dmu_render::RendererOptions;
use dmu_scene::PartId;
use glam::{DAffine3, DMat3, DQuat, DVec3};
use serde_json::{Value, json};

use dmu_testkit::image_path;

use crate::support::{Viewport, count_pixels, dmu, dmu_status, srgb, with_viewer};
use crate::xvfb::{first_look, no_overlays, path_str, plant_200k, run_script, step};

/// A reported selection's transform.
fn world(facts: &Value) -> DAffine3 {
    let t: [f64; 3] = serde_json::from_value(facts["translation"].clone()).unwrap();
    let m: [f64; 9] = serde_json::from_value(facts["matrix3"].clone()).unwrap();
    DAffine3 {
        matrix3: DMat3::from_cols_array(&m),
        translation: DVec3::from_array(t),
    }
}

/// Gizmo drags with snapping on the 200k plant: an arrow moves by a whole
/// number of 25 mm steps along its axis only, a plane square by whole steps
/// in its plane, a ring turns by a whole number of 15° steps about its axis,
/// Shift (`free`) moves off the steps; collisions are checked at every drag
/// frame; four undos put the part back bit for bit, in the saved file too.
#[test]
fn gizmo_drags_snap_and_undo_bit_for_bit_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let saved = dir.path().join("undone.glb");
        let png = image_path("viewer-gizmo.png");
        let report = run_script(
            dir.path(),
            &json!([
                {"overlays": {"stats": false}},
                {"select": "#300"},
                "focus",
                {"snap": {"step": 25, "degrees": 15}},
                {"gizmo_drag": {"handle": "x", "by": [60, 10], "steps": 5}},
                {"gizmo_drag": {"handle": "xy", "by": [-30, 25], "steps": 4}},
                {"gizmo_drag": {"handle": "rz", "by": [30, 40], "steps": 5}},
                {"screenshot": png},
                {"gizmo_drag": {"handle": "y", "by": [17, -3], "steps": 3, "free": true}},
                "undo", "undo", "undo", "undo",
                {"save": saved},
            ]),
        );
        let plant = plant_200k();
        let part = PartId(300);
        let start = plant.part_world(part);
        let after = |i: usize| world(step(&report, i, "gizmo_drag"));
        let step_of = |d: f64| d / 25.0;

        let x = after(4);
        let dx = x.translation - start.translation;
        assert!(
            step_of(dx.x).fract() == 0.0 && dx.x != 0.0,
            "x arrow moved {dx}"
        );
        assert_eq!((dx.y, dx.z), (0.0, 0.0), "x arrow moved off its axis: {dx}");
        assert_eq!(x.matrix3, start.matrix3);

        let xy = after(5);
        let d = xy.translation - x.translation;
        assert!(d.x != 0.0 || d.y != 0.0, "the xy square moved nothing");
        assert!(
            step_of(d.x).fract() == 0.0 && step_of(d.y).fract() == 0.0 && d.z == 0.0,
            "xy square moved {d}"
        );

        let rz = after(6);
        let turn = DQuat::from_mat3(&(rz.matrix3 * xy.matrix3.inverse()));
        let (axis, angle) = turn.to_axis_angle();
        let steps = angle.to_degrees() / 15.0;
        assert!(
            steps.round() >= 1.0 && (steps - steps.round()).abs() < 1e-9,
            "the ring turned {}°",
            angle.to_degrees()
        );
        assert!(axis.cross(DVec3::Z).length() < 1e-12, "about {axis}");

        let free = after(8);
        let d = free.translation - rz.translation;
        assert!(d.y != 0.0 && d.x == 0.0 && d.z == 0.0, "free y drag {d}");
        assert!(step_of(d.y).fract() != 0.0, "a free drag snapped: {d}");

        let frames: Vec<&Value> = report["frames"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["action"] == "gizmo_drag" && f["step"].as_u64() > Some(0))
            .collect();
        assert_eq!(frames.len(), 5 + 4 + 5 + 3);
        assert!(
            frames.iter().all(|f| f["check_ms"].as_f64() > Some(0.0)),
            "every drag frame checks collisions"
        );

        let (back, _) = dmu_scene::import_gltf(&saved, &Default::default()).unwrap();
        let id = back.find_part(&plant.part_path(part)).unwrap();
        assert_eq!(
            back.part_world(id),
            start,
            "undo restores the part bit for bit"
        );
    });
}

/// The camera of a report (the viewer's camera looks with Z up).
fn report_camera(camera: &Value) -> Camera {
    let v = |k: &str| DVec3::from_array(serde_json::from_value(camera[k].clone()).unwrap());
    Camera {
        eye: v("eye"),
        target: v("eye") + v("forward"),
        up: DVec3::Z,
        fov_y_rad: camera["fov_y_deg"].as_f64().unwrap().to_radians(),
        near: camera["near"].as_f64().unwrap(),
    }
}

/// The window opens and shows the progress while the 2M plant loads. A
/// section plane through the middle of the plant, seen from the top:
/// the screen beyond every corner of the kept half of the model's box shows
/// only background (before the cut it showed the plant), and the cut frame
/// draws fewer triangles, culling what is wholly cut away.
#[test]
fn a_section_plane_cuts_the_2m_plant_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let info = dmu(&["info", "--json"]);
        let v =
            |k: &str| DVec3::from_array(serde_json::from_value(info["bounds"][k].clone()).unwrap());
        let (min, max) = (v("min"), v("max"));
        let cut_x = 0.5 * (min.x + max.x);
        let (whole_png, cut_png) = (
            image_path("viewer-section-whole.png"),
            image_path("viewer-section-cut.png"),
        );
        let report = crate::xvfb::run_script_on(
            dir.path(),
            &[],
            &json!([
                no_overlays(),
                {"view": "top"},
                {"frames": 2},
                {"screenshot": whole_png},
                {"section_plane": {"point": [cut_x, min.y, min.z], "normal": [-1, 0, 0]}},
                {"frames": 2},
                {"screenshot": cut_png},
                {"overlays": {"tools": true}},
                {"section_drag": {"handle": 0, "by": [-40, 0], "steps": 4}},
            ]),
        );
        assert_eq!(report["model"]["triangles"], info["triangles"]);
        // The window opened and drew the progress while the model loaded, not
        // back to back (which took a core from the load): at most every quarter
        // of a second, so at most one frame more than the quarters of a second
        // before the model's first frame.
        let loading_frames = report["frames_while_loading"].as_u64().unwrap();
        let first_frame_ms = report["first_frame_ms"].as_f64().unwrap();
        assert!(loading_frames > 0, "no frame while the 2M plant loaded");
        assert!(
            loading_frames as f64 <= 1.0 + first_frame_ms / 250.0,
            "{loading_frames} frames of the loading screen before the first frame at {first_frame_ms} ms"
        );
        let reported: [f64; 3] =
            serde_json::from_value(report["model"]["bounds"]["min"].clone()).unwrap();
        assert!(
            DVec3::from_array(reported).abs_diff_eq(min, 1e-9 * min.length()),
            "the report's model bounds start at {reported:?}, dmu info's at {min}"
        );
        let frames = report["frames"].as_array().unwrap();
        let shot = |i: usize| {
            frames
                .iter()
                .filter(|f| f["action"] == "screenshot")
                .nth(i)
                .expect("screenshot frame")
        };
        let (whole, cut) = (shot(0), shot(1));
        let drawn = |f: &Value| f["triangles_drawn"].as_u64().unwrap();
        assert!(
            drawn(cut) * 10 < drawn(whole) * 7,
            "triangles drawn: {} whole, {} cut",
            drawn(whole),
            drawn(cut)
        );
        assert!(cut["culled_section"].as_u64() > Some(0), "{cut}");
        // The plane's handle slides it along its normal by whole 10 mm steps.
        let d = |s: &Value| s["planes"][0]["d"].as_f64().unwrap();
        let placed = d(step(&report, 4, "section_plane"));
        let slid = d(step(&report, 8, "section_drag"));
        assert!(
            slid != placed && ((slid - placed) / 10.0).fract() == 0.0,
            "the plane slid from d {placed} to {slid}"
        );

        // The kept half box projects inside the hull of its corners: every
        // column right of the rightmost corner can show only what was cut away.
        let view = Viewport::from_json(&report["viewport"]);
        let camera = report_camera(&report["camera"]);
        let size = (f64::from(view.width), f64::from(view.height));
        let clip = camera.projection(size.0 / size.1) * camera.view_matrix();
        let column = |p: DVec3| {
            let c = clip * p.extend(1.0);
            assert!(c.w > 0.0, "{p} is behind the eye");
            (c.x / c.w + 1.0) * 0.5 * size.0
        };
        let kept_max = [min.y, max.y]
            .into_iter()
            .flat_map(|y| [min.z, max.z].map(|z| column(DVec3::new(cut_x, y, z))))
            .chain(
                [min.y, max.y]
                    .into_iter()
                    .flat_map(|y| [min.z, max.z].map(|z| column(DVec3::new(min.x, y, z)))),
            )
            .fold(f64::MIN, f64::max);
        assert!(
            kept_max < size.0 - 50.0,
            "the cut leaves {} columns of {}",
            size.0 - kept_max,
            size.0
        );
        let background = RendererOptions::default().clear_color;
        let bg = [background.r, background.g, background.b].map(|c| srgb(c).round() as u8);
        let beyond = |png: &std::path::Path| {
            let image = image::open(png).expect("screenshot").to_rgba8();
            let right = Viewport {
                x: view.x + kept_max.ceil() as u32 + 2,
                width: view.width - kept_max.ceil() as u32 - 2,
                ..view
            };
            count_pixels(&image, right, |p| (0..3).any(|c| p[c].abs_diff(bg[c]) > 2))
        };
        let (before, after) = (beyond(&whole_png), beyond(&cut_png));
        assert!(
            before > 1000,
            "only {before} plant pixels beyond the cut before it"
        );
        assert_eq!(
            after, 0,
            "{after} pixels beyond the cut still show geometry"
        );
    });
}

/// The viewer's minimum distance between two neighbouring pipes (11.3 mm
/// apart) equals the
/// clearance `dmu collide` reports for the pair (1e-6 relative); the collide
/// report loads into the clash list, and showing the pair's clash isolates
/// the two parts and measures the same distance.
#[test]
fn measured_distance_equals_dmu_collide_clearance_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let plant = plant_200k();
        let (a, b) = (PartId(300), PartId(304));
        // One step: pipe a where it is, checked with a clearance wide enough to
        // reach its neighbour b.
        let w = plant.part_world(a);
        let (_, rotation, translation) = w.to_scale_rotation_translation();
        let record = dir.path().join("stay.jsonl");
        let line = json!({
            "t": 0.0,
            "part": "#300",
            "translation": translation.to_array(),
            "rotation": rotation.to_array(),
        });
        std::fs::write(&record, format!("{line}\n")).unwrap();
        let collide_json = dir.path().join("collide.json");
        let (status, collide) = dmu_status(&[
            "collide",
            "--plant-triangles",
            crate::xvfb::PLANT,
            "--record",
            path_str(&record),
            "--clearance",
            "50",
            "--json",
        ]);
        assert_eq!(status, Some(1), "soft clashes within 50 mm: {collide}");
        std::fs::write(&collide_json, serde_json::to_vec(&collide).unwrap()).unwrap();
        let clashes = collide["clashes"].as_array().unwrap();
        let index = clashes
            .iter()
            .position(|c| c["a_id"] == a.0 && c["b_id"] == b.0)
            .unwrap_or_else(|| panic!("no clash of #300 with #304 in {collide}"));
        let clearance = clashes[index]["distance"].as_f64().unwrap();
        assert!(clearance > 0.0, "the pipes are apart: {}", clashes[index]);

        let png = image_path("viewer-measure.png");
        let report = run_script(
            dir.path(),
            &json!([
                {"overlays": {"stats": false}},
                {"measure_parts": ["#300", "#304"]},
                {"load_clashes": collide_json},
                {"show_clash": index},
                {"frames": 2},
                {"screenshot": png},
            ]),
        );
        let measured = step(&report, 1, "measure_parts");
        let distance = measured["distance"].as_f64().unwrap();
        assert!(
            (distance - clearance).abs() <= 1e-6 * clearance,
            "viewer {distance} vs dmu collide {clearance}"
        );
        let pa = DVec3::from_array(serde_json::from_value(measured["point_a"].clone()).unwrap());
        let pb = DVec3::from_array(serde_json::from_value(measured["point_b"].clone()).unwrap());
        assert!((pa.distance(pb) - distance).abs() <= 1e-6 * distance);
        assert_eq!(
            step(&report, 2, "load_clashes")["added"],
            clashes.len(),
            "one list entry per clash of the report"
        );
        let shown = step(&report, 3, "show_clash");
        assert_eq!(shown["a"], plant.part_name(a));
        assert_eq!(shown["b"], plant.part_name(b));
        let shown_distance = shown["distance"].as_f64().unwrap();
        assert!((shown_distance - clearance).abs() <= 1e-6 * clearance);
        // Isolated: the frame after shows only the two pipes' triangles.
        let last = report["frames"].as_array().unwrap().last().unwrap();
        let pair = plant.part_mesh(a).triangle_count() + plant.part_mesh(b).triangle_count();
        assert!(
            last["triangles_drawn"].as_u64().unwrap() <= pair,
            "isolated pair draws {} triangles, the two parts have {pair}",
            last["triangles_drawn"]
        );
    });
}

/// The view commands no other test's script names, each through a script
/// on the 200k plant: panes, viewpoints saved and gone back to, clicks that
/// measure and place a section plane on a face, framing, and a BCF file
/// written and read back. (Every review command goes through the library's
/// one apply in `command.rs`'s test; the rest of the view commands through
/// the other scripts here.)
#[test]
fn every_view_command_a_script_names_under_xvfb() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let (_, (x, y), _) = first_look(dir.path(), "viewer-commands");
        let (x, y) = (f64::from(x), f64::from(y));
        let bcf = dir.path().join("review.bcfzip");
        let report = run_script(
            dir.path(),
            &json!([
                no_overlays(),
                {"pane": 0},
                {"save_viewpoint": "start"},
                {"measure": {"mode": "points", "at": [[x, y], [x + 2.0, y]]}},
                {"section_face": [x, y]},
                "clear_section",
                "frame_all",
                {"export_bcf": bcf},
                {"import_bcf": bcf},
                {"view": "top"},
                {"viewpoint": "start"},
            ]),
        );
        let saved = step(&report, 2, "save_viewpoint");
        assert_eq!(saved["name"], "start");
        let measured = step(&report, 3, "measure");
        let end = |k: &str| -> DVec3 {
            DVec3::from_array(serde_json::from_value(measured[k]["point"].clone()).unwrap())
        };
        let distance = measured["distance"].as_f64().unwrap();
        assert!(
            (distance - end("a").distance(end("b"))).abs() <= 1e-9 * distance.max(1.0),
            "{measured}"
        );
        let face = step(&report, 4, "section_face");
        assert!(
            face["section"].as_str().unwrap().contains("plane"),
            "{face}"
        );
        step(&report, 5, "clear_section");
        step(&report, 6, "frame_all");
        // One topic: the saved viewpoint (nothing moved, so no clash is listed).
        assert_eq!(step(&report, 7, "export_bcf")["topics"], 1);
        assert_eq!(report["bcf_export"]["topics"], 1);
        let imported = step(&report, 8, "import_bcf");
        assert_eq!(
            (imported["topics"].as_u64(), imported["viewpoints"].as_u64()),
            (Some(1), Some(1))
        );
        assert_eq!(imported["skipped_topics"], 0);
        // Back at the saved viewpoint after the top view: the report's camera
        // is the one saved.
        let eye = |v: &Value| DVec3::from_array(serde_json::from_value(v["eye"].clone()).unwrap());
        let (now, then) = (eye(&report["camera"]), eye(saved));
        assert!(
            now.distance(then) <= 1e-9 * then.length().max(1.0),
            "{now} vs {then}"
        );
    });
}
