//! The application: winit's event loop driving one frame at a time (script
//! step, panels, navigation, 3D render, egui paint, present), and the JSON
//! report of an automated run.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_collide::Report;
use dmu_geom::Ray3d;
use dmu_render::{Culling, FrameStats, Renderer};
use dmu_scene::PartId;
use dmu_tree::EntryId;
use glam::DVec3;
use serde_json::{Value, json};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::{Window, WindowId};

use crate::gfx::Gfx;
use crate::gizmo::{Gizmo, GizmoDrag, Snap};
use crate::measure::{MeasureMode, SNAP_PX};
use crate::nav::{Navigator, axis_offset};
use crate::panes::{Pane, PaneKind};
use crate::record::Recorder;
use crate::review::Review;
use crate::script::{Action, Axis};
use crate::ui::{Overlay, PaneShow, RectPx, UiState, ViewInput, ViewPoint};

/// Frames drawn before a script starts, so the layout (and the 3D view's size)
/// has settled.
const WARMUP_FRAMES: u64 = 3;
/// Radians of orbit or look per pixel of drag.
const TURN_PER_PIXEL: f64 = 0.005;

/// How the viewer runs.
#[derive(Debug)]
pub struct Options {
    /// Window size, physical pixels.
    pub size: (u32, u32),
    /// Initial culling mode.
    pub culling: Culling,
    /// Save the window as PNG after the last frame.
    pub screenshot: Option<PathBuf>,
    /// Exit after this many frames (after the script, if any).
    pub frames: Option<u32>,
    /// Actions to run, one per frame.
    pub script: Vec<Action>,
    /// Wait for vertical sync.
    pub vsync: bool,
    /// Compose frames from the panels as last painted where the surface
    /// allows (else paint the whole window every frame).
    pub compose: bool,
    /// Show the stats overlay from the start.
    pub stats: bool,
    /// While a part is dragged, how long the panels as last painted may
    /// stand for panels that changed ([`Gfx::panel_lag`]).
    pub panel_lag: std::time::Duration,
    /// Cull the back faces of solid meshes (`RendererOptions::cull_back_faces`).
    pub cull_back_faces: bool,
    /// Pixels of error a chunk's simplified level may show (0: exact).
    pub lod_error_px: f64,
    /// Coverage threshold of the main view: chunk instances smaller on
    /// screen (box diagonal, pixels) are not drawn.
    pub min_pixels: f64,
    /// A frame-time budget for the 3D view, ms.
    pub target_ms: Option<f64>,
    /// The length of a model unit, for BCF issues (BCF is in metres).
    pub unit: dmu_app::units::LengthUnit,
    /// The whole process's memory budget, bytes: the model streams from its
    /// store (the review's scene is its skeleton).
    pub memory_budget: Option<u64>,
    /// Under the budget, draw chunks not loaded yet as their boxes.
    pub stand_ins: bool,
    /// Where the main view draws the store's far fields.
    pub far_field: dmu_app::far_fields::FarUse,
    /// When the process started (for the first frame's time).
    pub started: Instant,
}

impl Options {
    fn automated(&self) -> bool {
        self.frames.is_some() || !self.script.is_empty()
    }
}

/// A primary-button drag in the 3D view.
#[derive(Clone, Debug, PartialEq)]
enum PointerDrag {
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

/// Parts the renderer has been told to tint, per tint.
#[derive(Debug, Default)]
struct Tints {
    selected: Vec<PartId>,
    clashing: Vec<PartId>,
    hovered: Vec<PartId>,
}

/// Tells the renderer (through `set`) which parts gain or lose a tint to go
/// from `now` to `want`; `now` becomes `want`.
pub(crate) fn retint(now: &mut Vec<PartId>, want: Vec<PartId>, mut set: impl FnMut(PartId, bool)) {
    for &p in now.iter().filter(|p| !want.contains(p)) {
        set(p, false);
    }
    for &p in want.iter().filter(|p| !now.contains(p)) {
        set(p, true);
    }
    *now = want;
}

/// The script's progress.
#[derive(Debug, Default)]
struct Runner {
    actions: Vec<Action>,
    /// Action being run and its step.
    index: usize,
    step: u32,
    /// One result per finished action, as compact JSON text (see `frames`).
    results: Vec<Box<str>>,
    /// One record per frame while the script runs, as compact JSON text: a
    /// record held as a `Value` took ten times as much (its maps' nodes and
    /// keys), 17 kB a frame, which over a soak's thousands of frames was
    /// most of what the process grew by (issue 48).
    frames: Vec<Box<str>>,
    /// Where the running gizmo or section drag pressed (view pixels).
    gizmo_from: ViewPoint,
}

/// What this frame of the script asks of the frame.
#[derive(Debug, Default)]
struct ScriptFrame {
    /// The action (and step) this frame ran, for the frame record.
    label: Option<(&'static str, u32)>,
    screenshot: Option<PathBuf>,
}

/// The viewer.
pub struct App {
    /// Proxies for the renderer, until it is made.
    pub proxies: Option<dmu_render::Proxies>,
    /// The store's far fields (`--far-field on|auto`), until the renderer
    /// is made.
    pub far_field_set: Option<dmu_app::far_fields::FarFieldSet>,
    /// The main view's far fields, once the renderer is made.
    far: Option<crate::far::FarFields>,
    options: Options,
    instance: wgpu::Instance,
    review: Review,
    /// The 3D panes; pane 0 is the main view.
    panes: Vec<Pane>,
    /// The pane keys, scripts and settings act on (the last one clicked).
    active: usize,
    /// Cells the main pane drew last frame, by cell id (for cells panes).
    drawn_cells: Vec<bool>,
    ui: UiState,
    egui_ctx: egui::Context,
    egui_state: Option<egui_winit::State>,
    gfx: Option<Gfx>,
    renderer: Option<Renderer>,
    /// The part under the pointer (or a scripted hover).
    hovered: Option<PartId>,
    /// The pointer's last pane and position, to pick the hovered part only
    /// when it moves.
    pointer_at: Option<(usize, ViewPoint)>,
    tints: Tints,
    overlay: Overlay,
    frame_ms: VecDeque<f64>,
    frames_drawn: u64,
    last_frame: Option<Instant>,
    pointer_drag: Option<PointerDrag>,
    /// Each pane's rectangle in the window (x, y, width, height), last frame.
    pane_rects: Vec<RectPx>,
    runner: Runner,
    /// The run's report (model and load facts), completed at exit.
    facts: Value,
    keep_drawing: bool,
    error: Option<anyhow::Error>,
    /// A BCF export in progress: a frame per topic for its snapshot.
    export: Option<Export>,
    /// Under a memory budget: the residency and its counts (made with the
    /// first frame, once the renderer's memory is in use).
    streaming: Option<crate::budget::Streaming>,
    /// Milliseconds from the start of the process to the end of the first
    /// frame of the model.
    first_frame_ms: Option<f64>,
    /// Every frame's time, ms.
    frame_times: Vec<f64>,
}

/// A BCF export in progress.
#[derive(Debug)]
struct Export {
    path: PathBuf,
    issues: Vec<crate::issues::Issue>,
    /// The issue whose snapshot is being taken.
    next: usize,
    /// Frames drawn for it (a snapshot waits for occlusion culling to settle).
    frames: u32,
    /// The view to go back to, and the overlays shown, when done.
    restore: crate::viewpoints::Viewpoint,
    overlays: (bool, bool, bool),
}

/// Frames an export waits at most for a view to settle before its snapshot.
const SNAPSHOT_SETTLE_FRAMES: u32 = 8;

impl std::fmt::Debug for App {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("App")
            .field("options", &self.options)
            .field("frames_drawn", &self.frames_drawn)
            .finish_non_exhaustive()
    }
}

impl App {
    /// A viewer of `review`; `facts` start the run's report.
    pub fn new(instance: wgpu::Instance, review: Review, options: Options, facts: Value) -> Self {
        let mut main = Pane::new(
            &review.tree.bounds(),
            None,
            PaneKind::Model,
            options.culling,
        );
        main.view.options.lod_error_px = options.lod_error_px;
        main.view.options.min_pixels = options.min_pixels;
        main.view.options.target_ms = options.target_ms;
        let mut ui = UiState::new(review.source.as_deref());
        ui.show_stats = options.stats;
        let runner = Runner {
            actions: options.script.clone(),
            ..Runner::default()
        };
        Self {
            proxies: None,
            far_field_set: None,
            far: None,
            options,
            instance,
            review,
            panes: vec![main],
            active: 0,
            drawn_cells: Vec::new(),
            ui,
            egui_ctx: egui::Context::default(),
            egui_state: None,
            gfx: None,
            renderer: None,
            hovered: None,
            pointer_at: None,
            tints: Tints::default(),
            overlay: Overlay::default(),
            frame_ms: VecDeque::new(),
            frames_drawn: 0,
            last_frame: None,
            pointer_drag: None,
            pane_rects: vec![(0, 0, 1, 1)],
            runner,
            facts,
            keep_drawing: true,
            error: None,
            export: None,
            streaming: None,
            first_frame_ms: None,
            frame_times: Vec::new(),
        }
    }

