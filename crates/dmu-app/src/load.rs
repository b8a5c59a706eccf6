//! Opening the model a command works on: a file, or the built-in plant.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use dmu_scene::{ImportOptions, ImportReport, Scene};
use indicatif::ProgressBar;

use crate::progress::style_mesh_bar;

/// A loaded model and how it was obtained.
#[derive(Debug)]
pub struct Loaded {
    pub scene: Scene,
    pub report: ImportReport,
    /// The file, or `None` for the built-in plant.
    pub source: Option<PathBuf>,
    /// Wall time to import (or generate) it.
    pub load_ms: f64,
}

/// Shared clap arguments for commands that open a model.
#[derive(Debug, Clone, clap::Args)]
pub struct ModelArgs {
    /// Model file (.glb, .gltf, or a .dmu store); the built-in plant when omitted.
    pub file: Option<PathBuf>,
    /// Maximum triangles per chunk (the unit of loading, drawing and picking).
    #[arg(long, default_value_t = dmu_scene::DEFAULT_CHUNK_TRIANGLES, value_parser = clap::value_parser!(u32).range(1..=crate::units::MAX_CHUNK_TRIANGLES as i64))]
    pub chunk_triangles: u32,
    /// Size of the built-in plant used when no file is given (10k to 1G).
    #[arg(long = "plant-triangles", default_value = "2M", value_parser = crate::units::count_in(10_000, crate::units::MAX_TRIANGLES))]
    pub plant_triangles: u64,
}

/// Opens the model: the file, or the built-in plant.
pub fn load(args: &ModelArgs) -> anyhow::Result<Loaded> {
    let start = Instant::now();
    let (scene, report) = match &args.file {
        Some(path) => import(path, args.chunk_triangles)?,
        None => {
            let options = dmu_samples::PlantOptions {
                triangles: args.plant_triangles,
                chunk_triangles: args.chunk_triangles,
                ..Default::default()
            };
            (dmu_samples::plant(&options), ImportReport::default())
        }
    };
    Ok(Loaded {
        scene,
        report,
        source: args.file.clone(),
        load_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn import(path: &Path, chunk_triangles: u32) -> anyhow::Result<(Scene, ImportReport)> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if ext.as_deref() == Some("dmu") || is_store(path) {
        // A store is chunked already: its own chunks are kept.
        let store = dmu_store::Store::open(path)?;
        let scene = store
            .load_scene()
            .with_context(|| format!("loading {}", path.display()))?;
        return Ok((scene, ImportReport::default()));
    }
    if !matches!(ext.as_deref(), Some("glb" | "gltf")) {
        bail!(
            "{}: unknown file type (dmu reads .glb, .gltf and .dmu)",
            path.display()
        );
    }
    // A bar only for files big enough to take a while; indicatif hides it when
    // stderr is not a terminal, so scripts see clean output.
    let big = std::fs::metadata(path)
        .map(|m| m.len() > 32 << 20)
        .unwrap_or(false);
    let bar = if big {
        ProgressBar::new(0)
    } else {
        ProgressBar::hidden()
    };
    style_mesh_bar(&bar);
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let options = ImportOptions {
        chunk_triangles,
        progress: Some(&progress),
    };
    let result = dmu_scene::import_gltf(path, &options)
        .with_context(|| format!("importing {}", path.display()));
    bar.finish_and_clear();
    result
}

/// Whether the file starts with a store's magic, whatever its name says (a store
/// renamed `.glb` is read as the store it is, not reported as malformed JSON).
fn is_store(path: &Path) -> bool {
    use std::io::Read as _;
    let mut magic = [0; 8];
    dmu_scene::open_regular_file(path).is_ok_and(|mut f| f.read_exact(&mut magic).is_ok())
        && &magic == b"DMUSTORE"
}
