//! Through the tree equals brute force over all part pairs, on random scenes.

use dmu_collide::{Checker, Report, Settings, triangle_distance};
use dmu_samples::Rng;
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use proptest::prelude::*;

use crate::support::{Expected, Shape, oracle, scene_of, tessellated_box_mesh, world_triangles};

fn random_pose(rng: &mut Rng, origin: DVec3, reach: f64) -> DAffine3 {
    let axis = DVec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    );
    let rotation = DQuat::from_axis_angle(axis.normalize_or(DVec3::Z), rng.range(-3.2, 3.2));
    let t = DVec3::new(
        rng.range(-reach, reach),
        rng.range(-reach, reach),
        rng.range(-reach, reach),
    );
    DAffine3::from_rotation_translation(rotation, origin + t)
}

/// Random parts near `origin`: closed boxes (one to four chunks, some big
/// enough to swallow others whole, far from any of their chunks) and open
/// triangle soups split into several chunks.
fn random_scene(rng: &mut Rng, parts: usize, origin: DVec3) -> (Scene, Vec<bool>) {
    let mut shapes = Vec::new();
    let mut closed = Vec::new();
    for p in 0..parts {
        let world = random_pose(rng, origin, 12.0);
        if rng.chance(0.4) {
            let h = Vec3::new(
                rng.range(0.5, 9.0) as f32,
                rng.range(0.5, 9.0) as f32,
                rng.range(0.5, 9.0) as f32,
            );
            let n = 1 + rng.below(2) as u32;
            shapes.push(Shape::new(
                &format!("box{p}"),
                tessellated_box_mesh(h, n),
                world,
            ));
            closed.push(true);
        } else {
            let size = rng.range(1.0, 8.0) as f32;
            let n = 1 + rng.below(30) as usize;
            let positions: Vec<Vec3> = (0..3 * n)
                .map(|_| {
                    Vec3::new(
                        rng.range(-1.0, 1.0) as f32,
                        rng.range(-1.0, 1.0) as f32,
                        rng.range(-1.0, 1.0) as f32,
                    ) * size
                })
                .collect();
            let indices = (0..3 * n as u32).collect();
            shapes.push(Shape::new(&format!("soup{p}"), (positions, indices), world));
            closed.push(false);
        }
    }
    // 12 triangles a chunk: a box is one or four chunks, a soup up to three.
    (scene_of(&shapes, 12), closed)
}

fn sorted(mut v: Vec<Expected>) -> Vec<Expected> {
    v.sort_by_key(|e| (e.a, e.b));
    v
}

