//! Queries against brute force on random scenes, before and after random moves.

use dmu_geom::{Aabb3d, Camera, Plane};
use dmu_samples::Rng;
use dmu_scene::Scene;
use dmu_tree::{EntryVisibility, Tree};
use glam::DVec3;
use proptest::prelude::*;

use crate::support::{
    brute_parts_in_box, brute_pick, brute_pick_where, random_box, random_ray, random_scene,
    random_scene_sized, random_transform, small_cells, world_triangles,
};

/// Picks and box queries agree with brute force; returns how many rays hit.
fn check_queries(
    tree: &Tree,
    scene: &Scene,
    rng: &mut Rng,
    rays: usize,
) -> Result<usize, TestCaseError> {
    let tris = world_triangles(scene);
    let bounds = scene.world_bounds();
    let mut hits = 0;
    let rays: Vec<_> = (0..rays).map(|_| random_ray(rng, &bounds)).collect();
    let many = tree.pick_many(scene, &rays);
    for (ray, got_many) in rays.iter().zip(many) {
        let ray = *ray;
        let got = tree.pick(scene, &ray);
        prop_assert_eq!(got, got_many, "pick_many differs from pick");
        let want = brute_pick(&tris, &ray);
        match (got, want) {
            (None, None) => {}
            (Some(g), Some((t, part))) => {
                hits += 1;
                prop_assert!(
                    (g.t - t).abs() <= 1e-6 * t.max(1.0),
                    "distance {} vs brute {t}",
                    g.t
                );
                // Another part may lie at the same distance (within rounding).
                if g.part != part {
                    let other = tris.iter().filter(|(p, _)| *p == g.part).count();
                    prop_assert!(
                        other > 0 && (g.t - t).abs() <= 1e-9 * t.max(1.0),
                        "part {} vs brute {part}",
                        g.part
                    );
                }
                let all = tree.pick_all(scene, &ray);
                prop_assert_eq!(all.first().map(|h| h.t), Some(g.t));
                prop_assert!(all.windows(2).all(|w| w[0].t <= w[1].t));
            }
            (g, w) => {
                // Only a grazing ray may disagree with the non-watertight oracle.
                let t = g.map(|h| h.t).or(w.map(|w| w.0)).unwrap_or(0.0);
                let near = tris.iter().any(|(_, v)| grazes(&ray, *v, t));
                prop_assert!(near, "tree {g:?} vs brute {w:?}");
            }
        }
    }
    for _ in 0..rays.len() / 2 {
        let b = random_box(rng, &bounds);
        prop_assert_eq!(tree.parts_in_box(scene, &b), brute_parts_in_box(&tris, &b));
    }
    Ok(hits)
}

/// Whether the ray passes within rounding of a triangle's edge at parameter `t`.
fn grazes(ray: &dmu_geom::Ray3d, v: [DVec3; 3], t: f64) -> bool {
    let p = ray.at(t);
    (0..3).any(|i| {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let ab = b - a;
        let s = ((p - a).dot(ab) / ab.length_squared().max(1e-300)).clamp(0.0, 1.0);
        (a + ab * s - p).length() < 1e-6 * (1.0 + p.length())
    })
}

