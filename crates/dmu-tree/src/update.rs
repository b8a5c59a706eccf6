//! Moving a part: only its chunks are touched. Chunks whose new box left their
//! cell are removed and re-inserted at the best cell (branch and bound on the
//! SAH cost increase); cells over budget split, cells under a quarter of it
//! merge with a leaf sibling; ancestors refit; a bounded number of rotations on
//! the touched paths keeps a long editing session from degrading the tree.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use dmu_geom::Aabb3d;
use dmu_scene::{PartId, Scene};
use glam::DAffine3;

use crate::build::{sah_partition, sort_key};
use crate::changes::Change;
use crate::tree::{EntryId, Kind, NONE, Tree};

impl Tree {
    /// Sets a part's absolute world transform in the scene and updates the tree
    /// for it. Cost is proportional to the part's chunk count times tree depth.
    pub fn move_part(&mut self, scene: &mut Scene, part: PartId, world: DAffine3) {
        scene.set_part_world(part, world);
        self.update_part(scene, part);
    }

    /// Brings the tree up to date with `part`'s current transform in `scene`.
    pub fn update_part(&mut self, scene: &Scene, part: PartId) {
        self.stats.moves += 1;
        let world = scene.part_world(part);
        let mut touched: Vec<u32> = Vec::new();
        let mut reinsert: Vec<(u32, u32)> = Vec::new(); // (entry, its former cell)
        for e in self.part_entries[part.index()].clone() {
            let entry = &mut self.entries[e as usize];
            entry.bounds = scene.chunk(entry.chunk).bounds.transformed(&world);
            let (cell, bounds) = (entry.cell, entry.bounds);
            self.log.push(Change::Entry(EntryId(e)));
            if self.nodes[self.cells[cell as usize].node as usize]
                .bounds
                .contains(&bounds)
            {
                self.stats.stayed += 1;
            } else {
                let c = &mut self.cells[cell as usize];
                c.entries.retain(|&x| x != e);
                c.triangles -= self.entries[e as usize].triangles;
                self.touch_cell(cell);
                reinsert.push((e, cell));
            }
            touched.push(cell);
        }
        touched.sort_unstable();
        touched.dedup();
        let mut paths = Vec::new();
        for cell in touched {
            // A cell may already be gone, merged into a neighbour touched earlier.
            if self.cells[cell as usize].node != NONE
                && let Some(node) = self.settle_cell(cell)
            {
                paths.push(node);
            }
        }
        for (e, cell) in reinsert {
            self.stats.reinserted += 1;
            // The former cell, if it still exists, seeds the search.
            let node = self.cells[cell as usize].node;
            paths.push(self.insert_entry(e, (node != NONE).then_some(node)));
        }
        self.rotate_paths(&paths);
        self.log.commit();
        debug_assert_eq!(self.validate(), Ok(()));
    }

    /// Refits a cell whose entries changed; removes it when empty, merges it with a
    /// leaf sibling when under a quarter of the budget. Returns a node from which
    /// ancestors were refit (for rotations), if the cell or its merge survives.
    fn settle_cell(&mut self, cell: u32) -> Option<u32> {
        let node = self.cells[cell as usize].node;
        if self.cells[cell as usize].entries.is_empty() && node != self.root {
            let grandparent = self.remove_leaf(node);
            self.free_cell(cell);
            self.refit_up(grandparent);
            return (grandparent != NONE).then_some(grandparent);
        }
        self.refit_cell(cell);
        self.refit_up(self.nodes[node as usize].parent);
        self.try_merge(cell).or(Some(node))
    }

