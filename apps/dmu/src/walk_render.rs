//! `dmu walk --render`: every frame of a camera path rendered on the GPU, with
//! frame times and culling stats per mode; with `--compare`, `none`, `frustum`,
//! `chc` and `hzb` run in one process over the same frames, each image is
//! compared with the unculled one pixel for pixel, and the chunks drawn by each
//! occlusion-culling mode are set against the exactly visible ones (chunk ids
//! rendered without occlusion culling).

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
pub use dmu_app::farfield::FarUse;
use dmu_app::farfield::{FarAuto, FarFieldSet};
use dmu_render::{
    Camera, Capture, Culling, CullingOptions, FrameStats, Renderer, RendererOptions, View,
    headless_device,
};
use dmu_scene::{ChunkId, Scene};
use dmu_store::{CameraFrame, Drawn, Store, WalkOptions};
use dmu_tree::{EntryId, Tree};
use serde::Serialize;

use crate::resident::StreamedFrames;
use dmu_geom::percentile;

/// One mode's frame.
#[derive(Debug, Serialize)]
struct ModeFrame {
    /// The culling the frame used (frustum where the mode's could not run
    /// or chose not to).
    culling: &'static str,
    /// Frame time on the CPU, waiting for the GPU included, ms.
    frame_ms: f64,
    gpu_ms: f64,
    /// Of `frame_ms`, uploading chunks to the GPU (and simplifying those
    /// whose levels the store does not hold), ms.
    upload_ms: f64,
    triangles_drawn: u64,
    chunks_drawn: u64,
    /// Proxies drawn (merged subtrees).
    proxies_drawn: u64,
    /// Nodes drawn coarser than the LOD bound asks while their stored
    /// proxies load.
    lod_coarse: u64,
    draw_calls: u64,
    queries: u64,
    rounds: u32,
    /// The LOD error bound and coverage threshold drawn with, pixels.
    lod_error_px: f64,
    min_pixels: f64,
    occlusion_enabled: bool,
    /// The frame drew a far field.
    far_field: bool,
    /// Triangles of the far field's depth meshes drawn.
    far_field_triangles: u64,
    /// Pixels differing from the reference image (with `--compare`).
    differing_pixels: Option<u64>,
    /// Mean colour difference of those pixels (0-255, mean over channels).
    mean_color_error: Option<f64>,
    /// Of those, pixels differing by more than `dmu_render::SURFACE_CHANGE`
    /// in a channel: showing another surface, not the same one shaded a
    /// little differently.
    surface_differing_pixels: Option<u64>,
}

/// One frame of the path.
#[derive(Debug, Serialize)]
struct PathFrame {
    /// Per mode; the reference's is `None` on frames it was not drawn (see
    /// [`Compare::reference_every`]).
    modes: Vec<Option<ModeFrame>>,
    /// Triangles of the chunk instances owning at least one pixel.
    exact_visible_triangles: Option<u64>,
    /// Exactly visible chunk instances that `chc` did not draw.
    chc_missing_chunks: Option<u64>,
    /// Exactly visible chunk instances that `hzb` did not draw.
    hzb_missing_chunks: Option<u64>,
}

/// What an occlusion-culling mode missed over the path, against the exactly
/// visible chunk instances.
#[derive(Debug, Default)]
struct Misses {
    /// Missing last frame.
    before: BTreeSet<EntryId>,
    /// Missing two frames running while visible: more than one frame late.
    late: u64,
}

impl Misses {
    /// This frame's missing chunk instances, given the exactly visible ones
    /// and those the mode drew.
    fn frame(&mut self, exact: &BTreeSet<EntryId>, drawn: impl Iterator<Item = EntryId>) -> u64 {
        let drawn: BTreeSet<EntryId> = drawn.collect();
        let missing: BTreeSet<EntryId> = exact.difference(&drawn).copied().collect();
        self.late += missing.intersection(&self.before).count() as u64;
        let count = missing.len() as u64;
        self.before = missing;
        count
    }
}

