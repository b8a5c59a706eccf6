//! `entries_in_box` against a linear scan of the entries, on random scenes
//! before and after random moves (which reshape the tree).

use dmu_geom::Aabb3d;
use dmu_samples::Rng;
use dmu_tree::{EntryId, Tree, TreeOptions};
use glam::DVec3;
use proptest::prelude::*;

use crate::support::{random_box, random_scene, random_transform, small_cells};

fn brute(tree: &Tree, query: &Aabb3d) -> Vec<EntryId> {
    (0..tree.entries().len() as u32)
        .map(EntryId)
        .filter(|&e| tree.entries()[e.0 as usize].bounds.overlaps(query))
        .collect()
}

fn sorted(mut v: Vec<EntryId>) -> Vec<EntryId> {
    v.sort_unstable();
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn entries_in_box_equal_a_linear_scan(seed in any::<u64>(), parts in 1usize..40, moves in 0usize..40) {
        let mut scene = random_scene(seed, parts, DVec3::new(1e7, -3e6, 0.0));
        let options = small_cells();
        let mut tree = Tree::build(&scene, options);
        let mut rng = Rng::new(seed ^ 0x5eed);
        for _ in 0..moves {
            let part = dmu_scene::PartId(rng.below(parts as u64) as u32);
            let world = random_transform(&mut rng, DVec3::new(1e7, -3e6, 0.0), 30.0);
            tree.move_part(&mut scene, part, world);
        }
        tree.validate_against(&scene)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let bounds = scene.world_bounds();
        let mut out = Vec::new();
        for _ in 0..20 {
            let query = random_box(&mut rng, &bounds);
            out.clear();
            tree.entries_in_box(&query, &mut out);
            let got = sorted(out.clone());
            let mut dedup = got.clone();
            dedup.dedup();
            prop_assert_eq!(&got, &dedup, "an entry reported twice");
            prop_assert_eq!(got, brute(&tree, &query));
        }
    }
}

#[test]
fn touching_boxes_count_and_the_buffer_accumulates() {
    let scene = dmu_samples::grid(3, 10.0, 4.0, 2048);
    let tree = Tree::build(&scene, TreeOptions::default());
    // The face x = 2 of box (0,0,0) touches this box; nothing else is near.
    let touching = Aabb3d::new(DVec3::new(2.0, -1.0, -1.0), DVec3::new(3.0, 1.0, 1.0));
    let mut out = Vec::new();
    tree.entries_in_box(&touching, &mut out);
    assert_eq!(out.len(), 1);
    assert_eq!(tree.entries()[out[0].0 as usize].part, dmu_scene::PartId(0));
    // A second query appends.
    tree.entries_in_box(&tree.bounds(), &mut out);
    assert_eq!(out.len(), 1 + 27);
    // Empty and far boxes find nothing.
    let before = out.len();
    tree.entries_in_box(&Aabb3d::EMPTY, &mut out);
    tree.entries_in_box(
        &Aabb3d::new(DVec3::splat(100.0), DVec3::splat(101.0)),
        &mut out,
    );
    assert_eq!(out.len(), before);
}
