//! `dmu bench`: measured figures for scripts (`--json`); ratios are taken within
//! one run, because the machine is shared and noisy.

use std::path::PathBuf;
use std::time::Instant;

use dmu_collide::{Checker, Report, Settings};
use dmu_geom::{median, percentile};
use dmu_render::Hierarchy;
use dmu_samples::Rng;
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::DAffine3;
use serde_json::json;

use crate::bench_collide::{drag_path, dragged_part};
use crate::bench_pick::{in_ball, random_rays};
use crate::load::{Loaded, ModelArgs, load};
use crate::units::{
    MAX_CHUNK_TRIANGLES, MAX_LENGTH, MAX_STEPS, MAX_TRIANGLES, MIN_PLANT_TRIANGLES, count_in,
    number_in,
};

/// Measure a subsystem on a model (the built-in plant by default).
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, clap::Subcommand)]
enum What {
    /// The cell tree: build, pick, move, rebuild-versus-move and SAH after moves.
    Tree(TreeArgs),
    /// Collision checks per second for a part dragged through the model, with and without the tree.
    Collide(crate::bench_collide::CollideArgs),
    /// Exact picks a second per core: random and camera rays, cold and warm,
    /// a sample checked against a brute force.
    Pick(crate::bench_pick::PickArgs),
}

/// The model a benchmark measures: a file, or the built-in plant.
#[derive(Debug, clap::Args)]
pub(crate) struct BenchModel {
    /// Model file; the built-in plant of `--triangles` when omitted.
    file: Option<PathBuf>,
    /// Size of the built-in plant.
    #[arg(long, default_value = "10M", value_parser = count_in(MIN_PLANT_TRIANGLES, MAX_TRIANGLES))]
    triangles: u64,
    /// Maximum triangles per chunk.
    #[arg(long, default_value_t = dmu_scene::DEFAULT_CHUNK_TRIANGLES, value_parser = clap::value_parser!(u32).range(1..=MAX_CHUNK_TRIANGLES as i64))]
    pub chunk_triangles: u32,
}

impl BenchModel {
    /// Opens the file or makes the plant.
    pub(crate) fn load(&self) -> anyhow::Result<Loaded> {
        load(&ModelArgs {
            file: self.file.clone(),
            chunk_triangles: self.chunk_triangles,
            plant_triangles: self.triangles,
            cad: Default::default(),
        })
    }

    /// How reports name the model opened from `source` (`None`: the plant).
    pub(crate) fn name(&self, source: Option<&std::path::Path>) -> String {
        source.map_or_else(
            || format!("built-in plant {}", self.triangles),
            |p| p.display().to_string(),
        )
    }
}

#[derive(Debug, clap::Args)]
struct TreeArgs {
    #[command(flatten)]
    model: BenchModel,
    /// Rays to pick (each aimed at a random triangle, so it hits).
    #[arg(long, default_value_t = 10_000, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_STEPS))]
    rays: usize,
    /// Timed moves of parts of about `--part-triangles`, and untimed random moves
    /// before the SAH comparison.
    #[arg(long, default_value_t = 10_000, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_STEPS))]
    moves: usize,
    /// Size of the parts moved for `move_us_median`.
    #[arg(long, default_value_t = 10_000)]
    part_triangles: u64,
    /// Largest move, model units (1 m in the millimetre plant).
    #[arg(long, default_value_t = 1000.0, value_parser = number_in(0.0, MAX_LENGTH))]
    move_reach: f64,
    /// Steps of the timed drag (`drag_step_us_median`): the part of about
    /// `--part-triangles` dragged towards the model's centre.
    #[arg(long, default_value_t = 1_000)]
    drag_steps: usize,
    /// Travel per drag step, model units (10 mm in the millimetre plant, as the viewer's drag).
    #[arg(long, default_value_t = 10.0)]
    drag_step: f64,
    /// Soft clash distance of the drag's collision check, model units.
    #[arg(long, default_value_t = 5.0)]
    clearance: f64,
    /// Cell triangle budget.
    #[arg(long, default_value_t = TreeOptions::default().cell_triangles, value_parser = clap::value_parser!(u32).range(1..=1 << 24))]
    cell_triangles: u32,
    /// Nodes the re-insertion search may expand (0: unlimited, the exact branch and bound).
    #[arg(long, default_value_t = TreeOptions::default().insert_search_nodes)]
    insert_search_nodes: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    match &args.what {
        What::Tree(t) => bench_tree(t),
        What::Collide(c) => crate::bench_collide::bench_collide(c),
        What::Pick(p) => crate::bench_pick::bench_pick(p),
    }
}