    /// The error that ended the run, if any, and the report of an automated run.
    pub fn finish(self) -> anyhow::Result<Option<Value>> {
        if let Some(e) = self.error {
            return Err(e);
        }
        if !self.options.automated() {
            return Ok(None);
        }
        let mut report = self.facts;
        let gfx = self.gfx.as_ref();
        report["adapter"] = json!(gfx.map(|g| g.adapter.clone()));
        report["window"] = json!(gfx.map(Gfx::size));
        report["frames_drawn"] = json!(self.frames_drawn);
        report["steps"] = Value::Array(parsed(&self.runner.results));
        report["moved_parts"] = json!(
            self.review
                .moved_parts()
                .iter()
                .map(|p| p.0)
                .collect::<Vec<_>>()
        );
        // The run's peak, before the records are parsed back for the report.
        report["peak_rss_bytes"] = json!(dmu_app::progress::peak_rss_bytes());
        let frames = parsed(&self.runner.frames);
        report["first_frame_ms"] = json!(self.first_frame_ms);
        report["median_frame_ms"] = summary(&self.frame_times)["median"].clone();
        if let Some(s) = &self.streaming {
            let facts = s.json();
            report["frames_with_hole"] = facts["frames_with_hole"].clone();
            report["frames_with_standin"] = facts["frames_with_standin"].clone();
            report["memory"] = facts;
        }
        if let Some(far) = &self.far {
            report["far_field"] = far.json();
        }
        if let Some(g) = &self.review.geometry {
            let (bytes, peak) = g.bytes();
            report["tool_geometry"] = json!({
                "bytes": bytes,
                "peak_bytes": peak,
                "mesh_loads": g.loads(),
            });
        }
        let drag: Vec<f64> = frames
            .iter()
            .filter(|f| matches!(f["action"].as_str(), Some("drag" | "mouse_drag")))
            .filter_map(|f| f["frame_ms"].as_f64())
            .collect();
        report["drag_frame_ms"] = summary(&drag);
        let all =
            |key: &str| -> Vec<f64> { frames.iter().filter_map(|f| f[key].as_f64()).collect() };
        report["frame_split_ms"] = json!({
            "frame": summary(&all("frame_ms")),
            "ui": summary(&all("ui_ms")),
            "view": summary(&all("view_ms")),
            "paint": summary(&all("paint_ms")),
            "frames_painted_whole": frames
                .iter()
                .filter(|f| f["painted_whole"] == true)
                .count(),
        });
        report["frames"] = Value::Array(frames);
        Ok(Some(report))
    }

    /// Takes over an open window (its egui state made with `ctx`): makes the
    /// renderer for the model and asks for the first frame.
    pub fn adopt(&mut self, gfx: Gfx, state: egui_winit::State, ctx: egui::Context) {
        let mut renderer = Renderer::new(
            &gfx.device,
            &gfx.queue,
            &self.review.scene,
            &self.review.tree,
            dmu_render::RendererOptions {
                color_format: gfx.view_format,
                // Levels cost upload time and memory: built when the view may
                // draw them (a LOD error raised from 0 in the panel later
                // draws chunks whole).
                lod_levels: self.panes[0].view.options.may_draw_lods(),
                cull_back_faces: self.options.cull_back_faces,
                ..Default::default()
            },
        );
        if let Some(proxies) = self.proxies.take() {
            renderer.set_proxies(proxies);
        }
        if let Some(set) = self.far_field_set.take() {
            // The model as loaded, before any edit: what the far fields show.
            renderer.enable_far_fields(&self.review.scene, &self.review.tree);
            self.far = Some(crate::far::FarFields::new(
                set,
                self.options.far_field,
                gfx.device.clone(),
                gfx.queue.clone(),
            ));
        }
        gfx.window.request_redraw();
        self.egui_ctx = ctx;
        self.renderer = Some(renderer);
        self.egui_state = Some(state);
        self.gfx = Some(gfx);
    }

    /// The active pane's camera.
    fn nav(&mut self) -> &mut Navigator {
        &mut self.panes[self.active].nav
    }

    /// The f64 ray through the point `(x, y)` (physical pixels) of the
    /// active pane.
    fn ray_at(&self, at: ViewPoint) -> Ray3d {
        self.ray_in(self.active, at)
    }

    /// The f64 ray through the point `(x, y)` of pane `pane`.
    fn ray_in(&self, pane: usize, (x, y): ViewPoint) -> Ray3d {
        let p = &self.panes[pane];
        p.nav.ray(p.view.size, x, y)
    }

    /// The active pane's rectangle in the window.
    fn active_rect(&self) -> RectPx {
        self.pane_rects
            .get(self.active)
            .copied()
            .unwrap_or((0, 0, 1, 1))
    }

    /// Frames the model in the active pane: what a section box keeps of it.
    fn frame_all(&mut self) {
        let bounds = self.review.section.kept_bounds(self.review.tree.bounds());
        self.frame_in_active(&bounds);
    }

    /// Frames `bounds` in the active pane, whose visibility starts afresh.
    fn frame_in_active(&mut self, bounds: &dmu_geom::Aabb3d) {
        let pane = &mut self.panes[self.active];
        pane.nav.frame(bounds);
        pane.view.reset_visibility();
    }

