//! The state of the review tools between frames, one struct for the panels,
//! the pointer, scripts and the XR hands alike: how drags snap, what the
//! gizmo and the overlays show, the measuring tool, the saved viewpoints.
//! The panels draw it; [`crate::command::apply`] changes it.

use crate::gizmo::Handle;
use crate::measure::MeasureTool;
use crate::script::{Axis, Overlays};
use crate::viewpoints::Viewpoint;

/// The review tools' state.
#[derive(Clone, Debug, PartialEq)]
pub struct Tools {
    /// The axis a primary drag on the selection slides it along (`None`: drags orbit).
    pub drag_axis: Option<Axis>,
    /// Drag offsets snap to multiples of this (0: no snapping), model units.
    pub snap: f64,
    /// Gizmo turns snap to multiples of this (0: no snapping), degrees.
    pub snap_deg: f64,
    /// Show the gizmo on the selection.
    pub show_gizmo: bool,
    /// The gizmo handle under the pointer (drawn highlighted).
    pub gizmo_hot: Option<Handle>,
    /// The next click places a section plane on the face under it.
    pub section_on_face: bool,
    /// The measuring tool.
    pub measure: MeasureTool,
    /// Saved viewpoints, by name (a new one replaces its namesake).
    pub viewpoints: Vec<Viewpoint>,
    /// Show the stats overlay.
    pub show_stats: bool,
    /// Mark clash points on the view.
    pub show_clashes: bool,
    /// Draw the review tools over the view (gizmo, section outlines,
    /// measurement); the gizmo still works when they are hidden.
    pub show_tools: bool,
}

impl Default for Tools {
    fn default() -> Self {
        Self {
            drag_axis: None,
            snap: 10.0,
            snap_deg: 15.0,
            show_gizmo: true,
            gizmo_hot: None,
            section_on_face: false,
            measure: MeasureTool::default(),
            viewpoints: Vec::new(),
            show_stats: false,
            show_clashes: true,
            show_tools: true,
        }
    }
}

impl Tools {
    /// Keeps `v`, replacing a saved viewpoint of the same name.
    pub fn save_viewpoint(&mut self, v: Viewpoint) {
        self.viewpoints.retain(|o| o.name != v.name);
        self.viewpoints.push(v);
    }

    /// The saved viewpoint named `name`.
    pub fn viewpoint(&self, name: &str) -> anyhow::Result<&Viewpoint> {
        self.viewpoints
            .iter()
            .find(|v| v.name == name)
            .ok_or_else(|| anyhow::anyhow!("viewpoint {name:?}: no viewpoint of that name"))
    }

    /// The overlays shown (stats, clash markers, tools' drawings).
    pub fn overlays(&self) -> Overlays {
        Overlays {
            stats: Some(self.show_stats),
            clashes: Some(self.show_clashes),
            tools: Some(self.show_tools),
        }
    }

    /// Shows or hides the overlays `o` names (the others stay as they are).
    pub fn set_overlays(&mut self, o: Overlays) {
        self.show_stats = o.stats.unwrap_or(self.show_stats);
        self.show_clashes = o.clashes.unwrap_or(self.show_clashes);
        self.show_tools = o.tools.unwrap_or(self.show_tools);
    }
}
