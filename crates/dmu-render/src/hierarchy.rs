//! The renderer's mirror of the cell tree, down to chunk instances.
//!
//! Occlusion culling keeps state per node and queries whole subtrees, so it
//! needs the tree's structure, which `dmu-tree` exposes only as a parents-first
//! traversal. A full binary tree is determined by its pre-order with leaves
//! marked, so one traversal with an accept-everything frustum rebuilds it. The
//! mirror adds one level: a cell's chunk instances are its leaves, so chunks
//! hidden inside a visible cell are culled too.

use dmu_geom::{Aabb3d, Frustum, Plane};
use dmu_tree::{CellId, EntryId, Tree, UpdateStats};

/// What a node is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NodeKind {
    /// An internal node of the tree; children are `children` in [`Hierarchy::links`].
    Internal,
    /// A cell; children are its entries.
    Cell(CellId),
    /// A chunk instance, the unit of drawing.
    Entry(EntryId),
}

/// A node of the mirror.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub bounds: Aabb3d,
    pub kind: NodeKind,
    /// Range of child node ids in [`Hierarchy::links`].
    pub children: (u32, u32),
    /// Range of entry leaves below, in [`Hierarchy::leaf_order`].
    pub leaves: (u32, u32),
}

/// The tree's structure as the renderer walks it.
#[derive(Debug, Default)]
pub(crate) struct Hierarchy {
    pub nodes: Vec<Node>,
    /// Child node ids, each node's a contiguous run.
    pub links: Vec<u32>,
    /// Entry ids in a depth-first order: every node's entries are a run.
    pub leaf_order: Vec<u32>,
    /// The node of each entry (by entry id).
    pub entry_node: Vec<u32>,
    /// The cell node holding each entry (by entry id).
    pub entry_cell: Vec<u32>,
    /// The node of each cell (by cell id; `u32::MAX` for dead cell ids).
    pub cell_node: Vec<u32>,
    /// The tree state this mirror was built from.
    stamp: Option<(UpdateStats, usize, usize)>,
}

impl Hierarchy {
    /// Rebuilds the mirror when the tree changed since the last call (a move, a
    /// split or merge changes its update counters).
    pub fn sync(&mut self, tree: &Tree) {
        let stamp = (tree.update_stats(), tree.cell_count(), tree.entries().len());
        if self.stamp == Some(stamp) {
            return;
        }
        self.stamp = Some(stamp);
        self.rebuild(tree);
        debug_assert_eq!(self.validate(tree), Ok(()));
    }

    fn rebuild(&mut self, tree: &Tree) {
        self.nodes.clear();
        self.links.clear();
        self.leaf_order.clear();
        self.entry_node.clear();
        self.entry_node.resize(tree.entries().len(), u32::MAX);
        self.entry_cell.clear();
        self.entry_cell.resize(tree.entries().len(), u32::MAX);
        self.cell_node.clear();
        // Binary structure first: children per tree node from the pre-order.
        let mut binary: Vec<(Aabb3d, Option<CellId>, Vec<u32>)> = Vec::new();
        let mut open: Vec<u32> = Vec::new();
        let everything = Frustum {
            planes: [Plane::ACCEPT_ALL; 6],
        };
        tree.visit_frustum(&everything, &mut |n| {
            let id = binary.len() as u32;
            binary.push((n.bounds, n.cell, Vec::new()));
            if let Some(&parent) = open.last() {
                let children = &mut binary[parent as usize].2;
                children.push(id);
                if children.len() == 2 {
                    open.pop();
                }
            }
            if n.cell.is_none() {
                open.push(id);
            }
            true
        });
        assert!(
            open.is_empty(),
            "tree traversal was not a full binary pre-order"
        );
        if binary.is_empty() {
            return;
        }
        // Lay nodes out depth-first with children runs, appending entry leaves.
        self.nodes.reserve(binary.len() + tree.entries().len());
        self.emit(tree, &binary, 0);
    }

    /// Emits tree node `b` and its subtree; returns its mirror id.
    fn emit(&mut self, tree: &Tree, binary: &[(Aabb3d, Option<CellId>, Vec<u32>)], b: u32) -> u32 {
        let (bounds, cell, ref children) = binary[b as usize];
        let id = self.nodes.len() as u32;
        let leaf_start = self.leaf_order.len() as u32;
        self.nodes.push(Node {
            bounds,
            kind: cell.map_or(NodeKind::Internal, NodeKind::Cell),
            children: (0, 0),
            leaves: (0, 0),
        });
        let mut child_ids = Vec::new();
        match cell {
            Some(cell) => {
                let slot = cell.0 as usize;
                if self.cell_node.len() <= slot {
                    self.cell_node.resize(slot + 1, u32::MAX);
                }
                self.cell_node[slot] = id;
                for (_, entries) in tree.cell_groups(cell) {
                    for &e in entries {
                        let leaf = self.nodes.len() as u32;
                        self.nodes.push(Node {
                            bounds: tree.entries()[e as usize].bounds,
                            kind: NodeKind::Entry(EntryId(e)),
                            children: (0, 0),
                            leaves: (
                                self.leaf_order.len() as u32,
                                self.leaf_order.len() as u32 + 1,
                            ),
                        });
                        self.leaf_order.push(e);
                        self.entry_node[e as usize] = leaf;
                        self.entry_cell[e as usize] = id;
                        child_ids.push(leaf);
                    }
                }
            }
            None => {
                for &c in children {
                    child_ids.push(self.emit(tree, binary, c));
                }
            }
        }
        let start = self.links.len() as u32;
        self.links.extend_from_slice(&child_ids);
        let node = &mut self.nodes[id as usize];
        node.children = (start, self.links.len() as u32);
        node.leaves = (leaf_start, self.leaf_order.len() as u32);
        id
    }

    /// Child ids of a node.
    pub fn children(&self, node: u32) -> &[u32] {
        let (a, b) = self.nodes[node as usize].children;
        &self.links[a as usize..b as usize]
    }

    /// Entry ids below a node.
    pub fn leaves(&self, node: u32) -> &[u32] {
        let (a, b) = self.nodes[node as usize].leaves;
        &self.leaf_order[a as usize..b as usize]
    }

    /// Checks the mirror against the tree: every entry exactly once, boxes nest.
    pub fn validate(&self, tree: &Tree) -> Result<(), String> {
        if self.leaf_order.len() != tree.entries().len() {
            return Err(format!(
                "{} leaves for {} entries",
                self.leaf_order.len(),
                tree.entries().len()
            ));
        }
        for (e, &n) in self.entry_node.iter().enumerate() {
            if self.nodes.get(n as usize).map(|n| n.kind)
                != Some(NodeKind::Entry(EntryId(e as u32)))
            {
                return Err(format!("entry {e} has no leaf"));
            }
        }
        for (i, node) in self.nodes.iter().enumerate() {
            for &c in self.children(i as u32) {
                if !node.bounds.contains(&self.nodes[c as usize].bounds) {
                    return Err(format!("node {i}: child {c} pokes out"));
                }
            }
        }
        Ok(())
    }
}