fn compare(got: &Report, want: &[Expected], settings: &Settings) -> Result<(), TestCaseError> {
    let got: Vec<Expected> = sorted(
        got.clashes
            .iter()
            .map(|c| Expected {
                a: c.a,
                b: c.b,
                kind: c.kind,
                distance: c.distance,
            })
            .collect(),
    );
    let want = sorted(want.to_vec());
    prop_assert_eq!(got.len(), want.len(), "tree {:?}\nbrute {:?}", got, want);
    for (g, w) in got.iter().zip(&want) {
        prop_assert_eq!(
            (g.a, g.b, g.kind),
            (w.a, w.b, w.kind),
            "tree {:?}\nbrute {:?}",
            got,
            want
        );
        prop_assert!(
            (g.distance - w.distance).abs() <= 1e-6 * (1.0 + settings.clearance),
            "distance {} vs brute {}",
            g.distance,
            w.distance
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    #[test]
    fn tree_equals_brute_force_over_all_pairs(seed in any::<u64>(), parts in 2usize..24, far in any::<bool>()) {
        let mut rng = Rng::new(seed);
        let origin = if far { DVec3::new(1e7, 1e7, -1e7) } else { DVec3::ZERO };
        let (mut scene, closed) = random_scene(&mut rng, parts, origin);
        let mut tree = Tree::build(&scene, TreeOptions { cell_triangles: 24, ..TreeOptions::default() });
        let mut checker = Checker::new(&scene);
        let mut report = Report::default();
        for round in 0..6 {
            // Some parts hidden, some pairs allowed, some clearance.
            let mut settings = Settings::with_clearance([0.0, 0.5, 3.0][rng.below(3) as usize]);
            for _ in 0..rng.below(3) {
                let (a, b) = (rng.below(parts as u64) as u32, rng.below(parts as u64) as u32);
                settings.allow.allow(PartId(a), PartId(b));
            }
            for p in scene.part_ids() {
                scene.set_part_hidden(p, rng.chance(0.1));
            }
            // Move one to three parts through the tree, then check them.
            let moved: Vec<PartId> = (0..1 + rng.below(3))
                .map(|_| PartId(rng.below(parts as u64) as u32))
                .collect();
            for &p in &moved {
                tree.move_part(&mut scene, p, random_pose(&mut rng, origin, 12.0));
            }
            tree.validate_against(&scene)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
            checker.check(&scene, &tree, &moved, &settings, &mut report);
            let want = oracle(&scene, &moved, &settings, &closed);
            compare(&report, &want, &settings).map_err(|e| TestCaseError::fail(format!("round {round}: {e}")))?;
            // And without the tree.
            let mut flat = Report::default();
            checker.check_without_tree(&scene, &moved, &settings, &mut flat);
            compare(&flat, &want, &settings)?;
        }
    }
}

#[test]
fn random_scenes_do_produce_every_kind() {
    // Guards the property test against testing nothing.
    let mut kinds = std::collections::BTreeSet::new();
    let mut rng = Rng::new(11);
    for _ in 0..40 {
        let (scene, closed) = random_scene(&mut rng, 16, DVec3::ZERO);
        let moved = [PartId(0), PartId(1)];
        for e in oracle(&scene, &moved, &Settings::with_clearance(3.0), &closed) {
            kinds.insert(e.kind);
        }
    }
    assert!(kinds.contains(&dmu_collide::ClashKind::Hard));
    assert!(kinds.contains(&dmu_collide::ClashKind::Soft));
}

/// The distance between two parts equals brute force over every triangle
/// pair (near the origin and 1e7 away), its closest points lie that far
/// apart, and a soft clash of the pair at a larger clearance reports the
/// same distance.
#[test]
fn part_distance_equals_brute_force() {
    let mut rng = Rng::new(99);
    let mut compared = 0;
    for round in 0..30 {
        let origin = if round % 2 == 1 {
            DVec3::new(1e7, -1e7, 1e7)
        } else {
            DVec3::ZERO
        };
        let (scene, _) = random_scene(&mut rng, 2, origin);
        let (a, b) = (PartId(0), PartId(1));
        let checker = Checker::new(&scene);
        let settings = Settings::default();
        let Some(got) = checker.distance(&scene, &settings, a, b) else {
            panic!("round {round}: parts with triangles have a distance");
        };
        let (ta, tb) = (world_triangles(&scene, a), world_triangles(&scene, b));
        let want = ta
            .iter()
            .flat_map(|x| tb.iter().map(|y| triangle_distance(x, y).0))
            .fold(f64::INFINITY, f64::min);
        let scale = origin.length().max(1.0);
        assert!(
            (got.distance - want).abs() <= 1e-9 * scale + 1e-9 * want,
            "round {round}: {} vs brute {want}",
            got.distance
        );
        if got.penetrating {
            continue;
        }
        assert!(
            ((got.point_a - got.point_b).length() - got.distance).abs() <= 1e-9 * scale,
            "round {round}: closest points {:?}",
            got
        );
        if want > 1e-3 {
            compared += 1;
            let mut tree_checker = Checker::new(&scene);
            let tree = Tree::build(&scene, TreeOptions::default());
            let mut report = Report::default();
            let soft = Settings::with_clearance(want * 2.0 + 1.0);
            tree_checker.check(&scene, &tree, &[a], &soft, &mut report);
            let clash = report
                .clashes
                .iter()
                .find(|c| c.b == b)
                .expect("soft clash");
            assert_eq!(clash.distance, got.distance, "round {round}");
        }
    }
    assert!(compared >= 5, "only {compared} separated pairs");
}