    /// Picks at a view point: selects what is hit (or nothing), orbits about
    /// the hit point from now on. Returns the ray and the report entry.
    fn pick(&mut self, at: ViewPoint) -> Value {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        self.review.select(hit.map(|h| h.part));
        if let Some(h) = hit {
            self.nav().pivot = h.point;
            self.ui.reveal = Some(h.part);
        }
        let scene = &self.review.scene;
        let length = ray.dir.length();
        json!({
            "pixel": [at.0, at.1],
            "viewport": rect_json(self.active_rect()),
            "pane": self.active,
            "ray": { "origin": ray.origin.to_array(), "dir": ray.dir.to_array() },
            "hit": hit.map_or_else(
                || json!({ "hit": false }),
                |h| dmu_app::hits::hit_json(scene, &h, length)
            ),
        })
    }

    /// A click in the active pane: places a section plane on the face under
    /// it when one is being placed, measures in a measuring mode, else picks.
    /// The report entry of what it did.
    fn click(&mut self, at: ViewPoint) -> anyhow::Result<Value> {
        if self.ui.section_on_face {
            self.ui.section_on_face = false;
            let hit = self
                .review
                .pick(&self.ray_at(at))
                .context("section on a face: nothing there to place the plane on")?;
            // The plane keeps what lies behind the face, away from the eye.
            self.review.section.add_plane(hit.point, -hit.normal)?;
            return Ok(json!({
                "point": hit.point.to_array(),
                "normal": (-hit.normal).to_array(),
                "section": self.review.section.describe(),
            }));
        }
        if self.ui.measure.mode == MeasureMode::Off {
            return Ok(self.pick(at));
        }
        let ray = self.ray_at(at);
        let Some(hit) = self.review.pick(&ray) else {
            return Ok(json!({ "hit": false }));
        };
        // Snap within SNAP_PX pixels at the hit's depth.
        let pane = &self.panes[self.active];
        let depth = (hit.point - pane.nav.eye).dot(pane.nav.forward());
        let px =
            crate::nav::world_per_pixel(pane.nav.fov_y_rad, depth, f64::from(pane.view.size.1));
        let point = crate::measure::snap(&self.review.scene, &hit, SNAP_PX * px);
        let result = self.ui.measure.click(&mut self.review, point);
        Ok(match result {
            Some(m) => {
                self.ui.status = format!("measured {}", m.label());
                m.json(&self.review.scene)
            }
            None => json!({ "first": point.point.to_array(), "snap": point.snap.name() }),
        })
    }

    /// Frames the selection (or the point under `at`, picking it first).
    fn focus(&mut self, at: Option<ViewPoint>) {
        if let Some(at) = at {
            self.pick(at);
        }
        if let Some(part) = self.review.selected {
            let bounds = self.review.scene.part_world_bounds(part);
            self.frame_in_active(&bounds);
        }
    }

    /// The gizmo on the selection in pane `pane`, when it shows.
    fn gizmo(&self, pane: usize) -> Option<Gizmo> {
        let part = self.review.selected.filter(|_| self.ui.show_gizmo)?;
        let p = self.panes.get(pane)?;
        let centre = self.review.scene.part_world_bounds(part).center();
        Gizmo::new(&p.nav.camera(), p.view.size, centre)
    }

