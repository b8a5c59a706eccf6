//! Shared test helpers: rigs on the binary's device (`dmu_testkit`), cameras,
//! image output.

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
