//! Rendering knobs on a camera path through the model, each frame compared
//! pixel for pixel with culling `none` (the reference image) and its drawn
//! chunks with the exactly visible ones (chunk ids rendered unculled).
//!
//! Each knob is one entry of [`KNOBS`]: how a setting sets up the view; the
//! stereo pair's ways of drawing follow (`stereo.rs`). Far
//! fields, whose settings are captures rather than a view's culling, are the
//! `far_field` section, reported under rendering too.

use std::collections::BTreeSet;

use anyhow::Context as _;
use dmu_render::{
    Camera, Capture, Culling, CullingOptions, Proxies, ProxyOptions, Renderer, RendererOptions,
    View, headless_device,
};
use dmu_scene::Scene;
use dmu_tree::{EntryId, Tree, TreeOptions};
use glam::DVec3;

use super::{Bench, Knob, Point};

/// A rendering knob: its settings and how one sets up a view's culling.
struct RenderKnob {
    name: &'static str,
    unit: &'static str,
    note: &'static str,
    quick: &'static [f64],
    full: &'static [f64],
    /// The culling mode and options of a setting.
    setup: fn(f64) -> (Culling, CullingOptions),
    /// Drawn by a renderer with proxies (merged subtrees).
    proxies: bool,
}

/// Occlusion knobs measure the knob itself: the adaptive switch, which would
/// turn queries off where they do not pay, stays off.
fn chc(options: CullingOptions) -> (Culling, CullingOptions) {
    (
        Culling::Occlusion,
        CullingOptions {
            adaptive: false,
            ..options
        },
    )
}

const OCCLUSION_NOTE: &str = "0 is no occlusion queries (frustum culling); the adaptive switch is off, so the knob itself is measured";

const KNOBS: &[RenderKnob] = &[
    RenderKnob {
        name: "coverage threshold",
        unit: "px",
        note: "frustum and coverage culling: nodes smaller on screen are dropped",
        quick: &[0.0, 2.0, 8.0],
        full: &[0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0],
        setup: |px| {
            (
                Culling::Frustum,
                CullingOptions {
                    min_pixels: px,
                    ..CullingOptions::default()
                },
            )
        },
        proxies: false,
    },
    RenderKnob {
        name: "LOD error",
        unit: "px",
        note: "frustum culling; each chunk drawn at its coarsest simplified level whose error \
               projects within the setting (0: every chunk whole)",
        quick: &[0.0, 1.0, 4.0],
        full: &[0.0, 0.5, 1.0, 2.0, 4.0, 8.0],
        setup: lod_error,
        proxies: false,
    },
    RenderKnob {
        name: "LOD error with proxies",
        unit: "px",
        note: "as LOD error, and where a merged, simplified subtree's error projects within the \
               setting it is drawn in one call instead of its chunks (0: every chunk whole)",
        quick: &[0.0, 1.0, 4.0],
        full: &[0.0, 0.5, 1.0, 2.0, 4.0, 8.0],
        setup: lod_error,
        proxies: true,
    },
    RenderKnob {
        name: "occlusion re-check interval",
        unit: "frames",
        note: OCCLUSION_NOTE,
        quick: &[0.0, 1.0, 4.0],
        full: &[0.0, 1.0, 2.0, 4.0, 8.0, 16.0],
        setup: |n| {
            if n == 0.0 {
                (Culling::Frustum, CullingOptions::default())
            } else {
                chc(CullingOptions {
                    requery_interval: n as u32,
                    ..CullingOptions::default()
                })
            }
        },
        proxies: false,
    },
    RenderKnob {
        name: "occlusion rounds",
        unit: "rounds a frame",
        note: OCCLUSION_NOTE,
        quick: &[0.0, 1.0, 6.0],
        full: &[0.0, 1.0, 2.0, 3.0, 6.0, 12.0],
        setup: |n| {
            if n == 0.0 {
                (Culling::Frustum, CullingOptions::default())
            } else {
                chc(CullingOptions {
                    max_rounds: n as u32,
                    ..CullingOptions::default()
                })
            }
        },
        proxies: false,
    },
];

/// Frustum culling drawing simplified geometry within `px` pixels of error.
fn lod_error(px: f64) -> (Culling, CullingOptions) {
    (
        Culling::Frustum,
        CullingOptions {
            lod_error_px: px,
            ..CullingOptions::default()
        },
    )
}

