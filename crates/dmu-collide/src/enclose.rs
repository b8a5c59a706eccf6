//! Which parts could swallow a moved part whole: every part whose world box
//! contains the moved part's box. A closed part holding a small part deep inside
//! has no chunk near it (a hollow hall of fifty wall chunks around a pump), so
//! the broad phase over chunk boxes cannot bring the pair together; this index
//! over whole-part boxes can.
//!
//! A static bounding-volume hierarchy over the parts' world boxes, built once
//! and kept current through the tree's change log: parts moved since the build
//! are *stale*, skipped in the hierarchy and tested at their current box
//! instead, until there are enough of them to make a rebuild worth it.

use dmu_geom::{Aabb3d, Aabb3f};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Change, Changes, Revision, Tree};

/// Parts per leaf.
const LEAF_PARTS: usize = 4;

/// A node of the hierarchy: a leaf holds `count > 0` parts from `first` in
/// [`Enclosers::parts`]; an internal node (`count == 0`) has its children at
/// the next index and at `first`. Its box only prunes (a leaf's parts are
/// tested at their own f64 boxes), so it is kept in f32 rounded outwards:
/// never smaller than its parts' union, and 32 bytes a node instead of 56
/// (13 MB less at 900k parts, docs/measurements.md).
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb3f,
    first: u32,
    count: u32,
}
const _: () = assert!(size_of::<Node>() == 32);

/// The index (see the module docs).
#[derive(Debug, Default)]
pub(crate) struct Enclosers {
    /// The tree revision the index is current with; `None` before the first use.
    revision: Option<Revision>,
    nodes: Vec<Node>,
    /// Parts with a non-empty box as of the build, in leaf order. Their
    /// boxes are read from the scene when a leaf is reached: a part not
    /// stale has the box it had at the build (a few bytes a part instead of
    /// sixty, at 900k parts 50 MB).
    parts: Vec<PartId>,
    /// Parts moved since the build, sorted, without repeats.
    stale: Vec<PartId>,
    /// Traversal stack, kept between queries.
    stack: Vec<u32>,
}

impl Enclosers {
    /// Brings the index up to date with `tree` (and `scene`, which the tree
    /// mirrors): rebuilt on the first call, after a tree rebuild, or once more
    /// than a sixteenth of the parts (at least 64) moved since the last build.
    pub fn sync(&mut self, scene: &Scene, tree: &Tree) {
        let changes = self.revision.map(|r| tree.changes_since(r));
        match changes {
            Some(Changes::Touched(changes)) => {
                let entries = tree.entries();
                self.stale.extend(changes.iter().filter_map(|c| match *c {
                    Change::Entry(e) => Some(entries[e.0 as usize].part),
                    _ => None,
                }));
                self.stale.sort_unstable();
                self.stale.dedup();
                if self.stale.len() > (scene.parts().len() / 16).max(64) {
                    self.build(scene);
                }
            }
            None | Some(Changes::Rebuild) => self.build(scene),
        }
        self.revision = Some(tree.revision());
    }

    fn build(&mut self, scene: &Scene) {
        self.stale.clear();
        // The boxes live only while the hierarchy is built (about 56 bytes a
        // part; a rebuild after many moves takes them again for a moment).
        let mut boxed: Vec<(PartId, Aabb3d)> = Vec::with_capacity(scene.parts().len());
        boxed.extend(
            scene
                .part_ids()
                .map(|p| (p, scene.part_world_bounds(p)))
                .filter(|(_, b)| !b.is_empty()),
        );
        self.nodes.clear();
        if !boxed.is_empty() {
            build_node(&mut self.nodes, &mut boxed, 0);
        }
        self.parts.clear();
        self.parts.extend(boxed.iter().map(|&(p, _)| p));
    }

