//! The loader and the renderer want the same things: the store's wanted set
//! and the renderer's frustum and coverage culling pick the same chunks, and
//! a scene lends chunk geometry only once it is loaded.

use std::collections::BTreeSet;

use dmu_render::{Capture, Culling, GeometrySource, Renderer, View};
use dmu_samples::{PlantOptions, plant};
use dmu_scene::{ChunkId, Scene};
use dmu_store::{CameraFrame, Store, Viewport, Wanted, WriteOptions, wanted, write_scene};
use dmu_tree::{Tree, TreeOptions};
use glam::DVec3;

fn small_plant() -> Scene {
    let mut scene = plant(&PlantOptions {
        triangles: 60_000,
        ..PlantOptions::default()
    });
    // Hidden parts are wanted by neither.
    for p in scene.part_ids().step_by(7).collect::<Vec<_>>() {
        scene.set_part_hidden(p, true);
    }
    scene
}

/// Outside looking in, inside along the x axis, and from above.
fn viewpoints(scene: &Scene) -> Vec<CameraFrame> {
    let b = scene.world_bounds();
    let (c, e) = (b.center(), b.extent());
    let frame = |eye: DVec3, target: DVec3| CameraFrame {
        eye,
        target,
        up: DVec3::Z,
        fov_y_deg: 60.0,
    };
    vec![
        frame(c + e * DVec3::new(-0.7, -0.6, 0.3), c),
        frame(
            c + e * DVec3::new(-0.2, 0.05, -0.3),
            c + e * DVec3::new(0.5, 0.1, -0.3),
        ),
        frame(c + e * DVec3::new(0.01, 0.0, 1.5), c),
    ]
}

#[test]
fn the_wanted_set_is_what_the_renderer_draws() {
    let scene = small_plant();
    let tree = Tree::build(&scene, TreeOptions::default());
    let viewport = Viewport {
        width: 320,
        height: 180,
    };
    let min_pixels = 12.0;
    // The loader's side runs everywhere; the renderer's needs the device.
    let gpu = dmu_testkit::gpu().map_err(dmu_testkit::skip).ok();
    let mut out = Wanted::default();
    let mut subpixel = 0;
    for frame in viewpoints(&scene) {
        let view = dmu_store::View::new(&frame, viewport).unwrap();
        wanted(&tree, &scene, &view, min_pixels, false, None, &mut out);
        let loader: BTreeSet<ChunkId> = out.drawn.iter().map(|&(c, _)| c).collect();
        assert!(!loader.is_empty(), "{frame:?} wants nothing");
        subpixel += out.subpixel.len();
        let Some(gpu) = gpu else {
            continue;
        };
        let (device, queue) = (&gpu.device, &gpu.queue);
        let mut renderer = Renderer::new(device, queue, &scene, &tree, Default::default());
        // The store's near plane: the frusta are then the same.
        let size = (viewport.width, viewport.height);
        let mut gpu_view = View::new(frame.camera(1e-3), size, Culling::Frustum);
        gpu_view.options.min_pixels = min_pixels;
        let capture = Capture::new(device, size);
        renderer
            .render(&mut gpu_view, &scene, &tree, &scene, capture.frame_target())
            .unwrap();
        let drawn: BTreeSet<ChunkId> = gpu_view
            .drawn_entries()
            .map(|e| tree.entries()[e.0 as usize].chunk)
            .collect();
        assert_eq!(drawn, loader, "{frame:?}");
    }
    assert!(subpixel > 0, "no viewpoint cut anything on coverage");
}

#[test]
fn a_skeleton_lends_no_geometry_and_a_loaded_scene_the_stores() {
    let scene = small_plant();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.dmu");
    write_scene(&scene, &path, WriteOptions::default()).unwrap();
    let store = Store::open(&path).unwrap();
    let skeleton = store.skeleton();
    let loaded = store.load_scene().unwrap();
    assert!(!skeleton.chunks().is_empty());
    for i in 0..skeleton.chunks().len() {
        let c = ChunkId(i as u32);
        assert_eq!(skeleton.chunk_geometry(c), None, "chunk {c}");
        assert!(!GeometrySource::has(skeleton, c), "chunk {c}");
        let decoded = store.chunk_geometry(c).unwrap();
        // A loaded scene keeps the geometry, not the stored levels.
        let geometry = dmu_scene::ChunkGeometry {
            levels: None,
            ..decoded.geometry()
        };
        assert_eq!(loaded.chunk_geometry(c), Some(geometry), "chunk {c}");
        assert_eq!(GeometrySource::chunk_geometry(&loaded, c), Some(geometry));
    }
}
