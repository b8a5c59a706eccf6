//! `dmu-viewer`: the desktop viewer of the dmu digital mockup. Open a plant,
//! ship or aircraft (glTF, a dmu store, or the built-in plant), walk through
//! it, pick a part, drag it and see at once what it collides with, undo, and
//! save the review.
//!
//! Design choices:
//! - winit owns the window and the event loop; egui (egui-winit, egui-wgpu)
//!   draws the panels; dmu-render draws the model into an offscreen target that
//!   egui shows as an image, so panels never cover the 3D view and picking
//!   works in the view's own pixels.
//! - The model opens through the same code and arguments as the `dmu` command
//!   line (`dmu_app::load`), so `--plant-triangles 10M` is the same plant in both
//!   and a pick here equals `dmu pick` for the same ray.
//! - Picking forms the ray in f64 from the camera's basis and asks the cell
//!   tree ([`dmu_tree::Tree::pick`]); moves place parts absolutely and update
//!   the tree at every drag step; collisions of the selection are checked live
//!   with dmu-collide; undo and redo restore transforms bit for bit.
//! - Up to four panes, each with its own camera and its own renderer view (so
//!   its own culling state); one can show the main pane's cells drawn or
//!   culled. Parts clashing with the selection and the part under the pointer
//!   are tinted by the renderer's per-part flags.
//! - A session can be recorded (`--record`) in the JSON Lines format `dmu
//!   collide --record` replays: every placement is one absolute pose.
//! - A store's far fields (`dmu farfield build`) stand in for what lies
//!   beyond the cull box of the eye's viewpoint cell in the main view
//!   (`--far-field on|auto`); a move makes those showing the part stale, and
//!   they are captured again once the view is calm (`far`).
//! - Automation runs the same frames: `--script` actions go one per frame (a
//!   drag one step per frame), `--screenshot` reads back the swapchain, and the
//!   run prints one JSON report (picks with their rays, saves, frame times).
//!
//! Conventions: model units (millimetres for the plant), Z up, f64 world
//! coordinates; view pixels are physical pixels of the 3D view, y down.

mod app;
mod budget;
mod compose;
mod farfield;
mod gfx;
mod launch;
mod panes;
mod tools_ui;
mod ui;
mod xr;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use anyhow::Context as _;
use clap::Parser;
use dmu_app::farfield::{FarFieldSet, FarUse};
use dmu_viewer::{
    clashes, command, gizmo, issues, measure, nav, record, review, script, section, settings,
    tools, viewpoints,
};
use serde::Serialize;

