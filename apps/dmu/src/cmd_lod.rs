//! `dmu lod build`: a store's level-of-detail hierarchy (merged, simplified
//! proxies of the tree's upper nodes), written into the store.

use std::path::PathBuf;

use dmu_app::units::number_in;
use dmu_render::ProxyOptions;
use indicatif::{ProgressBar, ProgressStyle};

/// A store's level-of-detail hierarchy.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(clap::Subcommand, Debug)]
enum Sub {
    /// Build the level-of-detail hierarchy of a store and write it into the
    /// store (replacing any it has).
    ///
    /// Every third level of the cell tree above the cells, and the root, gets
    /// a proxy: its subtree's chunk instances merged, welded and simplified
    /// until its error reaches --error-fraction of the node's diagonal (the
    /// error each proxy claims is measured as the chunk levels' is). Under a
    /// memory budget the viewer, `dmu walk --render` and `dmu render` draw
    /// far subtrees as these proxies, loaded coarse-first, and never show a
    /// hole while finer ones load. `dmu import` builds it by default.
    Build(BuildArgs),
}

#[derive(clap::Args, Debug)]
struct BuildArgs {
    /// The store (`.dmu`); it is rewritten with its hierarchy (temporary
    /// file, renamed into place).
    file: PathBuf,
    /// Bytes of chunk geometry the build holds at once (k/M/G, KiB/MiB/GiB).
    #[arg(long, default_value = "256MiB", value_parser = dmu_app::units::parse_bytes)]
    chunk_budget: u64,
    /// Each proxy's simplification target, as a fraction of its node's box
    /// diagonal (smaller: finer proxies, more bytes).
    #[arg(long, default_value_t = ProxyOptions::default().error_fraction, value_parser = number_in(1e-6, 0.25))]
    error_fraction: f64,
    /// Print a JSON report.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let Sub::Build(args) = &args.command;
    let report = build_into(
        &args.file,
        args.chunk_budget,
        args.error_fraction,
        args.json,
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{}: {} proxies, {} triangles, {:.1} MB in the store, {:.1} s",
            args.file.display(),
            report.nodes,
            report.triangles,
            report.stored_bytes as f64 / 1e6,
            report.seconds
        );
    }
    Ok(())
}

/// Builds the hierarchy of the store at `path` with a progress bar (hidden
/// when `quiet`).
pub fn build_into(
    path: &std::path::Path,
    chunk_budget: u64,
    error_fraction: f64,
    quiet: bool,
) -> anyhow::Result<dmu_app::lod::LodBuildReport> {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} level-of-detail hierarchy {pos}/{len} [{bar:30}] {elapsed} (eta {eta})",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    let options = ProxyOptions {
        error_fraction,
        ..ProxyOptions::default()
    };
    let report = dmu_app::lod::build(path, chunk_budget, options, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    report
}