    /// The section handle under view point `at` of pane `pane` (index, world
    /// point, slide direction), when the tools are drawn.
    fn section_handle_at(&self, pane: usize, at: ViewPoint) -> Option<(usize, DVec3, DVec3)> {
        let p = self.panes.get(pane).filter(|_| self.ui.show_tools)?;
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
            step: self.ui.snap,
            degrees: self.ui.snap_deg,
        })
    }

    /// A primary drag starts at `at`: on the selection with a drag axis set
    /// it moves the part along the axis; on a section handle it slides the
    /// plane or box face; on a gizmo handle it drags the handle; anywhere
    /// else it orbits about the point under it.
    fn begin_pointer_drag(&mut self, at: ViewPoint, axis: Option<Axis>) {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        // With a drag axis set, a press on the selection slides it (the
        // mode asked for), even where a gizmo handle crosses the part.
        if let (Some(axis), Some(h)) = (axis, hit.filter(|h| Some(h.part) == self.review.selected))
            && self.review.begin_drag()
        {
            let axis = axis.unit();
            self.pointer_drag = Some(PointerDrag::Part {
                axis,
                origin: h.point,
                start: axis_offset(h.point, axis, &ray).unwrap_or(0.0),
                snap: self.ui.snap,
            });
            return;
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
            return;
        }
        if let Some(g) = self.gizmo(self.active)
            && let Some(handle) = g.handle_at(glam::DVec2::new(at.0, at.1))
            && let Some(drag) = g.begin(handle, &ray)
            && self.review.begin_drag()
        {
            self.pointer_drag = Some(PointerDrag::Gizmo(drag));
            return;
        }
        if let Some(h) = hit {
            self.nav().pivot = h.point;
        }
        self.pointer_drag = Some(PointerDrag::Orbit);
    }

    fn pointer_drag_to(&mut self, at: ViewPoint, delta: ViewPoint, free: bool) {
        match self.pointer_drag {
            Some(PointerDrag::Gizmo(drag)) => {
                if let Some(delta) = drag.delta(&self.ray_at(at), self.snap(free))
                    && let Err(e) = self.review.drag_by(delta)
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
                    let step = if free { 0.0 } else { self.ui.snap };
                    self.review.section =
                        before.slid(index, crate::gizmo::snap_to(s - start, step));
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
                    if let Err(e) = self
                        .review
                        .drag_to(axis * crate::gizmo::snap_to(s - start, step))
                    {
                        self.ui.status = format!("{e:#}");
                    }
                }
            }
            None => {}
        }
    }

    fn end_pointer_drag(&mut self) {
        if let Some(PointerDrag::Part { .. } | PointerDrag::Gizmo(_)) = self.pointer_drag.take() {
            self.review.end_drag();
        }
    }

    /// The part under a view point, for the hover tint (nothing while a
    /// primary drag goes on).
    fn hover(&mut self, at: Option<(usize, ViewPoint)>) {
        if self.export.is_some() {
            return;
        }
        self.ui.gizmo_hot =
            at.and_then(|(pane, (x, y))| self.gizmo(pane)?.handle_at(glam::DVec2::new(x, y)));
        self.hovered = match at {
            Some((pane, at)) if self.pointer_drag.is_none() && pane < self.panes.len() => {
                self.review.pick(&self.ray_in(pane, at)).map(|h| h.part)
            }
            _ => None,
        };
    }

    /// Applies the pointer and keys of this frame.
    fn apply_view_input(&mut self, input: &ViewInput, dt: f64) {
        // A press, drag or wheel makes its pane the active one (not while a
        // drag that began elsewhere goes on).
        if let Some(pane) = input.pane.filter(|&p| p < self.panes.len())
            && (self.pointer_drag.is_none() || input.drag_started.is_some())
        {
            self.active = pane;
        }
        if input.hover != self.pointer_at {
            self.pointer_at = input.hover;
            self.hover(input.hover);
        }
        if let Some(at) = input.double_clicked {
            self.focus(Some(at));
        } else if let Some(at) = input.clicked
            && let Err(e) = self.click(at)
        {
            self.ui.status = format!("{e:#}");
        }
        if let Some(at) = input.drag_started {
            self.begin_pointer_drag(at, self.ui.drag_axis);
        }
        if let Some((at, delta)) = input.dragging {
            self.pointer_drag_to(at, delta, input.free);
        }
        if input.drag_stopped {
            self.end_pointer_drag();
        }
        if input.look != (0.0, 0.0) {
            self.nav().look(
                -input.look.0 * TURN_PER_PIXEL,
                -input.look.1 * TURN_PER_PIXEL,
            );
        }
        if input.pan != (0.0, 0.0) {
            let height = f64::from(self.panes[self.active].view.size.1);
            self.nav().pan(input.pan.0, input.pan.1, height);
        }
        if let Some((wheel, at)) = input.wheel {
            let toward = self
                .review
                .pick(&self.ray_at(at))
                .map_or(self.panes[self.active].nav.pivot, |h| h.point);
            self.nav()
                .dolly_toward(toward, (wheel / 400.0).clamp(-0.5, 0.5));
        }
        if input.keys != Default::default() {
            self.nav().walk(input.keys, dt);
        }
        if input.focus {
            self.focus(None);
        }
        if input.frame_all {
            self.frame_all();
        }
    }

    /// Runs the script's current action for this frame.
    fn script_frame(&mut self) -> anyhow::Result<ScriptFrame> {
        let mut out = ScriptFrame::default();
        if self.frames_drawn < WARMUP_FRAMES || self.export.is_some() {
            return Ok(out);
        }
        let Some(action) = self.runner.actions.get(self.runner.index).cloned() else {
            return Ok(out);
        };
        let step = self.runner.step;
        out.label = Some((action.name(), step));
        let mut result = None;
        match &action {
            Action::Pick([x, y]) => {
                // Pixel (x, y) is aimed at through its centre.
                result = Some(self.pick((x + 0.5, y + 0.5)));
            }
            Action::Select(key) => {
                let part = self.review.scene.find_part(key)?;
                self.review.select(Some(part));
                self.ui.reveal = Some(part);
                result = Some(json!({ "part_id": part.0 }));
            }
            Action::Move(d) => {
                anyhow::ensure!(
                    self.review.translate_selection(DVec3::from_array(*d))?,
                    "move: nothing is selected"
                );
                result = Some(self.selection_facts());
            }
            Action::Drag(d) => {
                if step == 0 {
                    anyhow::ensure!(self.review.begin_drag(), "drag: nothing is selected");
                }
                let steps = d.steps.max(1);
                let t = f64::from(step + 1) / f64::from(steps);
                self.review.drag_to(DVec3::from_array(d.by) * t)?;
                if step + 1 == steps {
                    self.review.end_drag();
                    result = Some(self.selection_facts());
                }
            }
            Action::MouseDrag(d) => {
                let steps = d.steps.max(1);
                let from = (d.from[0] + 0.5, d.from[1] + 0.5);
                let to = (d.to[0] + 0.5, d.to[1] + 0.5);
                let at = |i: u32| {
                    let t = f64::from(i) / f64::from(steps);
                    (from.0 + (to.0 - from.0) * t, from.1 + (to.1 - from.1) * t)
                };
                if step == 0 {
                    self.begin_pointer_drag(from, Some(d.axis));
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Part { .. })),
                        "mouse_drag: the press at {:?} is not on the selected part",
                        d.from
                    );
                } else {
                    let (prev, now) = (at(step - 1), at(step));
                    self.pointer_drag_to(now, (now.0 - prev.0, now.1 - prev.1), false);
                }
                if step == steps {
                    self.end_pointer_drag();
                    result = Some(self.selection_facts());
                }
            }
            Action::SectionDrag(d) => {
                if step == 0 {
                    let pane = &self.panes[self.active];
                    let projector =
                        crate::gizmo::Projector::new(&pane.nav.camera(), pane.view.size);
                    let (point, _) = *self
                        .review
                        .section
                        .handles(&self.review.tree.bounds())
                        .get(d.handle)
                        .with_context(|| format!("section_drag: no section handle {}", d.handle))?;
                    let from = projector
                        .project(point)
                        .context("section_drag: the handle is behind the eye")?;
                    self.runner.gizmo_from = (from.x, from.y);
                    self.begin_pointer_drag(self.runner.gizmo_from, None);
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Section { index, .. }) if index == d.handle),
                        "section_drag: the press at {from} does not grab handle {} (are the tools' drawings hidden?)",
                        d.handle
                    );
                } else {
                    self.script_pointer_step(step, d.steps, d.by, false);
                }
                if step == d.steps.max(1) {
                    self.end_pointer_drag();
                    result = Some(self.review.section.json());
                }
            }
            Action::GizmoDrag(d) => {
                if step == 0 {
                    let g = self.gizmo(self.active).context(
                        "gizmo_drag: nothing is selected, or the gizmo is hidden or behind the eye",
                    )?;
                    let from = match d.from {
                        Some([x, y]) => glam::DVec2::new(x + 0.5, y + 0.5),
                        None => g
                            .grab_point(d.handle)
                            .context("gizmo_drag: the handle is off screen")?,
                    };
                    self.runner.gizmo_from = (from.x, from.y);
                    self.begin_pointer_drag(self.runner.gizmo_from, None);
                    anyhow::ensure!(
                        matches!(self.pointer_drag, Some(PointerDrag::Gizmo(g)) if g.handle == d.handle),
                        "gizmo_drag: the press at {from} does not grab the {:?} handle",
                        d.handle
                    );
                } else {
                    self.script_pointer_step(step, d.steps, d.by, d.free);
                }
                if step == d.steps.max(1) {
                    self.end_pointer_drag();
                    result = Some(self.selection_facts());
                }
            }
            Action::Snap(s) => {
                self.ui.snap = s.step.unwrap_or(self.ui.snap);
                self.ui.snap_deg = s.degrees.unwrap_or(self.ui.snap_deg);
            }
            Action::Gizmo(show) => self.ui.show_gizmo = *show,
            Action::SectionPlane(p) => {
                self.review
                    .section
                    .add_plane(DVec3::from_array(p.point), DVec3::from_array(p.normal))?;
                result = Some(self.review.section.json());
            }
            Action::SectionFace([x, y]) => {
                self.ui.section_on_face = true;
                result = Some(self.click((x + 0.5, y + 0.5))?);
            }
            Action::SectionBox(b) => {
                self.review
                    .section
                    .set_box(DVec3::from_array(b.min), DVec3::from_array(b.max))?;
                result = Some(self.review.section.json());
            }
            Action::ClearSection => self.review.section = crate::section::Section::Off,
            Action::Measure(m) => {
                anyhow::ensure!(
                    m.mode != MeasureMode::Off,
                    "measure: mode \"off\" measures nothing (give points, parts or angle)"
                );
                self.ui.measure.set_mode(m.mode);
                let mut last = Value::Null;
                for [x, y] in m.at {
                    last = self.click((x + 0.5, y + 0.5))?;
                    anyhow::ensure!(
                        last["hit"] != false,
                        "measure: the click at [{x}, {y}] hits no part"
                    );
                }
                result = Some(last);
            }
            Action::MeasureParts([a, b]) => {
                let (a, b) = (
                    self.review.scene.find_part(a)?,
                    self.review.scene.find_part(b)?,
                );
                let s = self
                    .review
                    .distance(a, b)
                    .context("measure_parts: a part has no triangles")?;
                let m = crate::measure::Measurement::Parts(a, b, s);
                self.ui.measure.result = Some(m);
                result = Some(m.json(&self.review.scene));
            }
            Action::LoadClashes(path) => {
                let added = crate::clashes::load_report(&mut self.review, path)?;
                result = Some(json!({ "added": added, "listed": self.review.clash_list.len() }));
            }
            Action::ShowClash(i) => {
                result = Some(crate::tools_ui::show_clash(
                    &mut self.review,
                    &mut self.ui.measure,
                    &mut self.panes[self.active],
                    *i,
                )?);
            }
            Action::ExportBcf(path) => {
                let topics = self.start_export(path.clone())?;
                result = Some(json!({ "path": path, "topics": topics }));
            }
            Action::ImportBcf(path) => result = Some(self.import_bcf(path)?),
            Action::SaveViewpoint(name) => {
                let v = crate::viewpoints::Viewpoint::capture(
                    name,
                    &self.panes[self.active].nav,
                    &self.review,
                );
                result = Some(v.json());
                self.ui.viewpoints.retain(|o| o.name != *name);
                self.ui.viewpoints.push(v);
            }
            Action::Viewpoint(name) => {
                let v = self
                    .ui
                    .viewpoints
                    .iter()
                    .find(|v| v.name == *name)
                    .cloned()
                    .with_context(|| format!("viewpoint {name:?}: no viewpoint of that name"))?;
                crate::tools_ui::go_to(&v, &mut self.review, &mut self.panes[self.active]);
                result = Some(v.json());
            }
            Action::Rotate(r) => {
                anyhow::ensure!(
                    self.review.rotate_selection(r.axis.unit(), r.degrees)?,
                    "rotate: nothing is selected"
                );
                result = Some(self.selection_facts());
            }
            Action::Hover([x, y]) => {
                self.hover(Some((self.active, (x + 0.5, y + 0.5))));
                result = Some(json!({ "part_id": self.hovered.map(|p| p.0) }));
            }
            Action::View(preset) => {
                let pane = &mut self.panes[self.active];
                pane.nav.preset(*preset, &self.review.tree.bounds());
                pane.view.reset_visibility();
            }
            Action::Camera(c) => {
                let bounds = self.review.tree.bounds();
                let pivot = if bounds.is_empty() {
                    1.0
                } else {
                    bounds.extent().length() * 0.1
                };
                let pane = &mut self.panes[self.active];
                let (eye, forward) = (DVec3::from_array(c.eye), DVec3::from_array(c.forward));
                anyhow::ensure!(
                    pane.nav.look_along(eye, forward, pivot),
                    "camera: no direction to look along"
                );
                pane.view.reset_visibility();
                result = Some(camera_json(&pane.nav));
            }
            Action::Panes(n) => {
                anyhow::ensure!(
                    (1..=crate::panes::MAX_PANES).contains(n),
                    "panes: {n} is not 1 to {}",
                    crate::panes::MAX_PANES
                );
                crate::panes::set_count(&mut self.panes, *n, &self.review.tree.bounds());
                self.active = self.active.min(n - 1);
            }
            Action::Pane(i) => {
                anyhow::ensure!(
                    *i < self.panes.len(),
                    "pane {i}: there are {}",
                    self.panes.len()
                );
                self.active = *i;
            }
            Action::Record(path) => {
                self.review.recorder = path.as_deref().map(Recorder::create).transpose()?;
            }
            Action::Clearance(c) => {
                self.review.settings.clearance = *c;
                self.review.check();
            }
            Action::Occlusion(o) => o.apply(&mut self.panes[self.active].view),
            Action::Undo => result = Some(json!({ "part_id": self.review.undo().map(|p| p.0) })),
            Action::Redo => result = Some(json!({ "part_id": self.review.redo().map(|p| p.0) })),
            Action::Focus => self.focus(None),
            Action::FrameAll => self.frame_all(),
            Action::Culling(name) => {
                self.panes[self.active].view.culling =
                    crate::script::culling_from_name(name).context("culling mode")?;
            }
            Action::PaintWhole(whole) => {
                if let Some(gfx) = self.gfx.as_mut() {
                    gfx.set_compose(!whole);
                }
            }
            Action::Overlays(o) => {
                self.ui.show_stats = o.stats.unwrap_or(self.ui.show_stats);
                self.ui.show_clashes = o.clashes.unwrap_or(self.ui.show_clashes);
                self.ui.show_tools = o.tools.unwrap_or(self.ui.show_tools);
            }
            Action::Frames(_) => {}
            Action::Screenshot(path) => {
                out.screenshot = Some(path.clone());
                result = Some(json!({ "path": path }));
            }
            Action::Save(path) => {
                let saved = self.review.save(path)?;
                result = Some(json!({ "path": saved.path, "format": saved.format }));
            }
        }
        if let Some(e) = self.review.record_error.take() {
            anyhow::bail!("{}: {e}", action.name());
        }
        self.runner.step += 1;
        if self.runner.step >= action.frames() {
            let mut entry = result.unwrap_or_else(|| json!({}));
            entry["action"] = json!(action.name());
            self.runner.results.push(entry.to_string().into_boxed_str());
            self.runner.index += 1;
            self.runner.step = 0;
        }
        Ok(out)
    }

    /// Carries out the BCF export or import the panel asked for.
    fn panel_bcf_request(&mut self) {
        let Some(request) = self.ui.tools.bcf_request.take() else {
            return;
        };
        let path = PathBuf::from(&self.ui.tools.bcf_path);
        match request {
            crate::tools_ui::BcfRequest::Export if self.export.is_none() => {
                self.ui.status = match self.start_export(path) {
                    Ok(n) => format!("writing {n} issues…"),
                    Err(e) => format!("{e:#}"),
                };
            }
            crate::tools_ui::BcfRequest::Export => {}
            crate::tools_ui::BcfRequest::Import => {
                if let Err(e) = self.import_bcf(&path) {
                    self.ui.status = format!("{e:#}");
                }
            }
        }
    }

    /// Starts writing the review's issues (listed clashes, saved viewpoints)
    /// to a BCF file at `path`: each issue's view is shown for a frame or a
    /// few, its snapshot taken, then the file written and the view restored.
    /// How many topics it will hold. A name not ending in `.bcfzip` is
    /// refused before anything is shown (the export wrote over the model it
    /// had open).
    pub fn start_export(&mut self, path: PathBuf) -> anyhow::Result<usize> {
        dmu_app::bcf::check_output_name(&path)?;
        let nav = &self.panes[self.active].nav;
        let issues = crate::issues::issues(
            &self.review,
            &self.ui.viewpoints,
            nav.forward(),
            nav.fov_y_rad,
            nav.near,
        );
        let n = issues.len();
        self.export = Some(Export {
            path,
            issues,
            next: 0,
            frames: 0,
            restore: crate::viewpoints::Viewpoint::capture("", nav, &self.review),
            overlays: (self.ui.show_stats, self.ui.show_clashes, self.ui.show_tools),
        });
        (self.ui.show_stats, self.ui.show_clashes, self.ui.show_tools) = (false, false, false);
        Ok(n)
    }

    /// Shows the view of the issue being exported (its first frame), or ends
    /// the export when every snapshot is in.
    fn export_view(&mut self) {
        let Some(e) = self.export.as_mut() else {
            return;
        };
        if let Some(issue) = e.issues.get(e.next) {
            // Snapshots show the model, not where the pointer rests.
            self.hovered = None;
            if e.frames == 0 {
                let view = issue.view.clone();
                crate::tools_ui::go_to(&view, &mut self.review, &mut self.panes[self.active]);
            }
            return;
        }
        let e = self.export.take().expect("checked");
        let topics: Vec<dmu_app::bcf::Topic> = e.issues.into_iter().map(|i| i.topic).collect();
        let name = self.review.scene.name().to_owned();
        let written = dmu_app::bcf::write_bcfzip(
            &e.path,
            &topics,
            Some(&name),
            self.options.unit.per_metre(),
        );
        crate::tools_ui::go_to(&e.restore, &mut self.review, &mut self.panes[self.active]);
        (self.ui.show_stats, self.ui.show_clashes, self.ui.show_tools) = e.overlays;
        match written {
            Ok(()) => {
                self.ui.status = format!("{} issues written to {}", topics.len(), e.path.display());
                self.facts["bcf_export"] = json!({ "path": e.path, "topics": topics.len() });
            }
            Err(err) if self.options.automated() => self.error = Some(err.into()),
            Err(err) => self.ui.status = format!("{err:#}"),
        }
    }

    /// The active pane's pixels of `window` as the snapshot of the issue
    /// being exported.
    fn export_snapshot(&mut self, window: &image::RgbaImage) -> anyhow::Result<()> {
        let (x, y, w, h) = self.active_rect();
        let Some(e) = self.export.as_mut() else {
            return Ok(());
        };
        let view = image::imageops::crop_imm(window, x, y, w, h).to_image();
        let png = dmu_render::encode_png(&view)?;
        if let Some(v) = e.issues[e.next].topic.viewpoints.first_mut() {
            v.snapshot = Some(png.into());
        }
        e.next += 1;
        e.frames = 0;
        Ok(())
    }

    /// Reads a BCF file's topics as viewpoints (added to the saved ones,
    /// replacing those of the same name) and goes to the first.
    pub fn import_bcf(&mut self, path: &std::path::Path) -> anyhow::Result<Value> {
        let topics = dmu_app::bcf::read_bcfzip(path, self.options.unit.per_metre())?;
        let bounds = self.review.tree.bounds();
        let pivot = if bounds.is_empty() {
            1.0
        } else {
            bounds.extent().length() * 0.1
        };
        let imported = crate::issues::import(&self.review, &topics, pivot)?;
        for v in &imported.viewpoints {
            self.ui.viewpoints.retain(|o| o.name != v.name);
            self.ui.viewpoints.push(v.clone());
        }
        let first = imported.viewpoints.first().cloned();
        if let Some(v) = &first {
            crate::tools_ui::go_to(v, &mut self.review, &mut self.panes[self.active]);
        }
        self.ui.status = format!(
            "{} viewpoints from {} ({} topics skipped, {} parts not in the model)",
            imported.viewpoints.len(),
            path.display(),
            imported.skipped_topics,
            imported.unknown_components
        );
        Ok(json!({
            "topics": topics.len(),
            "viewpoints": imported.viewpoints.len(),
            "skipped_topics": imported.skipped_topics,
            "unknown_components": imported.unknown_components,
            "first": first.map(|v| json!({
                "view": v.json(),
                "section": v.section.json(),
                "selected": v.selected.map(|p| self.review.scene.part_name(p).to_owned()),
            })),
        }))
    }

    /// Step `step` (from 1) of `steps` of a scripted drag that moves the
    /// pointer by `by` pixels from where it pressed.
    fn script_pointer_step(&mut self, step: u32, steps: u32, by: [f64; 2], free: bool) {
        let steps = steps.max(1);
        let (t, prev) = (
            f64::from(step) / f64::from(steps),
            f64::from(step - 1) / f64::from(steps),
        );
        let (x, y) = self.runner.gizmo_from;
        let now = (x + by[0] * t, y + by[1] * t);
        self.pointer_drag_to(now, ((t - prev) * by[0], (t - prev) * by[1]), free);
    }

    /// The selection's transform and clashes, for the report.
    fn selection_facts(&self) -> Value {
        selection_json(&self.review)
    }

    fn script_done(&self) -> bool {
        self.runner.index >= self.runner.actions.len()
    }

    /// Tints the selection, the parts clashing with it and the hovered part
    /// in the renderer, telling it only what changed.
    fn sync_tints(&mut self) {
        let Some(renderer) = self.renderer.as_mut() else {
            return;
        };
        let t = &mut self.tints;
        let selected = self.review.selected.into_iter().collect();
        retint(&mut t.selected, selected, |p, on| {
            renderer.set_selected(p, on)
        });
        let clashing = self.review.clashing_parts();
        retint(&mut t.clashing, clashing, |p, on| {
            renderer.set_clashing(p, on)
        });
        let hovered = self.hovered.into_iter().collect();
        retint(&mut t.hovered, hovered, |p, on| renderer.set_hovered(p, on));
    }

    /// Renders every pane into its target (sized as laid out); the stats of
    /// each. The main pane's drawn cells are noted for cells panes.
    fn render_panes(&mut self, dt: f64) -> anyhow::Result<Vec<FrameStats>> {
        if let Some(e) = self.review.geometry_error.take() {
            anyhow::bail!("{e}");
        }
        self.start_streaming();
        let gfx = self.gfx.as_mut().expect("made with the window");
        let renderer = self.renderer.as_mut().expect("made with the window");
        gfx.ensure_views(self.panes.len());
        let mut stats = Vec::with_capacity(self.panes.len());
        let section = self.review.section.planes();
        for (i, pane) in self.panes.iter_mut().enumerate() {
            pane.view.set_section(&section);
            let rect = self.pane_rects.get(i).copied().unwrap_or((0, 0, 1, 1));
            gfx.resize_view(i, (rect.2, rect.3));
            pane.view.size = gfx.views[i].size;
            pane.view.camera = pane.nav.camera();
        }
        if let Some(far) = self.far.as_mut() {
            self.panes[0].view.far_field = far.for_frame(self.panes[0].view.camera.eye)?;
        }
        let (scene, tree) = (&self.review.scene, &self.review.tree);
        let source = match self.streaming.as_mut() {
            Some(streaming) => {
                let camera = self.panes[0].view.camera;
                streaming.begin_frame(renderer.geometry_pool(), tree, scene, &camera, dt)?;
                Some(streaming.source(scene))
            }
            None => None,
        };
        let geometry: &dyn dmu_render::GeometrySource = match &source {
            Some(s) => s,
            None => scene,
        };
        for (i, pane) in self.panes.iter_mut().enumerate() {
            stats.push(renderer.render(
                &mut pane.view,
                scene,
                tree,
                geometry,
                gfx.views[i].frame_target(),
            )?);
        }
        if let Some(source) = source {
            let stood_in = source.stood_in();
            let drawn: Vec<Vec<EntryId>> = self
                .panes
                .iter()
                .map(|p| p.view.drawn_entries().collect())
                .collect();
            let not_resident = stats.iter().map(|s| s.not_resident).sum();
            let streaming = self.streaming.as_mut().expect("it made the source");
            streaming.end_frame(tree, stood_in, &drawn, not_resident);
        }
        if let Some(far) = self.far.as_mut() {
            far.after_render(&stats[0], self.frames_drawn);
        }
        if self.panes.iter().any(|p| p.kind == PaneKind::Cells) {
            crate::panes::drawn_cells(
                &self.review.tree,
                &self.panes[0].view,
                &mut self.drawn_cells,
            );
        }
        Ok(stats)
    }

    /// Captures again a far field that moved parts made stale, when the view
    /// is calm: no drag of a part, the gizmo or a section going on, and no
    /// camera moved by this frame's input (`moving`).
    fn rebuild_far_fields(&mut self, moving: bool) -> anyhow::Result<()> {
        let (Some(far), Some(renderer)) = (self.far.as_mut(), self.renderer.as_ref()) else {
            return Ok(());
        };
        let calm = !moving && self.pointer_drag.is_none() && !self.review.dragging();
        far.rebuild(
            &self.review,
            renderer.moved_parts(),
            calm,
            self.panes[0].view.camera.eye,
        )
    }

    /// Under a memory budget, starts streaming with the first frame (drawn
    /// with stand-ins only); the residency gets its budget once that frame
    /// shows what the renderer takes.
    fn start_streaming(&mut self) {
        let (Some(budget), None, Some(geometry)) = (
            self.options.memory_budget,
            &self.streaming,
            &self.review.geometry,
        ) else {
            return;
        };
        let main = &self.panes[0].view;
        self.streaming = Some(crate::budget::Streaming::new(
            Arc::clone(geometry.store()),
            &self.review.tree,
            budget,
            dmu_store::Viewport {
                width: main.size.0.max(1),
                height: main.size.1.max(1),
            },
            main.options.min_pixels,
            self.options.stand_ins,
        ));
    }

    /// Each pane for the report: kind, rectangle, camera, triangles drawn and,
    /// for cells panes, the main pane's drawn cells.
    fn panes_json(&self, stats: &[FrameStats]) -> Value {
        let tree = &self.review.tree;
        let panes: Vec<Value> = self
            .panes
            .iter()
            .zip(stats)
            .enumerate()
            .map(|(i, (pane, s))| {
                let mut v = json!({
                    "kind": pane.kind_name(),
                    "rect": rect_json(self.pane_rects[i]),
                    "camera": camera_json(&pane.nav),
                    "triangles_drawn": s.triangles_drawn,
                    "culled_frustum": s.culled_frustum,
                });
                if pane.kind == PaneKind::Cells {
                    let (drawn, culled) = crate::panes::cell_counts(tree, &self.drawn_cells);
                    let ids: Vec<u32> = tree
                        .cell_ids()
                        .filter(|c| self.drawn_cells.get(c.0 as usize) == Some(&true))
                        .map(|c| c.0)
                        .collect();
                    v["cells_drawn"] = json!(drawn);
                    v["cells_culled"] = json!(culled);
                    v["drawn_cell_ids"] = json!(ids);
                }
                v
            })
            .collect();
        json!(panes)
    }

    /// One frame; returns whether the run is over.
    fn redraw(&mut self) -> anyhow::Result<bool> {
        let start = Instant::now();
        let dt = self
            .last_frame
            .map_or(0.0, |t| t.elapsed().as_secs_f64().min(0.25));
        self.last_frame = Some(start);
        let scripted = self.script_frame()?;
        self.export_view();

        let (Some(gfx), Some(egui_state)) = (self.gfx.as_mut(), self.egui_state.as_mut()) else {
            return Ok(false);
        };
        let raw = egui_state.take_egui_input(&gfx.window);
        gfx.ensure_views(self.panes.len());
        let textures: Vec<egui::TextureId> = gfx.views.iter().map(|v| v.texture).collect();
        let mut input = ViewInput::default();
        self.ui.memory = self
            .streaming
            .as_ref()
            .map(crate::budget::Streaming::summary);
        {
            let (ui_state, review, overlay) = (&mut self.ui, &mut self.review, &self.overlay);
            let mut panes = PaneShow {
                panes: &mut self.panes,
                active: self.active,
                textures: &textures,
                drawn_cells: &self.drawn_cells,
            };
            let ui_start = Instant::now();
            let mut output = self.egui_ctx.run_ui(raw, |ui| {
                shortcuts(ui, review);
                input = crate::ui::show(ui, ui_state, review, &mut panes, overlay);
            });
            self.active = self.active.min(self.panes.len() - 1);
            egui_state
                .handle_platform_output(&gfx.window, std::mem::take(&mut output.platform_output));
            let repaint_now = output
                .viewport_output
                .get(&egui::ViewportId::ROOT)
                .is_some_and(|v| v.repaint_delay < Duration::from_millis(50));
            self.keep_drawing = repaint_now;
            if input.rects_px.len() == self.panes.len() {
                self.pane_rects.clone_from(&input.rects_px);
            }
            self.apply_view_input(&input, dt);
            self.panel_bcf_request();
            self.keep_drawing |= input.active();

            let final_frame = self.script_done()
                && self.export.is_none()
                && self.options.automated()
                && self.frames_drawn + 1 >= u64::from(self.options.frames.unwrap_or(0));
            let screenshot = scripted.screenshot.clone().or_else(|| {
                final_frame
                    .then(|| self.options.screenshot.clone())
                    .flatten()
            });
            let ui_ms = ms_since(ui_start);
            self.sync_tints();
            let view_start = Instant::now();
            let stats = match self.render_panes(dt) {
                Ok(stats) => stats,
                Err(e) => {
                    // egui's output is dropped unpainted; say so, or it asserts.
                    output.textures_delta.clear();
                    return Err(e);
                }
            };
            let view_ms = ms_since(view_start);
            let main = stats[0];
            let shown = stats[self.active.min(stats.len() - 1)];
            // Occlusion culling converges over a few frames.
            self.keep_drawing |= stats.iter().any(|s| s.newly_visible > 0);
            let renderer = self.renderer.as_mut().expect("made with the window");
            let resident = renderer.geometry_pool().resident_bytes();
            let gfx = self.gfx.as_mut().expect("checked above");
            let paint_start = Instant::now();
            let snapshot = self.export.as_mut().is_some_and(|e| {
                e.frames += 1;
                e.frames >= SNAPSHOT_SETTLE_FRAMES || stats.iter().all(|s| s.newly_visible == 0)
            });
            let presented = gfx.present(
                &self.egui_ctx,
                output,
                screenshot.is_some() || snapshot,
                self.review.dragging(),
            )?;
            if snapshot && let Some(image) = &presented.image {
                self.export_snapshot(image)?;
            }
            let paint_ms = ms_since(paint_start);
            if let (Some(path), Some(image)) = (&screenshot, presented.image) {
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir)?;
                }
                dmu_render::save_png(&image, path)?;
            }
            self.rebuild_far_fields(input.active())?;
            // A far field loading or to be captured again needs frames.
            self.keep_drawing |= self.far.as_ref().is_some_and(|f| f.wants_frames());
            let frame_ms = ms_since(start);
            self.frame_times.push(frame_ms);
            if self.first_frame_ms.is_none() {
                self.first_frame_ms = Some(ms_since(self.options.started));
            }
            self.frame_ms.push_back(frame_ms);
            if self.frame_ms.len() > 30 {
                self.frame_ms.pop_front();
            }
            self.overlay = Overlay {
                frame: shown,
                frame_ms,
                frame_ms_avg: self.frame_ms.iter().sum::<f64>() / self.frame_ms.len() as f64,
                ui_ms,
                view_ms,
                paint_ms,
                painted_whole: presented.painted_whole,
                model_triangles: self.review.scene.triangle_count(),
                resident_bytes: resident,
                far: self.far.as_ref().map(|f| f.report().clone()),
            };
            if let Some((action, step)) = scripted.label {
                let mut record = json!({
                    "frame": self.frames_drawn,
                    "action": action,
                    "step": step,
                    "frame_ms": frame_ms,
                    "ui_ms": ui_ms,
                    "view_ms": view_ms,
                    "paint_ms": paint_ms,
                    "painted_whole": presented.painted_whole,
                    "panels_stale": presented.panels_stale,
                    "render_cpu_ms": main.cpu_ms,
                    "render_gpu_ms": main.gpu_ms,
                    "culling": main.culling.name(),
                    "triangles_drawn": main.triangles_drawn,
                    "chunks_drawn": main.chunks_drawn,
                    "proxies_drawn": main.proxies_drawn,
                    "proxies_stale": main.proxies_stale,
                    "culled_section": main.culled_section,
                    "draw_calls": main.draw_calls,
                    "lod_error_px": main.lod_error_px,
                    "min_pixels": main.min_pixels,
                    "queries": main.queries,
                    "rss_bytes": dmu_app::progress::rss_bytes(),
                    "t_s": self.options.started.elapsed().as_secs_f64(),
                    "move_us": self.review.timings.move_us,
                    "check_ms": self.review.timings.check_ms,
                    "clashes": clashes_json(&self.review.report),
                });
                if let Some(s) = &self.streaming {
                    let pool = self
                        .renderer
                        .as_mut()
                        .expect("made with the window")
                        .geometry_pool();
                    record["memory"] = s.frame_json(pool);
                }
                if let Some(far) = &self.far {
                    record["far_field"] = far.report().json();
                }
                if stats.len() > 1 {
                    record["pane_triangles_drawn"] =
                        json!(stats.iter().map(|s| s.triangles_drawn).collect::<Vec<_>>());
                }
                self.runner.frames.push(record.to_string().into_boxed_str());
            }
            self.frames_drawn += 1;
            if final_frame {
                self.facts["viewport"] = rect_json(self.pane_rects[0]);
                let nav = &self.panes[self.active].nav;
                self.facts["camera"] = camera_json(nav);
                self.facts["last_frame"] = json!({
                    "triangles_drawn": main.triangles_drawn,
                    "chunks_drawn": main.chunks_drawn,
                    "culled_frustum": main.culled_frustum,
                    "culled_occlusion": main.culled_occlusion,
                });
                self.facts["panes"] = self.panes_json(&stats);
            }
            Ok(final_frame)
        }
    }
}

