//! `dmu generate`: the built-in sample models, written to glTF.

use std::path::PathBuf;
use std::time::Instant;

use dmu_samples::{PlantOptions, grid, plant};

use crate::units::{
    MAX_CHUNK_TRIANGLES, MAX_TRIANGLES, MIN_PLANT_TRIANGLES, count_in, parse_dvec3,
};

/// Generate a sample model and write it as glTF (.glb, or .gltf with an embedded
/// buffer) or as a dmu store (.dmu).
///
/// Models are deterministic: the same options give the same file.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which model: `plant` (a multi-storey process plant, millimetres) or `grid`
    /// (N×N×N boxes, a trivial oracle).
    #[arg(value_enum)]
    model: Model,
    /// Triangle target for `plant`: 10k to 1G; suffixes k, M, G.
    #[arg(long, default_value = "1M", value_parser = count_in(MIN_PLANT_TRIANGLES, MAX_TRIANGLES))]
    triangles: u64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// World offset of the plant in millimetres (real plants sit far from 0),
    /// within ±1e14.
    #[arg(long, value_parser = parse_dvec3)]
    origin: Option<glam::DVec3>,
    /// Boxes per side for `grid` (1 to 400: 64M boxes, 768M triangles).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=400))]
    n: u32,
    /// Maximum triangles per chunk.
    #[arg(long, default_value_t = dmu_scene::DEFAULT_CHUNK_TRIANGLES, value_parser = clap::value_parser!(u32).range(1..=MAX_CHUNK_TRIANGLES as i64))]
    chunk_triangles: u32,
    /// Output file (.glb, .gltf or .dmu).
    #[arg(short, long)]
    output: PathBuf,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Model {
    Plant,
    Grid,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(10_000..=500_000_000).contains(&args.triangles) && matches!(args.model, Model::Plant) {
        anyhow::bail!(
            "--triangles {} is outside the plant's range 10k..500M",
            args.triangles
        );
    }
    let start = Instant::now();
    let mut scene = match args.model {
        Model::Plant => {
            let mut options = PlantOptions {
                triangles: args.triangles,
                seed: args.seed,
                chunk_triangles: args.chunk_triangles,
                ..Default::default()
            };
            if let Some(origin) = args.origin {
                // The plant (kilometres) must fit inside the ±1e15 world.
                let limit = dmu_scene::MAX_WORLD_COORDINATE / 10.0;
                if origin.abs().max_element() > limit {
                    anyhow::bail!("--origin must lie within ±{limit:e} mm");
                }
                options.origin = origin;
            }
            plant(&options)
        }
        Model::Grid => grid(args.n, 10.0, 4.0, args.chunk_triangles),
    };
    let generate_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    dmu_store::save_scene(&mut scene, None, &args.output)?;
    let write_ms = start.elapsed().as_secs_f64() * 1e3;
    let bytes = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    let triangles = scene.triangle_count();
    let summary = serde_json::json!({
        "output": args.output.display().to_string(),
        "parts": scene.parts().len(),
        "triangles": triangles,
        "unique_triangles": scene.unique_triangle_count(),
        "bytes": bytes,
        "generate_ms": generate_ms,
        "generate_triangles_per_s": triangles as f64 / (generate_ms / 1e3).max(1e-9),
        "write_ms": write_ms,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "wrote {} : {} parts, {} triangles, {:.1} MB; generated in {:.0} ms ({:.1} M triangles/s), written in {:.0} ms",
            args.output.display(),
            scene.parts().len(),
            triangles,
            bytes as f64 / 1e6,
            generate_ms,
            triangles as f64 / generate_ms / 1e3,
            write_ms
        );
    }
    Ok(())
}
