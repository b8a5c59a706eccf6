//! The tree's data: nodes, cells (leaves) and entries (chunk instances).

use std::ops::Range;

use dmu_geom::Aabb3d;
use dmu_scene::{ChunkId, PartId};

use crate::chunk_bvh::ChunkBvhCache;

/// "No node / no cell": the root's parent, an unlinked slot.
pub(crate) const NONE: u32 = u32::MAX;

/// Settings of a tree; each is a knob with its cost measured by `dmu bench tree`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeOptions {
    /// Triangle budget of a cell: cells over it split, cells under a quarter of it
    /// merge with a leaf sibling. Thesis and Interviews3D: 1k-8k.
    pub cell_triangles: u32,
    /// Bins per axis of the SAH sweep.
    pub sah_bins: usize,
    /// At most this many tree rotations after each move (incremental re-optimisation).
    pub rotations_per_move: usize,
    /// At most this many nodes expanded when searching the best cell for a
    /// re-inserted chunk (`usize::MAX`: the exact branch and bound).
    pub insert_search_nodes: usize,
}

impl Default for TreeOptions {
    fn default() -> Self {
        Self {
            cell_triangles: 4096,
            sah_bins: 16,
            rotations_per_move: 32,
            insert_search_nodes: 64,
        }
    }
}

/// A leaf cell's id (stable while the cell lives).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CellId(pub u32);

/// An entry: one chunk of one part (a chunk instance).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct EntryId(pub u32);

/// A chunk instance: one chunk of one part at the part's current transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The part.
    pub part: PartId,
    /// The chunk (of the part's mesh).
    pub chunk: ChunkId,
    /// World box: the chunk's local box through the part's f64 transform.
    pub bounds: Aabb3d,
    /// Triangles in the chunk.
    pub triangles: u32,
    /// The cell holding it.
    pub(crate) cell: u32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Kind {
    /// Two children.
    Internal([u32; 2]),
    /// A leaf: the cell it holds.
    Leaf(u32),
    /// On the free list.
    Free,
}

#[derive(Clone, Debug)]
pub(crate) struct Node {
    /// Encloses the children's boxes (or the cell's entries) exactly after a refit.
    pub bounds: Aabb3d,
    pub parent: u32,
    pub kind: Kind,
}

/// A leaf cell: chunk instances grouped in sub-groups by part (MMDr thesis 3.1.6),
/// so whatever is found in a cell maps back to its part.
#[derive(Clone, Debug, Default)]
pub(crate) struct Cell {
    pub node: u32,
    /// Entry ids sorted by (part, chunk); runs of one part are the sub-groups.
    pub entries: Vec<u32>,
    pub triangles: u32,
}

/// Counters of the incremental updates since the tree was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// `move_part` calls.
    pub moves: u64,
    /// Entries whose box stayed inside their cell.
    pub stayed: u64,
    /// Entries that left their cell and were re-inserted.
    pub reinserted: u64,
    /// Cells split for exceeding the budget.
    pub splits: u64,
    /// Cells merged for falling under a quarter of the budget.
    pub merges: u64,
    /// Tree rotations applied.
    pub rotations: u64,
}

/// The dynamic cell tree over a scene's chunk instances.
///
/// Internal nodes are binary with possibly overlapping boxes; leaves are cells of
/// at most `cell_triangles` triangles (unless one chunk alone exceeds it);
/// triangles are never split. Built top-down with binned SAH, then updated
/// locally when parts move.
#[derive(Debug)]
pub struct Tree {
    pub(crate) options: TreeOptions,
    pub(crate) nodes: Vec<Node>,
    pub(crate) free_nodes: Vec<u32>,
    pub(crate) cells: Vec<Cell>,
    pub(crate) free_cells: Vec<u32>,
    pub(crate) root: u32,
    pub(crate) entries: Vec<Entry>,
    /// Entries of each part, a contiguous range in chunk order.
    pub(crate) part_entries: Vec<Range<u32>>,
    pub(crate) bvhs: ChunkBvhCache,
    pub(crate) stats: UpdateStats,
    /// Reused by the insertion search, so a move allocates nothing for it.
    pub(crate) search_scratch: Vec<crate::update::Candidate>,
    /// What moves changed, for mirrors of the tree.
    pub(crate) log: crate::changes::ChangeLog,
}

impl Tree {
    /// The settings it was built with.
    pub fn options(&self) -> &TreeOptions {
        &self.options
    }

    /// World box of everything (empty for an empty scene).
    pub fn bounds(&self) -> Aabb3d {
        self.nodes[self.root as usize].bounds
    }

    /// All entries (chunk instances), indexed by [`EntryId`].
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// A part's entries.
    pub fn part_entries(&self, part: PartId) -> impl ExactSizeIterator<Item = EntryId> + use<> {
        self.part_entries[part.index()].clone().map(EntryId)
    }

    /// The cell an entry lives in.
    pub fn entry_cell(&self, entry: EntryId) -> CellId {
        CellId(self.entries[entry.0 as usize].cell)
    }

    /// Live cells.
    pub fn cell_ids(&self) -> impl Iterator<Item = CellId> + '_ {
        self.cells
            .iter()
            .enumerate()
            .filter(|(_, c)| c.node != NONE)
            .map(|(i, _)| CellId(i as u32))
    }

    /// Number of live cells.
    pub fn cell_count(&self) -> usize {
        self.cells.len() - self.free_cells.len()
    }

    /// A cell's world box.
    pub fn cell_bounds(&self, cell: CellId) -> Aabb3d {
        self.nodes[self.cells[cell.0 as usize].node as usize].bounds
    }

    /// A cell's triangles.
    pub fn cell_triangles(&self, cell: CellId) -> u32 {
        self.cells[cell.0 as usize].triangles
    }

    /// A cell's sub-groups: for each part with geometry in the cell, its entries.
    pub fn cell_groups(&self, cell: CellId) -> impl Iterator<Item = (PartId, &[u32])> + '_ {
        self.cells[cell.0 as usize]
            .entries
            .chunk_by(|a, b| self.entries[*a as usize].part == self.entries[*b as usize].part)
            .map(|run| (self.entries[run[0] as usize].part, run))
    }

    /// Chunks whose picking BVH has been built so far (they are built on first use).
    pub fn chunk_bvhs_built(&self) -> usize {
        self.bvhs.built()
    }

    /// Counters of incremental updates.
    pub fn update_stats(&self) -> UpdateStats {
        self.stats
    }

    /// Depth of the tree (a lone root leaf has depth 1).
    pub fn depth(&self) -> usize {
        let mut max = 0;
        let mut stack = vec![(self.root, 1usize)];
        while let Some((n, d)) = stack.pop() {
            max = max.max(d);
            if let Kind::Internal(c) = self.nodes[n as usize].kind {
                stack.extend(c.map(|c| (c, d + 1)));
            }
        }
        max
    }

    /// The surface-area-heuristic cost of the tree, normalised by the root's area:
    /// internal nodes cost their area, cells their area times their triangles.
    /// Comparing this after many moves with a fresh build measures degradation.
    pub fn sah_cost(&self) -> f64 {
        let root_area = self.bounds().surface_area().max(f64::MIN_POSITIVE);
        let mut cost = 0.0;
        for node in &self.nodes {
            cost += match node.kind {
                Kind::Internal(_) => node.bounds.surface_area(),
                Kind::Leaf(c) => {
                    node.bounds.surface_area() * f64::from(self.cells[c as usize].triangles)
                }
                Kind::Free => 0.0,
            };
        }
        cost / root_area
    }
}