/// Opens the viewer's window with `options`' size and sync, and egui's
/// state for it on `ctx`.
pub fn open_window(
    event_loop: &ActiveEventLoop,
    instance: &wgpu::Instance,
    options: &Options,
    ctx: &egui::Context,
) -> anyhow::Result<(Gfx, egui_winit::State)> {
    let attributes = Window::default_attributes()
        .with_title("dmu")
        .with_inner_size(winit::dpi::PhysicalSize::new(
            options.size.0,
            options.size.1,
        ));
    let window = event_loop
        .create_window(attributes)
        .context("opening the window")?;
    let mut gfx = Gfx::new(instance, Arc::new(window), options.vsync, options.compose)?;
    gfx.panel_lag = options.panel_lag;
    let state = egui_winit::State::new(
        ctx.clone(),
        egui::ViewportId::ROOT,
        &gfx.window,
        Some(gfx.window.scale_factor() as f32),
        gfx.window.theme(),
        Some(gfx.device.limits().max_texture_dimension_2d as usize),
    );
    Ok((gfx, state))
}

/// Keyboard shortcuts that act on the review: undo, redo, deselect.
fn shortcuts(ui: &mut egui::Ui, review: &mut Review) {
    if ui.ctx().egui_wants_keyboard_input() {
        return;
    }
    let (undo, redo, escape) = ui.input_mut(|i| {
        let undo = i.consume_key(egui::Modifiers::COMMAND, egui::Key::Z);
        let redo = i.consume_key(egui::Modifiers::COMMAND, egui::Key::Y)
            || i.consume_key(
                egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
                egui::Key::Z,
            );
        (undo, redo, i.key_pressed(egui::Key::Escape))
    });
    if undo {
        review.undo();
    }
    if redo {
        review.redo();
    }
    if escape {
        review.select(None);
    }
}