/// The visibility traversal against every chunk instance: since a box's
/// coverage never exceeds its parent's and a box meeting the frustum has
/// parents meeting it, the traversal must yield, as wanted, exactly the
/// instances whose own box meets the frustum and covers `min_pixels`; what
/// else it yields it must classify right.
fn check_visible(tree: &Tree, scene: &Scene, rng: &mut Rng) -> Result<usize, TestCaseError> {
    let bounds = scene
        .world_bounds()
        .inflated(scene.world_bounds().extent().length() * 0.2);
    let point = |rng: &mut Rng| {
        bounds.min + DVec3::new(rng.unit(), rng.unit(), rng.unit()) * bounds.extent()
    };
    let camera = Camera {
        eye: point(rng),
        target: point(rng),
        up: DVec3::Z,
        fov_y_rad: rng.range(0.3, 2.0),
        near: 1e-3,
    };
    prop_assume!(camera.is_valid());
    let height = 100 + (rng.unit() * 900.0) as u32;
    let (frustum, coverage) = (camera.frustum(1.5), camera.coverage(height));
    let min_pixels = rng.range(0.0, 60.0);
    let mut seen = vec![false; tree.entries().len()];
    let mut wanted = Vec::new();
    let mut result = Ok(());
    tree.visit_visible(&frustum, &coverage, min_pixels, &mut |e, entry, v| {
        let in_frustum = frustum.intersects_aabb(&entry.bounds);
        let size = coverage.size_px(&entry.bounds);
        let ok = !std::mem::replace(&mut seen[e.0 as usize], true)
            && match v {
                EntryVisibility::OutsideFrustum => !in_frustum,
                EntryVisibility::InFrustum { size_px, wanted: w } => {
                    in_frustum && size_px == size && w == (size >= min_pixels)
                }
            };
        if !ok && result.is_ok() {
            result = Err(TestCaseError::fail(format!("entry {} told {v:?}", e.0)));
        }
        if matches!(v, EntryVisibility::InFrustum { wanted: true, .. }) {
            wanted.push(e.0);
        }
    });
    result?;
    let brute: Vec<u32> = (0..tree.entries().len() as u32)
        .filter(|&e| {
            let b = &tree.entries()[e as usize].bounds;
            frustum.intersects_aabb(b) && coverage.size_px(b) >= min_pixels
        })
        .collect();
    wanted.sort_unstable();
    prop_assert_eq!(&wanted, &brute);
    Ok(brute.len())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn the_visible_walk_equals_brute_force(seed in any::<u64>(), parts in 1usize..40) {
        let scene = random_scene(seed, parts, DVec3::ZERO);
        let tree = Tree::build(&scene, small_cells());
        let mut rng = Rng::new(seed ^ 3);
        for _ in 0..8 {
            check_visible(&tree, &scene, &mut rng)?;
        }
    }

    #[test]
    fn pick_and_box_equal_brute_force(seed in any::<u64>(), parts in 1usize..40) {
        let scene = random_scene(seed, parts, DVec3::ZERO);
        let tree = Tree::build(&scene, small_cells());
        tree.validate_against(&scene)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        check_queries(&tree, &scene, &mut Rng::new(seed ^ 1), 40)?;
    }

    #[test]
    fn picks_through_chunk_bvhs_equal_brute_force(seed in any::<u64>(), parts in 1usize..12) {
        // Meshes of up to 400 triangles in chunks of 128: most chunks have a BVH.
        let scene = random_scene_sized(seed, parts, DVec3::ZERO, 400, 128);
        let tree = Tree::build(&scene, small_cells());
        let hits = check_queries(&tree, &scene, &mut Rng::new(seed ^ 5), 60)?;
        prop_assert!(tree.chunk_bvhs_built() > 0 || hits == 0);
    }

    #[test]
    fn queries_stay_exact_after_random_moves(seed in any::<u64>(), parts in 2usize..30, moves in 1usize..60) {
        let mut scene = random_scene(seed, parts, DVec3::ZERO);
        let mut tree = Tree::build(&scene, small_cells());
        let mut rng = Rng::new(seed ^ 2);
        for _ in 0..moves {
            let part = dmu_scene::PartId(rng.below(parts as u64) as u32);
            let world = random_transform(&mut rng, DVec3::ZERO, 25.0);
            tree.move_part(&mut scene, part, world);
            tree.validate_against(&scene)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        }
        if rng.chance(0.5) {
            scene.set_part_hidden(dmu_scene::PartId(0), true);
        }
        check_queries(&tree, &scene, &mut rng, 40)?;
    }
}