fn time<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed().as_secs_f64())
}

fn bench_tree(args: &TreeArgs) -> anyhow::Result<()> {
    let mut loaded = args.model.load()?;
    loaded.require_triangles("benchmark")?;
    let scene = &mut loaded.scene;
    let options = TreeOptions {
        cell_triangles: args.cell_triangles,
        ..TreeOptions::default()
    };
    let mut rng = Rng::new(args.seed);

    let (mut tree, build_s) = time(|| Tree::build(scene, options));

    // Rays aimed at random triangles from a few metres away: each hits something.
    let reach = (0.5 * args.move_reach, 20.0 * args.move_reach);
    let rays = random_rays(scene, &mut rng, args.rays, reach);
    let mut pick_cold = Vec::with_capacity(rays.len());
    let mut pick_warm = Vec::with_capacity(rays.len());
    let mut hits = 0usize;
    for ray in &rays {
        let (hit, s) = time(|| tree.pick(scene, ray));
        pick_cold.push(s * 1e6);
        hits += usize::from(hit.is_some());
    }
    for ray in &rays {
        pick_warm.push(time(|| tree.pick(scene, ray)).1 * 1e6);
    }

    // Parts of about `part_triangles` triangles, moved up to `move_reach` from home.
    let mut by_size: Vec<PartId> = scene.part_ids().collect();
    by_size.sort_by_key(|&p| {
        scene
            .part_mesh(p)
            .triangle_count()
            .abs_diff(args.part_triangles)
    });
    let movers: Vec<PartId> = by_size.into_iter().take(32).collect();
    let home: Vec<DAffine3> = movers.iter().map(|&p| scene.part_world(p)).collect();
    let mover_triangles = movers
        .iter()
        .map(|&p| scene.part_mesh(p).triangle_count())
        .sum::<u64>()
        / movers.len().max(1) as u64;
    let mut move_us = Vec::with_capacity(args.moves);
    for _ in 0..args.moves {
        let i = rng.below(movers.len() as u64) as usize;
        let world = DAffine3::from_translation(in_ball(&mut rng) * args.move_reach) * home[i];
        move_us.push(time(|| tree.move_part(scene, movers[i], world)).1 * 1e6);
    }
    for (&p, &w) in movers.iter().zip(&home) {
        tree.move_part(scene, p, w);
    }

    let drag = drag(scene, &mut tree, args)?;

    // What a move would cost without incremental update: a rebuild from the boxes.
    let (_, rebuild_s) = time(|| tree.rebuild());

    // Random moves of random parts, then the SAH cost against a fresh build.
    let parts = scene.parts().len() as u64;
    let mut random_move_us = Vec::with_capacity(args.moves);
    for _ in 0..args.moves {
        let p = PartId(rng.below(parts) as u32);
        let world =
            DAffine3::from_translation(in_ball(&mut rng) * args.move_reach) * scene.part_world(p);
        random_move_us.push(time(|| tree.move_part(scene, p, world)).1 * 1e6);
    }
    let fresh = Tree::build(scene, options);
    let move_median = median(&mut move_us);
    let out = json!({
        "model": args.model.name(loaded.source.as_deref()),
        "triangles": scene.triangle_count(),
        "parts": scene.parts().len(),
        "entries": tree.entries().len(),
        "cells": fresh.cell_count(),
        "depth": fresh.depth(),
        "cell_triangles": args.cell_triangles,
        "insert_search_nodes": args.insert_search_nodes,
        "chunk_triangles": args.model.chunk_triangles,
        "load_ms": loaded.load_ms,
        "build_ms": build_s * 1e3,
        "rays": rays.len(),
        "rays_hit": hits,
        "pick_us_median": median(&mut pick_warm),
        "pick_us_p95": percentile(&mut pick_warm, 0.95),
        "pick_us_median_cold": median(&mut pick_cold),
        "chunk_bvhs_built": tree.chunk_bvhs_built(),
        "moved_part_triangles": mover_triangles,
        "move_us_median": move_median,
        "move_us_p95": percentile(&mut move_us, 0.95),
        "random_move_us_median": median(&mut random_move_us),
        "drag_part_triangles": drag.part_triangles,
        "drag_steps": args.drag_steps,
        "drag_step_us_median": median(&mut drag.step_us.clone()),
        "drag_step_us_p90": percentile(&mut drag.step_us.clone(), 0.9),
        "drag_tree_us_median": median(&mut drag.tree_us.clone()),
        "drag_mirror_us_median": median(&mut drag.mirror_us.clone()),
        "drag_collide_us_median": median(&mut drag.collide_us.clone()),
        "rebuild_ms": rebuild_s * 1e3,
        "rebuild_over_move": rebuild_s * 1e6 / move_median,
        "sah_after_moves_over_fresh": tree.sah_cost() / fresh.sah_cost(),
        "update_stats": {
            "moves": tree.update_stats().moves,
            "stayed": tree.update_stats().stayed,
            "reinserted": tree.update_stats().reinserted,
            "splits": tree.update_stats().splits,
            "merges": tree.update_stats().merges,
            "rotations": tree.update_stats().rotations,
        },
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "tree bench on {} ({} triangles, {} parts)",
            out["model"].as_str().unwrap_or_default(),
            out["triangles"],
            out["parts"]
        );
        for key in [
            "entries",
            "cells",
            "depth",
            "build_ms",
            "pick_us_median",
            "pick_us_p95",
            "pick_us_median_cold",
            "move_us_median",
            "move_us_p95",
            "drag_step_us_median",
            "drag_step_us_p90",
            "rebuild_ms",
            "rebuild_over_move",
            "sah_after_moves_over_fresh",
        ] {
            println!("  {key:<28} {}", out[key]);
        }
    }
    Ok(())
}

