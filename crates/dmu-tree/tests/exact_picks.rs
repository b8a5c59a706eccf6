//! Picks exactly equal to a brute force with the same triangle test, on hostile
//! rays and chunks: a chunk BVH deep enough to spill the traversal stack,
//! directions of extreme length, grazing rays from far away, parts far from
//! the origin. Included from `tests.rs` as `mod exact_picks;`.

use dmu_geom::Ray3d;
use dmu_samples::Rng;
use dmu_scene::{MeshData, Scene, SceneBuilder};
use dmu_tree::{Tree, TreeOptions, pick_brute_force};
use glam::{DAffine3, DVec3, Vec3, Vec3A};

use crate::support::{random_ray, random_scene_sized, small_cells};

fn one_mesh(positions: Vec<Vec3>, chunk: u32) -> Scene {
    let mut b = SceneBuilder::new("deep", chunk);
    let material = b.add_material("m", [1.0; 4]);
    let indices: Vec<u32> = (0..positions.len() as u32).collect();
    let normals = dmu_scene::compute_normals(&positions, &indices);
    let mut data = MeshData {
        name: "m".into(),
        ..MeshData::default()
    };
    data.push_primitive(&positions, &normals, &indices, material);
    let mesh = b.add_mesh(&data);
    let node = b.add_node(SceneBuilder::ROOT, "p", DAffine3::IDENTITY);
    b.add_part(node, mesh);
    b.finish()
}

fn bvh_depth(tris: &[[Vec3; 3]]) -> usize {
    let tris: Vec<obvhs::triangle::Triangle> = tris
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: Vec3A::from(t[0]),
            v1: Vec3A::from(t[1]),
            v2: Vec3A::from(t[2]),
        })
        .collect();
    let mut d = std::time::Duration::ZERO;
    let bvh =
        obvhs::bvh2::builder::build_bvh2(&tris, obvhs::BvhBuildParams::very_fast_build(), &mut d);
    fn depth(n: &[obvhs::bvh2::node::Bvh2Node], i: usize) -> usize {
        if n[i].prim_count > 0 {
            1
        } else {
            let f = n[i].first_index as usize;
            1 + depth(n, f).max(depth(n, f + 1))
        }
    }
    depth(&bvh.nodes, 0)
}

/// Nested triangles whose sizes grow geometrically: a chain-like BVH far
/// deeper than the 64 entries kept on the call stack.
#[test]
fn deep_chunk_bvh_spills_and_stays_exact() {
    let n = 240;
    let mut tris = Vec::new();
    for i in 0..n {
        let s = 1.2f32.powi(i - 120);
        let z = (i as f32 - 120.0) * 0.37 * s;
        tris.push([
            Vec3::new(-s, -s, z),
            Vec3::new(s * 1.3, -s * 0.7, z + 0.1 * s),
            Vec3::new(-s * 0.2, s * 1.1, z - 0.05 * s),
        ]);
    }
    let depth = bvh_depth(&tris);
    let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
    let scene = one_mesh(positions, 1 << 20);
    let tree = Tree::build(&scene, TreeOptions::default());
    let mut rng = Rng::new(7);
    let mut hits = 0;
    for k in 0..4000 {
        let o = DVec3::new(
            rng.range(-1e-3, 1e-3),
            rng.range(-1e-3, 1e-3),
            rng.range(-1e3, 1e3),
        );
        let d = DVec3::new(
            rng.range(-1e-3, 1e-3),
            rng.range(-1e-3, 1e-3),
            if k % 2 == 0 { 1.0 } else { -1.0 },
        );
        let ray = Ray3d::new(o, d);
        let got = tree.pick(&scene, &ray).map(|h| h.t);
        let want = pick_brute_force(&scene, &ray);
        assert_eq!(got, want, "ray {ray:?}");
        hits += usize::from(got.is_some());
    }
    assert!(depth > 64, "depth {depth}: the stack does not spill");
    assert!(hits > 1000, "{hits} of 4,000 rays hit");
}

