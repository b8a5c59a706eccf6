//! Shared test helpers: rigs on the binary's device (`dmu_testkit`), cameras,
//! image output.

use std::time::Duration;

use dmu_geom::glam::DVec3;
use dmu_render::{
    Camera, Capture, Culling, FrameStats, Proxies, ProxyOptions, Renderer, RendererOptions, View,
};
use dmu_scene::Scene;
use dmu_testkit::Gpu;
use dmu_tree::Tree;

pub fn camera(eye: DVec3, target: DVec3, near: f64) -> Camera {
    Camera {
        eye,
        target,
        up: DVec3::Z,
        fov_y_rad: 60f64.to_radians(),
        near,
    }
}

/// A renderer, a capture and one frame of a fresh view.
pub struct Rig {
    pub device: dmu_render::wgpu::Device,
    pub queue: dmu_render::wgpu::Queue,
    pub renderer: Renderer,
    pub capture: Capture,
}

impl Rig {
    pub fn new(gpu: &Gpu, scene: &Scene, tree: &Tree, size: (u32, u32)) -> Rig {
        Self::with_options(gpu, scene, tree, size, Default::default())
    }

    /// A rig whose chunks get their simplified levels.
    pub fn with_lods(gpu: &Gpu, scene: &Scene, tree: &Tree, size: (u32, u32)) -> Rig {
        let options = RendererOptions {
            lod_levels: true,
            ..Default::default()
        };
        Self::with_options(gpu, scene, tree, size, options)
    }

    /// A rig drawing chunk LODs and the scene's proxies.
    pub fn with_proxies(gpu: &Gpu, scene: &Scene, tree: &Tree, size: (u32, u32)) -> Rig {
        let mut rig = Self::with_lods(gpu, scene, tree, size);
        let proxies = Proxies::build(scene, tree, scene, ProxyOptions::default(), &mut |_, _| {});
        rig.renderer.set_proxies(proxies);
        rig
    }

    /// A rig drawing stored proxies ([`stored_proxies`]) loaded within
    /// `budget` bytes, as fast as a frame asks for them.
    pub fn with_stored_proxies(
        gpu: &Gpu,
        scene: &Scene,
        tree: &Tree,
        size: (u32, u32),
        budget: u64,
    ) -> Rig {
        Self::with_stored_proxies_loading(gpu, scene, tree, size, budget, Duration::from_secs(1))
    }

    /// A rig drawing stored proxies loaded within `budget` bytes and `load`
    /// of loading a frame.
    pub fn with_stored_proxies_loading(
        gpu: &Gpu,
        scene: &Scene,
        tree: &Tree,
        size: (u32, u32),
        budget: u64,
        load: Duration,
    ) -> Rig {
        let mut rig = Self::with_lods(gpu, scene, tree, size);
        rig.renderer
            .set_proxies(stored_proxies(scene, tree, budget, load).0);
        rig
    }

    pub fn with_options(
        gpu: &Gpu,
        scene: &Scene,
        tree: &Tree,
        size: (u32, u32),
        options: RendererOptions,
    ) -> Rig {
        let (device, queue) = (gpu.device.clone(), gpu.queue.clone());
        let renderer = Renderer::new(&device, &queue, scene, tree, options);
        let capture = Capture::new(&device, size);
        Rig {
            device,
            queue,
            renderer,
            capture,
        }
    }

    pub fn frame(&mut self, view: &mut View, scene: &Scene, tree: &Tree) -> FrameStats {
        self.renderer
            .render(view, scene, tree, scene, self.capture.frame_target())
            .expect("render")
    }

    pub fn image(&self) -> image::RgbaImage {
        self.capture
            .read_color(&self.device, &self.queue)
            .expect("read colour")
    }

    pub fn ids(&mut self, view: &mut View, scene: &Scene, tree: &Tree) -> dmu_render::IdImage {
        self.renderer
            .render_ids(view, scene, tree, scene, &self.capture)
            .expect("render ids")
    }

