//! Opening the model a command works on: a file, or the built-in plant.

use std::path::{Path, PathBuf};
use std::time::Instant;

use dmu_scene::{ImportOptions, ImportReport, Scene};
use dmu_store::cad::{ANGULAR_DEFLECTION_RANGE, CadOptions, DEFLECTION_RANGE};
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

impl Loaded {
    /// [`require_triangles`] of this model.
    pub fn require_triangles(&self, work: &str) -> anyhow::Result<()> {
        let source = self.source.as_ref().map_or_else(
            || "the built-in plant".to_owned(),
            |p| p.display().to_string(),
        );
        require_triangles(&self.scene, &source, work)
    }
}

/// Refuses a model with no triangles (read from `source`) for `work` that
/// needs some (sweeps, far fields, benchmarks): an empty glTF (no nodes)
/// panicked in each of them, on a sample drawn from nothing or a view of
/// nothing.
pub fn require_triangles(scene: &Scene, source: &str, work: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        scene.triangle_count() > 0,
        "{source}: the model has no triangles ({} parts): nothing to {work}",
        scene.parts().len()
    );
    Ok(())
}

/// Shared clap arguments for commands that open a model.
#[derive(Debug, Clone, clap::Args)]
pub struct ModelArgs {
    /// Model file (.glb, .gltf, .step, .stp, .ifc, or a .dmu store); the
    /// built-in plant when omitted.
    pub file: Option<PathBuf>,
    /// Maximum triangles per chunk (the unit of loading, drawing and picking).
    #[arg(long, default_value_t = dmu_scene::DEFAULT_CHUNK_TRIANGLES, value_parser = clap::value_parser!(u32).range(1..=crate::units::MAX_CHUNK_TRIANGLES as i64))]
    pub chunk_triangles: u32,
    /// Size of the built-in plant used when no file is given (10k to 1G).
    #[arg(long = "plant-triangles", default_value = "2M", value_parser = crate::units::count_in(crate::units::MIN_PLANT_TRIANGLES, crate::units::MAX_TRIANGLES))]
    pub plant_triangles: u64,
    #[command(flatten)]
    pub cad: CadArgs,
}

/// How STEP and IFC files are read (through `DMU_PYTHON` or `python3` with
/// `pip install 'dmu[cad]'`).
#[derive(Debug, Clone, clap::Args)]
pub struct CadArgs {
    /// STEP: the largest gap between a surface and its triangles, as a
    /// fraction of each part's size.
    #[arg(long, default_value_t = CadOptions::default().deflection, value_parser = crate::units::number_in(*DEFLECTION_RANGE.start(), *DEFLECTION_RANGE.end()))]
    pub deflection: f64,
    /// STEP: the largest angle between neighbouring triangles' normals on a
    /// curved face, radians.
    #[arg(long, default_value_t = CadOptions::default().angular_deflection, value_parser = crate::units::number_in(*ANGULAR_DEFLECTION_RANGE.start(), *ANGULAR_DEFLECTION_RANGE.end()))]
    pub angular_deflection: f64,
    /// IFC: classes to keep that are left out by default, comma separated
    /// (IfcSpace, IfcOpeningElement).
    #[arg(long, value_delimiter = ',')]
    pub ifc_include: Vec<String>,
}

impl Default for CadArgs {
    /// The defaults of the command line.
    fn default() -> Self {
        let d = CadOptions::default();
        Self {
            deflection: d.deflection,
            angular_deflection: d.angular_deflection,
            ifc_include: d.ifc_include,
        }
    }
}

impl CadArgs {
    /// The converter's settings.
    pub fn options(&self) -> CadOptions {
        CadOptions {
            deflection: self.deflection,
            angular_deflection: self.angular_deflection,
            ifc_include: self.ifc_include.clone(),
            ..Default::default()
        }
    }
}

/// Opens the model: the file, or the built-in plant.
pub fn load(args: &ModelArgs) -> anyhow::Result<Loaded> {
    load_reporting(args, &|_, _| {})
}

/// [`load`], telling `progress` the meshes imported so far and in all
/// (`(done, total)`, from any thread; not called for the built-in plant) as
/// well as drawing the terminal's bar: a window shows it while it loads.
pub fn load_reporting(
    args: &ModelArgs,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> anyhow::Result<Loaded> {
    let start = Instant::now();
    let (scene, report) = match &args.file {
        Some(path) => import(path, args.chunk_triangles, &args.cad.options(), progress)?,
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

fn import(
    path: &Path,
    chunk_triangles: u32,
    cad: &CadOptions,
    report: &(dyn Fn(usize, usize) + Sync),
) -> anyhow::Result<(Scene, ImportReport)> {
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
        report(done, total);
    };
    let options = ImportOptions {
        chunk_triangles,
        progress: Some(&progress),
    };
    // The one opening path, shared with the GPU-free users (the Python module).
    let result = dmu_store::open_scene(path, &options, cad);
    bar.finish_and_clear();
    Ok(result?)
}
