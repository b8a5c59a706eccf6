//! `dmu bench collide`: a part dragged through the model, checked at every
//! step through the tree and, for the ratio, without it. Single-threaded: the
//! timed loops run on the calling thread (only the tree build uses rayon).

use std::time::Instant;

use dmu_collide::{Checker, ClashKind, Report, Settings};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};
use serde_json::json;
use xxhash_rust::xxh3::Xxh3;

use crate::cmd_bench::BenchModel;
use crate::units::{MAX_LENGTH, MAX_STEPS, number_in};
use dmu_geom::{median, percentile};

/// Collision checks per second for a part moving through the model.
#[derive(Debug, clap::Args)]
pub struct CollideArgs {
    #[command(flatten)]
    model: BenchModel,
    /// The moving part is the one whose triangle count is closest to this.
    #[arg(long, default_value_t = 10_000)]
    part_triangles: u64,
    /// Steps of the motion, each moved through the tree and checked.
    #[arg(long, default_value_t = 2_000, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_STEPS))]
    steps: usize,
    /// Travel per step, model units, straight towards the model's centre
    /// (horizontally) and on past it.
    #[arg(long, default_value_t = 10.0, value_parser = number_in(0.0, MAX_LENGTH))]
    step_length: f64,
    /// Turn per step about the vertical axis through the part's centre, degrees.
    #[arg(long, default_value_t = 0.5, value_parser = number_in(-360.0, 360.0))]
    turn_deg: f64,
    /// Steps of the same motion checked without the tree (all parts tested).
    #[arg(long, default_value_t = 200, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_STEPS))]
    no_tree_steps: usize,
    /// Soft clash distance, model units.
    #[arg(long, default_value_t = 5.0, value_parser = number_in(0.0, MAX_LENGTH))]
    clearance: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// The poses of a part dragged `steps` steps of `step_length`: from home, a
/// straight line towards the model's centre in the horizontal plane, turning
/// `turn_deg` per step about the vertical through the part's centre.
pub(crate) fn drag_path(
    scene: &Scene,
    part: PartId,
    steps: usize,
    step_length: f64,
    turn_deg: f64,
) -> Vec<DAffine3> {
    let home = scene.part_world(part);
    let centre = scene.part_world_bounds(part).center();
    let mut towards = scene.world_bounds().center() - centre;
    towards.z = 0.0;
    let dir = towards.normalize_or(DVec3::X);
    (1..=steps)
        .map(|i| {
            let k = i as f64;
            let at = centre + dir * (step_length * k);
            DAffine3::from_translation(at)
                * DAffine3::from_rotation_z((turn_deg * k).to_radians())
                * DAffine3::from_translation(-centre)
                * home
        })
        .collect()
}

/// The visible part whose triangle count is closest to `triangles`: the one dragged.
pub(crate) fn dragged_part(scene: &Scene, triangles: u64) -> anyhow::Result<PartId> {
    scene
        .part_ids()
        .filter(|&p| !scene.part(p).hidden)
        .min_by_key(|&p| scene.part_mesh(p).triangle_count().abs_diff(triangles))
        .ok_or_else(|| anyhow::anyhow!("the model has no visible part"))
}

/// What a step found, for comparing the two runs.
type Found = Vec<(PartId, PartId, ClashKind)>;

/// Per-step figures of one run through the tree.
#[derive(Default)]
struct TreeRun {
    move_us: Vec<f64>,
    check_us: Vec<f64>,
    chunk_pairs: Vec<u64>,
    part_pairs: u64,
    clashes: u64,
    /// Clashes by kind: hard, contact, soft.
    kinds: [u64; 3],
    results: Vec<Found>,
    /// Every step's clashes (parts and kind), hashed in order: equal digests
    /// mean the same answers at every step, across runs and versions.
    digest: Xxh3,
}

impl TreeRun {
    fn step_us(&self) -> Vec<f64> {
        self.move_us
            .iter()
            .zip(&self.check_us)
            .map(|(m, c)| m + c)
            .collect()
    }

