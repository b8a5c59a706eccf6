//! The renderer's mirror of the cell tree, down to chunk instances.
//!
//! Occlusion culling keeps state per chunk instance and queries whole
//! subtrees, so it walks the tree's structure with one more level: a cell's
//! chunk instances are its leaves, so chunks hidden inside a visible cell are
//! culled too. The mirror keeps the tree's node slots as they are (node `n` of
//! the tree is mirror node `entries + n`; entry `e` is mirror node `e`), so a
//! move updates it by re-reading only what the tree's change log names: a
//! drag step costs the same on any model size. Per-view state is kept per
//! entry, whose ids never change. Boxes are never copied: a node's is the
//! tree's, read through [`Hierarchy::bounds`] (the tree node boxes alone
//! were 25 MB at 500M triangles, docs/measurements.md).

use dmu_geom::Aabb3d;
use dmu_tree::{CellId, Change, Changes, EntryId, InvariantError, NodeId, Revision, Tree};

/// "No node": a free slot's children, a free cell's node.
const NONE: u32 = u32::MAX;

/// What a node is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NodeKind {
    /// An internal node of the tree with two children.
    Internal,
    /// A cell; children are its entries.
    Cell(CellId),
    /// A chunk instance, the unit of drawing.
    Entry(EntryId),
    /// A free slot of the tree's nodes, in no subtree.
    Free,
}

/// A node of the tree (entries have none: they are implicit); its box is
/// the tree's.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    kind: NodeKind,
    /// The children of an internal node.
    children: [u32; 2],
}

const FREE: Node = Node {
    kind: NodeKind::Free,
    children: [NONE; 2],
};

/// The tree's structure as the renderer walks it. A [`Renderer`](crate::Renderer)
/// keeps one and brings it up to date with [`Hierarchy::sync`] each frame; it
/// needs no GPU, so its update cost is measured alone (`dmu bench tree`).
///
/// Entries are implicit: mirror node `e` below the entry count is entry `e`.
/// Every box is the tree's (`Hierarchy::bounds`); the mirror holds no copy
/// of the entries' boxes (76 MB at 500M triangles) nor of the nodes'.
#[derive(Debug, Default, PartialEq)]
pub struct Hierarchy {
    /// The tree's node slots (mirror node `entries + n` is slot `n`).
    tree_nodes: Vec<Node>,
    pub(crate) root: u32,
    /// Entry ids of each cell (by cell id; empty for dead cell ids).
    cell_entries: Vec<Vec<u32>>,
    /// The cell node holding each entry (by entry id).
    pub(crate) entry_cell: Vec<u32>,
    /// The node of each cell (by cell id; `NONE` for dead cell ids).
    pub(crate) cell_node: Vec<u32>,
    /// The tree revision this mirror shows.
    revision: Option<Revision>,
}

impl Hierarchy {
    /// Brings the mirror up to date with `tree`: re-reads what changed since
    /// the last call (the whole tree the first time, after a rebuild, for
    /// another tree, or when very far behind).
    pub fn sync(&mut self, tree: &Tree) {
        let revision = tree.revision();
        if self.revision == Some(revision) {
            return;
        }
        match self
            .revision
            .map_or(Changes::Rebuild, |r| tree.changes_since(r))
        {
            Changes::Rebuild => self.rebuild(tree),
            Changes::Touched(changes) => {
                self.grow(tree);
                for &change in changes {
                    match change {
                        Change::Node(n) => self.read_node(tree, n),
                        Change::Cell(c) => self.read_cell(tree, c),
                        // An entry's box is read from the tree.
                        Change::Entry(_) => {}
                    }
                }
                self.root = self.tree_node(tree.root());
            }
        }
        self.revision = Some(revision);
        debug_assert_eq!(self.validate(tree), Ok(()));
    }

    /// Re-reads the whole tree, reusing allocations.
    fn rebuild(&mut self, tree: &Tree) {
        self.tree_nodes.clear();
        self.entry_cell.clear();
        self.entry_cell.resize(tree.entries().len(), NONE);
        self.cell_node.clear();
        self.cell_entries.truncate(tree.cell_slots());
        self.grow(tree);
        for n in 0..tree.node_slots() {
            self.read_node(tree, NodeId(n as u32));
        }
        for c in 0..tree.cell_slots() {
            self.read_cell(tree, CellId(c as u32));
        }
        self.root = self.tree_node(tree.root());
    }

