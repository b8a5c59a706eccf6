//! `dmu bench pick`: exact picks a second per core on a batch of rays, random
//! and from a camera, cold (chunk BVHs built on the way) and warm, beside a
//! brute-force check of a sample.

use std::time::Instant;

use dmu_geom::Ray3d;
use dmu_samples::Rng;
use dmu_scene::{ChunkId, PartId, Scene};
use dmu_tree::{Hit, Tree, TreeOptions, pick_brute_force};
use glam::DVec3;
use rayon::prelude::*;
use serde_json::{Value, json};

use crate::cmd_bench::BenchModel;
use crate::units::{MAX_LENGTH, MAX_STEPS, number_in};

/// Picks a second per core, random and camera rays, cold and warm, checked
/// against a brute force on a sample.
#[derive(Debug, clap::Args)]
pub struct PickArgs {
    #[command(flatten)]
    model: BenchModel,
    /// Rays of each kind: random rays, each aimed at the centroid of a
    /// triangle drawn uniformly (instances counted) from
    /// 0.5-20 m away, and a square camera grid of about as many.
    #[arg(long, default_value_t = 100_000, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_STEPS))]
    rays: usize,
    /// Threads that pick (rayon); times are per ray per core.
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1024))]
    threads: usize,
    /// Rays of each kind checked against a brute force (every triangle of
    /// every visible part, no tree, no BVH), on all cores.
    #[arg(long, default_value_t = 100, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_STEPS))]
    sample: usize,
    /// Length unit of the 0.5-20 m of the random rays, in model units (the
    /// built-in plant is in millimetres).
    #[arg(long, default_value_t = 1000.0, value_parser = number_in(1e-6, MAX_LENGTH))]
    metre: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// A point in the unit ball, uniformly.
pub(crate) fn in_ball(rng: &mut Rng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        if v.length_squared() <= 1.0 {
            return v;
        }
    }
}

/// Rays aimed at the centroids of triangles drawn uniformly (instances
/// counted), from `near`-`far` away in a random direction: each hits
/// something.
pub(crate) fn random_rays(
    scene: &Scene,
    rng: &mut Rng,
    count: usize,
    (near, far): (f64, f64),
) -> Vec<Ray3d> {
    // Every chunk instance with the triangles before it, to draw a triangle
    // and find its instance.
    let instances: Vec<(PartId, ChunkId)> = scene
        .part_ids()
        .flat_map(|p| scene.part_mesh(p).chunk_ids().map(move |c| (p, c)))
        .collect();
    let mut starts = Vec::with_capacity(instances.len());
    let mut total = 0u64;
    for &(_, chunk) in &instances {
        starts.push(total);
        total += u64::from(scene.chunk(chunk).triangle_count());
    }
    (0..count)
        .map(|_| {
            let k = rng.below(total);
            let i = starts.partition_point(|&s| s <= k) - 1;
            let (part, chunk) = instances[i];
            let c = scene.chunk(chunk);
            let t = c.triangles.start + (k - starts[i]) as u32;
            let tri = scene.triangle_local(c.mesh, chunk, t);
            let target = scene
                .part_world(part)
                .transform_point3(((tri[0] + tri[1] + tri[2]) / 3.0).as_dvec3());
            let eye = target + in_ball(rng).normalize_or(DVec3::Z) * rng.range(near, far);
            Ray3d::new(eye, (target - eye).normalize())
        })
        .collect()
}

/// A pinhole camera's `side` × `side` rays: from above one corner of the
/// box of the model's triangles, looking at its centre, 60° across (as
/// benches/pick_embree.py, whose box leaves hidden parts out).
fn camera_rays(scene: &Scene, side: usize) -> Vec<Ray3d> {
    let b = scene.tight_world_bounds();
    let centre = b.center();
    let eye = centre + DVec3::new(-0.45, -0.55, 0.35) * b.extent();
    let forward = (centre - eye).normalize_or(DVec3::X);
    // A model with no width in x and y looks straight down: any right will do.
    let right = forward.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::Y);
    let up = right.cross(forward);
    let half = 30f64.to_radians().tan();
    let at = |i: usize| ((i as f64 + 0.5) / side as f64 * 2.0 - 1.0) * half;
    (0..side * side)
        .map(|k| {
            let d = forward + at(k % side) * right - at(k / side) * up;
            Ray3d::new(eye, d.normalize())
        })
        .collect()
}

