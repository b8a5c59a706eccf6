//! Automation scripts: a JSON list of actions run one per frame (a drag one
//! step per frame), so a script exercises the same code as the mouse and the
//! panels do, and its frames are real frames.
//!
//! ```json
//! [
//!   {"pick": [640, 360]},
//!   {"move": [100, 0, 0]},
//!   {"drag": {"by": [0, 0, 500], "steps": 20}},
//!   {"mouse_drag": {"axis": "x", "from": [640, 360], "to": [700, 360], "steps": 10}},
//!   "undo", "redo", "focus", "frame_all",
//!   {"select": "U00-L1-PIPE-0003"}, {"search": "2O2Fr$t4X7Zf8NOew3FLOH"},
//!   {"rotate": {"axis": "z", "degrees": 90}},
//!   {"hover": [640, 360]},
//!   {"view": "top"}, {"camera": {"eye": [0, 0, 1500], "forward": [1, 0, 0]}},
//!   {"panes": 4}, {"pane": 1},
//!   {"record": "/tmp/session.jsonl"}, {"record": null},
//!   {"clearance": 5},
//!   {"culling": "chc"},
//!   {"occlusion": "auto"},
//!   {"overlays": {"stats": false, "clashes": true}},
//!   {"paint_whole": true},
//!   {"gizmo_drag": {"handle": "rz", "by": [40, -10], "steps": 8}},
//!   {"snap": {"step": 25, "degrees": 15}}, {"gizmo": true},
//!   {"section_plane": {"point": [0, 0, 1000], "normal": [0, 0, -1]}},
//!   {"section_face": [640, 360]}, {"section_box": {"min": [0, 0, 0], "max": [9e3, 9e3, 3e3]}},
//!   {"section_drag": {"handle": 0, "by": [0, -40], "steps": 4}}, "clear_section",
//!   {"measure": {"mode": "points", "at": [[600, 300], [700, 320]]}},
//!   {"measure_parts": ["U00-L1-PIPE-0003", "U00-L1-PIPE-0004"]},
//!   {"load_clashes": "/tmp/collide.json"}, {"show_clash": 0},
//!   {"save_viewpoint": "pump"}, {"viewpoint": "pump"},
//!   {"export_bcf": "/tmp/review.bcfzip"}, {"import_bcf": "/tmp/other.bcfzip"},
//!   {"frames": 5},
//!   {"screenshot": "docs/viewer.png"},
//!   {"save": "/tmp/edited.glb"}
//! ]
//! ```
//!
//! Pixels are physical pixels of the 3D view (origin at its top-left corner,
//! y down); a pick aims at the pixel's centre. Distances are model units
//! (millimetres for the plant).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use dmu_geom::Short;
use dmu_render::Culling;
use dmu_scene::MAX_WORLD_COORDINATE;
use glam::DVec3;
use serde::Deserialize;

/// A world axis for constrained drags.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// World X.
    X,
    /// World Y.
    Y,
    /// World Z.
    Z,
}

impl Axis {
    /// The unit vector.
    pub fn unit(self) -> glam::DVec3 {
        match self {
            Self::X => glam::DVec3::X,
            Self::Y => glam::DVec3::Y,
            Self::Z => glam::DVec3::Z,
        }
    }

    /// `x`, `y` or `z`.
    pub fn name(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
        }
    }
}

/// A drag of the selection by a world offset, in equal steps, one per frame.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragBy {
    /// Total offset `[dx, dy, dz]`, model units.
    pub by: [f64; 3],
    /// Steps (frames); at least 1.
    #[serde(default = "default_steps")]
    pub steps: u32,
}

/// A mouse drag of the selection along an axis from one pixel to another,
/// through the same code as an interactive drag.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MouseDrag {
    /// The axis the part slides along.
    pub axis: Axis,
    /// Where the button goes down (view pixels).
    pub from: [f64; 2],
    /// Where it comes up.
    pub to: [f64; 2],
    /// Pointer positions in between (frames); at least 1.
    #[serde(default = "default_steps")]
    pub steps: u32,
}

/// Which overlays the view shows (absent fields stay as they are).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Overlays {
    /// The stats box.
    pub stats: Option<bool>,
    /// The clash markers.
    pub clashes: Option<bool>,
    /// The review tools' drawings: gizmo, section outlines, measurement.
    pub tools: Option<bool>,
}