    /// Makes room for the tree's node and cell slots (they only grow between rebuilds).
    fn grow(&mut self, tree: &Tree) {
        self.tree_nodes.resize(tree.node_slots(), FREE);
        self.cell_node.resize(tree.cell_slots(), NONE);
        self.cell_entries.resize_with(tree.cell_slots(), Vec::new);
    }

    /// The mirror id of a tree node.
    fn tree_node(&self, node: NodeId) -> u32 {
        self.entry_cell.len() as u32 + node.0
    }

    fn read_node(&mut self, tree: &Tree, node: NodeId) {
        let (kind, children) = match tree.node_kind(node) {
            dmu_tree::NodeKind::Internal(c) => (NodeKind::Internal, c.map(|c| self.tree_node(c))),
            dmu_tree::NodeKind::Cell(c) => (NodeKind::Cell(c), [NONE; 2]),
            dmu_tree::NodeKind::Free => (NodeKind::Free, [NONE; 2]),
        };
        self.tree_nodes[node.0 as usize] = Node { kind, children };
    }

    fn read_cell(&mut self, tree: &Tree, cell: CellId) {
        let node = tree.cell_node(cell).map_or(NONE, |n| self.tree_node(n));
        let slot = cell.0 as usize;
        self.cell_node[slot] = node;
        let entries = &mut self.cell_entries[slot];
        entries.clear();
        entries.extend_from_slice(tree.cell_entries(cell));
        for &e in entries.iter() {
            self.entry_cell[e as usize] = node;
        }
    }

    /// Mirror nodes: entries, then the tree's node slots.
    pub(crate) fn len(&self) -> usize {
        self.entry_cell.len() + self.tree_nodes.len()
    }

    /// Whether the mirror is empty (not synced yet).
    pub(crate) fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The tree node slot of mirror node `node`, `None` for an entry.
    fn tree_slot(&self, node: u32) -> Option<&Node> {
        let slot = (node as usize).checked_sub(self.entry_cell.len())?;
        Some(&self.tree_nodes[slot])
    }

    /// What mirror node `node` is.
    pub(crate) fn kind(&self, node: u32) -> NodeKind {
        self.tree_slot(node)
            .map_or(NodeKind::Entry(EntryId(node)), |n| n.kind)
    }

