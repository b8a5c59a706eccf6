//! `dmu farfield build`: far fields (textured depth meshes) of a store's
//! viewpoint cells, written into the store.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context as _;
use dmu_app::farfield::{
    BuildOptions, FarFieldIndex, IndexCell, all_cells, build, build_cell, cells_along, max_cells,
    new_index, write,
};
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
    /// Build only every N-th cell from the K-th (`K/N`, K from 0) and
    /// write each into --cells-out instead of the store: one worker's share
    /// of a build spread over machines (examples/ray_farfield.py).
    #[arg(long, value_parser = parse_shard, requires = "cells_out")]
    shard: Option<(usize, usize)>,
    /// With --shard: the folder each built cell goes to (`cell-I.bin`, its
    /// bytes, and `cell-I.json`, its index entry).
    #[arg(long, requires = "shard")]
    cells_out: Option<PathBuf>,
    /// Build nothing: write the cells the shards left in this folder into
    /// the store (every cell of the same options must be there).
    #[arg(long, conflicts_with = "shard")]
    cells_from: Option<PathBuf>,
    /// Print a JSON report.
    #[arg(long)]
    json: bool,
}

/// `K/N` with K < N.
fn parse_shard(s: &str) -> anyhow::Result<(usize, usize)> {
    let (k, n) = s
        .split_once('/')
        .with_context(|| format!("{s:?}: give K/N, e.g. 0/4"))?;
    let (k, n): (usize, usize) = (k.trim().parse()?, n.trim().parse()?);
    anyhow::ensure!(k < n, "{s:?}: K must be below N (K counts from 0)");
    Ok((k, n))
}

/// The cell size and the cells a build of `args` lists over `tree`.
fn cells_of(args: &BuildArgs, tree: &Tree) -> anyhow::Result<(f64, Vec<[i64; 3]>)> {
    let cell_size = args
        .cell_size
        .unwrap_or(tree.bounds().extent().max_element() / 24.0);
    let cells = if args.along_walk {
        let path = crate::cmd_walk::camera_path(args.path.as_deref(), args.fps, args.range, tree)?;
        cells_along(tree, cell_size, path.iter().map(|f| f.eye))
    } else {
        // Where the kernel does not say, 4 GiB is taken to be there.
        let memory = dmu_app::progress::available_memory_bytes().unwrap_or(4 << 30);
        all_cells(tree, cell_size, max_cells(memory, args.resolution))?
    };
    Ok((cell_size, cells))
}

fn build_options(args: &BuildArgs, cell_size: f64) -> BuildOptions {
    BuildOptions {
        cell_size,
        triangle_budget: args.triangle_budget,
        capture: FarFieldOptions {
            resolution: args.resolution,
            grid_step: args.grid_step,
            mesh_error_px: args.mesh_error_px,
            skins: !args.no_skins,
            ..FarFieldOptions::default()
        },
    }
}

/// `cell-I.bin` and `cell-I.json` in `dir`.
fn cell_files(dir: &Path, i: usize) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("cell-{i}.bin")),
        dir.join(format!("cell-{i}.json")),
    )
}

/// What a shard's cells were built from: the index's options and the
/// model's signature (no cells), and the store's version on object storage.
fn shard_source(index: &FarFieldIndex, store: &Store) -> serde_json::Value {
    serde_json::json!({ "index": index, "version": store.remote_version() })
}