    /// Merges `cell` with its sibling when both are leaves, `cell` is under a
    /// quarter of the budget and the two fit in one cell.
    fn try_merge(&mut self, cell: u32) -> Option<u32> {
        let budget = self.options.cell_triangles;
        let node = self.cells[cell as usize].node;
        let parent = self.nodes[node as usize].parent;
        if parent == NONE || self.cells[cell as usize].triangles >= budget / 4 {
            return None;
        }
        let sibling = self.sibling(node);
        let Kind::Leaf(other) = self.nodes[sibling as usize].kind else {
            return None;
        };
        if self.cells[cell as usize].triangles + self.cells[other as usize].triangles > budget {
            return None;
        }
        self.stats.merges += 1;
        let mut ids = std::mem::take(&mut self.cells[cell as usize].entries);
        ids.extend(std::mem::take(&mut self.cells[other as usize].entries));
        self.free_cell(cell);
        self.free_cell(other);
        self.free_node(node);
        self.free_node(sibling);
        let merged = self.alloc_cell(parent, ids);
        self.nodes[parent as usize].kind = Kind::Leaf(merged);
        self.touch_node(parent);
        self.refit_cell(merged);
        self.refit_up(self.nodes[parent as usize].parent);
        Some(parent)
    }

    /// Unlinks leaf `node`: its sibling takes the parent's place. Frees the leaf
    /// and the parent nodes; returns the grandparent (or NONE at the root).
    fn remove_leaf(&mut self, node: u32) -> u32 {
        let parent = self.nodes[node as usize].parent;
        let sibling = self.sibling(node);
        let grandparent = self.nodes[parent as usize].parent;
        self.nodes[sibling as usize].parent = grandparent;
        if grandparent == NONE {
            self.root = sibling;
        } else {
            self.replace_child(grandparent, parent, sibling);
        }
        self.free_node(node);
        self.free_node(parent);
        grandparent
    }

    /// The other child of `node`'s parent; `node` must not be the root.
    fn sibling(&self, node: u32) -> u32 {
        let parent = self.nodes[node as usize].parent;
        let Kind::Internal([a, b]) = self.nodes[parent as usize].kind else {
            unreachable!("parent is internal")
        };
        if a == node { b } else { a }
    }

    fn replace_child(&mut self, parent: u32, old: u32, new: u32) {
        if let Kind::Internal(c) = &mut self.nodes[parent as usize].kind {
            for slot in c.iter_mut().filter(|s| **s == old) {
                *slot = new;
            }
        }
        self.touch_node(parent);
    }

    /// Inserts entry `e` into the cell where it raises the SAH cost least, splitting
    /// the cell if it overflows. Returns the node the insertion ended at.
    fn insert_entry(&mut self, e: u32, hint: Option<u32>) -> u32 {
        let leaf = self.best_leaf(e, hint);
        let Kind::Leaf(cell) = self.nodes[leaf as usize].kind else {
            unreachable!("best_leaf returns a leaf")
        };
        let entries = &self.entries;
        let key = sort_key(entries[e as usize].part, entries[e as usize].chunk);
        let c = &mut self.cells[cell as usize];
        let at = c.entries.partition_point(|&x| {
            sort_key(entries[x as usize].part, entries[x as usize].chunk) < key
        });
        c.entries.insert(at, e);
        c.triangles += entries[e as usize].triangles;
        self.entries[e as usize].cell = cell;
        self.touch_cell(cell);
        self.touch_node(leaf);
        let b = self.nodes[leaf as usize]
            .bounds
            .union(self.entries[e as usize].bounds);
        self.nodes[leaf as usize].bounds = b;
        self.refit_up(self.nodes[leaf as usize].parent);
        self.split_if_over(cell);
        leaf
    }