    /// Seconds spent in the first `steps` steps.
    fn seconds(&self, steps: usize) -> f64 {
        let sum = |v: &[f64]| v[..steps].iter().sum::<f64>();
        (sum(&self.move_us) + sum(&self.check_us)) * 1e-6
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn found(report: &Report) -> Found {
    report.clashes.iter().map(|c| (c.a, c.b, c.kind)).collect()
}

pub fn bench_collide(args: &CollideArgs) -> anyhow::Result<()> {
    let mut loaded = args.model.load()?;
    let scene = &mut loaded.scene;
    let part = dragged_part(scene, args.part_triangles)?;
    let home = scene.part_world(part);
    let poses = drag_path(scene, part, args.steps, args.step_length, args.turn_deg);
    let settings = Settings::with_clearance(args.clearance);
    let build_start = Instant::now();
    let mut tree = Tree::build(scene, TreeOptions::default());
    let build_ms = build_start.elapsed().as_secs_f64() * 1e3;
    let mut checker = Checker::new(scene);
    let mut report = Report::default();
    let moved = [part];

    // Through the tree, twice: cold (chunk meshes built on first use) and warm.
    let mut run_tree = |scene: &mut Scene, tree: &mut Tree, checker: &mut Checker| {
        tree.move_part(scene, part, home);
        let mut run = TreeRun::default();
        for (i, &pose) in poses.iter().enumerate() {
            let start = Instant::now();
            tree.move_part(scene, part, pose);
            let moved_at = Instant::now();
            checker.check(scene, tree, &moved, &settings, &mut report);
            let done = Instant::now();
            run.move_us.push((moved_at - start).as_secs_f64() * 1e6);
            run.check_us.push((done - moved_at).as_secs_f64() * 1e6);
            run.part_pairs += report.part_pairs_tested;
            run.chunk_pairs.push(report.chunk_pairs_tested);
            run.clashes += report.clashes.len() as u64;
            for c in &report.clashes {
                run.kinds[c.kind as usize] += 1;
                run.digest.update(&c.a.0.to_le_bytes());
                run.digest.update(&c.b.0.to_le_bytes());
                run.digest.update(&[c.kind as u8]);
            }
            run.digest.update(b"/");
            if i < args.no_tree_steps {
                run.results.push(found(&report));
            }
        }
        run
    };
    let cold = run_tree(scene, &mut tree, &mut checker);
    let warm = run_tree(scene, &mut tree, &mut checker);
    tree.move_part(scene, part, home);

    // Without the tree, the first `no_tree_steps` of the same motion: every
    // part's box against the moved part's, each step.
    let flat_poses = &poses[..args.no_tree_steps.min(poses.len())];
    let mut flat_results: Vec<Found> = Vec::with_capacity(flat_poses.len());
    let mut flat_chunk_pairs = 0u64;
    let start = Instant::now();
    for &pose in flat_poses {
        scene.set_part_world(part, pose);
        checker.check_without_tree(scene, &moved, &settings, &mut report);
        flat_chunk_pairs += report.chunk_pairs_tested;
        flat_results.push(found(&report));
    }
    let flat_s = start.elapsed().as_secs_f64();
    scene.set_part_world(part, home);

    // The broad phase alone, same steps: the tree's box query per moved chunk
    // against a scan of every part's box.
    let (mut broad_tree_us, mut broad_scan_us) = (Vec::new(), Vec::new());
    let mut near = Vec::new();
    for &pose in flat_poses {
        tree.move_part(scene, part, pose);
        let start = Instant::now();
        near.clear();
        for e in tree.part_entries(part) {
            let query = tree.entries()[e.0 as usize].bounds.inflated(args.clearance);
            tree.entries_in_box(&query, &mut near);
        }
        std::hint::black_box(&near);
        broad_tree_us.push(start.elapsed().as_secs_f64() * 1e6);
        let start = Instant::now();
        let query = scene.part_world_bounds(part).inflated(args.clearance);
        let hits = scene
            .part_ids()
            .filter(|&p| scene.part_world_bounds(p).overlaps(&query))
            .count();
        std::hint::black_box(hits);
        broad_scan_us.push(start.elapsed().as_secs_f64() * 1e6);
    }
    tree.move_part(scene, part, home);

    let n = poses.len().max(1) as f64;
    let nf = flat_poses.len().max(1) as f64;
    let steps_per_s = n / warm.seconds(poses.len());
    // The tree's rate over the same steps as the run without it.
    let same_steps_per_s = nf / warm.seconds(flat_poses.len());
    let steps_per_s_no_tree = nf / flat_s;
    let out = json!({
        "model": args.model.name(loaded.source.as_deref()),
        "triangles": scene.triangle_count(),
        "parts": scene.parts().len(),
        "chunk_instances": tree.entries().len(),
        "tree_build_ms": build_ms,
        "moving_part": scene.part_name(part),
        "moving_part_triangles": scene.part_mesh(part).triangle_count(),
        "moving_part_chunks": scene.part_mesh(part).chunks.len(),
        "clearance": args.clearance,
        "steps": poses.len(),
        "step_length": args.step_length,
        "turn_deg_per_step": args.turn_deg,
        "threads": 1,
        "steps_per_s": steps_per_s,
        "steps_per_s_cold": n / cold.seconds(poses.len()),
        "step_us_median": median(&mut warm.step_us()),
        "step_us_p95": percentile(&mut warm.step_us(), 0.95),
        "move_us_median": median(&mut warm.move_us.clone()),
        "check_us_median": median(&mut warm.check_us.clone()),
        "move_us_mean": mean(&warm.move_us),
        "check_us_mean": mean(&warm.check_us),
        "part_pairs_tested_per_step": warm.part_pairs as f64 / n,
        "pairs_tested_per_step": warm.chunk_pairs.iter().sum::<u64>() as f64 / n,
        "clashes_per_step": warm.clashes as f64 / n,
        "clashes_by_kind": ([ClashKind::Hard, ClashKind::Contact, ClashKind::Soft]
            .map(|k| (k.as_str(), warm.kinds[k as usize]))
            .into_iter()
            .collect::<std::collections::BTreeMap<_, _>>()),
        "no_tree_steps": flat_poses.len(),
        "steps_per_s_no_tree": steps_per_s_no_tree,
        "steps_per_s_same_steps": same_steps_per_s,
        "parts_scanned_per_step_no_tree": scene.parts().len(),
        "pairs_tested_per_step_same_steps": warm.chunk_pairs[..flat_poses.len()].iter().sum::<u64>() as f64 / nf,
        "pairs_tested_per_step_no_tree": flat_chunk_pairs as f64 / nf,
        "tree_over_no_tree": same_steps_per_s / steps_per_s_no_tree,
        "broad_phase_us_median": median(&mut broad_tree_us),
        "broad_phase_us_median_no_tree": median(&mut broad_scan_us),
        "same_results": warm.results == flat_results,
        "results_digest": format!("{:016x}", warm.digest.digest()),
        "chunk_meshes_built": checker.chunk_meshes_built(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "collide bench on {} ({} triangles, {} parts), moving {} ({} triangles)",
            out["model"].as_str().unwrap_or_default(),
            out["triangles"],
            out["parts"],
            out["moving_part"].as_str().unwrap_or_default(),
            out["moving_part_triangles"],
        );
        for key in [
            "steps_per_s",
            "steps_per_s_cold",
            "step_us_median",
            "step_us_p95",
            "pairs_tested_per_step",
            "clashes_per_step",
            "move_us_median",
            "check_us_median",
            "steps_per_s_same_steps",
            "steps_per_s_no_tree",
            "tree_over_no_tree",
            "broad_phase_us_median",
            "broad_phase_us_median_no_tree",
            "same_results",
        ] {
            println!("  {key:<28} {}", out[key]);
        }
    }
    Ok(())
}