/// Totals of one mode.
#[derive(Debug, Serialize)]
struct ModeTotals {
    /// The mode: its culling, `+far` with far fields, `+far-auto` with far
    /// fields where they pay.
    culling: String,
    mean_frame_ms: f64,
    median_frame_ms: f64,
    p95_frame_ms: f64,
    mean_triangles_drawn: f64,
    mean_draw_calls: f64,
    mean_queries: f64,
    /// The LOD error bound drawn with, pixels, on average.
    mean_lod_error_px: f64,
    /// With a frame-time budget: the share of frames within 110 % of it.
    frames_within_110_percent_of_target: Option<f64>,
    /// Frames whose image differs from `none` in any pixel.
    frames_with_differing_pixels: Option<u64>,
    /// Pixels differing from `none`, per frame on average and at worst.
    mean_differing_pixels: Option<f64>,
    /// Pixels showing another surface than `none`'s, per frame on average.
    mean_surface_differing_pixels: Option<f64>,
    worst_differing_pixels: Option<u64>,
}

/// The renderer's camera for a path frame, the near plane at 1/10 000 of the
/// model's diagonal.
fn camera(frame: &CameraFrame, tree: &Tree) -> Camera {
    frame.camera((tree.bounds().extent().length() * 1e-4).max(1e-6))
}

/// The choices one mode made by measurement over its frames (occlusion on or
/// off, and under `target_ms` the LOD error and coverage threshold), each
/// line naming the mode.
fn explain(culling: Culling, target_ms: Option<f64>, frames: &[FrameStats]) -> Vec<String> {
    dmu_app::explain::occlusion_changes(culling, frames)
        .into_iter()
        .chain(dmu_app::explain::auto_changes(frames))
        .chain(dmu_app::explain::budget_changes(target_ms, frames))
        .map(|line| format!("{}: {line}", culling.name()))
        .collect()
}

fn mode_frame(stats: &FrameStats, differing: Option<Differing>) -> ModeFrame {
    ModeFrame {
        far_field: stats.far_field,
        far_field_triangles: stats.far_field_triangles,
        culling: stats.culling.name(),
        frame_ms: stats.cpu_ms,
        gpu_ms: stats.gpu_ms,
        upload_ms: stats.upload_ms,
        triangles_drawn: stats.triangles_drawn,
        chunks_drawn: stats.chunks_drawn,
        proxies_drawn: stats.proxies_drawn,
        lod_coarse: stats.lod_coarse,
        draw_calls: stats.draw_calls,
        queries: stats.queries,
        lod_error_px: stats.lod_error_px,
        min_pixels: stats.min_pixels,
        rounds: stats.rounds,
        occlusion_enabled: stats.occlusion.enabled,
        differing_pixels: differing.map(|d| d.any),
        surface_differing_pixels: differing.map(|d| d.surface),
        mean_color_error: differing.map(|d| d.mean_color_error),
    }
}

