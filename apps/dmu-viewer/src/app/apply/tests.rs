//! Every view command through the one [`App::apply_view`], on an app with
//! no window (the panes' views are sized by hand; nothing is drawn).

use std::time::{Duration, Instant};

use dmu_render::Culling;
use glam::{DVec2, DVec3};

use super::super::{App, Options, TURN_PER_PIXEL};
use crate::command::{ReviewCommand, ViewCommand, ViewPoint};
use crate::nav::{Keys, Motion, Preset};
use crate::review::Review;
use crate::settings::Occlusion;

/// Which variant a command is; a variant added to [`ViewCommand`] fails to
/// compile here until the test below drives it too.
fn variant(c: &ViewCommand) -> usize {
    use ViewCommand as V;
    match c {
        V::Pick(_) => 0,
        V::Click(_) => 1,
        V::Reveal(_) => 2,
        V::Focus(_) => 3,
        V::FrameAll => 4,
        V::Hover(_) => 5,
        V::Press { .. } => 6,
        V::PointerTo { .. } => 7,
        V::Release => 8,
        V::ShowClash(_) => 9,
        V::GoTo(_) => 10,
        V::SaveViewpoint(_) => 11,
        V::ExportBcf(_) => 12,
        V::ImportBcf(_) => 13,
        V::Preset(_) => 14,
        V::Camera { .. } => 15,
        V::Look(_) => 16,
        V::Pan(_) => 17,
        V::Zoom { .. } => 18,
        V::Walk { .. } => 19,
        V::Motion(_) => 20,
        V::Speed(_) => 21,
        V::MinPixels(_) => 22,
        V::LodErrorPx(_) => 23,
        V::Panes(_) => 24,
        V::ActivePane(_) => 25,
        V::Culling(_) => 26,
        V::Occlusion(_) => 27,
        V::PaintWhole(_) => 28,
        V::Screenshot(_) => 29,
    }
}
const VARIANTS: usize = 30;

/// Size of the panes' views, pixels.
const SIZE: (u32, u32) = (640, 480);

/// A windowless viewer of a 2x2x2 grid of 4-unit boxes on a pitch of 10.
fn app() -> App {
    let options = Options {
        size: SIZE,
        culling: Culling::Frustum,
        screenshot: None,
        frames: None,
        script: Vec::new(),
        vsync: false,
        compose: true,
        stats: false,
        panel_lag: Duration::ZERO,
        cull_back_faces: true,
        lod_error_px: 0.0,
        min_pixels: 0.0,
        target_ms: None,
        unit: dmu_app::units::LengthUnit::Mm,
        memory_budget: None,
        stand_ins: true,
        far_field: dmu_app::farfield::FarUse::Off,
        started: Instant::now(),
    };
    let review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let mut app = App::new(instance, review, options, serde_json::Value::Null);
    app.panes[0].view.size = SIZE;
    app
}

/// Where a world point shows in the active pane.
fn pixel_of(app: &App, point: DVec3) -> ViewPoint {
    let pane = &app.panes[app.active];
    let p: DVec2 = crate::gizmo::Projector::new(&pane.nav.camera(), pane.view.size)
        .project(point)
        .expect("in front of the eye");
    (p.x, p.y)
}

fn close(a: DVec3, b: DVec3) -> bool {
    a.distance(b) <= 1e-9 * b.length().max(1.0)
}