    /// Every part whose current world box contains `inner` (the caller filters
    /// out the part itself), appended to `out`.
    pub fn containing(&mut self, scene: &Scene, inner: &Aabb3d, out: &mut Vec<PartId>) {
        if !self.nodes.is_empty() {
            self.stack.clear();
            self.stack.push(0);
        }
        while let Some(i) = self.stack.pop() {
            let node = self.nodes[i as usize];
            if !node.bounds.as_dvec().contains(inner) {
                continue;
            }
            if node.count == 0 {
                self.stack.extend([i + 1, node.first]);
                continue;
            }
            let leaf = &self.parts[node.first as usize..(node.first + node.count) as usize];
            out.extend(leaf.iter().copied().filter(|p| {
                self.stale.binary_search(p).is_err() && scene.part_world_bounds(*p).contains(inner)
            }));
        }
        out.extend(
            self.stale
                .iter()
                .copied()
                .filter(|&p| scene.part_world_bounds(p).contains(inner)),
        );
    }
}

/// Builds the subtree over `parts` (a slice of the whole list starting at
/// `offset`) at the end of `nodes`: median split on the longest axis of the
/// box centres.
fn build_node(nodes: &mut Vec<Node>, parts: &mut [(PartId, Aabb3d)], offset: u32) {
    let bounds = parts
        .iter()
        .fold(Aabb3d::EMPTY, |acc, (_, b)| acc.union(*b));
    let at = nodes.len();
    nodes.push(Node {
        bounds: bounds.as_vec_outward(),
        first: offset,
        count: parts.len() as u32,
    });
    if parts.len() <= LEAF_PARTS {
        return;
    }
    let centres = parts
        .iter()
        .fold(Aabb3d::EMPTY, |acc, (_, b)| acc.grown(b.center()));
    let axis = centres.extent().max_position();
    let mid = parts.len() / 2;
    parts.select_nth_unstable_by(mid, |(_, x), (_, y)| {
        x.center()[axis].total_cmp(&y.center()[axis])
    });
    let (left, right) = parts.split_at_mut(mid);
    build_node(nodes, left, offset);
    let second = nodes.len() as u32;
    build_node(nodes, right, offset + mid as u32);
    nodes[at].first = second;
    nodes[at].count = 0;
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_geom::glam::{DAffine3, DVec3};
    use dmu_tree::TreeOptions;

    /// The parts found holding a box are those a brute force over every
    /// part finds, for parts far from the origin (where an f32 box rounded
    /// to nearest would shrink past a part's f64 box) and boxes that touch
    /// a part's own box exactly, slightly inside it or slightly beyond.
    #[test]
    fn containing_finds_what_a_brute_force_finds_far_from_the_origin() {
        let mut rng = dmu_samples::Rng::new(5);
        let mut scene = dmu_samples::grid(6, 3.0, 4.0, 4);
        let far = DVec3::new(4_756_000.3, 5_353_000.7, 13_700.1);
        for p in scene.part_ids().collect::<Vec<_>>() {
            let jitter = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let world = DAffine3::from_translation(far + jitter) * scene.part_world(p);
            scene.set_part_world(p, world);
        }
        let tree = Tree::build(&scene, TreeOptions::default());
        let mut index = Enclosers::default();
        index.sync(&scene, &tree);
        let parts: Vec<PartId> = scene.part_ids().collect();
        let mut found = Vec::new();
        for _ in 0..2_000 {
            let own = scene.part_world_bounds(parts[rng.below(parts.len() as u64) as usize]);
            let inner = match rng.below(3) {
                0 => own,
                // Within a few f64 ulps of the part's box, either side.
                1 => {
                    let d = DVec3::splat(rng.range(-4.0, 4.0) * f64::EPSILON * far.length());
                    Aabb3d {
                        min: own.min + d,
                        max: own.max - d,
                    }
                }
                _ => {
                    let c = own.center() + DVec3::splat(rng.range(-3.0, 3.0));
                    let h = DVec3::splat(rng.range(0.01, 1.5));
                    Aabb3d {
                        min: c - h,
                        max: c + h,
                    }
                }
            };
            found.clear();
            index.containing(&scene, &inner, &mut found);
            found.sort_unstable();
            let brute: Vec<PartId> = (parts.iter().copied())
                .filter(|&p| scene.part_world_bounds(p).contains(&inner))
                .collect();
            assert_eq!(found, brute, "parts holding {inner:?}");
        }
    }
}
