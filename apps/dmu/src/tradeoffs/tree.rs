//! Tree knobs: the cell size (triangles a cell) and the chunk size (triangles
//! a chunk, set at import), each setting's picks checked against a brute
//! force over every triangle of the model, its moves timed and the tree's SAH
//! cost after them set against a fresh build.

use dmu_app::load::{ModelArgs, load};
use dmu_geom::{Ray3d, RayTriTest3d};
use dmu_samples::Rng;
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};

use dmu_geom::median;

use super::{Bench, Knob, Point, timed};

const CELLS_QUICK: &[u32] = &[1024, 4096, 16384];
const CELLS_FULL: &[u32] = &[256, 1024, 4096, 16384, 65536];
const CHUNKS_QUICK: &[u32] = &[512, 2048];
const CHUNKS_FULL: &[u32] = &[256, 512, 1024, 2048, 4096, 8192];

pub fn steps(quick: bool) -> u64 {
    if quick {
        (CELLS_QUICK.len() + CHUNKS_QUICK.len()) as u64
    } else {
        (CELLS_FULL.len() + CHUNKS_FULL.len()) as u64
    }
}

/// Rays aimed at random triangles from up to a few metres (20x `reach`) away.
fn rays(scene: &Scene, count: usize, reach: f64, rng: &mut Rng) -> Vec<Ray3d> {
    let parts: Vec<PartId> = scene
        .part_ids()
        .filter(|&p| scene.part_mesh(p).triangle_count() > 0)
        .collect();
    (0..count)
        .map(|_| {
            let part = parts[rng.below(parts.len() as u64) as usize];
            let mesh = scene.part_mesh(part);
            let chunks: Vec<_> = mesh.chunk_ids().collect();
            let chunk = chunks[rng.below(chunks.len() as u64) as usize];
            let c = scene.chunk(chunk);
            let t = c.triangles.start + rng.below(u64::from(c.triangle_count())) as u32;
            let tri = scene.triangle_local(c.mesh, chunk, t);
            let target = scene
                .part_world(part)
                .transform_point3(((tri[0] + tri[1] + tri[2]) / 3.0).as_dvec3());
            let dir = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize_or(DVec3::Z);
            let eye = target + dir * rng.range(0.5, 20.0) * reach;
            Ray3d::new(eye, (target - eye).normalize())
        })
        .collect()
}

/// The oracle: the nearest hit of each ray over every triangle of every
/// visible part, in world coordinates, f64.
pub fn brute_force_picks(scene: &Scene, rays: &[Ray3d]) -> Vec<Option<f64>> {
    rays.iter()
        .map(|ray| {
            let test = RayTriTest3d::new(ray);
            let mut best: Option<f64> = None;
            for part in scene.part_ids() {
                if scene.part(part).hidden {
                    continue;
                }
                let world = scene.part_world(part);
                let mesh = scene.part_mesh(part);
                for chunk in mesh.chunk_ids() {
                    let c = scene.chunk(chunk);
                    for t in c.triangles.clone() {
                        let tri = scene
                            .triangle_local(c.mesh, chunk, t)
                            .map(|v| world.transform_point3(v.as_dvec3()));
                        let limit = best.unwrap_or(f64::INFINITY);
                        if let Some(hit) = test.hit(tri[0], tri[1], tri[2], 0.0, limit) {
                            best = Some(hit.t);
                        }
                    }
                }
            }
            best
        })
        .collect()
}

/// Rays whose pick differs from the oracle's by more than `tolerance`.
fn mismatches(tree: &Tree, scene: &Scene, rays: &[Ray3d], oracle: &[Option<f64>]) -> u64 {
    let tolerance = tree.bounds().extent().length() * 1e-9;
    rays.iter()
        .zip(oracle)
        .filter(|(ray, want)| {
            let got = tree.pick(scene, ray).map(|h| h.t);
            match (got, **want) {
                (Some(a), Some(b)) => (a - b).abs() > tolerance,
                (None, None) => false,
                _ => true,
            }
        })
        .count() as u64
}

/// The error of a tree after moves: how much its SAH cost exceeds a fresh
/// build's (0 where the moved tree is as good or better).
const SAH_EXCESS: &str = "SAH cost over a fresh build's, excess fraction";

fn sah_excess(ratio: f64) -> f64 {
    (ratio - 1.0).max(0.0)
}

/// One tree setting measured: build, pick (checked), moves and SAH after them.
struct Measured {
    build_ms: f64,
    pick_ms: f64,
    mismatches: u64,
    move_ms: f64,
    /// SAH cost after the moves over a fresh build's.
    sah_ratio: f64,
}

