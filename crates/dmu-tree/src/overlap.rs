//! Box overlap: the chunk instances whose world boxes meet a query box, the
//! broad phase of collision. Allocation-free: the traversal climbs back up by
//! parent links instead of keeping a stack, and results go to the caller's buffer.

use dmu_geom::Aabb3d;

use crate::tree::{CellId, EntryId, Kind, NONE, Tree};

impl Tree {
    /// Appends to `out` every entry (chunk instance, hidden parts included) whose
    /// world box overlaps `query`; touching boxes count. Order is the tree's, each
    /// entry at most once; `out` is not cleared, so one buffer can gather several
    /// queries. Boxes only: no triangle is tested.
    pub fn entries_in_box(&self, query: &Aabb3d, out: &mut Vec<EntryId>) {
        let overlaps = |node: u32| {
            let b = &self.nodes[node as usize].bounds;
            !b.is_empty() && b.overlaps(query)
        };
        if query.is_empty() || !overlaps(self.root) {
            return;
        }
        let mut node = self.root;
        'descend: loop {
            match self.nodes[node as usize].kind {
                Kind::Internal([left, right]) => {
                    if overlaps(left) {
                        node = left;
                        continue 'descend;
                    }
                    if overlaps(right) {
                        node = right;
                        continue 'descend;
                    }
                }
                Kind::Leaf(cell) => {
                    for (_, group) in self.cell_groups(CellId(cell)) {
                        out.extend(
                            group
                                .iter()
                                .filter(|&&e| self.entries[e as usize].bounds.overlaps(query))
                                .map(|&e| EntryId(e)),
                        );
                    }
                }
                Kind::Free => unreachable!("free node in the tree"),
            }
            // Climb until some ancestor's right child is still to visit.
            loop {
                if node == self.root {
                    return;
                }
                let parent = self.nodes[node as usize].parent;
                debug_assert_ne!(parent, NONE, "a non-root node has a parent");
                let Kind::Internal([left, right]) = self.nodes[parent as usize].kind else {
                    unreachable!("a parent is internal")
                };
                if node == left && overlaps(right) {
                    node = right;
                    continue 'descend;
                }
                node = parent;
            }
        }
    }
}