/// The selection's transform and clashes, and the last step's timings, for
/// reports (the desktop's script steps and `--xr`'s grab alike).
pub(crate) fn selection_json(review: &Review) -> Value {
    let Some(part) = review.selected else {
        return json!({ "part_id": null });
    };
    let scene = &review.scene;
    let world = scene.part_world(part);
    json!({
        "part_id": part.0,
        "part": scene.part_name(part),
        "path": scene.part_path(part),
        "translation": world.translation.to_array(),
        "matrix3": world.matrix3.to_cols_array(),
        "clashes": clashes_json(&review.report),
        "move_us": review.timings.move_us,
        "check_ms": review.timings.check_ms,
    })
}

/// The clashes of a report: part ids, kind, distance.
pub(crate) fn clashes_json(report: &Report) -> Value {
    json!(
        report
            .clashes
            .iter()
            .map(|c| json!({
                "a": c.a.0, "b": c.b.0, "kind": c.kind.as_str(), "distance": c.distance,
            }))
            .collect::<Vec<_>>()
    )
}

/// A camera in the report: eye, view direction, vertical field of view.
fn camera_json(nav: &Navigator) -> Value {
    json!({
        "eye": nav.eye.to_array(),
        "forward": nav.forward().to_array(),
        "fov_y_deg": nav.fov_y_rad.to_degrees(),
        "near": nav.near,
    })
}

