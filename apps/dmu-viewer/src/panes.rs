//! Up to four 3D panes side by side, each with its own camera and its own
//! renderer [`View`] (so its own culling and visibility state), over the one
//! model: the main perspective, a top view, a debug view of the main view's
//! cells (drawn or culled, like the MMDr thesis's windows) and a front view.

use dmu_geom::Aabb3d;
use dmu_render::{Culling, View};
use dmu_tree::{CellId, Tree};
use egui::{Color32, Pos2, Rect, Stroke};
use glam::DVec3;

use crate::nav::{Navigator, Preset};

/// Most panes the view area shows.
pub const MAX_PANES: usize = 4;

/// What a pane shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PaneKind {
    /// The model through its camera.
    Model,
    /// The model, with the cell boxes of the main pane (pane 0) drawn over
    /// it: green where the main view drew something of the cell last frame,
    /// red where it culled the whole cell; and the main camera's frustum.
    Cells,
}

/// One pane: a camera, the renderer's view and what it shows.
#[derive(Debug)]
pub struct Pane {
    /// Its camera.
    pub nav: Navigator,
    /// Its renderer view (size, culling, visibility state).
    pub view: View,
    /// What it shows.
    pub kind: PaneKind,
}

impl Pane {
    /// A pane looking at `bounds` from `preset` (or from the overview corner).
    pub fn new(bounds: &Aabb3d, preset: Option<Preset>, kind: PaneKind, culling: Culling) -> Self {
        let mut nav = Navigator::overview(bounds);
        if let Some(p) = preset {
            nav.preset(p, bounds);
        }
        let view = View::new(nav.camera(), (1, 1), culling);
        Self { nav, view, kind }
    }

    /// The pane that comes `index`-th when panes are added: 1 top, 2 the cells
    /// debug view (isometric, from another corner than the main view's
    /// start, so its frustum shows as a wedge), 3 front.
    pub fn nth(index: usize, bounds: &Aabb3d, culling: Culling) -> Self {
        match index {
            1 => Self::new(bounds, Some(Preset::Top), PaneKind::Model, culling),
            2 => Self::new(bounds, Some(Preset::Iso), PaneKind::Cells, culling),
            3 => Self::new(bounds, Some(Preset::Front), PaneKind::Model, culling),
            _ => Self::new(bounds, None, PaneKind::Model, culling),
        }
    }

    /// `model` or `cells`.
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            PaneKind::Model => "model",
            PaneKind::Cells => "cells",
        }
    }
}

/// Adds panes ([`Pane::nth`], culling and its options as the main pane's) looking at
/// `bounds`, or drops the last ones, to `count` (clamped to 1 to
/// [`MAX_PANES`]).
pub fn set_count(panes: &mut Vec<Pane>, count: usize, bounds: &Aabb3d) {
    let count = count.clamp(1, MAX_PANES);
    let (culling, options) = (panes[0].view.culling, panes[0].view.options);
    while panes.len() < count {
        let mut pane = Pane::nth(panes.len(), bounds, culling);
        pane.view.options = options;
        panes.push(pane);
    }
    panes.truncate(count);
}

/// Splits `area` into the rectangles of `count` panes (1 to 4): one fills it,
/// two side by side, three or four in a 2x2 grid (pane 0 top left, then
/// rows). Panes do not overlap and stay inside `area`.
pub fn layout(area: Rect, count: usize) -> Vec<Rect> {
    assert!(
        (1..=MAX_PANES).contains(&count),
        "{count} panes (1 to {MAX_PANES})"
    );
    let (cols, rows) = match count {
        1 => (1, 1),
        2 => (2, 1),
        _ => (2, 2),
    };
    // A 2-point gap shows where one pane ends.
    let gap = 2.0;
    let w = (area.width() - gap * (cols - 1) as f32) / cols as f32;
    let h = (area.height() - gap * (rows - 1) as f32) / rows as f32;
    (0..count)
        .map(|i| {
            let (c, r) = ((i % cols) as f32, (i / cols) as f32);
            let min = area.min + egui::vec2(c * (w + gap), r * (h + gap));
            // Whole points, inside the slot: panes never overlap.
            Rect::from_min_max(min.ceil(), (min + egui::vec2(w, h)).floor())
        })
        .collect()
}

/// For each cell slot of `tree` (indexed by [`CellId`]), whether `view`
/// drew any of its entries in its last frame.
pub fn drawn_cells(tree: &Tree, view: &View, out: &mut Vec<bool>) {
    out.clear();
    let slots = tree.cell_ids().map(|c| c.0 as usize + 1).max().unwrap_or(0);
    out.resize(slots, false);
    for e in view.drawn_entries() {
        out[tree.entry_cell(e).0 as usize] = true;
    }
}

/// World to clip of `nav`'s camera drawn into `rect` (its aspect).
pub(crate) fn clip_from_world(nav: &Navigator, rect: Rect) -> glam::DMat4 {
    let camera = nav.camera();
    let aspect = f64::from(rect.width()) / f64::from(rect.height().max(1.0));
    camera.projection(aspect) * camera.view_matrix()
}