/// A pick through section planes is the nearest kept hit by brute force: hits
/// on the cut-away side of any plane are seen through.
#[test]
fn picks_through_a_section_equal_brute_force() {
    let scene = random_scene(5, 30, DVec3::ZERO);
    let tree = Tree::build(&scene, small_cells());
    let tris = world_triangles(&scene);
    let bounds = scene.world_bounds();
    let mut rng = Rng::new(17);
    let (mut hits, mut seen_through) = (0, 0);
    for _ in 0..1000 {
        let ray = random_ray(&mut rng, &bounds);
        let planes: Vec<Plane> = (0..1 + rng.below(2))
            .map(|_| {
                let normal = DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                );
                let point = bounds.min + (bounds.max - bounds.min) * rng.unit();
                Plane::from_point_normal(point, normal + DVec3::splat(1e-3))
            })
            .collect();
        let keep = |p: DVec3| planes.iter().all(|pl| pl.signed_distance(p) >= 0.0);
        let got = tree
            .pick_kept(&scene, &ray, &planes)
            .map(|h| (h.t, h.point));
        let want = brute_pick_where(&tris, &ray, keep);
        match (got, want) {
            (None, None) => {}
            (Some((t, point)), Some((w, _))) => {
                hits += 1;
                assert!(
                    (t - w).abs() <= 1e-6 * w.max(1.0),
                    "distance {t} vs brute {w}"
                );
                assert!(
                    keep(point)
                        || planes
                            .iter()
                            .any(|pl| pl.signed_distance(point).abs() < 1e-9 * w.max(1.0))
                );
                if tree
                    .pick(&scene, &ray)
                    .is_some_and(|h| h.t < t - 1e-9 * t.max(1.0))
                {
                    seen_through += 1;
                }
            }
            (g, w) => {
                let t = g.map(|h| h.0).or(w.map(|w| w.0)).unwrap_or(0.0);
                let near = tris.iter().any(|(_, v)| grazes(&ray, *v, t))
                    || planes
                        .iter()
                        .any(|pl| pl.signed_distance(ray.at(t)).abs() < 1e-9 * t.max(1.0));
                assert!(near, "tree {g:?} vs brute {w:?}");
            }
        }
    }
    assert!(
        hits > 50 && seen_through > 10,
        "{hits} hits, {seen_through} through a cut"
    );
}

#[test]
fn random_cameras_do_want_something_often_enough_to_test_something() {
    let scene = random_scene(7, 30, DVec3::ZERO);
    let tree = Tree::build(&scene, small_cells());
    let mut rng = Rng::new(11);
    let wanted: usize = (0..40)
        .filter_map(|_| check_visible(&tree, &scene, &mut rng).ok())
        .filter(|&n| n > 0)
        .count();
    assert!(wanted >= 10, "only {wanted} of 40 cameras wanted anything");
}

#[test]
fn random_rays_do_hit_often_enough_to_test_something() {
    let scene = random_scene(7, 30, DVec3::ZERO);
    let tree = Tree::build(&scene, small_cells());
    let hits = check_queries(&tree, &scene, &mut Rng::new(3), 200).unwrap();
    assert!(hits > 50, "{hits} of 200 rays hit");
}

#[test]
fn empty_box_and_empty_scene() {
    let scene = random_scene(1, 5, DVec3::ZERO);
    let tree = Tree::build(&scene, small_cells());
    assert!(tree.parts_in_box(&scene, &Aabb3d::EMPTY).is_empty());
    let empty = dmu_scene::SceneBuilder::new("empty", 8).finish();
    let tree = Tree::build(&empty, small_cells());
    tree.validate_against(&empty).unwrap();
    assert!(
        tree.pick(&empty, &dmu_geom::Ray3d::new(DVec3::ZERO, DVec3::X))
            .is_none()
    );
    assert_eq!(tree.cell_count(), 1);
}

/// Regression: two nearly coincident triangles in one chunk BVH, hit 2e-14
/// apart. The box of the nearer one was entered, by its rounded slab
/// distance, just beyond the farther one's hit and skipped, so the pick
/// was the farther. Every pick must be the nearest of all hits.
#[test]
fn a_box_entered_an_ulp_beyond_the_nearest_hit_is_still_searched() {
    let seed = 12973194666839402101;
    let scene = random_scene_sized(seed, 8, DVec3::ZERO, 400, 128);
    let tree = Tree::build(&scene, small_cells());
    let mut rng = Rng::new(seed ^ 5);
    let bounds = scene.world_bounds();
    for _ in 0..60 {
        let ray = random_ray(&mut rng, &bounds);
        let nearest = tree.pick_all(&scene, &ray).first().map(|h| h.t);
        assert_eq!(tree.pick(&scene, &ray).map(|h| h.t), nearest);
    }
    assert!(tree.chunk_bvhs_built() > 0);
}
