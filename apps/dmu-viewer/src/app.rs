//! The application: winit's event loop driving one frame at a time (script
//! step, panels, commands applied (the pointer's and keys' too), 3D render,
//! egui paint, present). Its parts: `apply` (where commands take effect), `pointer`
//! (drags), `script_run` (a script's actions as commands), `export` (BCF
//! files), `report` (the JSON report of an automated run).

mod apply;
mod export;
mod pointer;
mod report;
mod script_run;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use dmu_geom::Ray3d;
use dmu_render::{Culling, FrameStats, Renderer};
use dmu_scene::PartId;
use dmu_tree::EntryId;
use serde_json::Value;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::{Window, WindowId};

use crate::command::{Command, ReviewCommand, ViewPoint};
use crate::gfx::Gfx;
use crate::nav::Navigator;
use crate::panes::{Pane, PaneKind};
use crate::review::Review;
use crate::script::Action;
use crate::tools::Tools;
use crate::ui::{Overlay, PaneShow, RectPx, UiState};
use export::{Export, SNAPSHOT_SETTLE_FRAMES};
use pointer::PointerDrag;
use report::FrameTimes;
use script_run::Runner;

pub(crate) use report::{Summary, clashes_json, selection_json, to_value};

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
    pub far_field: dmu_app::farfield::FarUse,
    /// When the process started (for the first frame's time).
    pub started: Instant,
}

impl Options {
    fn automated(&self) -> bool {
        self.frames.is_some() || !self.script.is_empty()
    }
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

/// The viewer.
pub struct App {
    /// Proxies for the renderer, until it is made.
    pub proxies: Option<dmu_render::Proxies>,
    /// Where stored proxies stand for subtrees, for the streaming's wanted
    /// set (a store's level-of-detail hierarchy, under a memory budget).
    lod_cut: Option<Arc<dmu_store::LodCut>>,
    /// The store's far fields (`--far-field on|auto`), until the renderer
    /// is made.
    pub far_field_set: Option<dmu_app::farfield::FarFieldSet>,
    /// The main view's far fields, once the renderer is made.
    far: Option<crate::farfield::FarFields>,
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
    /// The review tools' state (the panels draw it, commands change it).
    tools: Tools,
    /// Save the window as PNG after this frame (a scripted screenshot).
    screenshot: Option<PathBuf>,
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
    /// When the first frame with no hole and no stand-in was done.
    first_complete_frame_ms: Option<f64>,
    /// When the first frame complete and as fine as the LOD bound asks (no
    /// node drawn coarser while its stored proxy loads) was drawn, ms since
    /// start.
    first_faithful_frame_ms: Option<f64>,
    /// Every frame's time, ms.
    frame_times: Vec<f64>,
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
        let mut main = Pane::new(
            &review.tree.bounds(),
            None,
            PaneKind::Model,
            options.culling,
        );
        main.view.options.lod_error_px = options.lod_error_px;
        main.view.options.min_pixels = options.min_pixels;
        main.view.options.target_ms = options.target_ms;
        let ui = UiState::new(review.source.as_deref());
        let tools = Tools {
            show_stats: options.stats,
            ..Tools::default()
        };
        let runner = Runner::new(options.script.clone());
        Self {
            proxies: None,
            lod_cut: None,
            far_field_set: None,
            far: None,
            options,
            instance,
            review,
            panes: vec![main],
            active: 0,
            drawn_cells: Vec::new(),
            ui,
            tools,
            screenshot: None,
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
            first_complete_frame_ms: None,
            first_faithful_frame_ms: None,
            frame_times: Vec::new(),
        }
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
            self.lod_cut = dmu_app::lod::use_proxies(
                &mut renderer,
                proxies,
                &self.review.scene,
                &self.review.tree,
                self.panes[0].view.options.lod_error_px,
            );
        }
        if let Some(set) = self.far_field_set.take() {
            // The model as loaded, before any edit: what the far fields show.
            renderer.enable_far_fields(&self.review.scene, &self.review.tree);
            self.far = Some(crate::farfield::FarFields::new(
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
            self.lod_cut.clone(),
        ));
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
        let mut input = crate::ui::ViewInput::default();
        let mut commands = Vec::new();
        self.ui.memory = self
            .streaming
            .as_ref()
            .map(crate::budget::Streaming::summary);
        {
            let (ui_state, tools, review) = (&mut self.ui, &self.tools, &self.review);
            let overlay = &self.overlay;
            let mut panes = PaneShow {
                panes: &self.panes,
                active: self.active,
                textures: &textures,
                drawn_cells: &self.drawn_cells,
            };
            let ui_start = Instant::now();
            let mut output = self.egui_ctx.run_ui(raw, |ui| {
                shortcuts(ui, &mut commands);
                let shown = crate::ui::Shown {
                    tools,
                    review,
                    overlay,
                };
                input = crate::ui::show(ui, ui_state, shown, &mut panes, &mut commands);
            });
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
            if let Some(e) = self.review.record_error.take() {
                self.ui.status = e;
            }
            for command in commands {
                self.apply(command);
            }
            self.apply_view_input(&input, dt);
            self.keep_drawing |= input.active();

            let final_frame = self.script_done()
                && self.export.is_none()
                && self.options.automated()
                && self.frames_drawn + 1 >= u64::from(self.options.frames.unwrap_or(0));
            let screenshot = self.screenshot.take().or_else(|| {
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
            if let (Some(path), Some(image)) = (&screenshot, &presented.image) {
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir)?;
                }
                dmu_render::save_png(image, path)?;
            }
            self.rebuild_far_fields(input.active())?;
            // A far field loading or to be captured again needs frames.
            self.keep_drawing |= self.far.as_ref().is_some_and(|f| f.wants_frames());
            let frame_ms = ms_since(start);
            self.frame_times.push(frame_ms);
            if self.first_frame_ms.is_none() {
                self.first_frame_ms = Some(ms_since(self.options.started));
            }
            // Complete: nothing missing and nothing stood in for.
            let complete = self
                .streaming
                .as_ref()
                .is_none_or(|s| s.last_misses() == (0, 0));
            if complete && self.first_complete_frame_ms.is_none() {
                self.first_complete_frame_ms = Some(ms_since(self.options.started));
            }
            let faithful = complete && stats.iter().all(|s| s.lod_coarse == 0);
            if faithful && self.first_faithful_frame_ms.is_none() {
                self.first_faithful_frame_ms = Some(ms_since(self.options.started));
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
            if let Some(label) = scripted {
                let times = FrameTimes {
                    frame_ms,
                    ui_ms,
                    view_ms,
                    paint_ms,
                };
                self.record_frame(label, times, &presented, &stats);
            }
            self.frames_drawn += 1;
            if final_frame {
                self.note_last_frame(&stats);
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

/// Keyboard shortcuts that act on the review (undo, redo, deselect), as
/// commands.
fn shortcuts(ui: &mut egui::Ui, commands: &mut Vec<Command>) {
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
    for (pressed, command) in [
        (undo, ReviewCommand::Undo),
        (redo, ReviewCommand::Redo),
        (escape, ReviewCommand::Select(None)),
    ] {
        if pressed {
            commands.push(command.into());
        }
    }
}

/// Milliseconds since `start`.
fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
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
