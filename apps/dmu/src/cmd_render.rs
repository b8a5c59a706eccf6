//! `dmu render`: a headless capture of the model to PNG, with culling stats.

use std::path::PathBuf;

use std::collections::BTreeSet;
use std::path::Path;

use anyhow::{Context as _, bail};
use dmu_render::{
    Camera, Capture, Culling, CullingOptions, FrameStats, Renderer, RendererOptions, StereoCamera,
    StereoMode, StereoView, View, headless_device,
};
use dmu_scene::Scene;
use dmu_tree::{EntryId, Tree, TreeOptions};
use glam::DVec3;
use serde_json::json;

use crate::load::{ModelArgs, load};
use crate::units::{MAX_LENGTH, number_in, parse_dvec3};

/// Render the model from a viewpoint into a PNG, headless (any Vulkan, Metal or
/// DX12 adapter; lavapipe on machines without a GPU).
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// Eye position `x,y,z` in world units.
    #[arg(long, allow_hyphen_values = true)]
    eye: String,
    /// Point looked at, `x,y,z`.
    #[arg(long, allow_hyphen_values = true)]
    target: String,
    /// Vertical field of view, degrees (1 to 179).
    #[arg(long, default_value_t = 60.0, value_parser = number_in(1.0, 179.0))]
    fov: f64,
    /// Image size `WIDTHxHEIGHT`.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// Near plane distance, world units, more than 0 (default: 1/10 000 of the
    /// model's diagonal, at most half the distance to the nearest part).
    #[arg(long, value_parser = number_in(1e-9, MAX_LENGTH))]
    near: Option<f64>,
    /// Culling: none, frustum (with coverage), chc (plus occlusion queries)
    /// hzb (plus a depth pyramid of last frame's visible set, every box
    /// tested against it in a compute pass, the newly visible drawn at once)
    /// or auto (whichever of frustum, chc and hzb is fastest here, timed).
    #[arg(long, default_value = "frustum", value_parser = ["none", "frustum", "chc", "hzb", "auto"])]
    culling: String,
    /// Nodes covering fewer pixels across than this are dropped (0: none).
    #[arg(long, default_value_t = 0.0, value_parser = number_in(0.0, 1e6))]
    min_pixels: f64,
    /// Draw each chunk's coarsest simplified level whose estimated error
    /// projects to at most this many pixels (0: every chunk whole, the exact image).
    #[arg(long, default_value_t = 1.0, value_parser = number_in(0.0, 1e6))]
    lod_error_px: f64,
    /// Do not merge subtrees into simplified proxies. By default, with a LOD
    /// error above 0, each subtree of the cell tree gets one merged,
    /// simplified mesh, drawn in one call instead of its chunks where its
    /// error projects within --lod-error-px (frustum culling, and chc views
    /// whose queries are off).
    #[arg(long)]
    no_proxies: bool,
    /// Record every chunk draw as its own draw call instead of batching runs
    /// of them into indirect multi-draws (the same image; for measuring what
    /// batching saves).
    #[arg(long)]
    no_batch_draws: bool,
    /// Draw the back faces of solid meshes too. By default they are culled
    /// where no section plane cuts (from outside a solid they are hidden;
    /// see `dmu info`'s solid meshes); for measuring what that saves.
    #[arg(long)]
    no_cull_back_faces: bool,
    /// Frames rendered from the viewpoint (occlusion culling converges over a
    /// few); the image and stats are the last frame's.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    frames: u32,
    /// Output PNG (with --stereo, OUTPUT-left.png and OUTPUT-right.png).
    #[arg(short, long, value_parser = crate::units::output_with("png"))]
    output: PathBuf,
    /// Render a stereo pair around the eye (parallel axes, --ipd apart along
    /// screen right), culled once and drawn in one multiview pass; also renders
    /// the left eye alone and reports the stereo frame time against it.
    #[arg(long)]
    stereo: bool,
    /// Interpupillary distance for --stereo, world units (65: millimetres).
    #[arg(long, default_value_t = 65.0, requires = "stereo", value_parser = number_in(0.0, MAX_LENGTH))]
    ipd: f64,
    /// How --stereo reaches the two layers: auto (multiview where the driver
    /// draws it correctly), multiview, or layers (a pass per eye).
    #[arg(long, default_value = "auto", value_parser = ["auto", "multiview", "layers"], requires = "stereo")]
    stereo_mode: String,
    /// With --stereo: the left eye's field of view as `left,right,down,up`
    /// angles in degrees (left and down negative), as a headset gives it; the
    /// right eye's is its mirror image. Default: --fov, symmetric. Used by
    /// the pairs --shared-far-px and --reproject draw and compare (the plain
    /// --stereo pair, OUTPUT-left.png and OUTPUT-right.png, keeps --fov).
    #[arg(
        long,
        requires = "stereo",
        allow_hyphen_values = true,
        value_name = "L,R,D,U"
    )]
    eye_fov: Option<String>,
    /// With --stereo: also draw the pair with its far part shared (drawn once
    /// beyond the depth where the eyes' disparity is below this many pixels,
    /// less the eye windows' grid offset, and copied into both eyes; the near
    /// part per eye over it), and report its frame time against one eye and
    /// against the pair drawn in full, and the image difference
    /// (OUTPUT-shared-left.png, OUTPUT-shared-right.png).
    #[arg(long, requires = "stereo", value_parser = number_in(1e-3, 1e3))]
    shared_far_px: Option<f64>,
    /// With --stereo: also draw the pair with its right eye reprojected from
    /// the left eye's image by depth (the left eye drawn once, wide enough
    /// for both windows; each pixel moved by its disparity to the nearest
    /// pixel; the gaps along near silhouettes filled from the farther
    /// neighbour), and report its frame time against one eye and against
    /// the pair drawn in full, the gaps and the image difference
    /// (OUTPUT-reprojected-left.png, OUTPUT-reprojected-right.png).
    #[arg(long, requires = "stereo")]
    reproject: bool,
    /// Print stats as JSON.
    #[arg(long)]
    json: bool,
    /// Also render chunk ids without occlusion culling and report the exactly
    /// visible chunk instances (in either eye, with --stereo) against the
    /// drawn ones.
    #[arg(long)]
    oracle: bool,
    /// Print the choices made by measurement and the figures behind them
    /// (with chc: where occlusion queries were switched on or off, what they
    /// cost and saved); with --json, an "explain" array.
    #[arg(long)]
    explain: bool,
}

