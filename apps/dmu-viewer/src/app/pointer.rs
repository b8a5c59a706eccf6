//! Primary-button drags in the 3D view: of the selection along an axis, of a
//! section handle, of a gizmo handle, or an orbit; the mouse and scripts
//! press, move and release through these alike.

use glam::DVec3;

use super::{App, TURN_PER_PIXEL};
use crate::command::ViewPoint;
use crate::gizmo::{Gizmo, GizmoDrag, Snap};
use crate::nav::axis_offset;
use crate::script::Axis;
use dmu_viewer::command::{Outcome, ReviewCommand};

/// A primary-button drag in the 3D view.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum PointerDrag {
    /// Orbiting about the pivot.
    Orbit,
    /// Sliding the selection along `axis` through the grabbed point `origin`;
    /// `start` is the axis offset under the pointer when the drag began.
    Part {
        axis: DVec3,
        origin: DVec3,
        start: f64,
        snap: f64,
    },
    /// Dragging a handle of the gizmo on the selection.
    Gizmo(GizmoDrag),
    /// Sliding handle `index` of the section along `dir` through `origin`
    /// (see [`crate::section::Section::handles`]); `start` is the offset under
    /// the pointer when the drag began, `before` the section then.
    Section {
        index: usize,
        origin: DVec3,
        dir: DVec3,
        start: f64,
        before: crate::section::Section,
    },
}

impl App {
    /// The gizmo on the selection in pane `pane`, when it shows.
    pub(super) fn gizmo(&self, pane: usize) -> Option<Gizmo> {
        let part = self.review.selected.filter(|_| self.tools.show_gizmo)?;
        let p = self.panes.get(pane)?;
        let centre = self.review.scene.part_world_bounds(part).center();
        Gizmo::new(&p.nav.camera(), p.view.size, centre)
    }

    /// The section handle under view point `at` of pane `pane` (index, world
    /// point, slide direction), when the tools are drawn.
    pub(super) fn section_handle_at(
        &self,
        pane: usize,
        at: ViewPoint,
    ) -> Option<(usize, DVec3, DVec3)> {
        let p = self.panes.get(pane).filter(|_| self.tools.show_tools)?;
        let projector = crate::gizmo::Projector::new(&p.nav.camera(), p.view.size);
        let at = glam::DVec2::new(at.0, at.1);
        self.review
            .section
            .handles(&self.review.tree.bounds())
            .into_iter()
            .enumerate()
            .filter_map(|(i, (point, dir))| {
                let d = projector.project(point)?.distance(at);
                (d <= crate::gizmo::GRAB_PX).then_some((d, (i, point, dir)))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, h)| h)
    }

    /// The snapping of drags, or `None` to move freely.
    fn snap(&self, free: bool) -> Option<Snap> {
        (!free).then_some(Snap {
            step: self.tools.snap,
            degrees: self.tools.snap_deg,
        })
    }

    /// A primary drag starts at `at`: on the selection with a drag axis set
    /// it moves the part along the axis; on a section handle it slides the
    /// plane or box face; on a gizmo handle it drags the handle; anywhere
    /// else it orbits about the point under it.
    pub(super) fn begin_pointer_drag(
        &mut self,
        at: ViewPoint,
        axis: Option<Axis>,
    ) -> anyhow::Result<()> {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        // With a drag axis set, a press on the selection slides it (the
        // mode asked for), even where a gizmo handle crosses the part.
        if let (Some(axis), Some(h)) = (axis, hit.filter(|h| Some(h.part) == self.review.selected))
            && self.edit(ReviewCommand::BeginDrag)? == Outcome::Acted(true)
        {
            let axis = axis.unit();
            self.pointer_drag = Some(PointerDrag::Part {
                axis,
                origin: h.point,
                start: axis_offset(h.point, axis, &ray).unwrap_or(0.0),
                snap: self.tools.snap,
            });
            return Ok(());
        }
        if let Some((index, origin, dir)) = self.section_handle_at(self.active, at)
            && let Some(start) = axis_offset(origin, dir, &ray)
        {
            self.pointer_drag = Some(PointerDrag::Section {
                index,
                origin,
                dir,
                start,
                before: self.review.section.clone(),
            });
            return Ok(());
        }
        if let Some(g) = self.gizmo(self.active)
            && let Some(handle) = g.handle_at(glam::DVec2::new(at.0, at.1))
            && let Some(drag) = g.begin(handle, &ray)
            && self.edit(ReviewCommand::BeginDrag)? == Outcome::Acted(true)
        {
            self.pointer_drag = Some(PointerDrag::Gizmo(drag));
            return Ok(());
        }
        if let Some(h) = hit {
            self.nav().pivot = h.point;
        }
        self.pointer_drag = Some(PointerDrag::Orbit);
        Ok(())
    }

    pub(super) fn pointer_drag_to(
        &mut self,
        at: ViewPoint,
        delta: ViewPoint,
        free: bool,
    ) -> anyhow::Result<()> {
        match self.pointer_drag {
            Some(PointerDrag::Gizmo(drag)) => {
                if let Some(delta) = drag.delta(&self.ray_at(at), self.snap(free))
                    && let Err(e) = self.edit(ReviewCommand::DragBy(delta))
                {
                    self.ui.status = format!("{e:#}");
                }
            }
            Some(PointerDrag::Section {
                index,
                origin,
                dir,
                start,
                ref before,
            }) => {
                if let Some(s) = axis_offset(origin, dir, &self.ray_at(at)) {
                    let step = if free { 0.0 } else { self.tools.snap };
                    let section = before.slid(index, crate::gizmo::snap_to(s - start, step));
                    self.edit(ReviewCommand::Section(section))?;
                }
            }
            Some(PointerDrag::Orbit) => self
                .nav()
                .orbit(-delta.0 * TURN_PER_PIXEL, -delta.1 * TURN_PER_PIXEL),
            Some(PointerDrag::Part {
                axis,
                origin,
                start,
                snap,
            }) => {
                if let Some(s) = axis_offset(origin, axis, &self.ray_at(at)) {
                    let step = if free { 0.0 } else { snap };
                    let to = axis * crate::gizmo::snap_to(s - start, step);
                    if let Err(e) = self.edit(ReviewCommand::DragTo(to)) {
                        self.ui.status = format!("{e:#}");
                    }
                }
            }
            None => {}
        }
        Ok(())
    }

    pub(super) fn end_pointer_drag(&mut self) -> anyhow::Result<()> {
        if let Some(PointerDrag::Part { .. } | PointerDrag::Gizmo(_)) = self.pointer_drag.take() {
            self.edit(ReviewCommand::EndDrag)?;
        }
        Ok(())
    }
}
