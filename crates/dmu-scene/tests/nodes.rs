//! The assembly tree's name table and sibling links against what the builder
//! was given: any shape, children added to parents in any interleaving,
//! names of any text (empty, non-ASCII).

use dmu_scene::{MeshData, NodeId, PartId, SceneBuilder, SceneError};
use glam::{DAffine3, Vec3};
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// `find_part` by name, `#id` and path against the brute force it
    /// replaced (every part's path built and compared), on trees whose names
    /// repeat, are empty or hold `/` (issue 48: the lookup built a path a part
    /// per key).
    #[test]
    fn issue_48_find_part_matches_comparing_every_path(
        nodes in prop::collection::vec(
            (any::<prop::sample::Index>(), "[ab/]{0,3}", any::<bool>()), 0..60),
        keys in prop::collection::vec("[ab/#0-9]{0,6}", 0..20),
    ) {
        let mut b = SceneBuilder::new("root", 64);
        let material = b.add_material("grey", [0.5; 4]);
        let mut mesh = MeshData::default();
        mesh.push_primitive(&[Vec3::ZERO, Vec3::X, Vec3::Y], &[Vec3::Z; 3], &[0, 1, 2], material);
        let mesh = b.add_mesh(&mesh);
        for (k, (parent, name, part)) in nodes.iter().enumerate() {
            let node = b.add_node(NodeId(parent.index(k + 1) as u32), name, DAffine3::IDENTITY);
            if *part {
                b.add_part(node, mesh);
            }
        }
        let scene = b.finish();
        let brute = |key: &str| -> Vec<PartId> {
            let by_name: Vec<PartId> =
                scene.part_ids().filter(|&p| scene.part_name(p) == key).collect();
            if by_name.is_empty() && key.contains('/') {
                scene.part_ids().filter(|&p| scene.part_path(p) == key).collect()
            } else {
                by_name
            }
        };
        let paths = scene.part_ids().map(|p| scene.part_path(p));
        for key in keys.into_iter().chain(paths).filter(|k| !k.starts_with('#')) {
            match (brute(&key).as_slice(), scene.find_part(&key)) {
                ([one], Ok(found)) => prop_assert_eq!(*one, found, "{:?}", key),
                ([], Err(SceneError::UnknownPart { .. })) => {}
                (many, Err(SceneError::AmbiguousPart { count, .. })) if many.len() > 1 => {
                    prop_assert_eq!(count, many.len(), "{:?}", key);
                }
                (want, got) => prop_assert!(false, "{:?}: {:?} against {:?}", key, got, want),
            }
        }
    }
}
