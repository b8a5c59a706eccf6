//! `dmu render`: a headless capture of the model to PNG, with culling stats.

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use dmu_render::{Camera, Capture, Culling, FrameStats, Renderer, View, headless_device};
use dmu_tree::{Tree, TreeOptions};
use glam::DVec3;
use serde_json::json;

use crate::load::{ModelArgs, load};

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
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    fov: f64,
    /// Image size `WIDTHxHEIGHT`.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// Near plane distance, world units (default: 1/10 000 of the model's diagonal).
    #[arg(long)]
    near: Option<f64>,
    /// Culling: none, frustum (with coverage) or chc (plus occlusion queries).
    #[arg(long, default_value = "frustum", value_parser = ["none", "frustum", "chc"])]
    culling: String,
    /// Nodes covering fewer pixels across than this are dropped (0: none).
    #[arg(long, default_value_t = 0.0)]
    min_pixels: f64,
    /// Frames rendered from the viewpoint (occlusion culling converges over a
    /// few); the image and stats are the last frame's.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    frames: u32,
    /// Output PNG.
    #[arg(short, long)]
    output: PathBuf,
    /// Print stats as JSON.
    #[arg(long)]
    json: bool,
    /// Also render chunk ids without occlusion culling and report the exactly
    /// visible chunk instances against the drawn ones.
    #[arg(long)]
    oracle: bool,
}

fn parse_vec(what: &str, s: &str) -> anyhow::Result<DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--{what} {s:?}: expected three numbers x,y,z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(*x, *y, *z)),
        _ => bail!("--{what} {s:?}: expected three finite numbers x,y,z"),
    }
}

fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("--size {s:?}: expected WIDTHxHEIGHT"))?;
    let (w, h): (u32, u32) = (w.parse()?, h.parse()?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("--size {s:?}: each side must be 1 to 16384 pixels");
    }
    Ok((w, h))
}

fn stats_json(s: &FrameStats) -> serde_json::Value {
    json!({
        "frame": s.frame,
        "nodes_visited": s.nodes_visited,
        "culled_frustum": s.culled_frustum,
        "culled_coverage": s.culled_coverage,
        "culled_occlusion": s.culled_occlusion,
        "hidden": s.hidden,
        "not_resident": s.not_resident,
        "queries": s.queries,
        "queries_visible": s.queries_visible,
        "rounds": s.rounds,
        "passes": s.passes,
        "chunks_drawn": s.chunks_drawn,
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
    let eye = parse_vec("eye", &args.eye)?;
    let target = parse_vec("target", &args.target)?;
    let size = parse_size(&args.size)?;
    if eye == target {
        bail!("--eye and --target must differ");
    }
    if !(args.fov > 0.0 && args.fov < 180.0) {
        bail!("--fov {}: must be in (0, 180) degrees", args.fov);
    }
    let culling = match args.culling.as_str() {
        "none" => Culling::None,
        "chc" => Culling::Occlusion,
        _ => Culling::Frustum,
    };
    let loaded = load(&args.model)?;
    let scene = &loaded.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let near = args
        .near
        .unwrap_or_else(|| (tree.bounds().extent().length() * 1e-4).max(1e-6));
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
    let (device, queue, adapter) = headless_device().context("opening a GPU device")?;
    let mut renderer = Renderer::new(&device, &queue, scene, &tree, Default::default());
    let capture = Capture::new(&device, size);
    let mut view = View::new(camera, size, culling);
    view.options.min_pixels = args.min_pixels;
    let mut frames = Vec::new();
    for _ in 0..args.frames {
        frames.push(renderer.render(&mut view, scene, &tree, scene, capture.frame_target())?);
    }
    let image = capture.read_color(&device, &queue)?;
    dmu_render::save_png(&image, &args.output)?;
    let last = frames.last().expect("at least one frame");
    let oracle = if args.oracle {
        let drawn: std::collections::BTreeSet<_> = view.drawn_entries().collect();
        let exact = renderer
            .render_ids(&mut view, scene, &tree, scene, &capture)?
            .visible_entries();
        let triangles = |set: &std::collections::BTreeSet<dmu_tree::EntryId>| -> u64 {
            set.iter()
                .map(|e| u64::from(tree.entries()[e.0 as usize].triangles))
                .sum()
        };
        Some(json!({
            "exact_visible_chunks": exact.len(),
            "exact_visible_triangles": triangles(&exact),
            "missing_from_drawn": exact.difference(&drawn).count(),
            "drawn_over_exact_triangles": last.triangles_drawn as f64 / triangles(&exact).max(1) as f64,
        }))
    } else {
        None
    };
    if args.json {
        let out = json!({
            "output": args.output.display().to_string(),
            "adapter": adapter.name,
            "size": [size.0, size.1],
            "culling": args.culling,
            "scene_triangles": scene.triangle_count(),
            "load_ms": loaded.load_ms,
            "last": stats_json(last),
            "oracle": oracle,
            "frames": frames.iter().map(stats_json).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "{}: {}x{} {} on {}: {} of {} triangles drawn, {} queries in {} rounds, {:.1} ms CPU, {:.1} ms GPU",
            args.output.display(),
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
        if let Some(o) = oracle {
            println!("oracle: {o}");
        }
    }
    Ok(())
}