/// `--cells-from`: the shards' cells, checked against the cells these
/// options list and the store as it is now (the same options, model and
/// version as every shard read), written into the store.
fn assemble(args: &BuildArgs, store: &Store, dir: &Path) -> anyhow::Result<FarFieldIndex> {
    let scene = store.skeleton();
    let tree = Tree::build(scene, TreeOptions::default());
    let (cell_size, cells) = cells_of(args, &tree)?;
    let mut index = new_index(scene, &tree, &build_options(args, cell_size));
    let now = shard_source(&index, store);
    let mut shards = 0;
    for entry in std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))? {
        let path = entry?.path();
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if name.starts_with("shard-") && name.ends_with(".json") {
            let from: serde_json::Value = serde_json::from_slice(&std::fs::read(&path)?)
                .with_context(|| format!("{}: not a shard's record", path.display()))?;
            anyhow::ensure!(
                from == now,
                "{}: its cells were built from another version of {} or with other options; build them again",
                path.display(),
                args.file.display()
            );
            shards += 1;
        }
    }
    anyhow::ensure!(
        shards > 0,
        "{}: no shard-K.json (is it a --cells-out folder?)",
        dir.display()
    );
    for (i, &g) in cells.iter().enumerate() {
        let (_, json) = cell_files(dir, i);
        let entry: IndexCell = serde_json::from_slice(
            &std::fs::read(&json)
                .with_context(|| format!("{}: cell {i} is missing", json.display()))?,
        )
        .with_context(|| format!("{}: not a cell's index entry", json.display()))?;
        anyhow::ensure!(
            entry.grid == g && entry.segment as usize == i,
            "{}: cell {i} of another build (grid {:?}, this build's is {g:?})",
            json.display(),
            entry.grid
        );
        index.cells.push(entry);
    }
    let blobs = index.cells.iter().enumerate().map(|(i, entry)| {
        let (bin, _) = cell_files(dir, i);
        let bytes = std::fs::read(&bin).with_context(|| format!("{}: cell {i}", bin.display()))?;
        anyhow::ensure!(
            bytes.len() as u64 == entry.bytes,
            "{}: {} bytes, its entry says {}",
            bin.display(),
            bytes.len(),
            entry.bytes
        );
        Ok(bytes)
    });
    write(store, &index, blobs)?;
    Ok(index)
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let Sub::Build(args) = &args.command;
    let start = std::time::Instant::now();
    let store = Arc::new(Store::open(&args.file)?);
    if let Some(dir) = &args.cells_from {
        let index = assemble(args, &store, dir)?;
        let listed = index.cells.len();
        return report(args, &index, listed, None, start);
    }
    let scene = store
        .load_scene()
        .with_context(|| format!("loading {}", args.file.display()))?;
    dmu_app::load::require_triangles(
        &scene,
        &args.file.display().to_string(),
        "build far fields of",
    )?;
    let tree = Tree::build(&scene, TreeOptions::default());
    let (cell_size, cells) = cells_of(args, &tree)?;
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
    let options = build_options(args, cell_size);
    let bar = indicatif::ProgressBar::new(cells.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "far fields {bar:40} {pos}/{len} cells, {eta} left",
        )
        .expect("template"),
    );
    let index = match (args.shard, &args.cells_out) {
        (Some((k, n)), Some(dir)) => {
            std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
            let mut index = new_index(&scene, &tree, &options);
            // What the cells were built from, for --cells-from to check.
            let from = shard_source(&index, &store);
            let path = dir.join(format!("shard-{k}.json"));
            dmu_scene::write_file_atomically(&path, &serde_json::to_vec(&from)?)
                .with_context(|| format!("{}", path.display()))?;
            for (i, &g) in cells.iter().enumerate().skip(k).step_by(n) {
                let segment = u32::try_from(i).context("over 4G cells")?;
                let (entry, bytes) =
                    build_cell(&scene, &tree, &mut renderer, &index, g, segment, &options)?;
                let (bin, json) = cell_files(dir, i);
                dmu_scene::write_file_atomically(&bin, &bytes)
                    .with_context(|| format!("{}", bin.display()))?;
                dmu_scene::write_file_atomically(&json, &serde_json::to_vec(&entry)?)
                    .with_context(|| format!("{}", json.display()))?;
                bar.inc(1);
                index.cells.push(entry);
            }
            index
        }
        _ => build(
            &store,
            &scene,
            &tree,
            &mut renderer,
            &cells,
            &options,
            &mut |_| bar.inc(1),
        )?,
    };
    bar.finish_and_clear();
    report(args, &index, cells.len(), Some(&adapter.name), start)
}

/// Prints what was built (or, with --cells-from, written): `index`'s
/// cells of the `listed` these options list.
fn report(
    args: &BuildArgs,
    index: &FarFieldIndex,
    listed: usize,
    adapter: Option<&str>,
    start: std::time::Instant,
) -> anyhow::Result<()> {
    let cell_size = index.cell_size;
    let n = index.cells.len().max(1) as f64;
    let bytes: u64 = index.cells.iter().map(|c| c.bytes).sum();
    let build_ms: f64 = index.cells.iter().map(|c| c.build_ms).sum();
    let report = serde_json::json!({
        "file": args.file.display().to_string(),
        "adapter": adapter,
        "shard": args.shard.map(|(k, n)| format!("{k}/{n}")),
        "cells": index.cells.len(),
        "cells_listed": listed,
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