/// `WIDTHxHEIGHT`, each side 1 to 16384 pixels.
pub(crate) fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("--size {s:?}: expected WIDTHxHEIGHT"))?;
    let side = |v: &str| {
        v.parse::<u32>()
            .with_context(|| format!("--size {s:?}: {v:?} is not a whole number of pixels"))
    };
    let (w, h) = (side(w)?, side(h)?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("--size {s:?}: each side must be 1 to 16384 pixels");
    }
    Ok((w, h))
}

/// The near plane for an eye at `eye`: 1/10,000 of the model's size, but never
/// beyond half the distance to the nearest chunk, so one far-away part (a huge
/// diagonal) cannot clip away what stands near the eye.
pub(crate) fn default_near(tree: &Tree, eye: DVec3) -> f64 {
    let nearest = tree
        .entries()
        .iter()
        .map(|e| (eye.clamp(e.bounds.min, e.bounds.max) - eye).length())
        .filter(|&d| d > 0.0)
        .fold(f64::INFINITY, f64::min);
    (tree.bounds().extent().length() * 1e-4)
        .min(nearest * 0.5)
        .max(1e-6)
}

/// `OUTPUT-eye.png` next to `OUTPUT`.
fn eye_path(output: &Path, eye: &str) -> PathBuf {
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    let ext = output
        .extension()
        .map_or("png".into(), |e| e.to_string_lossy());
    output.with_file_name(format!("{stem}-{eye}.{ext}"))
}

/// Median CPU and GPU milliseconds of the last half of `frames` (at least one):
/// occlusion culling converges over the first few.
fn steady_ms(frames: &[FrameStats]) -> (f64, f64) {
    let tail = &frames[frames.len() / 2..];
    let median =
        |f: fn(&FrameStats) -> f64| dmu_geom::median(tail.iter().map(f).collect::<Vec<_>>());
    (median(|s| s.cpu_ms), median(|s| s.gpu_ms))
}

/// The oracle's report: chunk instances owning a pixel in any of `eyes` (ids
/// rendered into `capture`) against the ones drawn.
fn oracle_json(
    renderer: &mut Renderer,
    capture: &Capture,
    scene: &Scene,
    tree: &Tree,
    eyes: &[Camera],
    drawn: &BTreeSet<EntryId>,
    triangles_drawn: u64,
) -> anyhow::Result<serde_json::Value> {
    let mut exact = BTreeSet::new();
    for &eye in eyes {
        let mut view = View::new(eye, capture.size(), Culling::None);
        exact.extend(
            renderer
                .render_ids(&mut view, scene, tree, scene, capture)?
                .visible_entries(),
        );
    }
    let triangles: u64 = exact
        .iter()
        .map(|e| u64::from(tree.entries()[e.0 as usize].triangles))
        .sum();
    Ok(json!({
        "exact_visible_chunks": exact.len(),
        "exact_visible_triangles": triangles,
        "missing_from_drawn": exact.difference(drawn).count(),
        "drawn_over_exact_triangles": triangles_drawn as f64 / triangles.max(1) as f64,
    }))
}

