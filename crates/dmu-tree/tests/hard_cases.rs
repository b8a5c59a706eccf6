//! Hard cases with analytic answers: rays along faces, through edges and
//! vertices, axis-parallel, from inside; flat parts; far offsets; long sessions.

use dmu_geom::{Aabb3d, Ray3d};
use dmu_samples::{Rng, grid};
use dmu_scene::{MeshData, PartId, Scene, SceneBuilder};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3, Vec3};

use crate::support::{random_scene, random_transform, small_cells};

/// 3×3×3 boxes of side 4 (from -2 to 2 around each lattice point, pitch 10).
fn boxes() -> (Scene, Tree) {
    let scene = grid(3, 10.0, 4.0, 2048);
    let tree = Tree::build(
        &scene,
        TreeOptions {
            cell_triangles: 30,
            ..TreeOptions::default()
        },
    );
    (scene, tree)
}

fn hit(scene: &Scene, tree: &Tree, origin: DVec3, dir: DVec3) -> Option<(String, f64)> {
    tree.pick(scene, &Ray3d::new(origin, dir))
        .map(|h| (scene.part_name(h.part).to_owned(), h.t))
}

#[test]
fn axis_parallel_rays_with_zero_components() {
    let (scene, tree) = boxes();
    for (dir, origin, t) in [
        (DVec3::Z, DVec3::new(0.0, 0.0, -100.0), 98.0),
        (DVec3::NEG_Z, DVec3::new(0.0, 0.0, 100.0), 78.0),
        (DVec3::X, DVec3::new(-50.0, 10.0, 20.0), 48.0),
        (DVec3::NEG_Y, DVec3::new(20.0, 70.0, 0.0), 48.0),
    ] {
        let (_, got) = hit(&scene, &tree, origin, dir).expect("hit");
        assert_eq!(got, t, "{origin} {dir}");
    }
    // Exactly on a slab plane (x = 2 is box_0_0_0's face), running along it.
    assert_eq!(
        hit(&scene, &tree, DVec3::new(2.0, 0.0, -100.0), DVec3::Z),
        Some(("box_0_0_0".into(), 98.0))
    );
    // Between columns: nothing.
    assert_eq!(
        hit(&scene, &tree, DVec3::new(5.0, 5.0, -100.0), DVec3::Z),
        None
    );
}

#[test]
fn rays_along_a_face_through_an_edge_and_a_vertex() {
    let (scene, tree) = boxes();
    // In the plane of the top face z = 2, meeting the box at its edge x = -2.
    assert_eq!(
        hit(&scene, &tree, DVec3::new(-10.0, 0.0, 2.0), DVec3::X),
        Some(("box_0_0_0".into(), 8.0))
    );
    // Through the edge x = z = 2 of the box, diagonally, touching nothing else.
    let (name, t) = hit(
        &scene,
        &tree,
        DVec3::new(7.0, 0.0, -3.0),
        DVec3::new(-1.0, 0.0, 1.0),
    )
    .unwrap();
    assert_eq!((name.as_str(), t), ("box_0_0_0", 5.0));
    // Exactly at a corner, from the diagonal.
    let (name, t) = hit(&scene, &tree, DVec3::splat(-12.0), DVec3::ONE).unwrap();
    assert_eq!((name.as_str(), t), ("box_0_0_0", 10.0));
    // Through the diagonal of a face: the shared edge of its two triangles.
    let (_, t) = hit(&scene, &tree, DVec3::new(0.0, 0.0, -10.0), DVec3::Z).unwrap();
    assert_eq!(t, 8.0);
}

#[test]
fn rays_starting_inside_a_box() {
    let (scene, tree) = boxes();
    assert_eq!(
        hit(&scene, &tree, DVec3::ZERO, DVec3::X),
        Some(("box_0_0_0".into(), 2.0))
    );
    let all = tree.pick_all(&scene, &Ray3d::new(DVec3::ZERO, DVec3::X));
    let ts: Vec<f64> = all.iter().map(|h| h.t).collect();
    assert_eq!(ts, [2.0, 8.0, 12.0, 18.0, 22.0]);
}

fn flat_scene(offset: DVec3) -> Scene {
    let mut b = SceneBuilder::new("flat", 64);
    let m = b.add_material("m", [1.0; 4]);
    let quad = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    let mut data = MeshData {
        name: "sheet".into(),
        ..MeshData::default()
    };
    data.push_primitive(&quad, &[Vec3::Z; 4], &[0, 1, 2, 0, 2, 3], m);
    let mesh = b.add_mesh(&data);
    for i in 0..4 {
        let node = b.add_node(
            SceneBuilder::ROOT,
            format!("sheet{i}"),
            DAffine3::from_translation(offset + DVec3::new(0.0, 0.0, f64::from(i) * 0.01)),
        );
        b.add_part(node, mesh);
    }
    b.finish()
}

