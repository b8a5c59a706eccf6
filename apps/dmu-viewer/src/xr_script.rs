//! Scripts for `dmu-viewer --xr`: where the tracking space stands in the
//! model, and what the (simulated) hand does, one step per submitted frame,
//! so a VR session is testable on a runtime whose headset has no controllers.
//!
//! ```json
//! {
//!   "origin": [4509000, 5349750, 12000],
//!   "heading_deg": -90,
//!   "units_per_metre": 1000,
//!   "actions": [
//!     {"look": {"yaw_deg": 10, "frames": 10}},
//!     {"aim": [4515000, 5350000, 13500]},
//!     {"grab": {"by": [0, 0, -400], "frames": 20}},
//!     "undo",
//!     {"frames": 10}
//!   ]
//! }
//! ```
//!
//! `origin` is the world point of the tracking space's origin (OpenXR's local
//! space: the head as the session starts; default: the desktop viewer's
//! overview eye), `heading_deg`
//! turns the tracking space about world Z (0: the headset's forward is world
//! +Y). `aim` points the hand's ray at a world point and picks the first part
//! it hits; `grab` moves the aimed part with the hand by a world offset (model
//! units) in equal steps, one per frame, through the same drag code as the
//! desktop's `{"drag": ...}`, then releases it.

use std::path::Path;

use anyhow::Context as _;
use serde::Deserialize;

/// A turn of the view about the head, in equal steps.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Look {
    /// Total turn about world Z, degrees (counter-clockwise seen from above).
    pub yaw_deg: f64,
    /// Frames it takes; at least 1.
    pub frames: u32,
}

/// A grab: the aimed part follows the hand by a world offset, then is released.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grab {
    /// Total offset `[dx, dy, dz]`, model units.
    pub by: [f64; 3],
    /// Frames it takes; at least 1.
    pub frames: u32,
}

/// One action of an XR script.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum XrAction {
    /// Turn the view.
    Look(Look),
    /// Point the hand's ray at a world point; the first part hit is picked
    /// and selected (nothing when the ray misses).
    Aim([f64; 3]),
    /// Grab the selection and move it with the hand.
    Grab(Grab),
    /// Undo the last edit.
    Undo,
    /// Redo it.
    Redo,
    /// Submit this many frames doing nothing else.
    Frames(u32),
}

impl XrAction {
    /// Frames the action takes.
    pub fn frames(&self) -> u32 {
        match self {
            Self::Look(l) => l.frames.max(1),
            Self::Grab(g) => g.frames.max(1),
            Self::Frames(n) => (*n).max(1),
            _ => 1,
        }
    }

    /// Its name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Look(_) => "look",
            Self::Aim(_) => "aim",
            Self::Grab(_) => "grab",
            Self::Undo => "undo",
            Self::Redo => "redo",
            Self::Frames(_) => "frames",
        }
    }
}

/// An XR script: the placement of the tracking space and the actions.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct XrScript {
    /// World point of the tracking origin (the head at the start), model
    /// units (default: the desktop viewer's overview eye).
    #[serde(default)]
    pub origin: Option<[f64; 3]>,
    /// Heading of the tracking space, degrees about world Z.
    #[serde(default)]
    pub heading_deg: f64,
    /// Model units per metre (1000 for millimetres, the plant's unit).
    #[serde(default = "default_units_per_metre")]
    pub units_per_metre: f64,
    /// What the hand does, in order.
    #[serde(default)]
    pub actions: Vec<XrAction>,
}

impl Default for XrScript {
    fn default() -> Self {
        Self {
            origin: None,
            heading_deg: 0.0,
            units_per_metre: default_units_per_metre(),
            actions: Vec::new(),
        }
    }
}

fn default_units_per_metre() -> f64 {
    1000.0
}

/// Parses an XR script, checking every number where it enters.
pub fn parse(text: &str) -> anyhow::Result<XrScript> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let script: XrScript = serde_json::from_str(text)?;
    let world = dmu_scene::MAX_WORLD_COORDINATE;
    let in_world = |p: &[f64; 3]| p.iter().all(|v| v.is_finite() && v.abs() <= world);
    if let Some(o) = &script.origin {
        anyhow::ensure!(
            in_world(o),
            "origin {o:?}: coordinates must be finite and within ±{world:e}"
        );
    }
    anyhow::ensure!(
        script.heading_deg.is_finite(),
        "heading_deg: {} must be finite",
        script.heading_deg
    );
    anyhow::ensure!(
        script.units_per_metre.is_finite()
            && script.units_per_metre > 0.0
            && script.units_per_metre <= 1e9,
        "units_per_metre: {} must be in (0, 1e9]",
        script.units_per_metre
    );
    for (i, a) in script.actions.iter().enumerate() {
        let ok = match a {
            XrAction::Look(l) => l.yaw_deg.is_finite(),
            XrAction::Aim(p) => in_world(p),
            XrAction::Grab(g) => in_world(&g.by),
            _ => true,
        };
        anyhow::ensure!(
            ok,
            "action {i} ({}): numbers must be finite and within ±{world:e}",
            a.name()
        );
        let frames = match a {
            XrAction::Look(l) => l.frames,
            XrAction::Grab(g) => g.frames,
            XrAction::Frames(n) => *n,
            _ => 1,
        };
        anyhow::ensure!(
            frames <= crate::script::MAX_FRAMES,
            "action {i} ({}): {frames} frames is more than the limit of {}",
            a.name(),
            crate::script::MAX_FRAMES
        );
    }
    Ok(script)
}

/// Reads and parses an XR script file.
pub fn read(path: &Path) -> anyhow::Result<XrScript> {
    let bytes = dmu_scene::read_regular_file(path)
        .with_context(|| format!("reading {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .with_context(|| format!("reading {}: not UTF-8 text", path.display()))?;
    parse(&text).with_context(|| format!("parsing XR script {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_action_and_defaults() {
        let s = parse(
            r#"{"origin": [1, 2, 3], "heading_deg": -90, "actions": [
                {"look": {"yaw_deg": 10, "frames": 5}}, {"aim": [4, 5, 6]},
                {"grab": {"by": [0, 0, -400], "frames": 20}}, "undo", "redo", {"frames": 3}]}"#,
        )
        .unwrap();
        assert_eq!(s.origin, Some([1.0, 2.0, 3.0]));
        assert_eq!(s.units_per_metre, 1000.0);
        assert_eq!(s.actions.len(), 6);
        assert_eq!(s.actions[2].frames(), 20);
        assert_eq!(s.actions[3], XrAction::Undo);
        let frames: u32 = s.actions.iter().map(XrAction::frames).sum();
        assert_eq!(frames, 5 + 1 + 20 + 1 + 1 + 3);
        assert_eq!(parse("{}").unwrap(), XrScript::default());
    }

    #[test]
    fn rejects_bad_scripts() {
        let err = |t: &str| parse(t).unwrap_err().to_string();
        assert!(parse(r#"{"origin": [1, 2]}"#).is_err());
        assert!(err(r#"{"origin": [1e300, 2, 3]}"#).contains("origin"));
        assert!(err(r#"{"units_per_metre": 0}"#).contains("units_per_metre"));
        assert!(err(r#"{"actions": [{"aim": [1, 2, 1e16]}]}"#).contains("action 0 (aim)"));
        assert!(err(r#"{"actions": [{"frames": 4000000000}]}"#).contains("limit"));
        assert!(parse(r#"{"actions": [{"teleport": [1, 2, 3]}]}"#).is_err());
        assert!(parse(r#"{"speed": 3}"#).is_err());
    }
}
