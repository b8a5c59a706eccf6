//! `dmu tradeoffs`: sweep every accuracy knob on a model and write the report.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use serde_json::json;

use crate::load::{ModelArgs, load};
use crate::tradeoffs::{Bench, Machine, Run, Scale, run_sections, write_report};

/// What accuracy costs in time: sweep each knob on the model and write a
/// Markdown report with one plot per knob.
///
/// Each knob's settings are measured for time and for their error against an
/// exact reference (culling none for rendering, a brute-force pick for the
/// tree, a fine continuous sweep for collision, the analytic answer for
/// numerics), one section each: rendering (coverage threshold, occlusion
/// re-check interval and rounds; far fields: kind, resolution, mesh error,
/// skins, against the full-geometry image), loading (memory budget, load order), tree
/// (cell and chunk size), collision (discrete, continuous and auto step,
/// clearance, contact tolerance) and numerics (f32 against f64 at offsets of
/// 1 to 10^9 mm, store quantization). Rendering needs a GPU adapter (lavapipe
/// will do); without one the section is skipped and the report says why.
///
/// OUT gets README.md and one SVG per knob. The committed report in
/// docs/tradeoffs is the full run: `dmu tradeoffs --out docs/tradeoffs` on a
/// release build; --quick (small models, few points) is what CI runs.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file (.glb, .gltf, .dmu); the built-in plant when omitted.
    file: Option<PathBuf>,
    /// Small models and few points: a few minutes on two cores, for CI.
    #[arg(long)]
    quick: bool,
    /// Folder for the report (README.md) and its plots.
    #[arg(long, default_value = "docs/tradeoffs")]
    out: PathBuf,
    /// Size of the built-in plant (10k to 1G; default 2M, as the other
    /// commands').
    #[arg(long, value_parser = crate::units::count_in(crate::units::MIN_PLANT_TRIANGLES, crate::units::MAX_TRIANGLES))]
    plant_triangles: Option<u64>,
    /// Print the figures as one JSON document: `{"report", "knobs": [{"name",
    /// "unit", "reference", "points": [{"setting", "time_ms", "error",
    /// "error_unit"}]}], ...}`.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let start = Instant::now();
    // Before the model is made: a bad --out fails at once.
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let scale = Scale::new(args.quick, args.plant_triangles);
    let model_args = ModelArgs {
        file: args.file.clone(),
        chunk_triangles: dmu_scene::DEFAULT_CHUNK_TRIANGLES,
        plant_triangles: scale.plant_triangles,
        cad: Default::default(),
    };
    let loaded = load(&model_args)?;
    loaded.require_triangles("measure")?;
    let model = match &loaded.source {
        Some(p) => p.display().to_string(),
        None => format!(
            "built-in plant, {} triangles in {} parts",
            loaded.scene.triangle_count(),
            loaded.scene.parts().len()
        ),
    };
    // Stores the sweeps write, beside the report (the same file system).
    let scratch = tempfile::Builder::new()
        .prefix(".tradeoffs-scratch-")
        .tempdir_in(&args.out)
        .with_context(|| format!("creating a scratch folder in {}", args.out.display()))?;
    let steps = crate::tradeoffs::steps(scale.quick);
    let progress = indicatif::ProgressBar::new(steps);
    progress.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {pos}/{len} [{bar:30}] {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let bench = Bench {
        scale,
        scene: &loaded.scene,
        model_args: &model_args,
        scratch: scratch.path(),
        progress: &progress,
    };
    let (knobs, skipped, adapter) = run_sections(&bench);
    progress.finish_and_clear();
    for (section, why) in &skipped {
        eprintln!("dmu tradeoffs: SKIPPED {section}: {why}");
    }
    let command = match (&args.file, args.quick) {
        (Some(f), q) => format!(
            "dmu tradeoffs {}{} --out {}",
            f.display(),
            if q { " --quick" } else { "" },
            args.out.display()
        ),
        (None, q) => format!(
            "dmu tradeoffs{} --out {}",
            if q { " --quick" } else { "" },
            args.out.display()
        ),
    };
    let run = Run {
        model,
        quick: args.quick,
        machine: Machine::this(),
        adapter,
        command,
        knobs,
        skipped,
        wall_s: start.elapsed().as_secs_f64(),
    };
    let report = write_report(&run, &args.out)?;
    if args.json {
        let mut value = serde_json::to_value(&run)?;
        value["report"] = json!(report.display().to_string());
        for (k, knob) in value["knobs"]
            .as_array_mut()
            .into_iter()
            .flatten()
            .zip(&run.knobs)
        {
            k["plot"] = json!(args.out.join(knob.plot_file()).display().to_string());
            k["reading"] = json!(crate::tradeoffs::reading(knob));
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "{}: {} knobs in {} plots, {:.0} s{}",
            report.display(),
            run.knobs.len(),
            run.knobs.len(),
            run.wall_s,
            if run.skipped.is_empty() {
                String::new()
            } else {
                format!("; skipped: {}", run.skipped.len())
            }
        );
    }
    Ok(())
}
