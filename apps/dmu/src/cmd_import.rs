//! `dmu import`: glTF into a dmu store, streaming within a memory budget.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use indicatif::ProgressBar;

use crate::progress::{peak_rss_bytes, style_mesh_bar};
use crate::units::parse_bytes;

/// Import a glTF (.glb, .gltf), STEP (.step, .stp) or IFC (.ifc) file into a dmu store (.dmu).
///
/// glTF's JSON is read as a stream (nodes straight into flat arrays, a few
/// dozen bytes each), and meshes are decoded, chunked and written one batch
/// at a time and dropped, so peak memory stays near the budget whatever the
/// geometry's size. STEP and IFC are first converted to glTF in a scratch
/// folder beside OUTPUT, by OpenCascade and IfcOpenShell run from Python
/// (`DMU_PYTHON`, or `python3` on the PATH, with `pip install 'dmu[cad]'`):
/// the assembly or spatial structure, names, instancing, colours, units
/// (converted to millimetres) and each element's GlobalId, IFC class or STEP
/// product name (`dmu info --parts`, `dmu pick --json`). A product that
/// cannot be tessellated is named and left out. The store replaces OUTPUT
/// only when complete.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The glTF, STEP or IFC file.
    input: PathBuf,
    /// The store to write (`.dmu`).
    #[arg(short, long, value_parser = crate::units::output_with("dmu"))]
    output: PathBuf,
    /// Peak memory to stay within, e.g. 2GiB, 512MiB.
    #[arg(long, default_value = "2GiB", value_parser = parse_bytes)]
    memory_budget: u64,
    /// Maximum triangles per chunk (the unit of loading, drawing and picking).
    #[arg(long, default_value_t = dmu_scene::DEFAULT_CHUNK_TRIANGLES, value_parser = clap::value_parser!(u32).range(1..=crate::units::MAX_CHUNK_TRIANGLES as i64))]
    chunk_triangles: u32,
    /// Quantize geometry: positions to 16 bits per axis in each chunk's box,
    /// normals to 32 bits (10 instead of 24 bytes a vertex).
    #[arg(long)]
    quantize: bool,
    /// Do not build the level-of-detail hierarchy (`dmu lod build` adds it
    /// later). By default it is built after the geometry, reading chunks
    /// within a quarter of --memory-budget.
    #[arg(long)]
    no_lod: bool,
    #[command(flatten)]
    cad: dmu_app::load::CadArgs,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let start = Instant::now();
    // Hidden when stderr is not a terminal, so scripts see clean output.
    let bar = ProgressBar::new(0);
    style_mesh_bar(&bar);
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let options = dmu_store::ImportOptions {
        chunk_triangles: args.chunk_triangles,
        memory_budget_bytes: args.memory_budget,
        write: dmu_store::WriteOptions {
            quantize: args.quantize,
        },
        progress: Some(&progress),
        cad: &args.cad.options(),
    };
    // With the hierarchy the store is written twice (geometry, then the
    // hierarchy's rewrite): both go to a staging name beside it, renamed
    // over it once whole, so a kill at any moment leaves the previous store.
    // An import to object storage is built in a local file (in the cache
    // folder) and put there once whole.
    let remote = dmu_store::remote::is_remote(&args.output);
    let url = args.output.to_string_lossy().into_owned();
    if remote && !url.starts_with("s3://") {
        anyhow::bail!("{url}: stores are written to s3:// addresses only, not to http(s)");
    }
    let remote_options = dmu_store::remote::RemoteOptions::from_env();
    let staged = match (remote, args.no_lod) {
        (true, _) => dmu_store::remote::spool_path(&url, &remote_options)
            .with_context(|| format!("{url}: making a local file to build it in"))?,
        (false, true) => args.output.clone(),
        (false, false) => {
            let mut name = args.output.clone().into_os_string();
            name.push(".importing");
            PathBuf::from(name)
        }
    };
    let result = dmu_store::import_file(&args.input, &staged, &options).with_context(|| {
        format!(
            "importing {} into {}",
            args.input.display(),
            args.output.display()
        )
    });
    bar.finish_and_clear();
    let summary = result?;
    let geometry_ms = start.elapsed().as_secs_f64() * 1e3;
    let lod = (!args.no_lod)
        .then(|| {
            let built = crate::cmd_lod::build_into(
                &staged,
                args.memory_budget / 4,
                dmu_render::ProxyOptions::default().error_fraction,
                args.json,
            )
            .and_then(|built| {
                if !remote {
                    replace(&staged, &args.output)?;
                }
                Ok(built)
            });
            if built.is_err() {
                // Nothing of it is kept; the previous store stays.
                let _ = std::fs::remove_file(&staged);
            }
            built
        })
        .transpose()?;
    let import_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut summary = summary;
    summary.store.path = args.output.clone();
    let built = if remote { &staged } else { &args.output };
    summary.store.file_bytes = std::fs::metadata(built)
        .with_context(|| format!("{}: reading its size", built.display()))?
        .len();
    if remote {
        dmu_store::remote::upload_file(&staged, &url, &remote_options).with_context(|| {
            format!(
                "{url}: uploading the store (it is kept in {})",
                staged.display()
            )
        })?;
        std::fs::remove_file(&staged)
            .with_context(|| format!("{}: removing the local copy", staged.display()))?;
    }
    let peak_rss = peak_rss_bytes();
    if summary.fixed_bytes > args.memory_budget {
        eprintln!(
            "dmu: warning: this model's structure (nodes, parts, the JSON of meshes and accessors) needs about {:.0} MB on its own, over the {:.0} MB budget; geometry was streamed in the smallest batches",
            summary.fixed_bytes as f64 / 1e6,
            args.memory_budget as f64 / 1e6
        );
    }
    if args.json {
        let mut value = serde_json::to_value(&summary)?;
        value["import_ms"] = import_ms.into();
        value["geometry_ms"] = geometry_ms.into();
        value["lod"] = serde_json::to_value(&lod)?;
        value["memory_budget_bytes"] = args.memory_budget.into();
        value["peak_rss_bytes"] = peak_rss.into();
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    let s = &summary.store;
    println!(
        "wrote {}: {} parts, {} triangles ({} unique), {} chunks, {} chunk instances",
        s.path.display(),
        summary.parts,
        summary.triangles,
        summary.unique_triangles,
        s.chunks,
        summary.chunk_instances
    );
    println!(
        "  {:.1} MB on disk ({:.1} MB of geometry, {:.1} MB decoded); imported in {:.1} s, peak memory {}",
        s.file_bytes as f64 / 1e6,
        s.geometry_file_bytes as f64 / 1e6,
        s.geometry_resident_bytes as f64 / 1e6,
        import_ms / 1e3,
        peak_rss.map_or_else(|| "unknown".into(), |b| format!("{:.0} MB", b as f64 / 1e6))
    );
    if let Some(c) = &summary.converted {
        println!(
            "  converted from {} in {:.1} s: {} products, {} left out",
            c.format, c.seconds, c.products, c.failed
        );
    }
    for f in &summary.report.failed_products {
        println!("  left out: {}", crate::text::failed_product(f));
    }
    if summary.report.properties_dropped > 0 {
        println!(
            "  {} node properties dropped (nested, or past the limits of docs/limits.md)",
            summary.report.properties_dropped
        );
    }
    if let Some(lod) = lod {
        println!(
            "  level-of-detail hierarchy: {} proxies, {} triangles, {:.1} MB, {:.1} s",
            lod.nodes,
            lod.triangles,
            lod.stored_bytes as f64 / 1e6,
            lod.seconds
        );
    }
    Ok(())
}

/// Renames `staged` over `target` (atomic on one file system) and syncs
/// their folder, so the rename survives a power cut.
fn replace(staged: &std::path::Path, target: &std::path::Path) -> anyhow::Result<()> {
    std::fs::rename(staged, target)
        .with_context(|| format!("{}: putting the import in place", target.display()))?;
    std::fs::File::open(dmu_scene::folder_of(target))
        .and_then(|d| d.sync_all())
        .with_context(|| format!("{}: syncing its folder", target.display()))
}