/// Frame-time and drawing totals of one mode over its frames, drawn under
/// `target_ms` if any.
fn mode_totals<'a>(
    name: String,
    target_ms: Option<f64>,
    frames: impl Iterator<Item = &'a ModeFrame>,
) -> ModeTotals {
    let frames: Vec<&ModeFrame> = frames.collect();
    let mut ms: Vec<f64> = frames.iter().map(|f| f.frame_ms).collect();
    let n = frames.len().max(1) as f64;
    let differing: Vec<u64> = frames.iter().filter_map(|f| f.differing_pixels).collect();
    let compared = !differing.is_empty();
    ModeTotals {
        culling: name,
        mean_lod_error_px: frames.iter().map(|f| f.lod_error_px).sum::<f64>() / n,
        frames_within_110_percent_of_target: target_ms
            .map(|t| frames.iter().filter(|f| f.frame_ms <= 1.1 * t).count() as f64 / n),
        mean_frame_ms: ms.iter().sum::<f64>() / n,
        median_frame_ms: percentile(&mut ms, 0.5),
        p95_frame_ms: percentile(&mut ms, 0.95),
        mean_triangles_drawn: frames.iter().map(|f| f.triangles_drawn as f64).sum::<f64>() / n,
        mean_draw_calls: frames.iter().map(|f| f.draw_calls as f64).sum::<f64>() / n,
        mean_queries: frames.iter().map(|f| f.queries as f64).sum::<f64>() / n,
        frames_with_differing_pixels: compared
            .then(|| differing.iter().filter(|&&d| d > 0).count() as u64),
        mean_differing_pixels: compared
            .then(|| differing.iter().sum::<u64>() as f64 / differing.len().max(1) as f64),
        mean_surface_differing_pixels: compared.then(|| {
            frames
                .iter()
                .filter_map(|f| f.surface_differing_pixels)
                .sum::<u64>() as f64
                / differing.len().max(1) as f64
        }),
        worst_differing_pixels: compared.then(|| differing.iter().copied().max().unwrap_or(0)),
    }
}

/// Renderer options for views culled with `culling`: chunks get simplified
/// levels when the views may draw them.
fn lod_options(culling: &CullingOptions) -> RendererOptions {
    RendererOptions {
        lod_levels: culling.may_draw_lods(),
        ..Default::default()
    }
}

/// A walk mode: a culling, with or without far fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mode {
    pub culling: Culling,
    pub far: FarUse,
}

impl Mode {
    /// The culling alone.
    pub fn plain(culling: Culling) -> Self {
        Self {
            culling,
            far: FarUse::Off,
        }
    }

    /// Its name in the report: the culling's, `+far` or `+far-auto` after it.
    pub fn name(self) -> String {
        let far = match self.far {
            FarUse::Off => "",
            FarUse::On => "+far",
            FarUse::Auto => "+far-auto",
        };
        format!("{}{far}", self.culling.name())
    }
}

/// How two images differ: pixels differing at all, by more than
/// `SURFACE_CHANGE`, and the mean colour difference of the differing ones.
#[derive(Clone, Copy, Debug)]
struct Differing {
    any: u64,
    surface: u64,
    mean_color_error: f64,
}

fn differing(reference: &[u8], image: &[u8]) -> Differing {
    let (any, surface) = dmu_render::count_differing(reference, image);
    let error: u64 = reference
        .chunks_exact(4)
        .zip(image.chunks_exact(4))
        .filter(|(a, b)| a != b)
        .map(|(a, b)| (0..3).map(|c| u64::from(a[c].abs_diff(b[c]))).sum::<u64>())
        .sum();
    Differing {
        any,
        surface,
        mean_color_error: error as f64 / 3.0 / any.max(1) as f64,
    }
}

/// How a walk compares its modes with the exact image.
#[derive(Debug, Clone, Copy)]
pub struct Compare {
    /// The reference (the first mode, drawn exact) and the exactly visible
    /// chunks are drawn on every this many frames only (1: every frame); the
    /// other modes are timed on every frame and their images compared on
    /// those. On a large model the exact frame costs seconds.
    pub reference_every: usize,
}

impl Compare {
    /// Whether frame `k` draws the reference.
    fn sampled(self, k: usize) -> bool {
        k.is_multiple_of(self.reference_every.max(1))
    }
}