/// Records kept as JSON text, parsed back.
fn parsed(records: &[Box<str>]) -> Vec<Value> {
    records
        .iter()
        .map(|r| serde_json::from_str(r).expect("a record serde_json wrote"))
        .collect()
}

/// Milliseconds since `start`.
fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// A window rectangle (x, y, width, height) in the report.
fn rect_json(r: (u32, u32, u32, u32)) -> Value {
    json!({ "x": r.0, "y": r.1, "width": r.2, "height": r.3 })
}

/// Count, mean, median, 95th percentile and maximum of `values`.
pub(crate) fn summary(values: &[f64]) -> Value {
    if values.is_empty() {
        return json!({ "count": 0 });
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    json!({
        "count": sorted.len(),
        "mean": sorted.iter().sum::<f64>() / sorted.len() as f64,
        "median": at(0.5),
        "p95": at(0.95),
        "max": sorted[sorted.len() - 1],
    })
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match open_window(event_loop, &self.instance, &self.options, &self.egui_ctx) {
            Ok((gfx, state)) => self.adopt(gfx, state, self.egui_ctx.clone()),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let (Some(gfx), Some(state)) = (self.gfx.as_mut(), self.egui_state.as_mut()) else {
            return;
        };
        let response = state.on_window_event(&gfx.window, &event);
        if response.repaint {
            gfx.window.request_redraw();
        }
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                gfx.resize(size.width, size.height);
                gfx.window.request_redraw();
            }
            WindowEvent::RedrawRequested => match self.redraw() {
                Ok(true) => event_loop.exit(),
                Ok(false) => {}
                Err(e) => {
                    self.error = Some(e);
                    event_loop.exit();
                }
            },
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(gfx) = self.gfx.as_ref() else {
            return;
        };
        if self.keep_drawing || self.options.automated() {
            gfx.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Poll);
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}