    /// Branch and bound over the tree for the cell whose SAH cost grows least when
    /// `e` joins it: each ancestor costs its area growth, the cell its area times
    /// triangles growth. The search starts from the cell `e` came from (`hint`),
    /// whose cost is usually close to the best, skips a subtree once its lower
    /// bound is no better, and expands at most `insert_search_nodes` nodes (a knob:
    /// `dmu bench tree` measures its time and the SAH cost it leaves).
    fn best_leaf(&mut self, e: u32, hint: Option<u32>) -> u32 {
        let eb = self.entries[e as usize].bounds;
        let et = f64::from(self.entries[e as usize].triangles);
        let mut best = (f64::INFINITY, self.root);
        if let Some(leaf) = hint.filter(|&h| matches!(self.nodes[h as usize].kind, Kind::Leaf(_))) {
            best = (
                self.ancestors_growth(leaf, &eb) + self.leaf_growth(leaf, &eb, et),
                leaf,
            );
        }
        let mut heap = BinaryHeap::from(std::mem::take(&mut self.search_scratch));
        heap.clear();
        heap.push(Candidate {
            bound: floor(&eb, &self.nodes[self.root as usize].bounds, et),
            inherited: 0.0,
            node: self.root,
        });
        let mut budget = self.options.insert_search_nodes;
        while let Some(Candidate {
            bound,
            inherited,
            node,
        }) = heap.pop()
        {
            if bound >= best.0 || budget == 0 {
                break;
            }
            budget -= 1;
            let n = &self.nodes[node as usize];
            match n.kind {
                Kind::Leaf(_) => {
                    let cost = inherited + self.leaf_growth(node, &eb, et);
                    if cost < best.0 {
                        best = (cost, node);
                    }
                }
                Kind::Internal(children) => {
                    let inherited =
                        inherited + n.bounds.union(eb).surface_area() - n.bounds.surface_area();
                    for child in children {
                        let bound = inherited + floor(&eb, &self.nodes[child as usize].bounds, et);
                        if bound < best.0 {
                            heap.push(Candidate {
                                bound,
                                inherited,
                                node: child,
                            });
                        }
                    }
                }
                Kind::Free => unreachable!("free node in the tree"),
            }
        }
        self.search_scratch = heap.into_vec();
        best.1
    }

    /// SAH growth of leaf `node` when an entry of box `eb` and `et` triangles joins it.
    fn leaf_growth(&self, node: u32, eb: &Aabb3d, et: f64) -> f64 {
        let n = &self.nodes[node as usize];
        let Kind::Leaf(cell) = n.kind else {
            unreachable!("a leaf")
        };
        let t = f64::from(self.cells[cell as usize].triangles);
        n.bounds.union(*eb).surface_area() * (t + et) - n.bounds.surface_area() * t
    }

    /// Area growth of the ancestors of `node` when they must also hold `eb`.
    fn ancestors_growth(&self, node: u32, eb: &Aabb3d) -> f64 {
        let mut growth = 0.0;
        let mut at = self.nodes[node as usize].parent;
        while at != NONE {
            let b = self.nodes[at as usize].bounds;
            growth += b.union(*eb).surface_area() - b.surface_area();
            at = self.nodes[at as usize].parent;
        }
        growth
    }

    /// Splits a cell over budget in two by SAH, repeatedly, while it has more
    /// than one entry.
    fn split_if_over(&mut self, cell: u32) {
        let c = &self.cells[cell as usize];
        if c.triangles <= self.options.cell_triangles || c.entries.len() < 2 {
            return;
        }
        self.stats.splits += 1;
        let node = c.node;
        let mut ids = std::mem::take(&mut self.cells[cell as usize].entries);
        self.free_cell(cell);
        let mid = sah_partition(&self.entries, &mut ids, self.options.sah_bins);
        let right_ids = ids.split_off(mid);
        let mut children = [NONE; 2];
        for (slot, part) in children.iter_mut().zip([ids, right_ids]) {
            let bounds = part.iter().fold(Aabb3d::EMPTY, |b, &e| {
                b.union(self.entries[e as usize].bounds)
            });
            let child = self.alloc_node(bounds, node, Kind::Free);
            let new_cell = self.alloc_cell(child, part);
            self.nodes[child as usize].kind = Kind::Leaf(new_cell);
            *slot = child;
        }
        self.nodes[node as usize].kind = Kind::Internal(children);
        self.touch_node(node);
        for child in children {
            if let Kind::Leaf(c) = self.nodes[child as usize].kind {
                self.split_if_over(c);
            }
        }
    }

    /// Sets a cell's node box to the exact union of its entries.
    fn refit_cell(&mut self, cell: u32) {
        let c = &self.cells[cell as usize];
        let b = c.entries.iter().fold(Aabb3d::EMPTY, |b, &e| {
            b.union(self.entries[e as usize].bounds)
        });
        let node = c.node;
        self.nodes[node as usize].bounds = b;
        self.touch_node(node);
    }