/// A drag of a gizmo handle with the (simulated) mouse, through the same code
/// as an interactive one.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GizmoDrag {
    /// The handle: `x`, `y`, `z` (arrows), `xy`, `yz`, `zx` (planes), `rx`,
    /// `ry`, `rz` (rings).
    pub handle: crate::gizmo::Handle,
    /// Where the button goes down (view pixels); default: the handle's own
    /// grab point.
    #[serde(default)]
    pub from: Option<[f64; 2]>,
    /// How far the pointer moves, pixels `[dx, dy]`.
    pub by: [f64; 2],
    /// Pointer positions on the way (frames); at least 1.
    #[serde(default = "default_steps")]
    pub steps: u32,
    /// Move freely, without snapping (as with Shift held).
    #[serde(default)]
    pub free: bool,
}

/// Snapping of drags (absent fields stay as they are).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnapSteps {
    /// Offsets snap to multiples of this, model units (0: free).
    pub step: Option<f64>,
    /// Turns snap to multiples of this, degrees (0: free).
    pub degrees: Option<f64>,
}

/// A section plane through a point, keeping the side its normal points to.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionPlane {
    /// A world point of the plane.
    pub point: [f64; 3],
    /// The normal, toward what is kept.
    pub normal: [f64; 3],
}

/// A section box.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionBox {
    /// The low corner, world.
    pub min: [f64; 3],
    /// The high corner, world.
    pub max: [f64; 3],
}

/// A drag of a section handle (a plane's, or a box face's) with the
/// simulated mouse.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionDrag {
    /// The handle: the plane's index, or the box face's (-x, +x, -y, +y, -z, +z).
    pub handle: usize,
    /// How far the pointer moves from the handle, pixels `[dx, dy]`.
    pub by: [f64; 2],
    /// Pointer positions on the way (frames); at least 1.
    #[serde(default = "default_steps")]
    pub steps: u32,
}

/// Two clicks of the measuring tool in a mode.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measure {
    /// `points`, `parts` or `angle`.
    pub mode: crate::measure::MeasureMode,
    /// The two view pixels clicked.
    pub at: [[f64; 2]; 2],
}

/// A typed rotation of the selection about a world axis through its box centre.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rotate {
    /// The world axis.
    pub axis: Axis,
    /// Angle, degrees (counter-clockwise looking down the axis).
    pub degrees: f64,
}

/// Where the active pane's eye goes and where it looks.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraAt {
    /// The eye, world.
    pub eye: [f64; 3],
    /// The view direction (any length but 0; the view stays upright).
    pub forward: [f64; 3],
}

fn default_steps() -> u32 {
    1
}

