//! Structural invariants, checked by tests after every mutation and under
//! `debug_assert!` after every move.

use dmu_geom::Aabb3d;
use dmu_scene::Scene;

use crate::build::sort_key;
use crate::tree::{Kind, NONE, Tree};

/// A broken invariant of a [`Tree`], found by [`Tree::validate`] or
/// [`Tree::validate_against`]: a bug in the tree or a caller that moved a part
/// without telling the tree.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[error("{what}")]
pub struct InvariantError {
    /// Which invariant, where (e.g. "entry 12 (part #3, chunk #40) is stale").
    pub what: String,
}

impl InvariantError {
    /// A broken invariant described by `what` (for structures that mirror the
    /// tree, such as the renderer's).
    pub fn new(what: impl Into<String>) -> Self {
        Self { what: what.into() }
    }
}

impl Tree {
    /// Every entry in exactly one live cell that knows it; cells sorted by part and
    /// chunk with the right triangle counts; every node's box the exact union of
    /// its children or entries; parent links consistent; no free node reachable.
    pub fn validate(&self) -> Result<(), InvariantError> {
        self.check_structure()
            .map_err(|what| InvariantError { what })
    }

    /// [`Tree::validate`]'s checks, failing with what is wrong.
    fn check_structure(&self) -> Result<(), String> {
        let mut seen_entry = vec![false; self.entries.len()];
        let mut seen_cell = vec![false; self.cells.len()];
        let mut reached = 0usize;
        let mut stack = vec![(self.root, NONE)];
        while let Some((node, parent)) = stack.pop() {
            reached += 1;
            let n = self
                .nodes
                .get(node as usize)
                .ok_or(format!("node {node} out of range"))?;
            if n.parent != parent {
                return Err(format!(
                    "node {node}: parent {} but reached from {parent}",
                    n.parent
                ));
            }
            let expected = match n.kind {
                Kind::Free => return Err(format!("free node {node} is in the tree")),
                Kind::Internal(c) => {
                    stack.extend(c.map(|c| (c, node)));
                    self.nodes[c[0] as usize]
                        .bounds
                        .union(self.nodes[c[1] as usize].bounds)
                }
                Kind::Leaf(cell) => {
                    let c = self
                        .cells
                        .get(cell as usize)
                        .ok_or(format!("cell {cell} out of range"))?;
                    if c.node != node || std::mem::replace(&mut seen_cell[cell as usize], true) {
                        return Err(format!(
                            "cell {cell}: node {} but found at {node}, or found twice",
                            c.node
                        ));
                    }
                    let keys: Vec<u64> = c
                        .entries
                        .iter()
                        .map(|&e| {
                            let entry = &self.entries[e as usize];
                            sort_key(entry.part, entry.chunk)
                        })
                        .collect();
                    if !keys.is_sorted() {
                        return Err(format!("cell {cell}: entries not sorted by part"));
                    }
                    let mut tris = 0;
                    let mut bounds = Aabb3d::EMPTY;
                    for &e in &c.entries {
                        let entry = self
                            .entries
                            .get(e as usize)
                            .ok_or(format!("entry {e} out of range"))?;
                        if entry.cell != cell
                            || std::mem::replace(&mut seen_entry[e as usize], true)
                        {
                            return Err(format!(
                                "entry {e}: in cell {cell} but says {}, or listed twice",
                                entry.cell
                            ));
                        }
                        tris += entry.triangles;
                        bounds = bounds.union(entry.bounds);
                    }
                    if tris != c.triangles {
                        return Err(format!(
                            "cell {cell}: {} triangles recorded, {tris} held",
                            c.triangles
                        ));
                    }
                    bounds
                }
            };
            if n.bounds != expected {
                return Err(format!(
                    "node {node}: box {:?} is not the union {expected:?} below it",
                    n.bounds
                ));
            }
        }
        if let Some(e) = seen_entry.iter().position(|s| !s) {
            return Err(format!("entry {e} is in no cell"));
        }
        let live_cells = self.cells.iter().filter(|c| c.node != NONE).count();
        if seen_cell.iter().filter(|s| **s).count() != live_cells || live_cells != self.cell_count()
        {
            return Err("live cells and reachable cells disagree".into());
        }
        if reached + self.free_nodes.len() != self.nodes.len() {
            return Err(format!(
                "{reached} reachable + {} free != {} nodes",
                self.free_nodes.len(),
                self.nodes.len()
            ));
        }
        Ok(())
    }

    /// Checks that every entry's box is its chunk's box under the part's current
    /// transform in `scene` (the tree is up to date with the scene).
    pub fn validate_against(&self, scene: &Scene) -> Result<(), InvariantError> {
        self.validate()?;
        for (i, e) in self.entries.iter().enumerate() {
            if e.bounds != scene.chunk_world_bounds(e.part, e.chunk) {
                return Err(InvariantError {
                    what: format!("entry {i} (part {}, chunk {}) is stale", e.part, e.chunk),
                });
            }
        }
        Ok(())
    }
}