/// Renders `path` with each of `modes` (the first is the reference with
/// `compare`, drawn exact whatever `culling.lod_error_px`) and returns the
/// JSON report. Modes with far fields draw those of `far`, which must be
/// given then.
#[expect(
    clippy::too_many_arguments,
    reason = "the walk's settings from the command line, passed through once"
)]
pub fn run(
    scene: &Scene,
    tree: &Tree,
    path: &[CameraFrame],
    size: (u32, u32),
    modes: &[Mode],
    compare: Option<Compare>,
    culling: CullingOptions,
    proxies: bool,
    mut far: Option<FarFieldSet>,
) -> anyhow::Result<serde_json::Value> {
    let (device, queue, adapter) = headless_device().context("opening a GPU device")?;
    let mut renderer = Renderer::new(&device, &queue, scene, tree, lod_options(&culling));
    if proxies && culling.may_draw_lods() {
        renderer.set_proxies(dmu_app::progress::build_proxies(scene, tree, scene, false));
    }
    if far.is_some() {
        renderer.enable_far_fields(scene, tree);
    }
    let camera = |f: &CameraFrame| camera(f, tree);
    let captures: Vec<Capture> = modes.iter().map(|_| Capture::new(&device, size)).collect();
    let mut views: Vec<View> = modes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut view = View::new(camera(&path[0]), size, m.culling);
            view.options = culling;
            if compare.is_some() && i == 0 {
                // The reference is exact.
                view.options.lod_error_px = 0.0;
                view.options.target_ms = None;
            }
            view
        })
        .collect();
    let mut oracle_view = View::new(camera(&path[0]), size, Culling::Frustum);
    let plain = |c: Culling| modes.iter().position(|&m| m == Mode::plain(c));
    let chc = plain(Culling::Occlusion);
    let hzb = plain(Culling::Hzb);
    let mut frames = Vec::with_capacity(path.len());
    let (mut chc_misses, mut hzb_misses) = (Misses::default(), Misses::default());
    let mut stats_of: Vec<Vec<FrameStats>> = modes.iter().map(|_| Vec::new()).collect();
    let mut autos: Vec<FarAuto> = modes.iter().map(|_| FarAuto::default()).collect();
    let progress = indicatif::ProgressBar::new(path.len() as u64);
    for (k, frame) in path.iter().enumerate() {
        let field = match &mut far {
            // The first frame waits for its cell; later ones take what the
            // loader has.
            Some(set) if k == 0 => set.wait_for(frame.eye)?,
            Some(set) => set.for_eye(frame.eye)?,
            None => None,
        };
        let mut reference: Option<Vec<u8>> = None;
        let sampled = compare.map(|c| c.sampled(k));
        let mut modes_out = Vec::with_capacity(modes.len());
        for (i, view) in views.iter_mut().enumerate() {
            if i == 0 && sampled == Some(false) {
                modes_out.push(None);
                continue;
            }
            view.camera = camera(frame);
            view.far_field = match modes[i].far {
                FarUse::Off => None,
                FarUse::On => field.clone(),
                FarUse::Auto => autos[i].next_frame().then(|| field.clone()).flatten(),
            };
            let stats: FrameStats =
                renderer.render(view, scene, tree, scene, captures[i].frame_target())?;
            if modes[i].far == FarUse::Auto {
                autos[i].after(stats.cpu_ms - stats.upload_ms, k);
            }
            let differing = if sampled == Some(true) {
                let image = captures[i].read_color(&device, &queue)?;
                match &reference {
                    None => {
                        reference = Some(image.into_raw());
                        Some(differing(&[], &[]))
                    }
                    Some(r) => Some(differing(r, image.as_raw())),
                }
            } else {
                None
            };
            modes_out.push(Some(mode_frame(&stats, differing)));
            stats_of[i].push(stats);
        }
        let exact = match chc.or(hzb) {
            Some(c) if sampled == Some(true) => {
                oracle_view.camera = camera(frame);
                Some(
                    renderer
                        .render_ids(&mut oracle_view, scene, tree, scene, &captures[c])?
                        .visible_entries(),
                )
            }
            _ => None,
        };
        let missing = |mode: Option<usize>, misses: &mut Misses| {
            Some(misses.frame(exact.as_ref()?, views[mode?].drawn_entries()))
        };
        frames.push(PathFrame {
            modes: modes_out,
            exact_visible_triangles: exact.as_ref().map(|exact| {
                exact
                    .iter()
                    .map(|e| u64::from(tree.entries()[e.0 as usize].triangles))
                    .sum()
            }),
            chc_missing_chunks: missing(chc, &mut chc_misses),
            hzb_missing_chunks: missing(hzb, &mut hzb_misses),
        });
        progress.inc(1);
    }
    progress.finish_and_clear();

    let totals: Vec<ModeTotals> = modes
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            let target = views[i].options.target_ms;
            mode_totals(
                m.name(),
                target,
                frames.iter().filter_map(|f| f.modes[i].as_ref()),
            )
        })
        .collect();
    // The last mode of that name: the reference comes first and may share
    // its culling's name; drawn on some frames only, it is no ratio's side.
    let every_frame = compare.is_none_or(|c| c.reference_every == 1);
    let mean_of = |name: &str| {
        let (i, t) = totals
            .iter()
            .enumerate()
            .rfind(|(_, t)| t.culling == name)?;
        (i > 0 || every_frame).then_some(t.mean_frame_ms)
    };
    let ratio = |a: &str, b: &str| Some(mean_of(a)? / mean_of(b)?);
    // Per frame, a mode's triangles over the exactly visible ones.
    let over_exact = |mode: Option<usize>| -> Vec<f64> {
        let Some(m) = mode else { return Vec::new() };
        frames
            .iter()
            .filter_map(|f| {
                let exact = f.exact_visible_triangles?;
                Some(f.modes[m].as_ref()?.triangles_drawn as f64 / exact.max(1) as f64)
            })
            .collect()
    };
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let (chc_over, hzb_over) = (over_exact(chc), over_exact(hzb));
    Ok(serde_json::json!({
        "adapter": adapter.name,
        "size": [size.0, size.1],
        "frames": path.len(),
        "scene_triangles": scene.triangle_count(),
        "requery_interval": culling.requery_interval,
        "lod_error_px": culling.lod_error_px,
        "target_ms": culling.target_ms,
        "max_rounds": culling.max_rounds,
        "proxies": renderer.proxy_stats().as_ref().map(dmu_app::progress::proxies_json),
        "totals": totals,
        "frustum_over_chc_frame_time": ratio("frustum", "chc"),
        "none_over_chc_frame_time": ratio("none", "chc"),
        "chc_over_hzb_frame_time": ratio("chc", "hzb"),
        "frustum_over_hzb_frame_time": ratio("frustum", "hzb"),
        "chc_over_exact_triangles_mean": mean(&chc_over),
        "chc_over_exact_triangles_worst": chc_over.iter().copied().reduce(f64::max),
        "hzb_over_exact_triangles_mean": mean(&hzb_over),
        "hzb_over_exact_triangles_worst": hzb_over.iter().copied().reduce(f64::max),
        "reference_every": compare.map(|c| c.reference_every),
        // Lateness needs the exactly visible chunks of consecutive frames.
        "chc_chunks_more_than_one_frame_late": (compare.is_some() && every_frame && chc.is_some()).then_some(chc_misses.late),
        "hzb_chunks_more_than_one_frame_late": (compare.is_some() && every_frame && hzb.is_some()).then_some(hzb_misses.late),
        "explain": modes
            .iter()
            .zip(&stats_of)
            .zip(&views)
            .flat_map(|((&m, stats), view)| explain(m.culling, view.options.target_ms, stats))
            .chain(modes.iter().zip(&autos).flat_map(|(m, a)| {
                a.changes().iter().map(move |c| format!("{}: {c}", m.name()))
            }))
            .collect::<Vec<_>>(),
        "far_field": far_report(far.as_ref(), modes, &frames),
        "per_frame": frames,
    }))
}

