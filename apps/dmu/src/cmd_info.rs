//! `dmu info`: what a model holds.

use serde::Serialize;

use crate::load::{ModelArgs, load};
use crate::text::{failed_product, printable};

/// Print a model's size, structure and bounds.
///
/// Counts instanced geometry as drawn: `triangles` counts a mesh once per part that
/// uses it, `unique_triangles` once.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// List the parts instead, one a line: id, assembly path and properties
    /// (an IFC element's GlobalId and class, a STEP product's name, a glTF
    /// node's extras); with --json one object a line (`id`, `name`, `path`,
    /// `properties`).
    #[arg(long)]
    parts: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

/// One part as `--parts --json` lists it.
#[derive(Serialize)]
struct PartLine<'a> {
    id: u32,
    name: &'a str,
    path: String,
    properties: std::collections::BTreeMap<&'a str, &'a str>,
}

/// `--parts`: every part, one a line.
fn list_parts(scene: &dmu_scene::Scene, json: bool) -> anyhow::Result<()> {
    use std::io::Write as _;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    for part in scene.part_ids() {
        let line = PartLine {
            id: part.0,
            name: scene.part_name(part),
            path: scene.part_path(part),
            properties: scene.node_properties(scene.part(part).node).collect(),
        };
        if json {
            serde_json::to_writer(&mut out, &line)?;
            writeln!(out)?;
        } else {
            write!(out, "{:>8}  {}", line.id, printable(&line.path, 400))?;
            for (k, v) in &line.properties {
                write!(out, "  {}={}", printable(k, 80), printable(v, 200))?;
            }
            writeln!(out)?;
        }
    }
    out.flush()?;
    Ok(())
}

#[derive(Serialize)]
struct Bounds {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Serialize)]
struct Info {
    source: String,
    name: String,
    parts: usize,
    /// Mesh instances: one per part (compare with `meshes` for how much is shared).
    instances: usize,
    meshes: usize,
    /// Meshes that bound solids with outward windings: the renderer culls
    /// their back faces.
    solid_meshes: usize,
    nodes: usize,
    triangles: u64,
    unique_triangles: u64,
    vertices: u64,
    chunks: usize,
    chunk_instances: u64,
    chunk_triangles: u32,
    materials: usize,
    assembly_depth: usize,
    degenerate_triangles: u64,
    bounds: Bounds,
    import_ms: f64,
    import_triangles_per_s: f64,
    skipped: dmu_scene::ImportReport,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let loaded = load(&args.model)?;
    let s = &loaded.scene;
    if args.parts {
        return list_parts(s, args.json);
    }
    let b = s.tight_world_bounds();
    let (min, max) = if b.is_empty() {
        ([0.0; 3], [0.0; 3])
    } else {
        (b.min.to_array(), b.max.to_array())
    };
    let info = Info {
        source: loaded
            .source
            .as_ref()
            .map_or_else(|| "built-in plant".into(), |p| p.display().to_string()),
        name: s.name().to_owned(),
        parts: s.parts().len(),
        instances: s.parts().len(),
        meshes: s.meshes().len(),
        solid_meshes: s.meshes().iter().filter(|m| m.solid).count(),
        nodes: s.nodes().len(),
        triangles: s.triangle_count(),
        unique_triangles: s.unique_triangle_count(),
        vertices: s.meshes().iter().map(|m| m.positions.len() as u64).sum(),
        chunks: s.chunks().len(),
        chunk_instances: s.chunk_instance_count(),
        chunk_triangles: args.model.chunk_triangles,
        materials: s.materials().len(),
        assembly_depth: s.assembly_depth(),
        degenerate_triangles: s.degenerate_triangle_count(),
        bounds: Bounds { min, max },
        import_ms: loaded.load_ms,
        import_triangles_per_s: s.unique_triangle_count() as f64 / (loaded.load_ms / 1e3).max(1e-9),
        skipped: loaded.report,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(());
    }
    println!("{} ({})", info.name, info.source);
    println!(
        "  parts           {:>14}   (meshes {}, {} of them solid; nodes {})",
        info.parts, info.meshes, info.solid_meshes, info.nodes
    );
    println!(
        "  triangles       {:>14}   (unique {}, degenerate {})",
        info.triangles, info.unique_triangles, info.degenerate_triangles
    );
    println!(
        "  chunks          {:>14}   (instances {}, at most {} triangles each)",
        info.chunks, info.chunk_instances, info.chunk_triangles
    );
    println!("  materials       {:>14}", info.materials);
    println!("  assembly depth  {:>14}", info.assembly_depth);
    println!("  bounds min      {:?}", info.bounds.min);
    println!("  bounds max      {:?}", info.bounds.max);
    println!(
        "  import          {:>11.1} ms   ({:.2} M triangles/s)",
        info.import_ms,
        info.import_triangles_per_s / 1e6
    );
    let r = &info.skipped;
    for f in &r.failed_products {
        println!("  left out        {}", failed_product(f));
    }
    if r.point_primitives_skipped
        + r.line_primitives_skipped
        + r.unused_meshes
        + r.primitives_with_computed_normals
        + r.properties_dropped
        > 0
    {
        println!(
            "  skipped         points {}, lines {}, unused meshes {}, properties {}; normals computed for {} primitives",
            r.point_primitives_skipped,
            r.line_primitives_skipped,
            r.unused_meshes,
            r.properties_dropped,
            r.primitives_with_computed_normals
        );
    }
    Ok(())
}