/// One scripted action.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Action {
    /// Click at a view pixel `[x, y]`: select what is there (or nothing).
    Pick([f64; 2]),
    /// Select a part by name, path, `#id` or a property value (a GlobalId).
    Select(String),
    /// Type into the product structure's search: the parts whose name or a
    /// property value (a GlobalId, an IFC class) holds the text, ignoring
    /// case.
    Search(String),
    /// Move the selection by `[dx, dy, dz]` as one typed edit.
    Move([f64; 3]),
    /// Drag the selection by an offset in steps.
    Drag(DragBy),
    /// Drag the selection along an axis with the (simulated) mouse.
    MouseDrag(MouseDrag),
    /// Turn the selection about an axis through its box centre (one edit).
    Rotate(Rotate),
    /// Drag a handle of the gizmo on the selection.
    GizmoDrag(GizmoDrag),
    /// Set the snapping steps of drags.
    Snap(SnapSteps),
    /// Show or hide the gizmo on the selection.
    Gizmo(bool),
    /// Add a section plane.
    SectionPlane(SectionPlane),
    /// Add a section plane on the face under a view pixel `[x, y]`, cutting
    /// away the side facing the eye.
    SectionFace([f64; 2]),
    /// Cut away everything outside a box.
    SectionBox(SectionBox),
    /// Slide a section plane or box face by its handle.
    SectionDrag(SectionDrag),
    /// Remove every section plane and box.
    ClearSection,
    /// Measure between two clicked points, parts or faces.
    Measure(Measure),
    /// The minimum distance between two parts (names, paths or `#id`s).
    MeasureParts([String; 2]),
    /// Add the clashes of a `dmu collide --json` report to the clash list.
    LoadClashes(PathBuf),
    /// Show clash `i` (from 0) of the list: isolate and frame its two parts.
    ShowClash(usize),
    /// Write the review's issues (listed clashes, saved viewpoints) as BCF
    /// 2.1, a snapshot each (the next actions wait until it is written).
    ExportBcf(PathBuf),
    /// Read a BCF file's topics as viewpoints and go to the first.
    ImportBcf(PathBuf),
    /// Save the view (camera, selection, hidden parts, section) under a name.
    SaveViewpoint(String),
    /// Go back to a saved view.
    Viewpoint(String),
    /// Move the pointer over a view pixel `[x, y]` (hover highlight).
    Hover([f64; 2]),
    /// Look from a preset direction, framing the model (in the active pane).
    View(crate::nav::Preset),
    /// Put the active pane's eye at a point, looking along a direction.
    Camera(CameraAt),
    /// Show this many 3D panes (1 to 4): main, top, cells, front.
    Panes(usize),
    /// Make pane `i` (from 0) the active one: picks, moves of the camera,
    /// presets and culling settings act on it.
    Pane(usize),
    /// Start recording the session to a JSON Lines file, or stop (`null`).
    Record(Option<PathBuf>),
    /// Soft clash distance of the live check, model units.
    Clearance(f64),
    /// Undo the last edit.
    Undo,
    /// Redo the last undone edit.
    Redo,
    /// Frame the selection (as a double-click does).
    Focus,
    /// Frame the whole model.
    FrameAll,
    /// Culling mode: `none`, `frustum` or `chc`.
    Culling(String),
    /// Occlusion culling: `off`, `on` or `auto`.
    Occlusion(crate::settings::Occlusion),
    /// Show or hide the view's overlays.
    Overlays(Overlays),
    /// Paint the whole window every frame (`true`), or compose frames from
    /// the panels as last painted (`false`, the default).
    PaintWhole(bool),
    /// Render this many frames without doing anything.
    Frames(u32),
    /// Save the window as PNG after this frame.
    Screenshot(PathBuf),
    /// Save the model (`.glb`, `.gltf`, `.dmu`).
    Save(PathBuf),
}

impl Action {
    /// Frames the action takes.
    pub fn frames(&self) -> u32 {
        match self {
            Self::Drag(d) => d.steps.max(1),
            Self::MouseDrag(d) => d.steps.max(1).saturating_add(1),
            Self::GizmoDrag(d) => d.steps.max(1).saturating_add(1),
            Self::SectionDrag(d) => d.steps.max(1).saturating_add(1),
            Self::Frames(n) => (*n).max(1),
            _ => 1,
        }
    }

    /// Its name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Pick(_) => "pick",
            Self::Select(_) => "select",
            Self::Search(_) => "search",
            Self::Move(_) => "move",
            Self::Drag(_) => "drag",
            Self::MouseDrag(_) => "mouse_drag",
            Self::Rotate(_) => "rotate",
            Self::GizmoDrag(_) => "gizmo_drag",
            Self::Snap(_) => "snap",
            Self::Gizmo(_) => "gizmo",
            Self::SectionPlane(_) => "section_plane",
            Self::SectionFace(_) => "section_face",
            Self::SectionBox(_) => "section_box",
            Self::ClearSection => "clear_section",
            Self::SectionDrag(_) => "section_drag",
            Self::Measure(_) => "measure",
            Self::MeasureParts(_) => "measure_parts",
            Self::LoadClashes(_) => "load_clashes",
            Self::ShowClash(_) => "show_clash",
            Self::ExportBcf(_) => "export_bcf",
            Self::ImportBcf(_) => "import_bcf",
            Self::SaveViewpoint(_) => "save_viewpoint",
            Self::Viewpoint(_) => "viewpoint",
            Self::Hover(_) => "hover",
            Self::View(_) => "view",
            Self::Camera(_) => "camera",
            Self::Panes(_) => "panes",
            Self::Pane(_) => "pane",
            Self::Record(_) => "record",
            Self::Clearance(_) => "clearance",
            Self::Occlusion(_) => "occlusion",
            Self::Undo => "undo",
            Self::Redo => "redo",
            Self::Focus => "focus",
            Self::FrameAll => "frame_all",
            Self::Culling(_) => "culling",
            Self::Overlays(_) => "overlays",
            Self::PaintWhole(_) => "paint_whole",
            Self::Frames(_) => "frames",
            Self::Screenshot(_) => "screenshot",
            Self::Save(_) => "save",
        }
    }
}