/// The far fields' figures: their cells, bytes and build times, and per
/// far-field mode its frames' pixels differing from the reference (median,
/// worst) and frame time against the same culling without far fields.
fn far_report(
    far: Option<&FarFieldSet>,
    modes: &[Mode],
    frames: &[PathFrame],
) -> serde_json::Value {
    let Some(far) = far else {
        return serde_json::Value::Null;
    };
    let index = far.index();
    let n = index.cells.len().max(1) as f64;
    let of = |m: usize| frames.iter().filter_map(move |f| f.modes[m].as_ref());
    let median_ms = |m: usize| {
        let mut ms: Vec<f64> = of(m).map(|f| f.frame_ms).collect();
        percentile(&mut ms, 0.5)
    };
    let per_mode: Vec<serde_json::Value> = modes
        .iter()
        .enumerate()
        .filter(|(_, m)| m.far != FarUse::Off)
        .map(|(i, m)| {
            let mut differing: Vec<f64> = of(i)
                .filter_map(|f| f.differing_pixels.map(|d| d as f64))
                .collect();
            let mut surface: Vec<f64> = of(i)
                .filter_map(|f| f.surface_differing_pixels.map(|d| d as f64))
                .collect();
            let errors: Vec<f64> = of(i)
                .filter(|f| f.differing_pixels.is_some_and(|d| d > 0))
                .filter_map(|f| f.mean_color_error)
                .collect();
            // Not the reference (the first mode), which may share the name.
            let without = modes.iter().rposition(|&o| o == Mode::plain(m.culling)).filter(|&w| w > 0);
            serde_json::json!({
                "mode": m.name(),
                "frames_with_far_field": of(i).filter(|f| f.far_field).count(),
                "far_field_differing_pixels_median": (!differing.is_empty()).then(|| percentile(&mut differing, 0.5)),
                "far_field_differing_pixels_worst": differing.iter().copied().reduce(f64::max),
                "far_field_surface_differing_pixels_median": (!surface.is_empty()).then(|| percentile(&mut surface, 0.5)),
                "far_field_surface_differing_pixels_worst": surface.iter().copied().reduce(f64::max),
                "mean_color_error_of_differing": (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64),
                "median_frame_ms": median_ms(i),
                "without_over_with_median_frame_time": without.map(|w| median_ms(w) / median_ms(i).max(1e-9)),
            })
        })
        .collect();
    serde_json::json!({
        "cells": index.cells.len(),
        "cell_size": index.cell_size,
        "triangle_budget": index.triangle_budget,
        "resolution": index.resolution,
        "mesh_error_px": index.mesh_error_px,
        "bytes_per_cell": index.cells.iter().map(|c| c.bytes as f64).sum::<f64>() / n,
        "build_ms_per_cell": index.cells.iter().map(|c| c.build_ms).sum::<f64>() / n,
        "modes": per_mode,
    })
}

