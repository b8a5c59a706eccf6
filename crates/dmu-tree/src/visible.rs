//! The one visibility traversal: frustum and screen-coverage culling over the
//! tree, shared by the renderer's culling and the loader's wanted set, so the
//! two never disagree about what a camera wants.

use std::cmp::Ordering;

use dmu_geom::{Containment, Coverage, Frustum};

use crate::tree::{Entry, EntryId, Tree};

/// A chunk instance in a visited cell, as the traversal sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EntryVisibility {
    /// Its box is outside the frustum.
    OutsideFrustum,
    /// Its box meets the frustum and covers `size_px` ([`Coverage::size_px`]);
    /// `wanted` when that is not below the threshold.
    InFrustum {
        /// Projected size in pixels.
        size_px: f64,
        /// At least the threshold: drawn.
        wanted: bool,
    },
}

/// What a traversal did with the tree's nodes (inner nodes and cells; chunk
/// instances are told to the visitor).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VisibleNodes {
    /// Nodes looked at (those meeting the frustum).
    pub visited: u64,
    /// Nodes skipped because their box is outside the frustum (or empty).
    pub culled_frustum: u64,
    /// Visited nodes cut, with their subtree, for covering too few pixels.
    pub culled_coverage: u64,
}

impl Tree {
    /// Visits every chunk instance in the cells that meet `frustum` and whose
    /// subtrees cover at least `min_pixels` (a subtree is cut on its root's
    /// size, which is never less than a node's below), telling `visit` whether
    /// the instance's own box is in the frustum and how large it is. Hidden
    /// parts are the caller's to skip.
    pub fn visit_visible(
        &self,
        frustum: &Frustum,
        coverage: &Coverage,
        min_pixels: f64,
        visit: &mut dyn FnMut(EntryId, &Entry, EntryVisibility),
    ) -> VisibleNodes {
        self.visit_visible_above(frustum, coverage, min_pixels, &|_, _| false, visit)
    }

    /// [`Tree::visit_visible`], not descending below the nodes `cut` names
    /// (by slot, [`crate::FrustumNode::slot`], and box): where something
    /// else stands for a subtree, such as a merged proxy drawn instead.
    pub fn visit_visible_above(
        &self,
        frustum: &Frustum,
        coverage: &Coverage,
        min_pixels: f64,
        cut: &dyn Fn(u32, &dmu_geom::Aabb3d) -> bool,
        visit: &mut dyn FnMut(EntryId, &Entry, EntryVisibility),
    ) -> VisibleNodes {
        let mut counts = VisibleNodes::default();
        let mut expected = 1u64;
        self.visit_frustum(frustum, &mut |node| {
            counts.visited += 1;
            if coverage.size_px(&node.bounds) < min_pixels {
                counts.culled_coverage += 1;
                return false;
            }
            if cut(node.slot, &node.bounds) {
                return false;
            }
            let Some(cell) = node.cell else {
                expected += 2;
                return true;
            };
            for &e in &self.cells[cell.0 as usize].entries {
                let entry = &self.entries()[e as usize];
                let verdict = if node.containment != Containment::Inside
                    && !frustum.intersects_aabb(&entry.bounds)
                {
                    EntryVisibility::OutsideFrustum
                } else {
                    let size_px = coverage.size_px(&entry.bounds);
                    EntryVisibility::InFrustum {
                        size_px,
                        wanted: size_px.partial_cmp(&min_pixels) != Some(Ordering::Less),
                    }
                };
                visit(EntryId(e), entry, verdict);
            }
            false
        });
        counts.culled_frustum = expected - counts.visited;
        counts
    }
}