/// dmu-viewer: walk, pick, move with live collision, save the review.
///
/// Mouse: click picks, drag orbits about the picked point (or, with a drag
/// axis set, slides the selection along it), right-drag looks, middle-drag
/// pans, the wheel zooms toward the pointer, double-click focuses. Keys: WASD
/// walk (Q/E down/up, Shift faster), F focus, Home frame all, Ctrl+Z / Ctrl+Y
/// undo / redo, Esc deselect.
#[derive(Debug, Parser)]
#[command(name = "dmu-viewer", version, about, long_about)]
struct Cli {
    #[command(flatten)]
    model: dmu_app::load::ModelArgs,
    #[command(flatten)]
    remote: dmu_app::remote::RemoteArgs,
    /// Window width, pixels.
    #[arg(long, default_value_t = 1280, value_parser = clap::value_parser!(u32).range(64..=16384))]
    width: u32,
    /// Window height, pixels.
    #[arg(long, default_value_t = 800, value_parser = clap::value_parser!(u32).range(64..=16384))]
    height: u32,
    /// Culling: none, frustum (with coverage), chc (plus occlusion queries)
    /// hzb (plus a depth pyramid of last frame's visible set, every box
    /// tested against it in a compute pass, the newly visible drawn at once)
    /// or auto (whichever of frustum, chc and hzb is fastest here, timed).
    #[arg(long, default_value = "frustum", value_parser = ["none", "frustum", "chc", "hzb", "auto"])]
    culling: String,
    /// Save the window as PNG after the last frame (with --frames or --script).
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Draw this many frames, then exit (after the script, if any); at most
    /// 1,000,000.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    frames: Option<u32>,
    /// Run a JSON list of actions (pick, move, drag, save, screenshot...), then exit.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Record every move of the session to this JSON Lines file (the format
    /// `dmu collide --record` replays, docs/record-format.md).
    #[arg(long, value_name = "FILE.jsonl")]
    record: Option<PathBuf>,
    /// Do not wait for vertical sync (measure frame times).
    #[arg(long)]
    no_vsync: bool,
    /// Paint the whole window every frame instead of copying the panels as
    /// last painted and painting only the 3D views over them (slower on a CPU
    /// rasterizer; for comparison).
    #[arg(long)]
    paint_whole: bool,
    /// While a part is dragged, repaint the side panels (its position, its
    /// clashes) at most this often, in ms; the 3D view is drawn every frame
    /// and the panels are exact again once the drag ends. On a CPU
    /// rasterizer repainting the whole window costs about as much as the 3D
    /// view. 0: every frame.
    #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(0..=60_000))]
    panel_refresh_ms: u64,
    /// Show the stats overlay (frame time and its split, triangles, culling,
    /// memory) over the 3D view from the start; the top bar's "stats" box
    /// toggles it. Off by default: painting its text over the view each
    /// frame costs about 10 ms on a CPU rasterizer.
    #[arg(long)]
    stats: bool,
    /// Draw each chunk's coarsest simplified level whose estimated error
    /// projects to at most this many pixels (0: every chunk whole, the exact image).
    #[arg(long, default_value_t = 1.0, value_parser = dmu_app::units::number_in(0.0, 1e6))]
    lod_error_px: f64,
    /// Do not merge subtrees into simplified proxies. By default (with a LOD
    /// error above 0) each subtree of the cell tree gets one merged,
    /// simplified mesh while the model loads, drawn in one call instead of its
    /// chunks where its error projects within --lod-error-px.
    #[arg(long)]
    no_proxies: bool,
    /// Draw the back faces of solid meshes too. By default they are culled
    /// where no section plane cuts (from outside a solid they are hidden);
    /// for measuring what that saves.
    #[arg(long)]
    no_cull_back_faces: bool,
    /// A frame-time budget for the 3D view, ms (e.g. 100 for 10 frames a
    /// second): each frame then chooses its LOD error (from 0, exact) and
    /// coverage threshold after the last frame's time; the stats overlay shows
    /// the choice.
    #[arg(long, value_parser = dmu_app::units::number_in(1.0, 1e6))]
    target_ms: Option<f64>,
    /// Keep the whole process within this much memory (e.g. 1GiB): the model
    /// (a .dmu store) opens as its structure alone, chunks are read as the
    /// views want them and dropped least recently used, each pick or check
    /// loads the meshes it reads. Without it the whole model is loaded.
    #[arg(long, value_parser = dmu_app::units::parse_bytes, conflicts_with = "xr")]
    memory_budget: Option<u64>,
    /// Chunk instances whose box is smaller on screen than this (its
    /// diagonal, pixels) are not drawn, nor loaded under --memory-budget.
    /// Default 0 (everything drawn), and 2 under --memory-budget: a model
    /// seen whole has far more chunks than pixels, and the chunks a view
    /// wants must fit the budget.
    #[arg(long, value_parser = dmu_app::units::number_in(0.0, 1e6))]
    min_pixels: Option<f64>,
    /// Under --memory-budget, what a chunk wanted but not loaded yet is
    /// drawn as: its box, flat-shaded (box), or nothing (none: a hole).
    #[arg(long, default_value = "box", value_parser = ["box", "none"], requires = "memory_budget")]
    stand_ins: String,
    /// Far fields (`dmu farfield build`) in the main 3D view, for a .dmu
    /// store that has them: beyond the cull box of the eye's viewpoint cell
    /// the model is drawn as the cell's textured depth meshes (on), or only
    /// where frames are faster with them, timed every 60 frames (auto). Far
    /// fields made stale by moved parts are captured again once the view is
    /// calm (in memory; the store keeps its own). Not with --memory-budget.
    #[arg(long, default_value = "off", value_parser = FarUse::NAMES, conflicts_with = "xr")]
    far_field: String,
    /// The length of one model unit, for BCF issues written and read (BCF is
    /// in metres; the built-in plant is in millimetres).
    #[arg(long, value_enum, default_value = "mm")]
    unit: dmu_app::units::LengthUnit,
    /// Show the model in a headset through the active OpenXR runtime
    /// (XR_RUNTIME_JSON) instead of a window: both eyes drawn with the
    /// runtime's poses and fields of view, until --frames are submitted (and
    /// --xr-script has run) or the runtime ends the session. docs/xr.md.
    #[arg(long)]
    xr: bool,
    /// With --xr: where the tracking space stands in the model and what the
    /// hand does (aim, grab, undo), a JSON file (docs/xr.md).
    #[arg(long, requires = "xr", value_name = "FILE.json")]
    xr_script: Option<PathBuf>,
    /// With --xr: save the last frame's eye images as DIR/left.png and
    /// DIR/right.png.
    #[arg(long, requires = "xr", value_name = "DIR")]
    save_eyes: Option<PathBuf>,
    /// With --xr: the longest side of each eye's image, pixels (the
    /// runtime's recommended aspect, within its maximum size).
    #[arg(long, requires = "xr", default_value_t = 1024, value_parser = clap::value_parser!(u32).range(16..=8192))]
    eye_px: u32,
    /// With --xr: the frame-time budget of both eyes: `display` (the
    /// runtime's predicted display period: a frame that would be late draws
    /// coarser levels and drops small nodes), `off` (the LOD error and
    /// coverage threshold stay as set: exact images), or milliseconds.
    #[arg(long, requires = "xr", default_value = "display", value_parser = xr::Budget::parse)]
    xr_budget: xr::Budget,
    /// With --xr: cull and draw both eyes once where they form a parallel
    /// rig sharing a field of view (auto), each eye apart (per-eye), or
    /// alternate the two frame by frame to time both in one run (compare).
    #[arg(long, requires = "xr", value_enum, default_value = "auto")]
    xr_stereo: xr::Stereo,
    /// With --xr: print the report as one JSON object (else one line).
    #[arg(long, requires = "xr")]
    json: bool,
}

