//! A version-3 store, whose chunks have no stored levels (the renderer
//! computes them on upload), draws the same images as its version-4 copy,
//! whose levels are read from the file, and as the scene in memory.

use dmu_render::{Camera, Capture, Culling, GeometrySource, Renderer, RendererOptions, View};
use dmu_scene::{ChunkGeometry, ChunkId};
use dmu_store::{OwnedChunkGeometry, Store, save_edits};
use dmu_tree::{Tree, TreeOptions};
use glam::DVec3;

/// A store's chunks, every one decoded: what a residency lends once all are
/// resident.
struct Decoded(Vec<OwnedChunkGeometry>);

impl Decoded {
    fn of(store: &Store) -> Self {
        let chunks = store.skeleton().chunks().len();
        Self(
            (0..chunks)
                .map(|c| store.chunk_geometry(ChunkId::from_index(c)).unwrap())
                .collect(),
        )
    }
}

impl GeometrySource for Decoded {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        Some(self.0.get(chunk.index())?.geometry())
    }
}

#[test]
fn a_version_3_store_draws_as_its_rewritten_copy_and_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.dmu");
    let fixture = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../dmu-store/tests/data/plant10k_version3.dmu"
    );
    std::fs::copy(fixture, &path).unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.info().version, 3);
    let scene = store.load_scene().unwrap();
    let old = Decoded::of(&store);
    save_edits(&store, &scene).unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.info().version, 4);
    let new = Decoded::of(&store);
    assert!(
        new.0
            .iter()
            .any(|g| g.levels.as_ref().is_some_and(|l| !l.is_empty()))
    );

    let tree = Tree::build(&scene, TreeOptions::default());
    let b = scene.world_bounds();
    let camera = Camera {
        eye: b.center() + b.extent() * DVec3::new(-0.6, -0.8, 0.5),
        target: b.center(),
        up: DVec3::Z,
        fov_y_rad: 50f64.to_radians(),
        near: 10.0,
    };
    let size = (320, 180);
    dmu_testkit::with_gpu(|gpu| {
        let (device, queue) = (&gpu.device, &gpu.queue);
        let shot = |source: &dyn GeometrySource, tau: f64| {
            let options = RendererOptions {
                lod_levels: true,
                ..Default::default()
            };
            let mut renderer = Renderer::new(device, queue, &scene, &tree, options);
            let capture = Capture::new(device, size);
            let mut view = View::new(camera, size, Culling::Frustum);
            view.options.lod_error_px = tau;
            let stats = renderer
                .render(&mut view, &scene, &tree, source, capture.frame_target())
                .unwrap();
            let image = capture.read_color(device, queue).unwrap();
            (image, stats.triangles_drawn)
        };
        let mut triangles = Vec::new();
        for tau in [0.0, 2.0, 8.0] {
            let (in_memory, drawn) = shot(&scene, tau);
            let (from_v3, _) = shot(&old, tau);
            let (from_v4, _) = shot(&new, tau);
            assert!(
                in_memory == from_v3,
                "tau {tau}: the version-3 store draws otherwise"
            );
            assert!(
                in_memory == from_v4,
                "tau {tau}: the version-4 copy draws otherwise"
            );
            triangles.push(drawn);
        }
        assert!(triangles[2] < triangles[0], "levels drawn: {triangles:?}");
    });
}
