//! The application: winit's event loop driving one frame at a time (script
//! step, panels, navigation, 3D render, egui paint, present), and the JSON
//! report of an automated run.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_geom::Ray3d;
use dmu_render::{Culling, FrameStats, Renderer, View};
use dmu_scene::PartId;
use glam::DVec3;
use serde_json::{Value, json};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::{Window, WindowId};

use crate::gfx::Gfx;
use crate::nav::{Navigator, axis_offset};
use crate::review::Review;
use crate::script::{Action, Axis};
use crate::ui::{Overlay, UiState, ViewInput, ViewPoint};

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
}

impl Options {
    fn automated(&self) -> bool {
        self.frames.is_some() || !self.script.is_empty()
    }
}

/// A primary-button drag in the 3D view.
#[derive(Clone, Copy, Debug, PartialEq)]
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
}

/// The script's progress.
#[derive(Debug, Default)]
struct Runner {
    actions: Vec<Action>,
    /// Action being run and its step.
    index: usize,
    step: u32,
    /// One result per finished action.
    results: Vec<Value>,
    /// One record per frame while the script runs.
    frames: Vec<Value>,
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
    options: Options,
    instance: wgpu::Instance,
    review: Review,
    nav: Navigator,
    view: View,
    ui: UiState,
    egui_ctx: egui::Context,
    egui_state: Option<egui_winit::State>,
    gfx: Option<Gfx>,
    renderer: Option<Renderer>,
    highlighted: Option<PartId>,
    overlay: Overlay,
    frame_ms: VecDeque<f64>,
    frames_drawn: u64,
    last_frame: Option<Instant>,
    pointer_drag: Option<PointerDrag>,
    /// The 3D view's rectangle in the window (x, y, width, height), last frame.
    view_rect: (u32, u32, u32, u32),
    runner: Runner,
    /// The run's report (model and load facts), completed at exit.
    facts: Value,
    keep_drawing: bool,
    error: Option<anyhow::Error>,
}

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
        let nav = Navigator::overview(&review.tree.bounds());
        let view = View::new(nav.camera(), (1, 1), options.culling);
        let ui = UiState::new(review.source.as_deref());
        let runner = Runner {
            actions: options.script.clone(),
            ..Runner::default()
        };
        Self {
            options,
            instance,
            review,
            nav,
            view,
            ui,
            egui_ctx: egui::Context::default(),
            egui_state: None,
            gfx: None,
            renderer: None,
            highlighted: None,
            overlay: Overlay::default(),
            frame_ms: VecDeque::new(),
            frames_drawn: 0,
            last_frame: None,
            pointer_drag: None,
            view_rect: (0, 0, 1, 1),
            runner,
            facts,
            keep_drawing: true,
            error: None,
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
        report["steps"] = json!(self.runner.results);
        report["moved_parts"] = json!(
            self.review
                .moved_parts()
                .iter()
                .map(|p| p.0)
                .collect::<Vec<_>>()
        );
        report["frames"] = json!(self.runner.frames);
        let drag: Vec<f64> = self
            .runner
            .frames
            .iter()
            .filter(|f| matches!(f["action"].as_str(), Some("drag" | "mouse_drag")))
            .filter_map(|f| f["frame_ms"].as_f64())
            .collect();
        report["drag_frame_ms"] = summary(&drag);
        Ok(Some(report))
    }

    fn view_size(&self) -> (u32, u32) {
        self.view.size
    }

    /// The f64 ray through the view point `(x, y)` (physical pixels).
    fn ray_at(&self, (x, y): ViewPoint) -> Ray3d {
        self.nav.ray(self.view_size(), x, y)
    }

    /// Picks at a view point: selects what is hit (or nothing), orbits about
    /// the hit point from now on. Returns the ray and the report entry.
    fn pick(&mut self, at: ViewPoint) -> Value {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        self.review.select(hit.map(|h| h.part));
        if let Some(h) = hit {
            self.nav.pivot = h.point;
            self.ui.reveal = Some(h.part);
        }
        let scene = &self.review.scene;
        let length = ray.dir.length();
        json!({
            "pixel": [at.0, at.1],
            "viewport": rect_json(self.view_rect),
            "ray": { "origin": ray.origin.to_array(), "dir": ray.dir.to_array() },
            "hit": hit.map_or_else(
                || json!({ "hit": false }),
                |h| dmu::hits::hit_json(scene, &h, length)
            ),
        })
    }

    /// Frames the selection (or the point under `at`, picking it first).
    fn focus(&mut self, at: Option<ViewPoint>) {
        if let Some(at) = at {
            self.pick(at);
        }
        if let Some(part) = self.review.selected {
            self.nav.frame(&self.review.scene.part_world_bounds(part));
            self.view.reset_visibility();
        }
    }

    /// A primary drag starts at `at`: on the selection with a drag axis set it
    /// moves the part, anywhere else it orbits about the point under it.
    fn begin_pointer_drag(&mut self, at: ViewPoint, axis: Option<Axis>) {
        let ray = self.ray_at(at);
        let hit = self.review.pick(&ray);
        let on_selection = hit.filter(|h| Some(h.part) == self.review.selected);
        self.pointer_drag = match (axis, on_selection) {
            (Some(axis), Some(h)) if self.review.begin_drag() => {
                let axis = axis.unit();
                let start = axis_offset(h.point, axis, &ray).unwrap_or(0.0);
                Some(PointerDrag::Part {
                    axis,
                    origin: h.point,
                    start,
                    snap: self.ui.snap,
                })
            }
            _ => {
                if let Some(h) = hit {
                    self.nav.pivot = h.point;
                }
                Some(PointerDrag::Orbit)
            }
        };
    }

    fn pointer_drag_to(&mut self, at: ViewPoint, delta: ViewPoint) {
        match self.pointer_drag {
            Some(PointerDrag::Orbit) => self
                .nav
                .orbit(-delta.0 * TURN_PER_PIXEL, -delta.1 * TURN_PER_PIXEL),
            Some(PointerDrag::Part {
                axis,
                origin,
                start,
                snap,
            }) => {
                if let Some(s) = axis_offset(origin, axis, &self.ray_at(at)) {
                    let mut offset = s - start;
                    if snap > 0.0 {
                        offset = (offset / snap).round() * snap;
                    }
                    self.review.drag_to(axis * offset);
                }
            }
            None => {}
        }
    }

    fn end_pointer_drag(&mut self) {
        if let Some(PointerDrag::Part { .. }) = self.pointer_drag.take() {
            self.review.end_drag();
        }
    }

    /// Applies the pointer and keys of this frame.
    fn apply_view_input(&mut self, input: &ViewInput, dt: f64) {
        if let Some(at) = input.double_clicked {
            self.focus(Some(at));
        } else if let Some(at) = input.clicked {
            self.pick(at);
        }
        if let Some(at) = input.drag_started {
            self.begin_pointer_drag(at, self.ui.drag_axis);
        }
        if let Some((at, delta)) = input.dragging {
            self.pointer_drag_to(at, delta);
        }
        if input.drag_stopped {
            self.end_pointer_drag();
        }
        if input.look != (0.0, 0.0) {
            self.nav.look(
                -input.look.0 * TURN_PER_PIXEL,
                -input.look.1 * TURN_PER_PIXEL,
            );
        }
        if input.pan != (0.0, 0.0) {
            self.nav
                .pan(input.pan.0, input.pan.1, f64::from(self.view.size.1));
        }
        if let Some((wheel, at)) = input.wheel {
            let toward = self
                .review
                .pick(&self.ray_at(at))
                .map_or(self.nav.pivot, |h| h.point);
            self.nav
                .dolly_toward(toward, (wheel / 400.0).clamp(-0.5, 0.5));
        }
        if input.keys != Default::default() {
            self.nav.walk(input.keys, dt);
        }
        if input.focus {
            self.focus(None);
        }
        if input.frame_all {
            self.nav.frame(&self.review.tree.bounds());
        }
    }

    /// Runs the script's current action for this frame.
    fn script_frame(&mut self) -> anyhow::Result<ScriptFrame> {
        let mut out = ScriptFrame::default();
        if self.frames_drawn < WARMUP_FRAMES {
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
                    self.review.translate_selection(DVec3::from_array(*d)),
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
                self.review.drag_to(DVec3::from_array(d.by) * t);
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
                    self.pointer_drag_to(now, (now.0 - prev.0, now.1 - prev.1));
                }
                if step == steps {
                    self.end_pointer_drag();
                    result = Some(self.selection_facts());
                }
            }
            Action::Undo => result = Some(json!({ "part_id": self.review.undo().map(|p| p.0) })),
            Action::Redo => result = Some(json!({ "part_id": self.review.redo().map(|p| p.0) })),
            Action::Focus => self.focus(None),
            Action::FrameAll => self.nav.frame(&self.review.tree.bounds()),
            Action::Culling(name) => {
                self.view.culling =
                    crate::script::culling_from_name(name).context("culling mode")?;
            }
            Action::Overlays(o) => {
                self.ui.show_stats = o.stats.unwrap_or(self.ui.show_stats);
                self.ui.show_clashes = o.clashes.unwrap_or(self.ui.show_clashes);
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
        self.runner.step += 1;
        if self.runner.step >= action.frames() {
            let mut entry = result.unwrap_or_else(|| json!({}));
            entry["action"] = json!(action.name());
            self.runner.results.push(entry);
            self.runner.index += 1;
            self.runner.step = 0;
        }
        Ok(out)
    }

    /// The selection's transform and clashes, for the report.
    fn selection_facts(&self) -> Value {
        let Some(part) = self.review.selected else {
            return json!({ "part_id": null });
        };
        let scene = &self.review.scene;
        let world = scene.part_world(part);
        json!({
            "part_id": part.0,
            "part": scene.part_name(part),
            "path": scene.part_path(part),
            "translation": world.translation.to_array(),
            "matrix3": world.matrix3.to_cols_array(),
            "clashes": self.review.report.clashes.iter().map(|c| json!({
                "a": c.a.0, "b": c.b.0, "kind": c.kind.as_str(), "distance": c.distance,
            })).collect::<Vec<_>>(),
            "move_us": self.review.timings.move_us,
            "check_ms": self.review.timings.check_ms,
        })
    }

    fn script_done(&self) -> bool {
        self.runner.index >= self.runner.actions.len()
    }

    /// Highlights the selection in the renderer when it changed.
    fn sync_highlight(&mut self) {
        let Some(renderer) = self.renderer.as_mut() else {
            return;
        };
        if self.highlighted != self.review.selected {
            if let Some(p) = self.highlighted {
                renderer.set_selected(p, false);
            }
            if let Some(p) = self.review.selected {
                renderer.set_selected(p, true);
            }
            self.highlighted = self.review.selected;
        }
    }

    /// One frame; returns whether the run is over.
    fn redraw(&mut self) -> anyhow::Result<bool> {
        let start = Instant::now();
        let dt = self
            .last_frame
            .map_or(0.0, |t| t.elapsed().as_secs_f64().min(0.25));
        self.last_frame = Some(start);
        let scripted = self.script_frame()?;

        let (Some(gfx), Some(egui_state)) = (self.gfx.as_mut(), self.egui_state.as_mut()) else {
            return Ok(false);
        };
        let raw = egui_state.take_egui_input(&gfx.window);
        let texture = gfx.view_texture;
        let mut input = ViewInput::default();
        {
            let (ui_state, review, nav, view, overlay) = (
                &mut self.ui,
                &mut self.review,
                &mut self.nav,
                &mut self.view,
                &self.overlay,
            );
            let mut output = self.egui_ctx.run_ui(raw, |ui| {
                shortcuts(ui, review);
                input = crate::ui::show(ui, ui_state, review, nav, view, overlay, texture);
            });
            egui_state
                .handle_platform_output(&gfx.window, std::mem::take(&mut output.platform_output));
            let repaint_now = output
                .viewport_output
                .get(&egui::ViewportId::ROOT)
                .is_some_and(|v| v.repaint_delay < Duration::from_millis(50));
            self.keep_drawing = repaint_now;
            self.apply_view_input(&input, dt);
            self.keep_drawing |= input.active();

            let final_frame = self.script_done()
                && self.options.automated()
                && self.frames_drawn + 1 >= u64::from(self.options.frames.unwrap_or(0));
            let screenshot = scripted.screenshot.clone().or_else(|| {
                final_frame
                    .then(|| self.options.screenshot.clone())
                    .flatten()
            });
            self.sync_highlight();
            let gfx = self.gfx.as_mut().expect("checked above");
            gfx.ensure_view_size((input.rect_px.2, input.rect_px.3));
            self.view.size = gfx.view.size;
            self.view.camera = self.nav.camera();
            let renderer = self.renderer.as_mut().expect("made with the window");
            let stats: FrameStats = match renderer.render(
                &mut self.view,
                &self.review.scene,
                &self.review.tree,
                &self.review.scene,
                gfx.view.frame_target(),
            ) {
                Ok(stats) => stats,
                Err(e) => {
                    // egui's output is dropped unpainted; say so, or it asserts.
                    output.textures_delta.clear();
                    return Err(e.into());
                }
            };
            // Occlusion culling converges over a few frames.
            self.keep_drawing |= stats.newly_visible > 0;
            let resident = renderer.geometry_pool().resident_bytes();
            let image = gfx.present(&self.egui_ctx, output, screenshot.is_some())?;
            if let (Some(path), Some(image)) = (&screenshot, image) {
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir)?;
                }
                dmu_render::save_png(&image, path)?;
            }
            let frame_ms = start.elapsed().as_secs_f64() * 1e3;
            self.frame_ms.push_back(frame_ms);
            if self.frame_ms.len() > 30 {
                self.frame_ms.pop_front();
            }
            self.overlay = Overlay {
                frame: stats,
                frame_ms,
                frame_ms_avg: self.frame_ms.iter().sum::<f64>() / self.frame_ms.len() as f64,
                model_triangles: self.review.scene.triangle_count(),
                resident_bytes: resident,
            };
            if let Some((action, step)) = scripted.label {
                self.runner.frames.push(json!({
                    "frame": self.frames_drawn,
                    "action": action,
                    "step": step,
                    "frame_ms": frame_ms,
                    "render_cpu_ms": stats.cpu_ms,
                    "render_gpu_ms": stats.gpu_ms,
                    "triangles_drawn": stats.triangles_drawn,
                    "chunks_drawn": stats.chunks_drawn,
                    "queries": stats.queries,
                    "move_us": self.review.timings.move_us,
                    "check_ms": self.review.timings.check_ms,
                    "clashes": self.review.report.clashes.len(),
                }));
            }
            self.frames_drawn += 1;
            self.view_rect = input.rect_px;
            if final_frame {
                self.facts["viewport"] = rect_json(input.rect_px);
                self.facts["camera"] = json!({
                    "eye": self.nav.eye.to_array(),
                    "forward": self.nav.forward().to_array(),
                    "fov_y_deg": self.nav.fov_y_rad.to_degrees(),
                });
                self.facts["last_frame"] = json!({
                    "triangles_drawn": stats.triangles_drawn,
                    "chunks_drawn": stats.chunks_drawn,
                    "culled_frustum": stats.culled_frustum,
                    "culled_occlusion": stats.culled_occlusion,
                });
            }
            Ok(final_frame)
        }
    }
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