/// How [`run_resident`] draws: the culling and its options, stand-ins for
/// chunks not resident, and how far ahead it looks for what comes into view.
#[derive(Clone, Copy, Debug)]
pub struct Resident {
    pub culling: Culling,
    pub culling_options: CullingOptions,
    /// A chunk wanted but not resident is drawn as its box, not left out.
    pub stand_ins: bool,
    /// Seconds ahead of the eye that the predicted view looks from (0: none).
    pub predict_s: f64,
    /// Also draw the next frame's view, extrapolated.
    pub predict_next: bool,
    /// The predicted views' resolution, as a share of the frame's per axis.
    pub predict_scale: f64,
    /// Show a progress bar.
    pub progress: bool,
    /// Bytes the store's stored proxies may take when loaded (its
    /// level-of-detail hierarchy, if it has one).
    pub proxy_bytes: u64,
    /// When the command started: the first complete image is timed from it.
    pub started: Instant,
}

/// Renders `path` from `store` through a residency manager within
/// `options.budget_bytes`: the renderer draws what is resident (its GPU copies
/// of evicted chunks are dropped with them) and, with stand-ins, the boxes of
/// what is not; what it drew is requested as visible next frame. With a
/// prediction, each frame also draws the view from where the eye will be
/// `predict_s` ahead and, with `predict_next`, the next frame's view (both
/// extrapolated from the last two frames) at `predict_scale` of the
/// resolution, and requests what they drew as visible too: the next frame's
/// view finds what is about to show through a gap, the one further ahead
/// what comes into view in numbers, early enough to load it. A chunk
/// instance the renderer wanted but could not draw (a hole) or drew as its
/// box is a miss. The opening frames (`options.opening_frames`) draw the
/// first view, unrecorded and without a prediction, until one misses
/// nothing or the view proves not to fit.
/// Returns the walk's report and the renderer's per-frame stats.
pub fn run_resident(
    store: &Arc<Store>,
    tree: &Tree,
    path: &[CameraFrame],
    options: &WalkOptions,
    how: Resident,
) -> anyhow::Result<serde_json::Value> {
    let scene = store.skeleton();
    let size = (options.viewport.width, options.viewport.height);
    let scaled = |n: u32| ((f64::from(n) * how.predict_scale).round() as u32).max(1);
    let ahead_size = (scaled(size.0), scaled(size.1));
    let (device, queue, adapter) = headless_device().context("opening a GPU device")?;
    let mut renderer = Renderer::new(
        &device,
        &queue,
        scene,
        tree,
        lod_options(&how.culling_options),
    );
    let mut options = options.clone();
    if how.proxy_bytes > 0
        && how.culling_options.may_draw_lods()
        && let Some(proxies) = dmu_app::lod::stored_proxies(store, how.proxy_bytes)?
    {
        options.lod_cut = dmu_app::lod::use_proxies(
            &mut renderer,
            proxies,
            scene,
            tree,
            how.culling_options.lod_error_px,
        );
    }
    let options = &options;
    let capture = Capture::new(&device, size);
    let camera = |f: &CameraFrame| camera(f, tree);
    let mut view = View::new(camera(&path[0]), size, how.culling);
    view.options = how.culling_options;
    // Each predicted view and how many frames ahead it looks.
    let mut ahead: Vec<(View, f64)> = [
        (how.predict_s > 0.0).then_some(how.predict_s * options.frame_rate_hz),
        how.predict_next.then_some(1.0),
    ]
    .into_iter()
    .flatten()
    .map(|steps| {
        let mut v = View::new(camera(&path[0]), ahead_size, how.culling);
        v.options = how.culling_options;
        (v, steps)
    })
    .collect();
    // The predicted views, drawn one after the other into one target.
    let ahead_capture = (!ahead.is_empty()).then(|| Capture::new(&device, ahead_size));
    let mut streamed = StreamedFrames::new(scene.chunks().len(), how.stand_ins);
    let mut rendered = Vec::with_capacity(path.len());
    let mut stats_all = Vec::with_capacity(path.len());
    let mut frames = Vec::with_capacity(path.len());
    let progress = if how.progress {
        indicatif::ProgressBar::new(path.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut outage = dmu_app::remote::OutageWatch::default();
    let mut first_complete = None;
    let report = dmu_store::walk_with(store, tree, path, options, &mut |index, _, residency| {
        if let Some(line) = outage.update(residency, store.path()) {
            progress.suspend(|| eprintln!("{line}"));
        }
        streamed.begin(residency, renderer.geometry_pool());
        // An opening frame (no index) draws the first view, unrecorded.
        let i = index.unwrap_or(0);
        view.camera = camera(&path[i]);
        let source = streamed.source(residency, scene);
        let stats = renderer.render(&mut view, scene, tree, &source, capture.frame_target())?;
        // The chunks a view drew, one per chunk instance.
        let drawn_chunks = |v: &View| -> Vec<ChunkId> {
            v.drawn_entries()
                .map(|e| tree.entries()[e.0 as usize].chunk)
                .collect()
        };
        let mut visible = drawn_chunks(&view);
        let drawn = visible.len();
        let mut ahead_ms = None;
        // No prediction in an opening frame (the eye stands still) nor in
        // the first (no motion known yet).
        let before = index.and_then(|i| i.checked_sub(1));
        if let (Some(target), Some(before)) = (&ahead_capture, before) {
            let start = Instant::now();
            for (predicted, steps) in &mut ahead {
                if before == 0 {
                    // Its first frame: from the main view's visibility, not
                    // from nothing (which would ask for every chunk in view
                    // at once).
                    predicted.inherit_visibility(&view);
                }
                predicted.camera = view.camera.extrapolated(&camera(&path[before]), *steps);
                renderer.render(predicted, scene, tree, &source, target.frame_target())?;
                visible.extend(drawn_chunks(predicted));
            }
            ahead_ms = Some(start.elapsed().as_secs_f64() * 1e3);
        }
        let misses = streamed.end(
            source.stood_in(),
            visible[..drawn].iter().copied(),
            stats.not_resident,
        );
        if misses.holes + misses.stand_ins == 0 {
            first_complete.get_or_insert_with(|| how.started.elapsed());
        }
        if index.is_some() {
            rendered.push(mode_frame(&stats, None));
            frames.push(ResidentFrame {
                holes: misses.holes,
                stand_ins: misses.stand_ins,
                ahead_ms,
            });
            stats_all.push(stats);
            progress.inc(1);
        }
        Ok(Drawn {
            missing_chunks: misses.holes + misses.stand_ins,
            visible,
            pins: Vec::new(),
        })
    })?;
    progress.finish_and_clear();
    let warm = &frames[options.warmup_frames.min(frames.len())..];
    let count = |frames: &[ResidentFrame], f: fn(&ResidentFrame) -> bool| {
        frames.iter().filter(|&x| f(x)).count() as u64
    };
    let mut ahead_ms: Vec<f64> = frames.iter().filter_map(|f| f.ahead_ms).collect();
    Ok(serde_json::json!({
        "adapter": adapter.name,
        "first_complete_image_ms": first_complete.map(|t: Duration| t.as_secs_f64() * 1e3),
        "walk": report,
        "render": {
            "totals": mode_totals(how.culling.name().into(), how.culling_options.target_ms, rendered.iter()),
            "gpu_pool_bytes": renderer.geometry_pool().resident_bytes(),
            "stand_ins": if how.stand_ins { "box" } else { "none" },
            "frames_with_hole": count(&frames, |f| f.holes > 0),
            "frames_with_standin": count(&frames, |f| f.stand_ins > 0),
            "warm_frames": warm.len(),
            "warm_frames_with_hole": count(warm, |f| f.holes > 0),
            "warm_frames_with_standin": count(warm, |f| f.stand_ins > 0),
            "holes": frames.iter().map(|f| f.holes).sum::<u64>(),
            "stand_ins_drawn": frames.iter().map(|f| f.stand_ins).sum::<u64>(),
            "prediction": {
                "ahead_ms": how.predict_s * 1e3,
                "next_frame": how.predict_next,
                "resolution": (!ahead.is_empty()).then_some(ahead_size),
                "median_frame_ms": (!ahead_ms.is_empty()).then(|| percentile(&mut ahead_ms, 0.5)),
            },
            "per_frame": rendered,
            "per_frame_residency": frames,
        },
        "explain": explain(how.culling, how.culling_options.target_ms, &stats_all),
    }))
}

/// What a frame drawn from the residency lacked, and what its prediction cost.
#[derive(Debug, Serialize)]
struct ResidentFrame {
    /// Chunk instances not drawn for want of geometry.
    holes: u64,
    /// Chunk instances drawn as their boxes.
    stand_ins: u64,
    /// Time of the predicted views, ms.
    ahead_ms: Option<f64>,
}