    /// The box of mirror node `node`: `tree`'s (the tree this mirror was
    /// last synced with).
    pub(crate) fn bounds<'a>(&self, tree: &'a Tree, node: u32) -> &'a Aabb3d {
        match (node as usize).checked_sub(self.entry_cell.len()) {
            Some(slot) => tree.node_bounds(NodeId(slot as u32)),
            None => &tree.entries()[node as usize].bounds,
        }
    }

    /// Child ids of a node: an internal node's two, a cell's entries.
    pub(crate) fn children(&self, node: u32) -> &[u32] {
        let Some(n) = self.tree_slot(node) else {
            return &[];
        };
        match n.kind {
            NodeKind::Internal => &n.children,
            NodeKind::Cell(c) => &self.cell_entries[c.0 as usize],
            // A tree node is never an entry (entries are implicit).
            NodeKind::Entry(_) | NodeKind::Free => &[],
        }
    }

    /// The nodes under the root, parents before children (empty before the first sync).
    pub(crate) fn pre_order(&self) -> Vec<u32> {
        let mut order = Vec::with_capacity(self.len());
        if self.is_empty() {
            return order;
        }
        let mut stack = vec![self.root];
        while let Some(n) = stack.pop() {
            order.push(n);
            stack.extend_from_slice(self.children(n));
        }
        order
    }

    /// Appends the entry ids below a node to `out`.
    pub(crate) fn leaves(&self, node: u32, out: &mut Vec<u32>) {
        let mut stack = vec![node];
        while let Some(n) = stack.pop() {
            match self.kind(n) {
                NodeKind::Entry(e) => out.push(e.0),
                _ => stack.extend_from_slice(self.children(n)),
            }
        }
    }

    /// Checks the mirror against the tree: the same root and children for
    /// every live tree node, every entry below the root exactly once, in
    /// the cell holding it, boxes nesting.
    pub fn validate(&self, tree: &Tree) -> Result<(), InvariantError> {
        self.check(tree).map_err(InvariantError::new)
    }

    fn check(&self, tree: &Tree) -> Result<(), String> {
        if self.entry_cell.len() != tree.entries().len()
            || self.tree_nodes.len() != tree.node_slots()
        {
            return Err(format!(
                "{} entries and {} tree nodes for {} and {}",
                self.entry_cell.len(),
                self.tree_nodes.len(),
                tree.entries().len(),
                tree.node_slots()
            ));
        }
        if self.root != self.tree_node(tree.root()) {
            return Err(format!(
                "root {} for tree root {}",
                self.root,
                tree.root().0
            ));
        }
        let mut seen = vec![false; tree.entries().len()];
        for n in self.pre_order() {
            let Some(node) = self.tree_slot(n) else {
                if std::mem::replace(&mut seen[n as usize], true) {
                    return Err(format!("entry {n} reached twice"));
                }
                if self.entry_cell[n as usize]
                    != self.cell_node[tree.entry_cell(EntryId(n)).0 as usize]
                {
                    return Err(format!("entry {n} not in its cell"));
                }
                continue;
            };
            match node.kind {
                NodeKind::Entry(e) => return Err(format!("tree node {n} holds entry {}", e.0)),
                NodeKind::Free => return Err(format!("free node {n} in the tree")),
                NodeKind::Internal | NodeKind::Cell(_) => {
                    let t = NodeId(n - self.entry_cell.len() as u32);
                    let same = match (node.kind, tree.node_kind(t)) {
                        (NodeKind::Internal, dmu_tree::NodeKind::Internal(c)) => {
                            node.children == c.map(|c| self.tree_node(c))
                        }
                        (NodeKind::Cell(c), dmu_tree::NodeKind::Cell(tc)) => {
                            c == tc && self.children(n) == tree.cell_entries(c)
                        }
                        _ => false,
                    };
                    if !same {
                        return Err(format!("node {n} differs from the tree's"));
                    }
                    for &c in self.children(n) {
                        if !self.bounds(tree, n).contains(self.bounds(tree, c)) {
                            return Err(format!("node {n}: child {c} pokes out"));
                        }
                    }
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(e) => Err(format!("entry {e} unreachable")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dmu_geom::glam::{DAffine3, DVec3};
    use dmu_scene::PartId;
    use dmu_tree::TreeOptions;

    /// Every node's box, read from the tree rather than copied, is the
    /// union of the boxes of the chunk instances below it (the brute force)
    /// after each sync of a run of random moves that split, merge and
    /// rotate cells.
    #[test]
    fn node_boxes_are_the_union_of_their_entries_after_random_moves() {
        let options = TreeOptions {
            cell_triangles: 96,
            sah_bins: 8,
            rotations_per_move: 8,
            insert_search_nodes: 64,
        };
        let mut rng = dmu_samples::Rng::new(11);
        let mut scene = dmu_samples::grid(4, 10.0, 4.0, 4);
        let mut tree = Tree::build(&scene, options);
        let mut h = Hierarchy::default();
        let mut leaves = Vec::new();
        for _ in 0..60 {
            let part = PartId(rng.below(scene.parts().len() as u64) as u32);
            let reach = if rng.chance(0.3) { 60.0 } else { 1.5 };
            let step = DVec3::new(
                rng.range(-reach, reach),
                rng.range(-reach, reach),
                rng.range(-reach, reach),
            );
            let world = DAffine3::from_translation(step) * scene.part_world(part);
            tree.move_part(&mut scene, part, world);
            h.sync(&tree);
            for n in h.pre_order() {
                leaves.clear();
                h.leaves(n, &mut leaves);
                let union = (leaves.iter())
                    .map(|&e| tree.entries()[e as usize].bounds)
                    .fold(Aabb3d::EMPTY, Aabb3d::union);
                assert_eq!(*h.bounds(&tree, n), union, "node {n}");
            }
        }
    }
}
