//! `dmu farfield build`: far fields (textured depth meshes) of a store's
//! viewpoint cells, written into the store.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context as _;
use dmu_app::farfield::{BuildOptions, all_cells, build, cells_along, max_cells};
use dmu_app::units::number_in;
use dmu_render::{FAR_FIELD_RESOLUTIONS, FarFieldOptions, Renderer, RendererOptions};
use dmu_store::Store;
use dmu_tree::{Tree, TreeOptions};

/// Far fields of a store's viewpoint cells.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(clap::Subcommand, Debug)]
enum Sub {
    /// Build the far fields of a grid of viewpoint cells over the model (or
    /// of the cells a camera path visits) and write them into the store.
    ///
    /// Each cell gets a cull box (the largest cube around its centre whose
    /// chunk instances hold at most --triangle-budget triangles) and six
    /// captures from its centre of everything outside it, meshed from their
    /// depth and simplified within --mesh-error-px. A walk or the viewer then
    /// draws the cull box's geometry and the far field instead of the rest
    /// (`--far-field on`).
    Build(BuildArgs),
}

#[derive(clap::Args, Debug)]
struct BuildArgs {
    /// The store (`.dmu`); it is rewritten with its far fields (temporary
    /// file, renamed into place).
    file: PathBuf,
    /// Cell edge, model units (default: 1/24 of the model's largest extent).
    #[arg(long, value_parser = number_in(1e-9, 1e12))]
    cell_size: Option<f64>,
    /// Triangles of a cull box's chunk instances at most.
    #[arg(long, default_value = "2M", value_parser = dmu_app::units::parse_count)]
    triangle_budget: u64,
    /// Pixels per face side of the captures.
    #[arg(long, default_value_t = FarFieldOptions::default().resolution,
          value_parser = clap::value_parser!(u32).range(*FAR_FIELD_RESOLUTIONS.start() as i64..=*FAR_FIELD_RESOLUTIONS.end() as i64))]
    resolution: u32,
    /// Pixels between depth-mesh grid vertices.
    #[arg(long, default_value_t = FarFieldOptions::default().grid_step,
          value_parser = clap::value_parser!(u32).range(1..=64))]
    grid_step: u32,
    /// Simplification bound of the depth meshes, pixels of a capture.
    #[arg(long, default_value_t = FarFieldOptions::default().mesh_error_px, value_parser = number_in(0.0, 64.0))]
    mesh_error_px: f64,
    /// Leave holes at depth discontinuities instead of skins.
    #[arg(long)]
    no_skins: bool,
    /// Build only the cells a camera path visits: the built-in plant walk
    /// (`--along-walk`), or `--path`'s.
    #[arg(long)]
    along_walk: bool,
    /// Camera path (as `dmu walk --path`), with --along-walk.
    #[arg(long, requires = "along_walk")]
    path: Option<PathBuf>,
    /// Only frames START..END of the path, with --along-walk.
    #[arg(long, requires = "along_walk", value_parser = crate::cmd_walk::parse_range)]
    range: Option<(usize, usize)>,
    /// Frames per second of the built-in path.
    #[arg(long, default_value_t = 60.0, value_parser = number_in(0.01, 1000.0))]
    fps: f64,
    /// Print a JSON report.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let Sub::Build(args) = &args.command;
    let start = std::time::Instant::now();
    let store = Arc::new(Store::open(&args.file)?);
    let scene = store
        .load_scene()
        .with_context(|| format!("loading {}", args.file.display()))?;
    dmu_app::load::require_triangles(
        &scene,
        &args.file.display().to_string(),
        "build far fields of",
    )?;
    let tree = Tree::build(&scene, TreeOptions::default());
    let cell_size = args
        .cell_size
        .unwrap_or(tree.bounds().extent().max_element() / 24.0);
    let cells = if args.along_walk {
        let path = crate::cmd_walk::camera_path(args.path.as_deref(), args.fps, args.range, &tree)?;
        cells_along(&tree, cell_size, path.iter().map(|f| f.eye))
    } else {
        // Where the kernel does not say, 4 GiB is taken to be there.
        let memory = dmu_app::progress::available_memory_bytes().unwrap_or(4 << 30);
        all_cells(&tree, cell_size, max_cells(memory, args.resolution))?
    };
    let (device, queue, adapter) = dmu_render::headless_device().context("opening a GPU device")?;
    let mut renderer = Renderer::new(
        &device,
        &queue,
        &scene,
        &tree,
        RendererOptions {
            lod_levels: true,
            ..Default::default()
        },
    );
    let options = BuildOptions {
        cell_size,
        triangle_budget: args.triangle_budget,
        capture: FarFieldOptions {
            resolution: args.resolution,
            grid_step: args.grid_step,
            mesh_error_px: args.mesh_error_px,
            skins: !args.no_skins,
            ..FarFieldOptions::default()
        },
    };
    let bar = indicatif::ProgressBar::new(cells.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "far fields {bar:40} {pos}/{len} cells, {eta} left",
        )
        .expect("template"),
    );
    let index = build(
        &store,
        &scene,
        &tree,
        &mut renderer,
        &cells,
        &options,
        &mut |_| bar.inc(1),
    )?;
    bar.finish_and_clear();
    let n = index.cells.len().max(1) as f64;
    let bytes: u64 = index.cells.iter().map(|c| c.bytes).sum();
    let build_ms: f64 = index.cells.iter().map(|c| c.build_ms).sum();
    let report = serde_json::json!({
        "file": args.file.display().to_string(),
        "adapter": adapter.name,
        "cells": index.cells.len(),
        "cell_size": cell_size,
        "triangle_budget": args.triangle_budget,
        "resolution": args.resolution,
        "mesh_error_px": args.mesh_error_px,
        "skins": !args.no_skins,
        "bytes": bytes,
        "bytes_per_cell": bytes as f64 / n,
        "build_ms_per_cell": build_ms / n,
        "mean_far_triangles": index.cells.iter().map(|c| c.far_triangles as f64).sum::<f64>() / n,
        "mean_near_triangles": index.cells.iter().map(|c| c.near_triangles as f64).sum::<f64>() / n,
        "total_s": start.elapsed().as_secs_f64(),
        "per_cell": index.cells,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{}: {} far fields of cells {cell_size} units wide, {:.1} MB ({:.0} kB a cell), {:.1} s a cell, {:.0} depth-mesh triangles a cell",
            args.file.display(),
            index.cells.len(),
            bytes as f64 / 1e6,
            bytes as f64 / n / 1e3,
            build_ms / n / 1e3,
            report["mean_far_triangles"].as_f64().unwrap_or(0.0),
        );
    }
    Ok(())
}
