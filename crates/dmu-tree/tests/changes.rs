//! The change log: what a move names, and when a reader must re-read everything.

use dmu_geom::glam::{DAffine3, DVec3};
use dmu_tree::{Change, Changes, EntryId, Tree, TreeOptions};

#[test]
fn a_move_names_its_entries_and_the_nodes_whose_boxes_changed() {
    let mut scene = dmu_samples::grid(4, 10.0, 4.0, 4);
    let mut tree = Tree::build(&scene, TreeOptions::default());
    let start = tree.revision();
    assert_eq!(tree.changes_since(start), Changes::Touched(&[]));
    let part = scene.find_part("box_1_2_3").expect("a grid part");
    let boxes: Vec<_> = (0..tree.node_slots() as u32)
        .map(|n| *tree.node_bounds(dmu_tree::NodeId(n)))
        .collect();
    let world = DAffine3::from_translation(DVec3::new(0.5, 0.0, 0.0)) * scene.part_world(part);
    tree.move_part(&mut scene, part, world);
    assert_ne!(tree.revision(), start);
    let Changes::Touched(changes) = tree.changes_since(start) else {
        panic!("a move needs no rebuild");
    };
    for e in tree.part_entries(part) {
        assert!(changes.contains(&Change::Entry(e)), "entry {e:?} not named");
    }
    let others = (0..tree.entries().len() as u32)
        .map(EntryId)
        .filter(|e| tree.entries()[e.0 as usize].part != part);
    for e in others {
        assert!(
            !changes.contains(&Change::Entry(e)),
            "unmoved entry {e:?} named"
        );
    }
    // Oracle: every node whose box differs from before is named.
    for (n, before) in boxes.iter().enumerate() {
        let node = dmu_tree::NodeId(n as u32);
        if tree.node_bounds(node) != before {
            assert!(
                changes.contains(&Change::Node(node)),
                "node {n} changed unnamed"
            );
        }
    }
    assert_eq!(tree.changes_since(tree.revision()), Changes::Touched(&[]));
    tree.rebuild();
    assert_eq!(tree.changes_since(start), Changes::Rebuild);
    let other = Tree::build(&scene, TreeOptions::default());
    assert_eq!(other.changes_since(tree.revision()), Changes::Rebuild);
}