/// The most frames one `frames` action may ask for (about 4.6 hours at 60 Hz).
pub const MAX_FRAMES: u32 = 1_000_000;

/// Parses a script: a JSON list of at least one action (an empty list is
/// refused: it would leave the viewer waiting for actions that never come).
pub fn parse(text: &str) -> anyhow::Result<Vec<Action>> {
    // Editors on some systems start UTF-8 files with a byte-order mark.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let actions: Vec<Action> = serde_json::from_str(text)?;
    anyhow::ensure!(
        !actions.is_empty(),
        "the script is an empty list: give at least one action (e.g. [{{\"frames\": 1}}])"
    );
    for (i, a) in actions.iter().enumerate() {
        check_ranges(a).with_context(|| format!("action {i} ({})", a.name()))?;
        let finite = match a {
            Action::Pick(p) | Action::Hover(p) | Action::SectionFace(p) => {
                p.iter().all(|v| v.is_finite())
            }
            Action::GizmoDrag(d) => d.from.iter().flatten().chain(&d.by).all(|v| v.is_finite()),
            Action::Measure(m) => m.at.iter().flatten().all(|v| v.is_finite()),
            Action::SectionDrag(d) => d.by.iter().all(|v| v.is_finite()),
            Action::Rotate(r) => r.degrees.is_finite(),
            Action::Clearance(c) => {
                anyhow::ensure!(
                    c.is_finite() && *c >= 0.0,
                    "action {i} (clearance): {c} must be finite and not negative"
                );
                true
            }
            Action::MouseDrag(d) => d.from.iter().chain(&d.to).all(|v| v.is_finite()),
            Action::Culling(c) => {
                culling_from_name(c).with_context(|| format!("action {i}"))?;
                true
            }
            _ => true,
        };
        anyhow::ensure!(finite, "action {i} ({}): numbers must be finite", a.name());
        let frames = match a {
            Action::Frames(n) => Some(*n),
            Action::Drag(d) => Some(d.steps),
            Action::MouseDrag(d) => Some(d.steps),
            Action::GizmoDrag(d) => Some(d.steps),
            Action::SectionDrag(d) => Some(d.steps),
            _ => None,
        };
        if let Some(n) = frames {
            anyhow::ensure!(
                n <= MAX_FRAMES,
                "action {i} ({}): {n} frames is more than the limit of {MAX_FRAMES}",
                a.name()
            );
        }
    }
    Ok(actions)
}

/// World positions and offsets within ±[`MAX_WORLD_COORDINATE`] (a drag by
/// 1e300 was taken, then did nothing, silently), directions not zero, snap
/// steps free (0) or in their ranges ([`crate::gizmo::Snap::check`]: a step
/// of 1e-320 did nothing either). Pixel coordinates need only be finite.
fn check_ranges(a: &Action) -> anyhow::Result<()> {
    let world = |v: [f64; 3], what: &str| {
        let v = DVec3::from_array(v);
        anyhow::ensure!(
            dmu_geom::is_within(v, MAX_WORLD_COORDINATE),
            "{what} {} must be finite and within ±{MAX_WORLD_COORDINATE:e} model units",
            Short(v)
        );
        Ok(())
    };
    let direction = |v: [f64; 3], what: &str| {
        let v = DVec3::from_array(v);
        anyhow::ensure!(
            dmu_geom::unit_vector(v).is_some(),
            "{what} {} must be finite and not zero",
            Short(v)
        );
        Ok(())
    };
    match a {
        Action::Move(by) => world(*by, "the offset"),
        Action::Drag(d) => world(d.by, "the offset"),
        Action::SectionPlane(p) => {
            world(p.point, "the point")?;
            direction(p.normal, "the normal")
        }
        Action::SectionBox(b) => {
            world(b.min, "min")?;
            world(b.max, "max")
        }
        Action::Camera(c) => {
            world(c.eye, "the eye")?;
            direction(c.forward, "the forward direction")
        }
        Action::Snap(s) => crate::gizmo::Snap::check(s.step, s.degrees),
        _ => Ok(()),
    }
}

