//! The assembly tree's name table and sibling links against what the builder
//! was given: any shape, children added to parents in any interleaving,
//! names of any text (empty, non-ASCII).

use dmu_scene::{NodeId, SceneBuilder};
use glam::DAffine3;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn children_and_names_are_what_was_added(
        nodes in prop::collection::vec((any::<prop::sample::Index>(), ".{0,12}"), 0..200),
        root in ".{0,8}",
    ) {
        let mut b = SceneBuilder::new(root.clone(), 64);
        // The oracle: each node's children in the order they were added.
        let mut children: Vec<Vec<NodeId>> = vec![Vec::new()];
        let mut names = vec![root];
        for (k, (parent, name)) in nodes.iter().enumerate() {
            let parent = NodeId(parent.index(k + 1) as u32);
            let world = DAffine3::from_translation(glam::DVec3::splat(k as f64));
            let id = b.add_node(parent, name, world);
            prop_assert_eq!(id.index(), k + 1);
            children[parent.index()].push(id);
            children.push(Vec::new());
            names.push(name.clone());
        }
        let scene = b.finish();
        prop_assert_eq!(scene.validate(), Ok(()));
        prop_assert_eq!(scene.nodes().len(), names.len());
        for (i, (kids, name)) in children.iter().zip(&names).enumerate() {
            let id = NodeId(i as u32);
            prop_assert_eq!(&scene.children(id).collect::<Vec<_>>(), kids);
            prop_assert_eq!(scene.node_name(id), name.as_str());
            for c in kids {
                prop_assert_eq!(scene.node(*c).parent, Some(id));
            }
        }
        // A path joins the names below the root.
        if let Some(last) = (1..names.len()).last() {
            let mut path = Vec::new();
            let mut at = Some(NodeId(last as u32));
            while let Some(n) = at.filter(|n| n.index() != 0) {
                path.push(names[n.index()].as_str());
                at = scene.node(n).parent;
            }
            path.reverse();
            prop_assert_eq!(scene.node_path(NodeId(last as u32)), path.join("/"));
        }
    }
}