/// Cold and warm passes of `rays` on `threads` threads, and the sample's check.
fn measure(
    scene: &Scene,
    rays: &[Ray3d],
    pool: &rayon::ThreadPool,
    sample: usize,
    rng: &mut Rng,
) -> Value {
    let tree = Tree::build(scene, TreeOptions::default());
    let pass = || {
        let start = Instant::now();
        let hits = pool.install(|| tree.pick_many(scene, rays));
        (hits, start.elapsed().as_secs_f64())
    };
    let (_, cold_s) = pass();
    let bvhs = tree.chunk_bvhs_built();
    let (hits, warm_s) = (0..3)
        .map(|_| pass())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("three passes");
    // Distinct rays: the first `sample` of a partial shuffle.
    let mut checked: Vec<usize> = (0..rays.len()).collect();
    let sample = sample.min(rays.len());
    for i in 0..sample {
        let j = i + rng.below((rays.len() - i) as u64) as usize;
        checked.swap(i, j);
    }
    checked.truncate(sample);
    let wrong: Vec<Value> = checked
        .par_iter()
        .filter_map(|&i| {
            let truth = pick_brute_force(scene, &rays[i]);
            let got = hits[i].map(|h: Hit| h.t);
            (truth != got).then(|| json!({ "ray": i, "pick_t": got, "brute_force_t": truth }))
        })
        .collect();
    let per_core = |s: f64| s * pool.current_num_threads() as f64 / rays.len() as f64 * 1e6;
    json!({
        "rays": rays.len(),
        "hits": hits.iter().flatten().count(),
        "warm_us_per_ray_per_core": per_core(warm_s),
        "cold_us_per_ray_per_core": per_core(cold_s),
        "cold_over_warm": cold_s / warm_s,
        "rays_per_s_per_core": 1e6 / per_core(warm_s),
        "chunk_bvhs_built": bvhs,
        "checked_by_brute_force": checked.len(),
        "wrong": wrong,
    })
}

pub(crate) fn bench_pick(args: &PickArgs) -> anyhow::Result<()> {
    let loaded = args.model.load()?;
    loaded.require_triangles("benchmark")?;
    let scene = &loaded.scene;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()?;
    let mut rng = Rng::new(args.seed);
    let reach = (0.5 * args.metre, 20.0 * args.metre);
    let random = random_rays(scene, &mut rng, args.rays, reach);
    let side = (args.rays as f64).sqrt().round().max(1.0) as usize;
    let camera = camera_rays(scene, side);
    let out = json!({
        "model": args.model.name(loaded.source.as_deref()),
        "triangles": scene.triangle_count(),
        "threads": args.threads,
        "random": measure(scene, &random, &pool, args.sample, &mut rng),
        "camera": measure(scene, &camera, &pool, args.sample, &mut rng),
    });
    let wrong = ["random", "camera"]
        .iter()
        .map(|k| out[k]["wrong"].as_array().map_or(0, Vec::len))
        .sum::<usize>();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "pick bench on {} ({} triangles), {} thread(s)",
            out["model"].as_str().unwrap_or_default(),
            out["triangles"],
            args.threads
        );
        for kind in ["random", "camera"] {
            let r = &out[kind];
            println!(
                "  {kind}: {} rays, {} hit: {:.2} µs a ray warm, {:.2} cold ({:.2}×); {} of {} checked differ from brute force",
                r["rays"],
                r["hits"],
                r["warm_us_per_ray_per_core"].as_f64().unwrap_or_default(),
                r["cold_us_per_ray_per_core"].as_f64().unwrap_or_default(),
                r["cold_over_warm"].as_f64().unwrap_or_default(),
                r["wrong"].as_array().map_or(0, Vec::len),
                r["checked_by_brute_force"],
            );
        }
    }
    anyhow::ensure!(wrong == 0, "{wrong} picks differ from the brute force");
    Ok(())
}