#[test]
fn every_view_command_goes_through_apply_view() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = app();
    let a = app.review.scene.find_part("box_0_0_0").unwrap();
    let b = app.review.scene.find_part("box_1_0_0").unwrap();
    let centre = |app: &App, p| app.review.scene.part_world_bounds(p).center();
    let mut seen = [false; VARIANTS];
    let mut run = |app: &mut App, c: ViewCommand| {
        seen[variant(&c)] = true;
        app.apply_view(c)
    };
    use ViewCommand as V;

    // Panes and their settings.
    run(&mut app, V::Panes(2)).unwrap();
    assert_eq!(app.panes.len(), 2);
    run(&mut app, V::ActivePane(1)).unwrap();
    assert_eq!(app.active, 1);
    assert!(run(&mut app, V::ActivePane(2)).is_err());
    assert!(run(&mut app, V::Panes(0)).is_err());
    run(&mut app, V::Culling(Culling::None)).unwrap();
    run(&mut app, V::MinPixels(3.0)).unwrap();
    run(&mut app, V::LodErrorPx(1.5)).unwrap();
    let second = &app.panes[1].view;
    assert_eq!(second.culling, Culling::None);
    assert_eq!(
        (second.options.min_pixels, second.options.lod_error_px),
        (3.0, 1.5)
    );
    assert_eq!(app.panes[0].view.culling, Culling::Frustum);
    run(&mut app, V::ActivePane(0)).unwrap();
    run(&mut app, V::Occlusion(Occlusion::On)).unwrap();
    assert_eq!(Occlusion::of(&app.panes[0].view), Occlusion::On);
    assert_eq!(run(&mut app, V::PaintWhole(true)).unwrap(), None);

    // The camera: walking, looking, panning, the wheel.
    run(&mut app, V::Motion(Motion::Fly)).unwrap();
    run(&mut app, V::Speed(4.0)).unwrap();
    let before = app.panes[0].nav;
    assert_eq!((before.motion, before.speed_factor), (Motion::Fly, 4.0));
    let keys = Keys {
        forward: 1.0,
        ..Keys::default()
    };
    run(&mut app, V::Walk { keys, dt: 0.5 }).unwrap();
    let nav = app.panes[0].nav;
    let flown = before.forward() * before.speed() * 0.5;
    assert!(
        close(nav.eye - before.eye, flown),
        "{}",
        nav.eye - before.eye
    );
    run(&mut app, V::Look((10.0, -4.0))).unwrap();
    let looked = app.panes[0].nav;
    assert_eq!(looked.eye, nav.eye);
    assert!((looked.yaw - (nav.yaw - 10.0 * TURN_PER_PIXEL)).abs() < 1e-12);
    assert!((looked.pitch - (nav.pitch + 4.0 * TURN_PER_PIXEL)).abs() < 1e-12);
    run(&mut app, V::Pan((8.0, 0.0))).unwrap();
    let panned = app.panes[0].nav;
    let slid = panned.eye - looked.eye;
    assert!(slid.dot(looked.right()) < 0.0 && slid.cross(looked.right()).length() < 1e-9);
    assert!(close(panned.pivot - looked.pivot, slid));
    run(&mut app, V::FrameAll).unwrap();
    assert_eq!(app.panes[0].nav.pivot, app.review.tree.bounds().center());
    let at_a = pixel_of(&app, centre(&app, a));
    let eye = app.panes[0].nav.eye;
    run(
        &mut app,
        V::Zoom {
            wheel: 200.0,
            at: at_a,
        },
    )
    .unwrap();
    let zoomed = app.panes[0].nav;
    let hit = zoomed.pivot;
    assert!(
        app.review
            .scene
            .part_world_bounds(a)
            .inflated(1e-9)
            .contains_point(hit)
    );
    assert!(close(zoomed.eye, eye + (hit - eye) * 0.5));

    // Presets and cameras.
    run(&mut app, V::Preset(Preset::Top)).unwrap();
    assert!(app.panes[0].nav.forward().z < -0.99);
    let (eye, forward) = (DVec3::new(-30.0, 2.0, 2.0), DVec3::X);
    run(&mut app, V::Camera { eye, forward }).unwrap();
    assert_eq!(app.panes[0].nav.eye, eye);
    assert!(close(app.panes[0].nav.forward(), forward));
    let forward = DVec3::ZERO;
    assert!(run(&mut app, V::Camera { eye, forward }).is_err());

    // The pointer: picks, clicks, hovering, focusing, drags.
    run(&mut app, V::FrameAll).unwrap();
    let at_a = pixel_of(&app, centre(&app, a));
    let picked = run(&mut app, V::Pick(at_a)).unwrap().unwrap();
    assert_eq!(picked["hit"]["part_id"], a.0, "{picked}");
    assert_eq!(app.review.selected, Some(a));
    run(&mut app, V::Reveal(b)).unwrap();
    assert_eq!((app.review.selected, app.ui.reveal), (Some(b), Some(b)));
    run(&mut app, V::Click(at_a)).unwrap();
    assert_eq!(app.review.selected, Some(a));
    let hovered = run(&mut app, V::Hover(Some((0, at_a)))).unwrap().unwrap();
    assert_eq!(
        (hovered["part_id"].as_u64(), app.hovered),
        (Some(u64::from(a.0)), Some(a))
    );
    run(&mut app, V::Focus(None)).unwrap();
    assert_eq!(app.panes[0].nav.pivot, centre(&app, a));
    // A press off the model orbits about the pivot.
    let app_yaw = app.panes[0].nav.yaw;
    run(
        &mut app,
        V::Press {
            at: (1.0, 1.0),
            axis: None,
        },
    )
    .unwrap();
    let (at, delta, free) = ((21.0, 1.0), (20.0, 0.0), false);
    run(&mut app, V::PointerTo { at, delta, free }).unwrap();
    run(&mut app, V::Release).unwrap();
    assert!(app.pointer_drag.is_none());
    assert!((app.panes[0].nav.yaw - (app_yaw - 20.0 * TURN_PER_PIXEL)).abs() < 1e-12);

    // Viewpoints and BCF files.
    let saved = run(&mut app, V::SaveViewpoint("start".into()))
        .unwrap()
        .unwrap();
    assert_eq!(saved["name"], "start");
    let start = app.panes[0].nav.eye;
    run(&mut app, V::Preset(Preset::Side)).unwrap();
    run(&mut app, V::GoTo("start".into())).unwrap();
    assert!(close(app.panes[0].nav.eye, start));
    assert!(run(&mut app, V::GoTo("nowhere".into())).is_err());
    let bcf = dir.path().join("written.bcfzip");
    let near = app.panes[0].nav.near;
    let issues = crate::issues::issues(&app.review, &app.tools.viewpoints, near);
    let topics: Vec<_> = issues.into_iter().map(|i| i.topic).collect();
    dmu_app::bcf::write_bcfzip(&bcf, &topics, None, app.options.unit.per_metre()).unwrap();
    let imported = run(&mut app, V::ImportBcf(bcf)).unwrap().unwrap();
    assert_eq!(
        (imported["topics"].as_u64(), imported["viewpoints"].as_u64()),
        (Some(1), Some(1))
    );
    let export = dir.path().join("review.bcfzip");
    let exporting = run(&mut app, V::ExportBcf(export.clone()))
        .unwrap()
        .unwrap();
    assert_eq!(exporting["topics"], 1);
    assert!(app.export.is_some());
    // One export at a time: a second is refused out loud (it did nothing
    // and answered an empty entry).
    let again = run(&mut app, V::ExportBcf(export)).unwrap_err();
    assert!(
        format!("{again:#}").contains("still being written"),
        "{again:#}"
    );
    app.export = None;

    // A clash shown: its two parts alone.
    app.edit(ReviewCommand::Select(Some(a))).unwrap();
    app.edit(ReviewCommand::Translate(DVec3::X * 8.0)).unwrap();
    assert!(!app.review.clash_list.is_empty());
    run(&mut app, V::ShowClash(0)).unwrap();
    let shown: Vec<_> = app
        .review
        .scene
        .part_ids()
        .filter(|&p| !app.review.scene.part(p).hidden)
        .collect();
    assert_eq!(shown, [a, b]);

    let png = dir.path().join("shot.png");
    run(&mut app, V::Screenshot(png.clone())).unwrap();
    assert_eq!(app.screenshot, Some(png));

    let missed: Vec<usize> = (0..VARIANTS).filter(|&i| !seen[i]).collect();
    assert!(missed.is_empty(), "variants not driven: {missed:?}");
}