/// Per-step times of a drag, µs.
struct Drag {
    part_triangles: u64,
    /// Whole steps: tree move, mirror update and collision check.
    step_us: Vec<f64>,
    tree_us: Vec<f64>,
    mirror_us: Vec<f64>,
    collide_us: Vec<f64>,
}

/// What a drag step in the viewer costs on the CPU: the part moved in the tree,
/// the renderer's mirror of the tree brought up to date, the part checked for
/// collisions. Dragged once untimed (collision meshes are built on first use),
/// then timed; the part ends at home.
fn drag(scene: &mut Scene, tree: &mut Tree, args: &TreeArgs) -> anyhow::Result<Drag> {
    let part = dragged_part(scene, args.part_triangles)?;
    let home = scene.part_world(part);
    let poses = drag_path(scene, part, args.drag_steps, args.drag_step, 0.0);
    let settings = Settings::with_clearance(args.clearance);
    let mut checker = Checker::new(scene);
    let mut report = Report::default();
    let mut hierarchy = Hierarchy::default();
    hierarchy.sync(tree);
    for &pose in &poses {
        tree.move_part(scene, part, pose);
        hierarchy.sync(tree);
        checker.check(scene, tree, &[part], &settings, &mut report);
    }
    tree.move_part(scene, part, home);
    hierarchy.sync(tree);
    let mut out = Drag {
        part_triangles: scene.part_mesh(part).triangle_count(),
        step_us: Vec::with_capacity(poses.len()),
        tree_us: Vec::with_capacity(poses.len()),
        mirror_us: Vec::with_capacity(poses.len()),
        collide_us: Vec::with_capacity(poses.len()),
    };
    for &pose in &poses {
        let start = Instant::now();
        tree.move_part(scene, part, pose);
        let moved = Instant::now();
        hierarchy.sync(tree);
        let synced = Instant::now();
        checker.check(scene, tree, &[part], &settings, &mut report);
        let done = Instant::now();
        let us = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e6;
        out.step_us.push(us(start, done));
        out.tree_us.push(us(start, moved));
        out.mirror_us.push(us(moved, synced));
        out.collide_us.push(us(synced, done));
    }
    tree.move_part(scene, part, home);
    Ok(out)
}
