//! The renderer's mirror of the tree, updated from the tree's change log,
//! against the oracle of a mirror read afresh from the whole tree.

use dmu_geom::glam::{DAffine3, DVec3};
use dmu_render::Hierarchy;
use dmu_samples::Rng;
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};

/// Small cells, so that moves split and merge them.
const OPTIONS: TreeOptions = TreeOptions {
    cell_triangles: 96,
    sah_bins: 8,
    rotations_per_move: 8,
    insert_search_nodes: 64,
};

fn fresh(tree: &Tree) -> Hierarchy {
    let mut h = Hierarchy::default();
    h.sync(tree);
    h
}

/// Moves a random part: mostly small steps (a drag), sometimes far (re-insertion
/// elsewhere), sometimes home.
fn random_move(rng: &mut Rng, scene: &mut Scene, tree: &mut Tree, home: &[DAffine3]) {
    let p = rng.below(home.len() as u64) as usize;
    let part = PartId(p as u32);
    let world = if rng.chance(0.1) {
        home[p]
    } else {
        let reach = if rng.chance(0.3) { 80.0 } else { 1.5 };
        let step = DVec3::new(
            rng.range(-reach, reach),
            rng.range(-reach, reach),
            rng.range(-reach, reach),
        );
        DAffine3::from_translation(step) * scene.part_world(part)
    };
    tree.move_part(scene, part, world);
}

#[test]
fn incremental_mirror_equals_a_fresh_one_after_random_moves() {
    let mut totals = dmu_tree::UpdateStats::default();
    for seed in 1..=6 {
        let mut rng = Rng::new(seed);
        let mut scene = dmu_samples::grid(5, 10.0, 4.0, 4);
        let home: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
        let mut tree = Tree::build(&scene, OPTIONS);
        let mut mirror = fresh(&tree);
        for _ in 0..150 {
            // Several moves between syncs, as between frames.
            for _ in 0..1 + rng.below(4) {
                random_move(&mut rng, &mut scene, &mut tree, &home);
            }
            mirror.sync(&tree);
            assert_eq!(mirror.validate(&tree), Ok(()), "seed {seed}");
            assert!(
                mirror == fresh(&tree),
                "seed {seed}: mirror differs from a fresh one"
            );
        }
        let s = tree.update_stats();
        totals.reinserted += s.reinserted;
        totals.splits += s.splits;
        totals.merges += s.merges;
        totals.rotations += s.rotations;
    }
    // The moves exercised every kind of structural change.
    assert!(totals.reinserted > 0, "{totals:?}");
    assert!(totals.splits > 0, "{totals:?}");
    assert!(totals.merges > 0, "{totals:?}");
    assert!(totals.rotations > 0, "{totals:?}");
}

#[test]
fn mirror_follows_rebuilds_other_trees_and_long_absences() {
    let mut rng = Rng::new(7);
    let mut scene = dmu_samples::grid(4, 10.0, 4.0, 4);
    let home: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
    let mut tree = Tree::build(&scene, OPTIONS);
    let mut mirror = fresh(&tree);
    random_move(&mut rng, &mut scene, &mut tree, &home);
    tree.rebuild();
    mirror.sync(&tree);
    assert!(mirror == fresh(&tree), "after a rebuild");

    // More moves than the change log keeps.
    for _ in 0..8_000 {
        random_move(&mut rng, &mut scene, &mut tree, &home);
    }
    mirror.sync(&tree);
    assert!(mirror == fresh(&tree), "after many moves");

    let other = Tree::build(&dmu_samples::grid(3, 10.0, 4.0, 4), OPTIONS);
    mirror.sync(&other);
    assert!(mirror == fresh(&other), "another tree");
    mirror.sync(&tree);
    assert!(mirror == fresh(&tree), "back to the first tree");
}
