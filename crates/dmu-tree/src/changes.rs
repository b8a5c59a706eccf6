//! What moves changed, for mirrors of the tree (the renderer's) that update
//! themselves in time proportional to the change instead of re-reading the tree.
//!
//! Each change names a node, cell or entry whose state differs from before; a
//! reader re-reads the current state of what is named, so the log holds ids
//! only, possibly repeated, and a slot freed and reused is simply named again.

use std::sync::atomic::{AtomicU64, Ordering};

use dmu_geom::Aabb3d;

use crate::tree::{CellId, EntryId, Kind, NONE, Tree};

/// Changes kept for readers that are behind; older ones are dropped (a reader
/// that far behind re-reads the whole tree).
const LOG_CAPACITY: usize = 1 << 16;

/// Distinguishes trees, so a revision of one never reads as one of another.
static NEXT_TREE: AtomicU64 = AtomicU64::new(0);

/// A node of the tree (an index into its node slots; stable while the node lives).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(pub u32);

/// What a node slot holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// Two children.
    Internal([NodeId; 2]),
    /// A leaf: a cell.
    Cell(CellId),
    /// Nothing (a free slot).
    Free,
}

/// A point in a tree's history: changes after it are listed by [`Tree::changes_since`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Revision {
    tree: u64,
    count: u64,
}

/// Something whose state changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Change {
    /// A node's box or kind (children, cell) changed, or it was freed or allocated.
    Node(NodeId),
    /// A cell's entries or node changed, or it was freed or allocated.
    Cell(CellId),
    /// An entry's box changed.
    Entry(EntryId),
}

/// The answer of [`Tree::changes_since`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Changes<'a> {
    /// The log does not reach back to the revision (another tree, a rebuild,
    /// or too many changes since): read the whole tree again.
    Rebuild,
    /// Everything that changed since, each at least once, maybe repeated.
    Touched(&'a [Change]),
}

/// The log of changes since the oldest revision still covered.
#[derive(Debug)]
pub(crate) struct ChangeLog {
    tree: u64,
    /// The oldest revision whose changes since are all in `changes`.
    first: u64,
    /// `marks[i]`: where in `changes` revision `first + i` starts.
    marks: Vec<usize>,
    changes: Vec<Change>,
}

impl ChangeLog {
    /// The log of a new tree.
    pub fn new() -> Self {
        Self {
            tree: NEXT_TREE.fetch_add(1, Ordering::Relaxed),
            first: 0,
            marks: vec![0],
            changes: Vec::new(),
        }
    }

    fn revision(&self) -> u64 {
        self.first + self.marks.len() as u64 - 1
    }

    /// Forgets every change: a new revision that nothing older reaches.
    pub fn restart(&mut self) {
        self.first = self.revision() + 1;
        self.marks = vec![0];
        self.changes.clear();
    }

    pub fn push(&mut self, change: Change) {
        self.changes.push(change);
    }

    /// Closes the current revision; drops the oldest revisions when the log
    /// is over its capacity.
    pub fn commit(&mut self) {
        self.marks.push(self.changes.len());
        if self.changes.len() <= LOG_CAPACITY {
            return;
        }
        let keep_from = self
            .marks
            .iter()
            .position(|&m| self.changes.len() - m <= LOG_CAPACITY / 2)
            .unwrap_or(self.marks.len() - 1);
        let dropped = self.marks[keep_from];
        self.changes.drain(..dropped);
        self.marks.drain(..keep_from);
        for m in &mut self.marks {
            *m -= dropped;
        }
        self.first += keep_from as u64;
    }
}

impl Tree {
    /// The tree's current revision: it changes with every move and rebuild.
    pub fn revision(&self) -> Revision {
        Revision {
            tree: self.log.tree,
            count: self.log.revision(),
        }
    }

    /// What changed since `revision` (of this tree): enough for a mirror to
    /// update itself by re-reading only what is named.
    pub fn changes_since(&self, revision: Revision) -> Changes<'_> {
        if revision.tree != self.log.tree
            || revision.count < self.log.first
            || revision.count > self.log.revision()
        {
            return Changes::Rebuild;
        }
        let at = self.log.marks[(revision.count - self.log.first) as usize];
        Changes::Touched(&self.log.changes[at..])
    }

    /// The root node.
    pub fn root(&self) -> NodeId {
        NodeId(self.root)
    }

    /// Node slots, live or free: every [`NodeId`] is below this.
    pub fn node_slots(&self) -> usize {
        self.nodes.len()
    }

    /// A node's box (empty for a free slot).
    pub fn node_bounds(&self, node: NodeId) -> &Aabb3d {
        &self.nodes[node.0 as usize].bounds
    }

    /// What a node slot holds.
    pub fn node_kind(&self, node: NodeId) -> NodeKind {
        match self.nodes[node.0 as usize].kind {
            Kind::Internal(c) => NodeKind::Internal(c.map(NodeId)),
            Kind::Leaf(c) => NodeKind::Cell(CellId(c)),
            Kind::Free => NodeKind::Free,
        }
    }

    /// Cell slots, live or free: every [`CellId`] is below this.
    pub fn cell_slots(&self) -> usize {
        self.cells.len()
    }

    /// The node holding a cell; `None` for a free cell slot.
    pub fn cell_node(&self, cell: CellId) -> Option<NodeId> {
        let node = self.cells[cell.0 as usize].node;
        (node != NONE).then_some(NodeId(node))
    }

    /// A cell's entries (entry ids), sorted by part and chunk; empty for a free slot.
    pub fn cell_entries(&self, cell: CellId) -> &[u32] {
        &self.cells[cell.0 as usize].entries
    }

    pub(crate) fn touch_node(&mut self, node: u32) {
        self.log.push(Change::Node(NodeId(node)));
    }

    pub(crate) fn touch_cell(&mut self, cell: u32) {
        self.log.push(Change::Cell(CellId(cell)));
    }
}