/// A window rectangle (x, y, width, height) in the report.
fn rect_json(r: (u32, u32, u32, u32)) -> Value {
    json!({ "x": r.0, "y": r.1, "width": r.2, "height": r.3 })
}

/// Count, mean, median, 95th percentile and maximum of `values`.
fn summary(values: &[f64]) -> Value {
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
        let attributes = Window::default_attributes()
            .with_title("dmu")
            .with_inner_size(winit::dpi::PhysicalSize::new(
                self.options.size.0,
                self.options.size.1,
            ));
        let made = event_loop
            .create_window(attributes)
            .context("opening the window")
            .and_then(|w| Gfx::new(&self.instance, Arc::new(w), self.options.vsync));
        match made {
            Ok(gfx) => {
                let renderer = Renderer::new(
                    &gfx.device,
                    &gfx.queue,
                    &self.review.scene,
                    &self.review.tree,
                    Default::default(),
                );
                let state = egui_winit::State::new(
                    self.egui_ctx.clone(),
                    egui::ViewportId::ROOT,
                    &gfx.window,
                    Some(gfx.window.scale_factor() as f32),
                    gfx.window.theme(),
                    Some(gfx.device.limits().max_texture_dimension_2d as usize),
                );
                gfx.window.request_redraw();
                self.renderer = Some(renderer);
                self.egui_state = Some(state);
                self.gfx = Some(gfx);
            }
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