fn run(cli: &Cli, started: Instant) -> anyhow::Result<()> {
    let script = cli
        .script
        .as_deref()
        .map(script::read)
        .transpose()?
        .unwrap_or_default();
    if cli.screenshot.is_some() && cli.frames.is_none() && script.is_empty() {
        anyhow::bail!("--screenshot needs --frames or --script (it is taken at the end)");
    }
    if cli.xr {
        return run_xr(cli);
    }
    let far_field = FarUse::from_name(&cli.far_field)
        .with_context(|| format!("--far-field {}: not off, on or auto", cli.far_field))?;
    // Checked before the window opens: the error is the first thing seen.
    let far_store = far_field_store(cli, far_field)?;
    // The model loads on a thread while the window shows the progress.
    let progress = Arc::new(launch::LoadProgress::default());
    let (send, result) = std::sync::mpsc::channel();
    let (model, record_path, shared) = (cli.model.clone(), cli.record.clone(), progress.clone());
    // Made in memory from every chunk, or read from the store's
    // level-of-detail hierarchy under a memory budget.
    let proxies = cli.lod_error_px > 0.0 && !cli.no_proxies;
    let budget = cli.memory_budget;
    std::thread::Builder::new()
        .name("dmu load".into())
        .spawn(move || {
            let loaded = load_review(&model, record_path.as_deref(), &shared, proxies, budget)
                .and_then(|mut loaded| {
                    if let Some(store) = &far_store {
                        loaded.far_fields = Some(open_far_fields(store, &loaded.review)?);
                    }
                    Ok(loaded)
                });
            let _ = send.send(loaded);
        })
        .context("starting the loading thread")?;
    let automated = cli.frames.is_some() || !script.is_empty();
    let options = app::Options {
        size: (cli.width, cli.height),
        culling: script::culling_from_name(&cli.culling)?,
        screenshot: cli.screenshot.clone(),
        frames: cli.frames,
        script,
        vsync: !(cli.no_vsync || automated),
        compose: !cli.paint_whole,
        stats: cli.stats,
        panel_lag: std::time::Duration::from_millis(cli.panel_refresh_ms),
        cull_back_faces: !cli.no_cull_back_faces,
        lod_error_px: cli.lod_error_px,
        min_pixels: cli.min_pixels.unwrap_or(if cli.memory_budget.is_some() {
            budget::MIN_PIXELS
        } else {
            0.0
        }),
        target_ms: cli.target_ms,
        unit: cli.unit,
        memory_budget: cli.memory_budget,
        stand_ins: cli.stand_ins == "box",
        far_field,
        started,
    };
    let event_loop = match winit::event_loop::EventLoop::new() {
        Ok(e) => e,
        // Without a display the model's own errors still come first.
        Err(e) => {
            result
                .recv()
                .context("the loading thread ended without a model")??;
            return Err(e).context("opening the display (is DISPLAY or WAYLAND_DISPLAY set?)");
        }
    };
    let instance = wgpu::Instance::new(dmu_render::instance_descriptor(
        wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        )),
    ));
    let loading = launch::Loading {
        result,
        progress,
        started: Instant::now(),
        what: cli.model.file.as_ref().map_or_else(
            || {
                format!(
                    "the built-in plant ({:.1}M triangles)",
                    cli.model.plant_triangles as f64 / 1e6
                )
            },
            |f| f.display().to_string(),
        ),
    };
    let mut launcher = launch::Launcher::new(instance, options, loading);
    event_loop.run_app(&mut launcher)?;
    if let Some(report) = launcher.finish()? {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

/// Loads the model, builds its review (cell tree included) and starts the
/// recording asked for: everything before the first frame, on the loading
/// thread. The report's facts about the model come with it.
/// `--xr`: the review in a headset through OpenXR (docs/xr.md), the model
/// loaded first (no window to show its progress in).
fn run_xr(cli: &Cli) -> anyhow::Result<()> {
    anyhow::ensure!(
        cli.script.is_none() && cli.screenshot.is_none(),
        "--xr takes --xr-script and --save-eyes, not the window's --script and --screenshot"
    );
    let args = xr::XrArgs {
        script: cli
            .xr_script
            .as_deref()
            .map(dmu_viewer::xr_script::read)
            .transpose()?
            .unwrap_or_default(),
        frames: cli.frames,
        save_eyes: cli.save_eyes.clone(),
        eye_px: cli.eye_px,
        culling: script::culling_from_name(&cli.culling)?,
        culling_options: dmu_render::CullingOptions {
            lod_error_px: cli.lod_error_px,
            ..Default::default()
        },
        budget: cli.xr_budget,
        stereo: cli.xr_stereo,
    };
    let loaded = load_review(
        &cli.model,
        cli.record.as_deref(),
        &launch::LoadProgress::default(),
        false,
        None,
    )?;
    let report = xr::run(loaded.review, args, loaded.facts)?;
    if cli.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{}", xr::summary_line(&report));
    }
    Ok(())
}