/// Where a world point lands in `rect` through `clip_from_world`, or `None`
/// behind the eye.
pub(crate) fn project(clip_from_world: &glam::DMat4, rect: Rect, p: DVec3) -> Option<Pos2> {
    let clip = *clip_from_world * p.extend(1.0);
    if clip.w <= 0.0 {
        return None;
    }
    let ndc = clip.truncate() / clip.w;
    Some(Pos2::new(
        rect.min.x + ((ndc.x + 1.0) * 0.5) as f32 * rect.width(),
        rect.min.y + ((1.0 - ndc.y) * 0.5) as f32 * rect.height(),
    ))
}

/// Draws the edges of a box; edges with an end behind the eye are left out.
pub(crate) fn box_edges(
    painter: &egui::Painter,
    clip_from_world: &glam::DMat4,
    rect: Rect,
    b: &Aabb3d,
    stroke: Stroke,
) {
    let corners = b.corners();
    // Corner bit 0 = +x, 1 = +y, 2 = +z (as Aabb3d::corners orders them):
    // an edge joins corners differing in one bit.
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            let j = i | bit;
            if j == i {
                continue;
            }
            let (a, b) = (
                project(clip_from_world, rect, corners[i]),
                project(clip_from_world, rect, corners[j]),
            );
            if let (Some(a), Some(b)) = (a, b) {
                painter.line_segment([a, b], stroke);
            }
        }
    }
}

/// Paints the main view's cells over a cells pane: green drawn, red culled;
/// and the main camera's frustum out to the model's size, in yellow.
pub fn paint_cells(
    painter: &egui::Painter,
    rect: Rect,
    pane: &Pane,
    main: &Pane,
    tree: &Tree,
    drawn: &[bool],
) {
    let clip_from_world = clip_from_world(&pane.nav, rect);
    let (drawn_stroke, culled_stroke) = (
        Stroke::new(1.0, Color32::from_rgba_unmultiplied(60, 230, 90, 200)),
        Stroke::new(1.0, Color32::from_rgba_unmultiplied(240, 60, 50, 140)),
    );
    for cell in tree.cell_ids() {
        let seen = drawn.get(cell.0 as usize).copied().unwrap_or(false);
        let stroke = if seen { drawn_stroke } else { culled_stroke };
        box_edges(
            painter,
            &clip_from_world,
            rect,
            &tree.cell_bounds(cell),
            stroke,
        );
    }
    // The main camera's frustum: its eye joined to the far corners of its view.
    let main_cam = main.nav.camera();
    let bounds = tree.bounds();
    let reach = if bounds.is_empty() {
        1.0
    } else {
        bounds.extent().length()
    };
    let f = main.nav.forward();
    let (r, u) = (main.nav.right(), main.nav.up());
    let t = (main_cam.fov_y_rad * 0.5).tan();
    let ma = main.view.aspect();
    let far: Vec<DVec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(x, y)| main_cam.eye + (f + r * (x * t * ma) + u * (y * t)) * reach)
        .collect();
    let yellow = Stroke::new(1.5, Color32::from_rgb(255, 220, 40));
    let at = |p| project(&clip_from_world, rect, p);
    for i in 0..4 {
        for (a, b) in [(main_cam.eye, far[i]), (far[i], far[(i + 1) % 4])] {
            if let (Some(a), Some(b)) = (at(a), at(b)) {
                painter.line_segment([a, b], yellow);
            }
        }
    }
}

/// Drawn and culled cell counts of a [`drawn_cells`] result over `tree`.
pub fn cell_counts(tree: &Tree, drawn: &[bool]) -> (usize, usize) {
    let seen = tree
        .cell_ids()
        .filter(|c: &CellId| drawn.get(c.0 as usize).copied().unwrap_or(false))
        .count();
    (seen, tree.cell_count() - seen)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_tile_the_area_without_overlap() {
        let area = Rect::from_min_size(Pos2::new(280.0, 48.0), egui::vec2(710.0, 730.0));
        for n in 1..=MAX_PANES {
            let rects = layout(area, n);
            assert_eq!(rects.len(), n);
            for (i, a) in rects.iter().enumerate() {
                assert!(area.contains_rect(*a), "{n} panes: {a:?} outside {area:?}");
                assert!(a.width() > 100.0 && a.height() > 100.0);
                for b in &rects[i + 1..] {
                    assert!(!a.intersects(*b) || a.intersect(*b).area() == 0.0);
                }
            }
        }
        assert_eq!(layout(area, 1)[0], area);
    }

    /// The cells drawn are those of the drawn entries; counts add up.
    #[test]
    fn drawn_cells_follow_the_drawn_entries() {
        let scene = dmu_samples::grid(3, 10.0, 4.0, 2048);
        let tree = Tree::build(&scene, Default::default());
        let view = View::new(
            Navigator::overview(&tree.bounds()).camera(),
            (8, 8),
            Culling::Frustum,
        );
        let mut drawn = Vec::new();
        drawn_cells(&tree, &view, &mut drawn);
        assert_eq!(cell_counts(&tree, &drawn), (0, tree.cell_count()));
    }
}