/// Knobs the issue asks for that the renderer does not have yet, and when
/// they join [`KNOBS`] (none now: far fields, the last, are measured by the
/// `far_field` section).
pub const PLANNED: &[(&str, &str)] = &[];

/// A path along the model's longest horizontal side at a fifth of its height,
/// looking along it: through the aisles of the plant, across any model.
pub fn path(tree: &Tree, frames: usize) -> Vec<Camera> {
    let b = tree.bounds();
    let e = b.extent();
    let along = if e.x >= e.y { DVec3::X } else { DVec3::Y };
    let across = DVec3::ONE - along - DVec3::Z;
    let z = b.min.z + 0.2 * e.z;
    let start = b.min * along + b.center() * across + DVec3::Z * z;
    let length = (b.max - b.min).dot(along);
    let near = (e.length() * 1e-4).max(1e-6);
    (0..frames)
        .map(|i| {
            let f = 0.05 + 0.9 * i as f64 / frames.max(2) as f64;
            let eye = start + along * (length * f);
            // A slow turn, so occlusion sees parts come and go.
            let turn = 0.4 * (i as f64 / frames.max(1) as f64 - 0.5);
            let dir = along * turn.cos() + across * turn.sin();
            Camera {
                eye,
                target: eye + dir * length * 0.1,
                up: DVec3::Z,
                fov_y_rad: 60f64.to_radians(),
                near,
            }
        })
        .collect()
}

/// The rendering knobs and the adapter's name.
pub fn run(bench: &Bench<'_>) -> anyhow::Result<(Vec<Knob>, String)> {
    let scene: &Scene = bench.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let (device, queue, adapter) = headless_device().context("opening a GPU device")?;
    let size = bench.scale.render_size;
    // Chunks get their simplified levels (the LOD knob); the others draw
    // every chunk whole, as the reference does.
    let options = RendererOptions {
        lod_levels: true,
        ..Default::default()
    };
    let mut renderer = Renderer::new(&device, &queue, scene, &tree, options);
    let mut proxied = Renderer::new(&device, &queue, scene, &tree, options);
    proxied.set_proxies(dmu_app::progress::build_proxies(scene, &tree, scene, true));
    let capture = Capture::new(&device, size);
    let cameras = path(&tree, bench.scale.render_frames);
    // The references: each frame unculled, and its exactly visible chunks.
    let mut reference = Vec::with_capacity(cameras.len());
    let mut exact: Vec<BTreeSet<EntryId>> = Vec::with_capacity(cameras.len());
    let mut view = View::new(cameras[0], size, Culling::None);
    let mut ids_view = View::new(cameras[0], size, Culling::None);
    for &camera in &cameras {
        view.camera = camera;
        renderer.render(&mut view, scene, &tree, scene, capture.frame_target())?;
        reference.push(capture.read_color(&device, &queue)?.into_raw());
        ids_view.camera = camera;
        exact.push(
            renderer
                .render_ids(&mut ids_view, scene, &tree, scene, &capture)?
                .visible_entries(),
        );
    }
    let mut path = PathRun {
        cameras: &cameras,
        reference: &reference,
        exact: &exact,
        capture: &capture,
        device: &device,
        queue: &queue,
        scene,
        tree: &tree,
    };
    let mut knobs = Vec::new();
    for k in KNOBS {
        let settings = if bench.scale.quick { k.quick } else { k.full };
        let mut points = Vec::new();
        for &setting in settings {
            let (culling, options) = (k.setup)(setting);
            let renderer = if k.proxies {
                &mut proxied
            } else {
                &mut renderer
            };
            points.push(path.run(renderer, setting, culling, options)?);
            bench.progress.inc(1);
        }
        knobs.push(Knob {
            section: "rendering",
            name: k.name.to_owned(),
            unit: k.unit.to_owned(),
            note: k.note.to_owned(),
            reference: "culling none, every chunk drawn".to_owned(),
            time: "median frame time".to_owned(),
            error_unit: "differing pixels a frame".to_owned(),
            exact_setting: Some(0.0),
            log_x: false,
            log_error: false,
            points,
        });
    }
    // The proxies' aim: how finely each is simplified, against the size of
    // its subtree. Each setting builds them anew.
    let mut points = Vec::new();
    for &setting in aim_settings(bench.scale.quick) {
        let options = ProxyOptions {
            error_fraction: setting / 1000.0,
            ..ProxyOptions::default()
        };
        let proxies = Proxies::build(scene, &tree, scene, options, &mut |_, _| {});
        let stats = proxies.stats();
        proxied.set_proxies(proxies);
        let (culling, options) = lod_error(1.0);
        let point = path.run(&mut proxied, setting, culling, options)?;
        points.push(
            point
                .extra("proxies' triangles", stats.triangles as f64)
                .extra("ms to make them", stats.ms),
        );
        bench.progress.inc(1);
    }
    knobs.push(Knob {
        section: "rendering",
        name: "proxy aim".to_owned(),
        unit: "‰ of its subtree's diagonal".to_owned(),
        note: "LOD error with proxies at 1 px; each proxy is simplified aiming at an error of the \
               setting times its subtree's box diagonal (the default, 1/512, is about 2 ‰), and \
               claims what it measures: finer proxies hold more triangles and are drawn from \
               nearer"
            .to_owned(),
        reference: "culling none, every chunk drawn".to_owned(),
        time: "median frame time".to_owned(),
        error_unit: "differing pixels a frame".to_owned(),
        exact_setting: None,
        log_x: true,
        log_error: false,
        points,
    });
    knobs.push(super::stereo::knob(
        bench,
        &mut renderer,
        &device,
        &queue,
        scene,
        &tree,
    )?);
    Ok((knobs, adapter.name))
}