fn load_review(
    model: &dmu_app::load::ModelArgs,
    record_path: Option<&std::path::Path>,
    progress: &launch::LoadProgress,
    proxies: bool,
    memory_budget: Option<u64>,
) -> launch::LoadResult {
    let (loaded, store) = match memory_budget {
        Some(budget) => {
            let (loaded, store) = open_skeleton(model, budget)?;
            (loaded, Some(store))
        }
        None => {
            let loaded = dmu_app::load::load_reporting(model, &|done, total| {
                progress.total.store(total, Ordering::Relaxed);
                progress.done.store(done, Ordering::Relaxed);
            })?;
            (loaded, None)
        }
    };
    let rss_after_open = dmu_app::progress::rss_bytes();
    let tree_start = Instant::now();
    let mut review = review::Review::new(loaded.scene, loaded.source);
    let tree_ms = tree_start.elapsed().as_secs_f64() * 1e3;
    let mut check_index_ms = None;
    let mut stored_proxies = None;
    if let (Some(budget), Some(store)) = (memory_budget, store) {
        if proxies {
            // Read on a thread of their own: the viewer's frames are not
            // replayed, and loading is then not bound by their time.
            stored_proxies =
                dmu_app::lod::stored_proxies(&store, dmu_app::lod::proxy_budget(budget))?.map(
                    |mut p| {
                        p.load_in_background();
                        p
                    },
                );
        }
        let start = Instant::now();
        review.prepare_checks();
        check_index_ms = Some(start.elapsed().as_secs_f64() * 1e3);
        review.geometry = Some(dmu_viewer::on_demand::OnDemand::new(
            store,
            budget::tool_cap_bytes(budget),
        ));
    }
    review.recorder = record_path.map(record::Recorder::create).transpose()?;
    let proxies = match memory_budget {
        Some(_) => stored_proxies,
        None => proxies.then(|| {
            let r = &review;
            dmu_app::progress::build_proxies(&r.scene, &r.tree, &r.scene, true)
        }),
    };
    let b = review.scene.world_bounds();
    let facts = app::to_value(Facts {
        model: ModelFacts {
            source: review.source.as_deref(),
            name: review.scene.name(),
            triangles: review.scene.triangle_count(),
            parts: review.scene.parts().len(),
            load_ms: loaded.load_ms,
            tree_ms,
            check_index_ms,
            rss_after_open_bytes: rss_after_open,
            rss_after_load_bytes: dmu_app::progress::rss_bytes(),
            proxies: proxies
                .as_ref()
                .map(|p| dmu_app::progress::proxies_json(&p.stats())),
            cells: review.tree.cell_count(),
            bounds: Bounds {
                min: b.min.to_array(),
                max: b.max.to_array(),
            },
        },
    });
    Ok(launch::Loaded {
        review,
        facts,
        proxies,
        far_fields: None,
    })
}