    /// The chunk instances the id pass finds visible from `view` that its
    /// last frame did not draw (culling that drops nothing visible has none).
    pub fn visible_but_not_drawn(
        &mut self,
        view: &mut View,
        scene: &Scene,
        tree: &Tree,
    ) -> Vec<dmu_tree::EntryId> {
        let drawn: std::collections::BTreeSet<_> = view.drawn_entries().collect();
        let exact = self.ids(view, scene, tree).visible_entries();
        exact.difference(&drawn).copied().collect()
    }

    /// One frame with `culling`, as an image.
    pub fn shot(
        &mut self,
        camera: Camera,
        culling: Culling,
        scene: &Scene,
        tree: &Tree,
    ) -> image::RgbaImage {
        let mut view = View::new(camera, self.capture.size(), culling);
        self.frame(&mut view, scene, tree);
        self.image()
    }
}

/// Blobs held in memory, as a store holds them.
#[derive(Debug)]
pub struct Blobs(pub Vec<Vec<u8>>);

impl dmu_render::ProxyBlobs for Blobs {
    fn blob(&self, blob: u32) -> Result<Vec<u8>, String> {
        self.0
            .get(blob as usize)
            .cloned()
            .ok_or_else(|| format!("no blob #{blob}"))
    }
}

/// The whole scene as a stored build's chunk loader.
pub struct Loaded<'a>(pub &'a Scene);

impl dmu_render::ChunkLoader for Loaded<'_> {
    fn load(&mut self, _: &[dmu_scene::ChunkId]) -> Result<(), String> {
        Ok(())
    }

    fn source(&self) -> &(dyn dmu_render::GeometrySource + Sync) {
        self.0
    }
}

/// The scene's proxies built as a store keeps them, read back on demand
/// within `budget` bytes and `load` of loading a frame (at least one is
/// loaded; 1 s: a test's frames load everything they ask for), and the
/// bytes they take loaded (their geometry on the GPU).
pub fn stored_proxies(scene: &Scene, tree: &Tree, budget: u64, load: Duration) -> (Proxies, u64) {
    let mut blobs = Vec::new();
    let mut sink = |b: &[u8]| {
        blobs.push(b.to_vec());
        Ok(blobs.len() as u32 - 1)
    };
    let built = dmu_render::build_stored(
        scene,
        tree,
        &mut Loaded(scene),
        ProxyOptions::default(),
        8,
        &mut sink,
        &mut |_, _| {},
    )
    .expect("a scene in memory has every chunk");
    let loaded = built.stats.bytes;
    let proxies = Proxies::stored(&built.index, Box::new(Blobs(blobs)), budget, load)
        .expect("the index just built");
    (proxies, loaded)
}

/// A source holding only the chunks `has` marks.
pub struct Subset<'a> {
    pub scene: &'a Scene,
    pub has: Vec<bool>,
}

impl dmu_render::GeometrySource for Subset<'_> {
    fn chunk_geometry(&self, chunk: dmu_scene::ChunkId) -> Option<dmu_scene::ChunkGeometry<'_>> {
        self.has[chunk.index()]
            .then(|| self.scene.chunk_geometry(chunk))
            .flatten()
    }
}

/// A source holding only every other chunk of a scene: geometry that
/// arrives late.
pub struct EveryOther<'a>(pub &'a Scene);

impl dmu_render::GeometrySource for EveryOther<'_> {
    fn chunk_geometry(&self, chunk: dmu_scene::ChunkId) -> Option<dmu_scene::ChunkGeometry<'_>> {
        chunk
            .index()
            .is_multiple_of(2)
            .then(|| self.0.chunk_geometry(chunk))?
    }
}

impl Rig {
    /// Drops the chunks [`EveryOther`] withholds from the GPU pool (a
    /// reference frame uploaded everything).
    pub fn evict_odd_chunks(&mut self, scene: &Scene) {
        for c in (1..scene.chunks().len()).step_by(2) {
            self.renderer
                .geometry_pool()
                .evict(dmu_scene::ChunkId::from_index(c));
        }
    }
}

/// Pixels that differ.
pub fn differing(a: &image::RgbaImage, b: &image::RgbaImage) -> Vec<(u32, u32)> {
    a.enumerate_pixels()
        .filter(|(x, y, p)| b.get_pixel(*x, *y) != *p)
        .map(|(x, y, _)| (x, y))
        .collect()
}