fn measure(
    scene: &mut Scene,
    options: TreeOptions,
    rays: &[Ray3d],
    oracle: &[Option<f64>],
    moves: usize,
) -> Measured {
    let (mut tree, build_ms) = timed(|| Tree::build(scene, options));
    // Cold picks build the chunk BVHs; the timed ones are warm.
    let mismatches = mismatches(&tree, scene, rays, oracle);
    let pick_ms = median(
        rays.iter()
            .map(|r| timed(|| tree.pick(scene, r)).1)
            .collect::<Vec<_>>(),
    );
    let mut rng = Rng::new(7);
    let reach = tree.bounds().extent().length() * 0.01;
    let parts = scene.parts().len() as u64;
    let home: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
    let mut move_ms = Vec::with_capacity(moves);
    for _ in 0..moves {
        let p = PartId(rng.below(parts) as u32);
        let offset = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ) * reach;
        let world = DAffine3::from_translation(offset) * scene.part_world(p);
        move_ms.push(timed(|| tree.move_part(scene, p, world)).1);
    }
    let fresh = Tree::build(scene, options);
    let sah_ratio = tree.sah_cost() / fresh.sah_cost();
    for (i, &world) in home.iter().enumerate() {
        tree.move_part(scene, PartId(i as u32), world);
    }
    Measured {
        build_ms,
        pick_ms,
        mismatches,
        move_ms: median(move_ms),
        sah_ratio,
    }
}

pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let mut scene = bench.scene.clone();
    let tree = Tree::build(&scene, TreeOptions::default());
    let reach = tree.bounds().extent().length() * 0.002;
    let mut rng = Rng::new(1);
    let rays = rays(&scene, bench.scale.rays, reach, &mut rng);
    let oracle = brute_force_picks(&scene, &rays);
    let quick = bench.scale.quick;
    let mut pick = Vec::new();
    let mut moved = Vec::new();
    for &cells in if quick { CELLS_QUICK } else { CELLS_FULL } {
        let options = TreeOptions {
            cell_triangles: cells,
            ..TreeOptions::default()
        };
        let m = measure(&mut scene, options, &rays, &oracle, bench.scale.moves);
        let setting = f64::from(cells);
        pick.push(
            Point::new(setting, m.pick_ms, m.mismatches as f64, "picks wrong")
                .extra("build ms", m.build_ms),
        );
        moved.push(
            Point::new(setting, m.move_ms, sah_excess(m.sah_ratio), SAH_EXCESS)
                .extra("SAH after moves / fresh", m.sah_ratio)
                .extra("build ms", m.build_ms),
        );
        bench.progress.inc(1);
    }
    let mut chunked = Vec::new();
    for &chunk in if quick { CHUNKS_QUICK } else { CHUNKS_FULL } {
        let model = ModelArgs {
            chunk_triangles: chunk,
            ..bench.model_args.clone()
        };
        let mut scene = load(&model)?.scene;
        let m = measure(
            &mut scene,
            TreeOptions::default(),
            &rays,
            &oracle,
            bench.scale.moves,
        );
        chunked.push(
            Point::new(
                f64::from(chunk),
                m.pick_ms,
                m.mismatches as f64,
                "picks wrong",
            )
            .extra("build ms", m.build_ms)
            .extra("move ms", m.move_ms)
            .extra("SAH after moves / fresh", m.sah_ratio),
        );
        bench.progress.inc(1);
    }
    let pick_reference = "a brute-force pick over every triangle (f64, world)";
    Ok(vec![
        Knob {
            section: "tree",
            name: "cell size, pick".to_owned(),
            unit: "triangles a cell".to_owned(),
            note: format!("{} rays aimed at random triangles", rays.len()),
            reference: pick_reference.to_owned(),
            time: "median pick".to_owned(),
            error_unit: "picks wrong".to_owned(),
            exact_setting: Some(f64::from(TreeOptions::default().cell_triangles)),
            log_x: true,
            log_error: false,
            points: pick,
        },
        Knob {
            section: "tree",
            name: "cell size, move".to_owned(),
            unit: "triangles a cell".to_owned(),
            note: format!(
                "{} random moves of up to 1% of the model's size",
                bench.scale.moves
            ),
            reference: "a fresh SAH build of the moved scene".to_owned(),
            time: "median move".to_owned(),
            error_unit: SAH_EXCESS.to_owned(),
            exact_setting: None,
            log_x: true,
            log_error: false,
            points: moved,
        },
        Knob {
            section: "tree",
            name: "chunk size".to_owned(),
            unit: "triangles a chunk".to_owned(),
            note: "set at import; build and move times in the table".to_owned(),
            reference: pick_reference.to_owned(),
            time: "median pick".to_owned(),
            error_unit: "picks wrong".to_owned(),
            exact_setting: Some(f64::from(dmu_scene::DEFAULT_CHUNK_TRIANGLES)),
            log_x: true,
            log_error: false,
            points: chunked,
        },
    ])
}
