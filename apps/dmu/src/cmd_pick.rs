//! `dmu pick`: the nearest part along a ray.

use anyhow::bail;
use dmu_geom::Ray3d;
use dmu_tree::{Tree, TreeOptions};
use serde_json::json;

use crate::load::{ModelArgs, load};

/// Cast a ray into the model and report the nearest part hit (or every hit).
///
/// The ray is `origin + t * direction` in world units; `distance` is reported in
/// world units whatever the direction's length. Exit code 0 whether or not it hits.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// The ray: origin and direction, `ox,oy,oz,dx,dy,dz`.
    #[arg(long, allow_hyphen_values = true)]
    ray: String,
    /// Report every hit along the ray, nearest first.
    #[arg(long)]
    all: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Parses `ox,oy,oz,dx,dy,dz`; a direction too short or too long to square is
/// scaled by a power of two ([`Ray3d::with_safe_dir`]).
pub fn parse_ray(s: &str) -> anyhow::Result<Ray3d> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--ray {s:?}: expected six numbers ox,oy,oz,dx,dy,dz"))?;
    let [ox, oy, oz, dx, dy, dz] = v.as_slice() else {
        bail!("--ray {s:?}: expected six numbers, got {}", v.len())
    };
    Ray3d::with_safe_dir(
        glam::DVec3::new(*ox, *oy, *oz),
        glam::DVec3::new(*dx, *dy, *dz),
    )
    .ok_or_else(|| {
        anyhow::anyhow!(
            "--ray {s:?}: origin and direction must be finite and the direction non-zero"
        )
    })
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let ray = parse_ray(&args.ray)?;
    let loaded = load(&args.model)?;
    let scene = &loaded.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let length = ray.dir.length();
    let describe = |h: &dmu_tree::Hit| dmu_app::hits::hit_json(scene, h, length);
    let out = if args.all {
        json!({ "hits": tree.pick_all(scene, &ray).iter().map(describe).collect::<Vec<_>>() })
    } else {
        tree.pick(scene, &ray)
            .as_ref()
            .map_or_else(|| json!({ "hit": false }), describe)
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let print = |h: &serde_json::Value| {
        println!(
            "{} (#{}) at distance {} point {} triangle {}\n  path {}",
            h["part"].as_str().unwrap_or_default(),
            h["part_id"],
            h["distance"],
            h["point"],
            h["triangle"],
            h["path"].as_str().unwrap_or_default()
        );
    };
    match (&out["hits"], &out["hit"]) {
        (serde_json::Value::Array(hits), _) if hits.is_empty() => println!("no hit"),
        (serde_json::Value::Array(hits), _) => hits.iter().for_each(print),
        (_, serde_json::Value::Bool(false)) => println!("no hit"),
        _ => print(&out),
    }
    Ok(())
}