/// `count` frames of one view (or pair), each drawn by `frame`.
fn render_frames(
    count: u32,
    mut frame: impl FnMut() -> Result<FrameStats, dmu_render::RenderError>,
) -> Result<Vec<FrameStats>, dmu_render::RenderError> {
    (0..count).map(|_| frame()).collect()
}

fn stats_json(s: &FrameStats) -> serde_json::Value {
    json!({
        "frame": s.frame,
        "culling": s.culling.name(),
        "nodes_visited": s.nodes_visited,
        "culled_frustum": s.culled_frustum,
        "culled_coverage": s.culled_coverage,
        "culled_occlusion": s.culled_occlusion,
        "hidden": s.hidden,
        "culled_section": s.culled_section,
        "not_resident": s.not_resident,
        "queries": s.queries,
        "queries_visible": s.queries_visible,
        "rounds": s.rounds,
        "passes": s.passes,
        "chunks_drawn": s.chunks_drawn,
        "proxies_drawn": s.proxies_drawn,
        "culled_clusters": s.culled_clusters,
        "proxies_stale": s.proxies_stale,
        "lod_coarse": s.lod_coarse,
        "draw_calls": s.draw_calls,
        "upload_ms": s.upload_ms,
        "triangles_drawn": s.triangles_drawn,
        "triangles_in_frustum": s.triangles_in_frustum,
        "newly_visible": s.newly_visible,
        "cpu_ms": s.cpu_ms,
        "gpu_ms": s.gpu_ms,
        "gpu_draw_ms": s.gpu_draw_ms,
        "occlusion": {
            "enabled": s.occlusion.enabled,
            "cost_ms": s.occlusion.cost_ms,
            "saved_ms": s.occlusion.saved_ms,
            "retry_in_frames": s.occlusion.retry_in_frames,
        },
    })
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let eye = parse_dvec3(&args.eye).context("--eye")?;
    let target = parse_dvec3(&args.target).context("--target")?;
    let limit = dmu_scene::MAX_WORLD_COORDINATE;
    if eye.abs().max_element() > limit || target.abs().max_element() > limit {
        bail!("--eye and --target must lie within ±{limit:e} model units");
    }
    let size = parse_size(&args.size)?;
    if eye == target {
        bail!("--eye and --target must differ");
    }
    if !(args.fov > 0.0 && args.fov < 180.0) {
        bail!(
            "--fov {}: must be in (0, 180) degrees",
            dmu_geom::Short(args.fov)
        );
    }
    let culling: Culling = args.culling.parse().map_err(anyhow::Error::msg)?;
    if args.stereo && !(args.ipd >= 0.0 && args.ipd.is_finite()) {
        bail!(
            "--ipd {}: must be finite and not negative",
            dmu_geom::Short(args.ipd)
        );
    }
    let eye_fovs = args
        .eye_fov
        .as_deref()
        .map(crate::stereo_far::parse_eye_fov)
        .transpose()?;
    let loaded = load(&args.model)?;
    let scene = &loaded.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let near = args.near.unwrap_or_else(|| default_near(&tree, eye));
    // Looking straight up or down: any up that is not the view direction will do.
    let forward = (target - eye).normalize();
    let up = if forward.cross(DVec3::Z).length() < 1e-6 {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let camera = Camera {
        eye,
        target,
        up,
        fov_y_rad: args.fov.to_radians(),
        near,
    };
    let stereo_mode = match args.stereo_mode.as_str() {
        "multiview" => StereoMode::Multiview,
        "layers" => StereoMode::LayerPasses,
        _ => StereoMode::Auto,
    };
    let (device, queue, adapter) = headless_device().context("opening a GPU device")?;
    let culling_options = CullingOptions {
        min_pixels: args.min_pixels,
        lod_error_px: args.lod_error_px,
        ..CullingOptions::default()
    };
    let options = RendererOptions {
        stereo: stereo_mode,
        lod_levels: culling_options.may_draw_lods(),
        batch_draws: !args.no_batch_draws,
        cull_back_faces: !args.no_cull_back_faces,
        ..Default::default()
    };
    let mut renderer = Renderer::new(&device, &queue, scene, &tree, options);
    if culling_options.may_draw_lods() && !args.no_proxies {
        let proxies = dmu_app::progress::build_proxies(scene, &tree, scene, args.json);
        renderer.set_proxies(proxies);
    }
    let stereo_camera = StereoCamera {
        center: camera,
        ipd: args.ipd,
    };
    // With --stereo the single view is the left eye: the one-eye baseline.
    let single_camera = if args.stereo {
        stereo_camera.eyes()[0]
    } else {
        camera
    };
    let capture = Capture::new(&device, size);
    let mut view = View::new(single_camera, size, culling);
    view.options = culling_options;
    let single_frames = render_frames(args.frames, || {
        renderer.render(&mut view, scene, &tree, scene, capture.frame_target())
    })?;
    let stereo = if args.stereo {
        let capture = Capture::stereo(&device, size);
        let mut pair = StereoView::new(stereo_camera, size, culling);
        pair.view.options = culling_options;
        let frames = render_frames(args.frames, || {
            renderer.render_stereo(&mut pair, scene, &tree, scene, capture.stereo_target())
        })?;
        let outputs = [
            eye_path(&args.output, "left"),
            eye_path(&args.output, "right"),
        ];
        for (layer, path) in outputs.iter().enumerate() {
            let image = capture.read_color_layer(&device, &queue, layer as u32)?;
            dmu_render::save_png(&image, path)?;
        }
        Some((pair, frames, outputs))
    } else {
        let image = capture.read_color(&device, &queue)?;
        dmu_render::save_png(&image, &args.output)?;
        None
    };
    // The reported frames: the pair's with --stereo.
    let (frames, drawn, eyes) = match &stereo {
        Some((pair, frames, _)) => (
            frames,
            pair.view.drawn_entries().collect(),
            stereo_camera.eyes().to_vec(),
        ),
        None => (&single_frames, view.drawn_entries().collect(), vec![camera]),
    };
    let last = frames.last().expect("at least one frame");
    let mut explain = dmu_app::explain::occlusion_changes(culling, frames);
    explain.extend(dmu_app::explain::auto_changes(frames));
    let oracle = if args.oracle {
        Some(oracle_json(
            &mut renderer,
            &capture,
            scene,
            &tree,
            &eyes,
            &drawn,
            last.triangles_drawn,
        )?)
    } else {
        None
    };
    let variants = crate::stereo_far::Variants {
        shared_far: args.shared_far_px.map(|error_px| {
            (
                error_px,
                [
                    eye_path(&args.output, "shared-left"),
                    eye_path(&args.output, "shared-right"),
                ],
            )
        }),
        reprojected: args.reproject.then(|| {
            [
                eye_path(&args.output, "reprojected-left"),
                eye_path(&args.output, "reprojected-right"),
            ]
        }),
    };
    let compared = if variants.shared_far.is_some() || variants.reprojected.is_some() {
        let fovs = eye_fovs.unwrap_or_else(|| {
            let aspect = f64::from(size.0) / f64::from(size.1);
            [dmu_geom::Fov::symmetric(camera.fov_y_rad, aspect); 2]
        });
        let setup = crate::stereo_far::Setup {
            center: camera,
            ipd: args.ipd,
            fovs,
            size,
            culling,
            options: culling_options,
            frames: args.frames,
            scene,
            tree: &tree,
        };
        crate::stereo_far::compare(&mut renderer, &device, &queue, &setup, &variants)?
    } else {
        json!({ "shared_far": null, "reprojected": null })
    };
    let stereo_json = stereo.as_ref().map(|(_, frames, outputs)| {
        let (stereo_ms, stereo_gpu_ms) = steady_ms(frames);
        let (one_eye_ms, one_eye_gpu_ms) = steady_ms(&single_frames);
        json!({
            "ipd": args.ipd,
            "mode": format!("{:?}", renderer.stereo_mode()),
            "outputs": outputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "frame_ms": stereo_ms,
            "one_eye_frame_ms": one_eye_ms,
            "ratio": stereo_ms / one_eye_ms,
            "gpu_ms": stereo_gpu_ms,
            "one_eye_gpu_ms": one_eye_gpu_ms,
            "gpu_ratio": if one_eye_gpu_ms > 0.0 { json!(stereo_gpu_ms / one_eye_gpu_ms) } else { json!(null) },
            "one_eye_last": stats_json(single_frames.last().expect("at least one frame")),
            "one_eye_frames": single_frames.iter().map(stats_json).collect::<Vec<_>>(),
            "shared_far": compared["shared_far"],
            "reprojected": compared["reprojected"],
        })
    });
    if args.json {
        let out = json!({
            "output": args.output.display().to_string(),
            "adapter": adapter.name,
            "size": [size.0, size.1],
            "culling": args.culling,
            "lod_error_px": args.lod_error_px,
            "scene_triangles": scene.triangle_count(),
            "load_ms": loaded.load_ms,
            "proxies": renderer.proxy_stats().as_ref().map(dmu_app::progress::proxies_json),
            "last": stats_json(last),
            "oracle": oracle,
            "stereo": stereo_json,
            "frames": frames.iter().map(stats_json).collect::<Vec<_>>(),
        });
        let mut out = out;
        if args.explain {
            out["explain"] = json!(explain);
        }
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let written = match &stereo {
            Some((_, _, [left, right])) => format!("{} + {}", left.display(), right.display()),
            None => args.output.display().to_string(),
        };
        println!(
            "{written}: {}x{} {} on {}: {} of {} triangles drawn, {} queries in {} rounds, {:.1} ms CPU, {:.1} ms GPU",
            size.0,
            size.1,
            args.culling,
            adapter.name,
            last.triangles_drawn,
            scene.triangle_count(),
            last.queries,
            last.rounds,
            last.cpu_ms,
            last.gpu_ms
        );
        if let Some(s) = &stereo_json {
            println!(
                "stereo ({}): {:.1} ms a frame against {:.1} ms for one eye: {:.2}x",
                s["mode"].as_str().unwrap_or_default(),
                s["frame_ms"].as_f64().unwrap_or_default(),
                s["one_eye_frame_ms"].as_f64().unwrap_or_default(),
                s["ratio"].as_f64().unwrap_or_default()
            );
            let f = &s["shared_far"];
            if !f.is_null() {
                println!(
                    "shared far part beyond depth {:.0} (disparity error at most {:.2} px): {:.1} ms a frame, {:.2}x one eye; the pair in full {:.1} ms, {:.2}x; {:.2} % of pixels differ from it",
                    f["split_depth"].as_f64().unwrap_or_default(),
                    f["disparity_error_bound_px"].as_f64().unwrap_or_default(),
                    f["frame_ms"].as_f64().unwrap_or_default(),
                    f["ratio"].as_f64().unwrap_or_default(),
                    f["true_stereo_frame_ms"].as_f64().unwrap_or_default(),
                    f["true_stereo_ratio"].as_f64().unwrap_or_default(),
                    100.0
                        * f["image_difference"]["fraction_differing"]
                            .as_array()
                            .map_or(0.0, |v| v.iter().filter_map(|x| x.as_f64()).sum::<f64>()
                                / 2.0)
                );
                println!(
                    "  of which the far pass {:.1} ms ({} draws), the near passes {:.1} ms ({} draws, both eyes); one eye {} draws",
                    f["far_pass_ms"].as_f64().unwrap_or_default(),
                    f["draw_calls"]["far"],
                    f["near_passes_ms"].as_f64().unwrap_or_default(),
                    f["draw_calls"]["near_both_eyes"],
                    f["draw_calls"]["one_eye"],
                );
            }
        }
        if let Some(r) = stereo_json.as_ref().map(|s| &s["reprojected"])
            && !r.is_null()
        {
            let f = |k: &str| r[k].as_f64().unwrap_or_default();
            let diff = &r["image_difference"]["fraction_differing"];
            println!(
                "right eye reprojected from a {} px wide left eye: {:.1} ms a frame ({:.1} drawing, {:.1} reprojecting), {:.2}x one eye; the pair in full {:.2}x; gaps filled {:.3} %; pixels differing from the pair in full {:.3} % (left), {:.3} % (right)",
                r["wide_width"],
                f("frame_ms"),
                f("wide_pass_ms"),
                f("reproject_ms"),
                f("ratio"),
                f("true_stereo_ratio"),
                100.0 * f("gap_fraction"),
                100.0 * diff[0].as_f64().unwrap_or_default(),
                100.0 * diff[1].as_f64().unwrap_or_default(),
            );
        }
        if let Some(o) = oracle {
            println!("oracle: {o}");
        }
        if args.explain {
            for line in &explain {
                println!("explain: {line}");
            }
        }
    }
    Ok(())
}