/// Steps of the progress bar this section takes.
pub fn steps(quick: bool) -> u64 {
    KNOBS
        .iter()
        .map(|k| if quick { k.quick.len() } else { k.full.len() } as u64)
        .sum::<u64>()
        + aim_settings(quick).len() as u64
        + super::stereo::steps()
}

/// The proxy aim's settings, per mille of a proxy's subtree's box diagonal.
fn aim_settings(quick: bool) -> &'static [f64] {
    match quick {
        true => &[8.0, 2.0],
        false => &[8.0, 4.0, 2.0, 1.0, 0.5],
    }
}

/// A camera path with its reference images and exactly visible chunks, to
/// draw again at each setting of a knob.
struct PathRun<'a> {
    cameras: &'a [Camera],
    reference: &'a [Vec<u8>],
    exact: &'a [BTreeSet<EntryId>],
    capture: &'a Capture,
    device: &'a dmu_render::wgpu::Device,
    queue: &'a dmu_render::wgpu::Queue,
    scene: &'a Scene,
    tree: &'a Tree,
}

impl PathRun<'_> {
    /// The path drawn by `renderer` with `culling` and `options`: the median
    /// frame time, the differing pixels a frame, the chunks late more than a
    /// frame, and the pixels showing another surface a frame.
    fn run(
        &mut self,
        renderer: &mut Renderer,
        setting: f64,
        culling: Culling,
        options: CullingOptions,
    ) -> anyhow::Result<Point> {
        let (scene, tree) = (self.scene, self.tree);
        let size = self.capture.size();
        let mut view = View::new(self.cameras[0], size, culling);
        view.options = options;
        let mut ms = Vec::new();
        let (mut pixels, mut surface) = (0u64, 0u64);
        let mut late = 0u64;
        let mut missing_before = BTreeSet::new();
        for (i, &camera) in self.cameras.iter().enumerate() {
            view.camera = camera;
            let stats =
                renderer.render(&mut view, scene, tree, scene, self.capture.frame_target())?;
            ms.push(stats.cpu_ms);
            let (any, other_surface) = dmu_render::count_differing(
                &self.reference[i],
                self.capture.read_color(self.device, self.queue)?.as_raw(),
            );
            pixels += any;
            surface += other_surface;
            let drawn: BTreeSet<EntryId> = view.drawn_entries().collect();
            let missing: BTreeSet<EntryId> = self.exact[i].difference(&drawn).copied().collect();
            late += missing.intersection(&missing_before).count() as u64;
            missing_before = missing;
        }
        let frames = self.cameras.len() as f64;
        Ok(Point::new(
            setting,
            dmu_geom::median(ms),
            pixels as f64 / frames,
            "differing pixels a frame",
        )
        .extra("late chunks", late as f64)
        .extra(
            "pixels showing another surface a frame",
            surface as f64 / frames,
        ))
    }
}