/// The culling mode called `none`, `frustum`, `chc` or `hzb`.
pub fn culling_from_name(name: &str) -> anyhow::Result<Culling> {
    name.parse().map_err(anyhow::Error::msg)
}

/// Reads and parses a script file.
pub fn read(path: &Path) -> anyhow::Result<Vec<Action>> {
    let bytes = dmu_scene::read_regular_file(path)
        .with_context(|| format!("reading {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .with_context(|| format!("reading {}: not UTF-8 text", path.display()))?;
    parse(&text).with_context(|| format!("parsing script {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 48: a drag by 1e300 and a snap step of 1e-320 were taken and
    /// then did nothing, silently; section boxes and cameras beyond ±1e15
    /// were taken and then exported to BCF files the reader refuses; a plane
    /// normal of length 1e300 panicked. Each is refused here, in one short
    /// line naming the action, and a huge normal is a direction.
    #[test]
    fn issue_48_world_vectors_and_snap_steps_are_in_range() {
        for (script, names) in [
            (r#"[{"drag": {"by": [1e300, 0, 0]}}]"#, "action 0 (drag)"),
            (r#"[{"move": [0, -2e15, 0]}]"#, "action 0 (move)"),
            (r#"[{"snap": {"step": 1e-320}}]"#, "action 0 (snap)"),
            (r#"[{"snap": {"degrees": 1e300}}]"#, "action 0 (snap)"),
            (
                r#"[{"frames": 1}, {"section_box": {"min": [-1e16, 0, 0], "max": [1, 1, 1]}}]"#,
                "action 1 (section_box)",
            ),
            (
                r#"[{"section_plane": {"point": [0, 0, 1e300], "normal": [0, 0, 1]}}]"#,
                "action 0 (section_plane)",
            ),
            (
                r#"[{"section_plane": {"point": [0, 0, 0], "normal": [0, 0, 0]}}]"#,
                "action 0 (section_plane)",
            ),
        ] {
            let err = format!("{:#}", parse(script).unwrap_err());
            assert!(err.starts_with(names), "{script}: {err}");
            assert!(
                err.len() < 200 && !err.contains("00000000000"),
                "{script}: a short message: {err}"
            );
        }
        for fine in [
            r#"[{"section_plane": {"point": [0, 0, 1e15], "normal": [1e300, 0, 0]}}]"#,
            r#"[{"snap": {"step": 0, "degrees": 0}}]"#,
            r#"[{"snap": {"step": 0.5, "degrees": 15}}]"#,
            r#"[{"drag": {"by": [1e14, 0, 0]}}]"#,
        ] {
            parse(fine).unwrap_or_else(|e| panic!("{fine}: {e:#}"));
        }
        assert_eq!(crate::gizmo::snap_to(12.0, 1e-320), 12.0);
        assert_eq!(crate::gizmo::snap_to(12.0, 5.0), 10.0);
    }

    /// An empty script is refused (the viewer waited for actions forever), a
    /// byte-order mark is skipped, and frame counts have a limit.
    #[test]
    fn issue_20_empty_scripts_marks_and_huge_frame_counts() {
        let err = parse("[]").unwrap_err().to_string();
        assert!(err.contains("empty list"), "{err}");
        assert_eq!(parse("\u{feff}[{\"frames\": 2}]").unwrap().len(), 1);
        let err = parse("[{\"frames\": 4000000000}]").unwrap_err().to_string();
        assert!(err.contains("limit"), "{err}");
        let drag = "[{\"drag\": {\"by\": [0, 0, 10], \"steps\": 4294967295}}]";
        let err = parse(drag).unwrap_err().to_string();
        assert!(err.contains("limit"), "{err}");
    }

    #[test]
    fn parses_every_action() {
        let script = parse(
            r##"[{"pick": [640, 360.5]}, {"move": [100, 0, 0]},
                {"drag": {"by": [0, 0, 500], "steps": 20}},
                {"mouse_drag": {"axis": "x", "from": [1, 2], "to": [3, 4]}},
                "undo", "redo", "focus", "frame_all", {"select": "#3"},
                {"culling": "chc"}, {"frames": 5}, {"overlays": {"stats": false}},
                {"screenshot": "a.png"}, {"save": "b.glb"},
                {"rotate": {"axis": "y", "degrees": -45}}, {"hover": [3, 4]},
                {"view": "iso"}, {"record": "s.jsonl"}, {"record": null},
                {"clearance": 2.5}, {"occlusion": "on"},
                {"gizmo_drag": {"handle": "rz", "by": [40, -10], "steps": 8}},
                {"snap": {"step": 25}}, {"gizmo": false},
                {"section_plane": {"point": [0, 0, 1], "normal": [0, 0, -1]}},
                {"section_face": [3, 4]}, {"section_box": {"min": [0, 0, 0], "max": [1, 1, 1]}},
                "clear_section", {"measure": {"mode": "angle", "at": [[1, 2], [3, 4]]}},
                {"measure_parts": ["a", "#2"]}, {"load_clashes": "c.json"}, {"show_clash": 0},
                {"save_viewpoint": "v"}, {"viewpoint": "v"}]"##,
        )
        .unwrap();
        assert_eq!(script.len(), 34);
        assert_eq!(script[21].frames(), 9);
        assert_eq!(
            script[23],
            Action::Gizmo(false),
            "{:?}",
            script.iter().map(Action::name).collect::<Vec<_>>()
        );
        assert_eq!(
            script[14],
            Action::Rotate(Rotate {
                axis: Axis::Y,
                degrees: -45.0
            })
        );
        assert_eq!(script[16], Action::View(crate::nav::Preset::Iso));
        assert_eq!(script[18], Action::Record(None));
        assert_eq!(
            script[20],
            Action::Occlusion(crate::settings::Occlusion::On)
        );
        assert_eq!(script[0], Action::Pick([640.0, 360.5]));
        assert_eq!(script[2].frames(), 20);
        assert_eq!(script[3].frames(), 2);
        assert_eq!(script[4], Action::Undo);
    }

    #[test]
    fn rejects_bad_scripts() {
        assert!(parse(r#"[{"pick": [1]}]"#).is_err());
        assert!(parse(r#"[{"teleport": [1, 2, 3]}]"#).is_err());
        assert!(parse(r#"[{"culling": "fast"}]"#).is_err());
        assert!(parse(r#"[{"clearance": -1}]"#).is_err());
        assert!(parse(r#"[{"view": "bottom"}]"#).is_err());
        assert!(parse(r#"[{"occlusion": "sometimes"}]"#).is_err());
        assert!(parse(r#"{"pick": [1, 2]}"#).is_err());
        assert!(parse(r#"[{"snap": {"step": -1}}]"#).is_err());
        assert!(parse(r#"[{"gizmo_drag": {"handle": "w", "by": [1, 2]}}]"#).is_err());
        assert!(parse(r#"[{"measure": {"mode": "volume", "at": [[1, 2], [3, 4]]}}]"#).is_err());
        let zero = r#"[{"camera": {"eye": [1, 2, 3], "forward": [0, 0, 0]}}]"#;
        assert!(format!("{:#}", parse(zero).unwrap_err()).contains("zero"));
        assert!(parse(r#"[{"camera": {"eye": [1, 2], "forward": [1, 0, 0]}}]"#).is_err());
    }

    #[test]
    fn parses_a_camera() {
        let script = parse(r#"[{"camera": {"eye": [1, 2, 3], "forward": [0, 1, 0]}}]"#).unwrap();
        assert_eq!(
            script[0],
            Action::Camera(CameraAt {
                eye: [1.0, 2.0, 3.0],
                forward: [0.0, 1.0, 0.0]
            })
        );
        assert_eq!(script[0].name(), "camera");
    }

    /// `frames` saturates on the largest counts the format can hold (`parse`
    /// refuses them now, over its limit; the actions are read without it).
    #[test]
    fn the_largest_step_counts_do_not_overflow() {
        let script: Vec<Action> = serde_json::from_str(
            r#"[{"mouse_drag": {"axis": "x", "from": [0, 0], "to": [1, 1], "steps": 4294967295}},
                {"drag": {"by": [0, 0, 1], "steps": 4294967295}}, {"frames": 4294967295}]"#,
        )
        .unwrap();
        let frames: Vec<u32> = script.iter().map(Action::frames).collect();
        assert_eq!(frames, [u32::MAX; 3]);
    }
}