/// Directions far from unit length (the tree API takes any finite ray).
#[test]
fn extreme_direction_lengths_stay_exact() {
    let mut bad = Vec::new();
    for seed in 0..40u64 {
        let scene = random_scene_sized(seed, 8, DVec3::ZERO, 400, 128);
        let tree = Tree::build(&scene, small_cells());
        let mut rng = Rng::new(seed ^ 9);
        let bounds = scene.world_bounds();
        for _ in 0..60 {
            let r = random_ray(&mut rng, &bounds);
            for scale in [1e-300, 1e300, 1e307] {
                let ray = Ray3d::new(r.origin, r.dir * scale);
                let got = tree.pick(&scene, &ray).map(|h| h.t);
                let want = pick_brute_force(&scene, &ray);
                let all = tree.pick_all(&scene, &ray).first().map(|h| h.t);
                if got != want || got != all {
                    bad.push((seed, scale, got, want, all));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} differ: {:?}",
        bad.len(),
        &bad[..bad.len().min(8)]
    );
}

/// Rays through random scenes with chunk BVHs: the pick is the brute
/// force's minimum over the same watertight test, exactly.
#[test]
fn picks_equal_same_test_brute_force_exactly() {
    let mut bad = Vec::new();
    for seed in 0..60u64 {
        let scene = random_scene_sized(seed, 10, DVec3::new(3e5, -2e5, 1e5), 400, 128);
        let tree = Tree::build(&scene, small_cells());
        let mut rng = Rng::new(seed ^ 11);
        let bounds = scene.world_bounds();
        for _ in 0..80 {
            let ray = random_ray(&mut rng, &bounds);
            let got = tree.pick(&scene, &ray).map(|h| h.t);
            let want = pick_brute_force(&scene, &ray);
            if got != want {
                bad.push((seed, got, want));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} differ: {:?}",
        bad.len(),
        &bad[..bad.len().min(8)]
    );
}

/// Far origins and nearly axis-parallel directions in rotated parts, near
/// `origin`: the world entry boxes and the local triangle tests round
/// differently. Scenes of `seeds`, 200 rays each.
fn far_grazing_rays_stay_exact_near(seeds: std::ops::Range<u64>, origin: DVec3) {
    let mut bad = Vec::new();
    let mut hits = 0;
    for seed in seeds {
        let scene = random_scene_sized(seed, 10, origin, 200, 32);
        let tree = Tree::build(&scene, small_cells());
        let mut rng = Rng::new(seed ^ 13);
        let bounds = scene.world_bounds();
        for k in 0..200 {
            let target =
                bounds.min + DVec3::new(rng.unit(), rng.unit(), rng.unit()) * bounds.extent();
            let axis = k % 3;
            let mut d = DVec3::ZERO;
            d[axis] = if rng.chance(0.5) { 1.0 } else { -1.0 };
            let tiny = 10f64.powf(rng.range(-16.0, -6.0));
            for j in 0..3 {
                if j != axis && rng.chance(0.7) {
                    d[j] = rng.range(-1.0, 1.0) * tiny;
                }
            }
            let dist = 10f64.powf(rng.range(0.0, 7.0));
            let ray = Ray3d::new(target - d * dist, d);
            let got = tree.pick(&scene, &ray).map(|h| h.t);
            let want = pick_brute_force(&scene, &ray);
            hits += usize::from(want.is_some());
            if got != want {
                bad.push((seed, k, got, want, ray));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} differ: {:?}",
        bad.len(),
        &bad[..bad.len().min(6)]
    );
    assert!(hits > 2000, "{hits} of 10,000 rays hit");
}

#[test]
fn far_grazing_rays_stay_exact() {
    far_grazing_rays_stay_exact_near(0..50, DVec3::ZERO);
}

#[test]
fn far_grazing_rays_stay_exact_off_origin() {
    far_grazing_rays_stay_exact_near(100..150, DVec3::new(2.5e6, -1.3e6, 7e5));
}