    /// Recomputes boxes from `node` up to the root, stopping where nothing changes.
    fn refit_up(&mut self, mut node: u32) {
        while node != NONE {
            let Kind::Internal([a, b]) = self.nodes[node as usize].kind else {
                unreachable!("ancestor is internal")
            };
            let bounds = self.nodes[a as usize]
                .bounds
                .union(self.nodes[b as usize].bounds);
            if bounds == self.nodes[node as usize].bounds {
                return;
            }
            self.nodes[node as usize].bounds = bounds;
            self.touch_node(node);
            node = self.nodes[node as usize].parent;
        }
    }

    /// Tree rotations (Kopta et al. 2012) on the ancestors of the given nodes,
    /// bottom-up, at most `rotations_per_move` applied: a child swaps with a
    /// grandchild on the other side when that shrinks the area of the node between.
    fn rotate_paths(&mut self, starts: &[u32]) {
        let mut budget = self.options.rotations_per_move;
        for &start in starts {
            let mut node = start;
            while node != NONE && budget > 0 {
                if self.nodes[node as usize].kind != Kind::Free && self.rotate_best(node) {
                    budget -= 1;
                    self.stats.rotations += 1;
                }
                node = self.nodes[node as usize].parent;
            }
        }
    }

    /// Applies the best of the four rotations at `node`, if any shrinks a child.
    fn rotate_best(&mut self, node: u32) -> bool {
        let Kind::Internal(children) = self.nodes[node as usize].kind else {
            return false;
        };
        let area = |t: &Tree, n: u32| t.nodes[n as usize].bounds.surface_area();
        let mut best: Option<(f64, usize, usize)> = None; // (gain, side kept as internal, grandchild index)
        for side in 0..2 {
            let (inner, other) = (children[side], children[1 - side]);
            let Kind::Internal(grand) = self.nodes[inner as usize].kind else {
                continue;
            };
            for g in 0..2 {
                // Swap `other` with grand[g]: `inner` then holds grand[1-g] and `other`.
                let kept = self.nodes[grand[1 - g] as usize].bounds;
                let new_area = kept.union(self.nodes[other as usize].bounds).surface_area();
                let gain = area(self, inner) - new_area;
                if gain > 1e-9 * area(self, node) && best.is_none_or(|(bg, _, _)| gain > bg) {
                    best = Some((gain, side, g));
                }
            }
        }
        let Some((_, side, g)) = best else {
            return false;
        };
        let (inner, other) = (children[side], children[1 - side]);
        let Kind::Internal(grand) = self.nodes[inner as usize].kind else {
            return false;
        };
        let moved = grand[g];
        // `moved` goes up to `node`; `other` goes down into `inner`.
        self.replace_child(node, other, moved);
        self.nodes[moved as usize].parent = node;
        self.replace_child(inner, moved, other);
        self.nodes[other as usize].parent = inner;
        let Kind::Internal([a, b]) = self.nodes[inner as usize].kind else {
            return false;
        };
        self.nodes[inner as usize].bounds = self.nodes[a as usize]
            .bounds
            .union(self.nodes[b as usize].bounds);
        true
    }
}

/// A lower bound on the growth of any leaf inside a node with box `node` when an
/// entry `eb` of `et` triangles joins it: the leaf must at least span `eb` and
/// reach into the node's box, i.e. `eb` stretched across any gap to the node.
fn floor(eb: &Aabb3d, node: &Aabb3d, et: f64) -> f64 {
    let stretched = Aabb3d::new(eb.min.min(node.max), eb.max.max(node.min));
    stretched.surface_area() * et
}

/// A subtree waiting in the branch-and-bound queue, cheapest bound first.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    bound: f64,
    inherited: f64,
    node: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.bound.total_cmp(&other.bound) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Candidate {
    /// Reversed: `BinaryHeap` is a max-heap and the smallest bound comes first.
    fn cmp(&self, other: &Self) -> Ordering {
        other.bound.total_cmp(&self.bound)
    }
}