/// The model and load facts a run's report begins with.
#[derive(Debug, Serialize)]
struct Facts<'a> {
    model: ModelFacts<'a>,
}

/// The model opened: its source, size, load times and memory, proxies,
/// cells and world bounds.
#[derive(Debug, Serialize)]
struct ModelFacts<'a> {
    source: Option<&'a std::path::Path>,
    name: &'a str,
    triangles: u64,
    parts: usize,
    load_ms: f64,
    tree_ms: f64,
    check_index_ms: Option<f64>,
    rss_after_open_bytes: Option<u64>,
    rss_after_load_bytes: Option<u64>,
    proxies: Option<serde_json::Value>,
    cells: usize,
    bounds: Bounds,
}

/// A world box in a report.
#[derive(Debug, Serialize)]
struct Bounds {
    min: [f64; 3],
    max: [f64; 3],
}

/// With `--far-field on|auto`: the model's store, checked to hold far
/// fields (its skeleton dropped: the scene loads apart); `None` with off.
fn far_field_store(cli: &Cli, far: FarUse) -> anyhow::Result<Option<Arc<dmu_store::Store>>> {
    if far == FarUse::Off {
        return Ok(None);
    }
    let flag = format!("--far-field {}", far.name());
    anyhow::ensure!(
        cli.memory_budget.is_none(),
        "{flag}: not under --memory-budget (a far field made stale by a move is captured \
         again from everything outside its cull box, which a store's skeleton has not loaded)"
    );
    let path = cli.model.file.as_ref().with_context(|| {
        format!(
            "{flag}: the built-in plant has no far fields; make a store that has them with \
             `dmu generate plant -o plant.dmu` and `dmu farfield build plant.dmu`"
        )
    })?;
    let gltf = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    anyhow::ensure!(
        !gltf,
        "{flag}: {} is glTF, and far fields live in .dmu stores; make one with \
         `dmu import {0} -o model.dmu` and `dmu farfield build model.dmu`",
        path.display()
    );
    let mut store = dmu_store::Store::open(path)?;
    anyhow::ensure!(
        store.far_field_index()?.is_some(),
        "{flag}: {} has no far fields; make them with `dmu farfield build {0}`",
        path.display()
    );
    drop(store.take_skeleton());
    Ok(Some(Arc::new(store)))
}

/// The far fields of `store` for the model `review` loaded: made from its
/// poses, or refused.
fn open_far_fields(
    store: &Arc<dmu_store::Store>,
    review: &review::Review,
) -> anyhow::Result<FarFieldSet> {
    FarFieldSet::open(store, &review.scene)?.with_context(|| {
        format!(
            "{} has no far fields; make them with `dmu farfield build {0}`",
            store.path().display()
        )
    })
}

/// Under `--memory-budget`: the store's structure alone, no geometry.
fn open_skeleton(
    model: &dmu_app::load::ModelArgs,
    budget: u64,
) -> anyhow::Result<(dmu_app::load::Loaded, Arc<dmu_store::Store>)> {
    let start = Instant::now();
    let path = model.file.as_ref().with_context(|| {
        format!(
            "--memory-budget {budget}: needs a .dmu store (the built-in plant is made in memory; \
             `dmu import` makes a store of a glTF file)"
        )
    })?;
    let mut store = dmu_store::Store::open(path)?;
    let loaded = dmu_app::load::Loaded {
        scene: store.take_skeleton(),
        report: Default::default(),
        source: Some(path.clone()),
        load_ms: start.elapsed().as_secs_f64() * 1e3,
    };
    Ok((loaded, Arc::new(store)))
}

#[expect(unsafe_code, reason = "quiet_device_select runs before any thread")]
fn main() -> ExitCode {
    // SAFETY: first in main, while the process has one thread.
    unsafe { dmu_app::quiet_device_select() };
    let started = Instant::now();
    let cli = Cli::parse();
    cli.remote.apply();
    match run(&cli, started) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", dmu_app::text::error_line("dmu-viewer", &e));
            ExitCode::from(2)
        }
    }
}