#[test]
fn zero_extent_parts() {
    let scene = flat_scene(DVec3::ZERO);
    let tree = Tree::build(
        &scene,
        TreeOptions {
            cell_triangles: 2,
            ..TreeOptions::default()
        },
    );
    tree.validate_against(&scene).unwrap();
    let top = tree
        .pick(
            &scene,
            &Ray3d::new(DVec3::new(0.3, 0.2, 10.0), DVec3::NEG_Z),
        )
        .unwrap();
    assert_eq!(scene.part_name(top.part), "sheet3");
    assert!((top.t - 9.97).abs() < 1e-12);
    assert_eq!(
        tree.pick_all(
            &scene,
            &Ray3d::new(DVec3::new(0.3, 0.2, 10.0), DVec3::NEG_Z)
        )
        .len(),
        4
    );
    // A flat query box in the plane of one sheet finds exactly that sheet.
    let plane = Aabb3d::new(DVec3::new(-5.0, -5.0, 0.01), DVec3::new(5.0, 5.0, 0.01));
    assert_eq!(tree.parts_in_box(&scene, &plane), [PartId(1)]);
    // A ray lying in a sheet's plane meets it in no area: a miss, never a NaN.
    assert!(
        tree.pick(&scene, &Ray3d::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::X))
            .is_none()
    );
    // Just above it, tilted down, it hits at the computed distance.
    let tilted = tree
        .pick(
            &scene,
            &Ray3d::new(DVec3::new(-5.0, 0.0, 1e-3), DVec3::new(1.0, 0.0, -2e-4)),
        )
        .unwrap();
    assert_eq!(tilted.part, PartId(0));
    assert!((tilted.t - 5.0).abs() < 1e-9, "{}", tilted.t);
}

#[test]
fn a_model_far_from_the_origin_keeps_hundredth_millimetres() {
    // Sheets 0.01 mm apart at 1e7 mm: picked and separated exactly.
    let offset = DVec3::new(1e7, -1e7, 5e6);
    let scene = flat_scene(offset);
    let tree = Tree::build(
        &scene,
        TreeOptions {
            cell_triangles: 2,
            ..TreeOptions::default()
        },
    );
    let ray = Ray3d::new(offset + DVec3::new(0.3, 0.2, 10.0), DVec3::NEG_Z);
    let hits = tree.pick_all(&scene, &ray);
    let ts: Vec<f64> = hits.iter().map(|h| h.t).collect();
    for (got, want) in ts.iter().zip([9.97, 9.98, 9.99, 10.0]) {
        assert!((got - want).abs() < 1e-6, "{ts:?}");
    }
    let between = Aabb3d::new(
        offset + DVec3::new(-1.0, -1.0, 0.004),
        offset + DVec3::new(1.0, 1.0, 0.006),
    );
    assert!(
        tree.parts_in_box(&scene, &between).is_empty(),
        "a box between sheets 0.01 mm apart touches none"
    );
}

#[test]
fn a_thousand_moves_and_back_restore_the_boxes_exactly() {
    let mut scene = random_scene(11, 40, DVec3::new(4.5e6, 5.3e6, 1.2e4));
    let mut tree = Tree::build(&scene, small_cells());
    let original: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
    let boxes: Vec<Aabb3d> = tree.entries().iter().map(|e| e.bounds).collect();
    let mut rng = Rng::new(5);
    for _ in 0..1000 {
        let part = PartId(rng.below(40) as u32);
        // Moves of up to 1 m (1000 mm) with rotations, composed on the current pose.
        let delta = random_transform(&mut rng, DVec3::ZERO, 1000.0);
        let world = delta * scene.part_world(part);
        tree.move_part(&mut scene, part, world);
    }
    tree.validate_against(&scene).unwrap();
    for p in scene.part_ids() {
        tree.move_part(&mut scene, p, original[p.index()]);
    }
    let after: Vec<Aabb3d> = tree.entries().iter().map(|e| e.bounds).collect();
    assert_eq!(after, boxes, "world boxes restored bit for bit");
    tree.validate_against(&scene).unwrap();
    let stats = tree.update_stats();
    assert!(stats.reinserted > 0 && stats.moves == 1040, "{stats:?}");
}

#[test]
fn many_moves_do_not_degrade_the_tree() {
    // Bounded rotations and SAH re-insertion keep the cost near a fresh build, even
    // when parts drift across the whole model.
    let mut scene = random_scene(21, 300, DVec3::ZERO);
    let options = small_cells();
    let mut tree = Tree::build(&scene, options);
    let mut rng = Rng::new(9);
    for _ in 0..2000 {
        let part = PartId(rng.below(300) as u32);
        let delta = DAffine3::from_translation(DVec3::new(
            rng.range(-10.0, 10.0),
            rng.range(-10.0, 10.0),
            rng.range(-10.0, 10.0),
        ));
        let world = delta * scene.part_world(part);
        tree.move_part(&mut scene, part, world);
    }
    let fresh = Tree::build(&scene, options);
    // Measured 1.00; without re-insertion (cells only growing) it reaches 2.26.
    let ratio = tree.sah_cost() / fresh.sah_cost();
    assert!(
        ratio < 1.15,
        "SAH after moves / fresh = {ratio}, {:?}",
        tree.update_stats()
    );
}
