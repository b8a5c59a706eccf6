//! The panels: product structure with search, properties and moves of the
//! selection, clashes, settings, the stats overlay, and the 3D view's area,
//! whose pointer and key input is handed back to the app as [`ViewInput`].

use std::path::PathBuf;

use dmu_render::{Culling, FrameStats};
use dmu_scene::{NodeId, PartId, Scene};
use egui::{Color32, Pos2, Rect, RichText, Sense, Vec2};
use glam::DVec3;

pub use crate::command::ViewPoint;
use crate::command::{Command, ReviewCommand as R, ViewCommand as V};
use crate::nav::{Keys, Motion, Navigator, Preset};
use crate::panes::{MAX_PANES, Pane, PaneKind};
use crate::review::Review;
use crate::script::{Axis, Overlays};
use crate::settings::Occlusion;
use crate::tools::Tools;
use crate::tools_ui::{clash_colour, vec_text};

/// Children listed under one node of the structure tree before "… more".
const CHILDREN_SHOWN: usize = 500;

/// A rectangle in window pixels: x, y, width, height.
pub type RectPx = (u32, u32, u32, u32);

/// What the pointer and keys did to the 3D panes this frame. Points are in the
/// pixels of the pane the pointer acts in, [`ViewInput::pane`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewInput {
    /// Each pane's rectangle in window pixels.
    pub rects_px: Vec<RectPx>,
    /// The pane pressed, dragged or scrolled in this frame (it becomes the
    /// active pane, which keys and settings act on).
    pub pane: Option<usize>,
    /// A primary click (not a drag).
    pub clicked: Option<ViewPoint>,
    /// A primary double-click.
    pub double_clicked: Option<ViewPoint>,
    /// A primary drag started here.
    pub drag_started: Option<ViewPoint>,
    /// The pointer while a primary drag goes on, and its motion this frame.
    pub dragging: Option<(ViewPoint, ViewPoint)>,
    /// The primary drag ended.
    pub drag_stopped: bool,
    /// Secondary-button drag motion (mouse look), pixels.
    pub look: ViewPoint,
    /// Middle-button drag motion (pan), pixels.
    pub pan: ViewPoint,
    /// Wheel over the view (positive: toward the scene) and where the pointer is.
    pub wheel: Option<(f64, ViewPoint)>,
    /// Walking keys.
    pub keys: Keys,
    /// Frame the selection (F), or everything (Home).
    pub focus: bool,
    /// Frame everything.
    pub frame_all: bool,
    /// The pane the pointer is over and where (for the hover tint).
    pub hover: Option<(usize, ViewPoint)>,
    /// Shift is held: drags move freely, without snapping.
    pub free: bool,
}

impl ViewInput {
    /// Whether anything is moving the camera or a part (keep drawing).
    pub fn active(&self) -> bool {
        self.dragging.is_some()
            || self.look != (0.0, 0.0)
            || self.pan != (0.0, 0.0)
            || self.keys != Keys::default()
    }
}

/// Counters of the last frame for the overlay.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    /// The renderer's stats of the last frame.
    pub frame: FrameStats,
    /// Wall time of the last whole frame (UI, 3D, present), ms.
    pub frame_ms: f64,
    /// Average wall time over recent frames, ms.
    pub frame_ms_avg: f64,
    /// Of the last frame: running the panels (egui), ms.
    pub ui_ms: f64,
    /// Drawing the 3D views, waiting for the GPU included, ms.
    pub view_ms: f64,
    /// Painting the panels and views into the window and presenting, ms.
    pub paint_ms: f64,
    /// Whether the whole window was painted (else the panels were copied
    /// from their last paint).
    pub painted_whole: bool,
    /// Triangles in the model (instances counted).
    pub model_triangles: u64,
    /// Chunk geometry on the GPU, bytes.
    pub resident_bytes: u64,
    /// The main view's far fields (`--far-field on|auto`).
    pub far: Option<crate::farfield::FarReport>,
}

/// State of the panels between frames.
#[derive(Debug)]
pub struct UiState {
    /// Under a memory budget, what the top bar says of it (`None`: the whole
    /// model is resident).
    pub memory: Option<String>,
    search: String,
    /// Parts matching `search` (computed when it changes).
    matches: Vec<PartId>,
    matches_for: String,
    /// The typed translation.
    pub move_by: [f64; 3],
    /// The typed rotation angle, degrees.
    pub rotate_deg: f64,
    /// Where the record button records the session.
    record_path: String,
    /// Panel fields of the review tools.
    pub fields: crate::tools_ui::ToolFields,
    save_path: String,
    /// A message for the status line.
    pub status: String,
    /// Open the structure tree down to this part next frame.
    pub reveal: Option<PartId>,
}

impl UiState {
    /// Panels for a model loaded from `source` (the default save path derives from it).
    pub fn new(source: Option<&std::path::Path>) -> Self {
        let save_path = match source {
            // STEP and IFC are read, never written: saves go to a store beside.
            Some(p) if dmu_store::cad::is_cad(p) => p.with_extension("dmu").display().to_string(),
            Some(p) => p.display().to_string(),
            None => "dmu-review.glb".to_owned(),
        };
        Self {
            memory: None,
            search: String::new(),
            matches: Vec::new(),
            matches_for: String::new(),
            move_by: [0.0; 3],
            rotate_deg: 90.0,
            record_path: "dmu-session.jsonl".to_owned(),
            fields: Default::default(),
            save_path,
            status: String::new(),
            reveal: None,
        }
    }
}

/// What the panels show and do not change: the review, its tools, the
/// last frame's counters. The panels change them through commands.
#[derive(Clone, Copy, Debug)]
pub struct Shown<'a> {
    /// The review tools' state.
    pub tools: &'a Tools,
    /// The review.
    pub review: &'a Review,
    /// The last frame's counters.
    pub overlay: &'a Overlay,
}

/// What the 3D panes show this frame.
#[derive(Debug)]
pub struct PaneShow<'a> {
    /// The panes (1 to [`MAX_PANES`]); the panels read them, commands
    /// change them.
    pub panes: &'a [Pane],
    /// The pane keys and settings act on.
    pub active: usize,
    /// The egui texture of each pane's image.
    pub textures: &'a [egui::TextureId],
    /// Cells the main pane drew last frame (by cell id), for cells panes.
    pub drawn_cells: &'a [bool],
}

/// Lays out one frame of the panels and the 3D panes; what the panels'
/// buttons ask for goes into `commands`.
pub fn show(
    ui: &mut egui::Ui,
    state: &mut UiState,
    shown: Shown<'_>,
    panes: &mut PaneShow<'_>,
    commands: &mut Vec<Command>,
) -> ViewInput {
    let Shown {
        tools,
        review,
        overlay,
    } = shown;
    top_bar(ui, state, shown, panes, commands);
    egui::Panel::left("structure")
        .default_size(280.0)
        .show(ui, |ui| structure_panel(ui, state, review, commands));
    egui::Panel::right("properties")
        .default_size(320.0)
        .show(ui, |ui| {
            // Long paths wrap instead of widening the panel (and shrinking the view).
            ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Wrap);
            egui::ScrollArea::vertical().show(ui, |ui| {
                why_section(ui, panes.panes, overlay);
                properties_panel(ui, state, shown, commands);
                crate::tools_ui::panel(ui, &mut state.fields, tools, review, commands);
            });
        });
    egui::Panel::bottom("status").show(ui, |ui| {
        ui.horizontal(|ui| {
            ui.label(&state.status);
            ui.separator();
            ui.add(
                egui::Label::new(
                    RichText::new(
                        "click: pick · drag: orbit · right-drag: look · middle-drag: pan · \
                         wheel: zoom · WASD/QE: walk · double-click: focus · F: frame · \
                         Ctrl+Z/Y: undo/redo · gizmo: drag arrows, squares, rings \
                         (Shift: no snapping)",
                    )
                    .weak(),
                )
                .truncate(),
            );
        });
    });
    egui::CentralPanel::no_frame()
        .show(ui, |ui| view_area(ui, shown, panes))
        .inner
}

fn top_bar(
    ui: &mut egui::Ui,
    state: &mut UiState,
    Shown { tools, review, .. }: Shown<'_>,
    show: &mut PaneShow<'_>,
    commands: &mut Vec<Command>,
) {
    egui::Panel::top("top").show(ui, |ui| {
        ui.horizontal(|ui| {
            ui.strong("dmu");
            ui.label(match &review.source {
                Some(p) => p.display().to_string(),
                None => "built-in plant".to_owned(),
            });
            ui.separator();
            ui.label("Save to");
            ui.add(egui::TextEdit::singleline(&mut state.save_path).desired_width(220.0));
            if ui
                .button("Save")
                .on_hover_text(".glb/.gltf: export glTF; .dmu: save the edits into the store")
                .clicked()
            {
                let path = PathBuf::from(state.save_path.trim());
                commands.push(R::Save(path).into());
            }
            ui.separator();
            record_button(ui, state, review, commands);
        });
        ui.horizontal(|ui| {
            let panes = show.panes;
            let mut count = panes.len();
            egui::ComboBox::from_label("panes")
                .selected_text(count.to_string())
                .show_ui(ui, |ui| {
                    for n in 1..=MAX_PANES {
                        ui.selectable_value(&mut count, n, n.to_string());
                    }
                })
                .response
                .on_hover_text("2: + top · 3: + cells of the main view · 4: + front");
            if count != panes.len() {
                commands.push(V::Panes(count).into());
            }
            let active = show.active.min(panes.len() - 1);
            let Pane { nav, view, .. } = &panes[active];
            let mut culling = view.culling;
            egui::ComboBox::from_label("culling")
                .selected_text(culling.name())
                .show_ui(ui, |ui| {
                    for c in Culling::ALL.into_iter().chain([Culling::Auto]) {
                        ui.selectable_value(&mut culling, c, c.name());
                    }
                });
            if culling != view.culling {
                commands.push(V::Culling(culling).into());
            }
            let mut occlusion = Occlusion::of(view);
            egui::ComboBox::from_label("occlusion")
                .selected_text(occlusion.name())
                .show_ui(ui, |ui| {
                    for o in Occlusion::ALL {
                        ui.selectable_value(&mut occlusion, o, o.name());
                    }
                })
                .response
                .on_hover_text("auto: queries only where they save more than they cost");
            if occlusion != Occlusion::of(view) {
                commands.push(V::Occlusion(occlusion).into());
            }
            let (mut min_pixels, mut lod_error_px) =
                (view.options.min_pixels, view.options.lod_error_px);
            ui.add(
                egui::DragValue::new(&mut min_pixels)
                    .range(0.0..=64.0)
                    .speed(0.1)
                    .prefix("min px "),
            )
            .on_hover_text("cells covering fewer pixels across are not drawn");
            if min_pixels != view.options.min_pixels {
                commands.push(V::MinPixels(min_pixels).into());
            }
            ui.add(
                egui::DragValue::new(&mut lod_error_px)
                    .range(0.0..=16.0)
                    .speed(0.05)
                    .prefix("LOD px "),
            )
            .on_hover_text(
                "chunks are drawn simplified where the difference is at most this many \
                 pixels (0: exact)",
            );
            if lod_error_px != view.options.lod_error_px {
                commands.push(V::LodErrorPx(lod_error_px).into());
            }
            match &state.memory {
                Some(text) => ui.label(text).on_hover_text(BUDGET_HOVER),
                None => ui.label(memory_text(review)).on_hover_text(MEMORY_HOVER),
            };
            ui.separator();
            for preset in Preset::ALL {
                if ui.button(preset.name()).clicked() {
                    commands.push(V::Preset(preset).into());
                }
            }
            ui.separator();
            let (mut motion, mut speed) = (nav.motion, nav.speed_factor);
            ui.selectable_value(&mut motion, Motion::Walk, "walk");
            ui.selectable_value(&mut motion, Motion::Fly, "fly");
            if motion != nav.motion {
                commands.push(V::Motion(motion).into());
            }
            ui.add(
                egui::Slider::new(&mut speed, 0.01..=100.0)
                    .logarithmic(true)
                    .text("speed"),
            );
            if speed != nav.speed_factor {
                commands.push(V::Speed(speed).into());
            }
            let mut stats = tools.show_stats;
            if ui.checkbox(&mut stats, "stats").changed() {
                commands.push(overlays(Overlays {
                    stats: Some(stats),
                    ..Overlays::default()
                }));
            }
        });
    });
}

/// Why the memory budget is shown but not set.
const MEMORY_HOVER: &str = "The viewer loads the whole model (a .dmu store too) and \
    uploads every chunk once: no budget is enforced. Open a .dmu store with \
    --memory-budget to stream its chunks within a budget.";

/// What the memory setting under a budget means.
const BUDGET_HOVER: &str = "--memory-budget: the whole process stays within it. Chunks \
    stream in from the store as the view needs them; one not loaded yet is drawn as its \
    box (with --stand-ins none it is a hole).";

/// The memory setting, read-only: what the model takes.
fn memory_text(review: &Review) -> String {
    let kind = match review.source.as_deref().and_then(|p| p.extension()) {
        Some(e) if e.eq_ignore_ascii_case("dmu") => "store",
        _ => "model",
    };
    format!("memory: whole {kind} resident (no budget)")
}

/// Starts or stops recording the session to the typed path.
fn record_button(
    ui: &mut egui::Ui,
    state: &mut UiState,
    review: &Review,
    commands: &mut Vec<Command>,
) {
    match &review.recorder {
        Some(rec) => {
            let label = format!("stop recording ({} moves)", rec.lines());
            if ui
                .button(label)
                .on_hover_text(rec.path().display().to_string())
                .clicked()
            {
                state.status = format!("recorded {}", rec.path().display());
                commands.push(R::Record(None).into());
            }
        }
        None => {
            ui.add(egui::TextEdit::singleline(&mut state.record_path).desired_width(160.0));
            if ui
                .button("record")
                .on_hover_text("record every move as JSON Lines for `dmu collide --record`")
                .clicked()
            {
                let path = PathBuf::from(state.record_path.trim());
                commands.push(R::Record(Some(path)).into());
            }
        }
    }
}

impl UiState {
    /// Types `text` into the structure's search, as a user does: the parts
    /// it lists.
    pub fn search(&mut self, scene: &Scene, text: &str) -> &[PartId] {
        self.search = text.to_owned();
        self.matches_for = text.trim().to_lowercase();
        self.matches = scene.search_parts(&self.matches_for);
        &self.matches
    }
}

fn structure_panel(
    ui: &mut egui::Ui,
    state: &mut UiState,
    review: &Review,
    commands: &mut Vec<Command>,
) {
    ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Truncate);
    ui.heading("Product structure");
    ui.horizontal(|ui| {
        ui.label("search");
        ui.text_edit_singleline(&mut state.search);
    });
    let query = state.search.trim().to_lowercase();
    if query.is_empty() {
        egui::ScrollArea::vertical()
            .auto_shrink([false, false])
            .show(ui, |ui| {
                let reveal = state.reveal.take().map(|p| ancestors(&review.scene, p));
                let top: Vec<NodeId> = review.scene.children(NodeId(0)).collect();
                for child in top {
                    node_ui(ui, review, child, reveal.as_deref(), commands);
                }
            });
        return;
    }
    if state.matches_for != query {
        state.matches = review.scene.search_parts(&query);
        state.matches_for = query;
    }
    ui.weak(format!("{} parts", state.matches.len()));
    let row = ui.text_style_height(&egui::TextStyle::Body);
    egui::ScrollArea::vertical()
        .auto_shrink([false, false])
        .show_rows(ui, row, state.matches.len(), |ui, rows| {
            for &part in &state.matches[rows] {
                part_label(ui, review, part, commands);
            }
        });
}

/// The nodes from the root's child down to `part`'s node.
fn ancestors(scene: &Scene, part: PartId) -> Vec<NodeId> {
    let mut at = Some(scene.part(part).node);
    let mut path = Vec::new();
    while let Some(n) = at {
        path.push(n);
        at = scene.node(n).parent;
    }
    path
}

fn part_label(
    ui: &mut egui::Ui,
    review: &Review,
    part: PartId,
    commands: &mut Vec<Command>,
) -> egui::Response {
    let scene = &review.scene;
    let mut text = RichText::new(scene.part_name(part));
    if scene.part(part).hidden {
        text = text.weak().italics();
    }
    let response = ui.selectable_label(review.selected == Some(part), text);
    if response.clicked() {
        commands.push(R::Select(Some(part)).into());
    }
    response.on_hover_text(review.scene.part_path(part))
}

fn node_ui(
    ui: &mut egui::Ui,
    review: &Review,
    node: NodeId,
    reveal: Option<&[NodeId]>,
    commands: &mut Vec<Command>,
) {
    let children: Vec<NodeId> = review.scene.children(node).collect();
    let part = review.scene.node(node).part;
    let on_path = reveal.is_some_and(|r| r.contains(&node));
    if children.is_empty() {
        let response = match part {
            Some(p) => part_label(ui, review, p, commands),
            None => ui.label(review.scene.node_name(node)),
        };
        if on_path {
            response.scroll_to_me(Some(egui::Align::Center));
        }
        return;
    }
    let id = ui.make_persistent_id(("structure node", node.0));
    let mut collapsing =
        egui::collapsing_header::CollapsingState::load_with_default_open(ui.ctx(), id, false);
    if on_path {
        collapsing.set_open(true);
    }
    collapsing
        .show_header(ui, |ui| match part {
            Some(p) => {
                part_label(ui, review, p, commands);
            }
            None => {
                ui.label(format!(
                    "{} ({})",
                    review.scene.node_name(node),
                    children.len()
                ));
            }
        })
        .body(|ui| {
            for &child in children.iter().take(CHILDREN_SHOWN) {
                node_ui(ui, review, child, reveal, commands);
            }
            if children.len() > CHILDREN_SHOWN {
                ui.weak(format!(
                    "… {} more (search by name, GlobalId or class)",
                    children.len() - CHILDREN_SHOWN
                ));
                // The part being revealed is shown even past the limit.
                if let Some(&c) = children[CHILDREN_SHOWN..]
                    .iter()
                    .find(|c| reveal.is_some_and(|r| r.contains(c)))
                {
                    node_ui(ui, review, c, reveal, commands);
                }
            }
        });
}

/// "Why": the choices made by measurement in each pane, with the figures
/// behind them (the same words as `dmu render --explain`).
fn why_section(ui: &mut egui::Ui, panes: &[Pane], overlay: &Overlay) {
    egui::CollapsingHeader::new("Why")
        .default_open(false)
        .show(ui, |ui| {
            for (i, pane) in panes.iter().enumerate() {
                let view = &pane.view;
                let last = view.last_stats();
                let why = match &last.auto {
                    Some(a) => dmu_app::explain::auto_now(last.culling, a),
                    None => dmu_app::explain::occlusion_now(view.culling, &last.occlusion),
                };
                ui.label(format!("pane {}: {why}", i + 1));
            }
            if let Some(auto) = overlay.far.as_ref().and_then(|f| f.auto.as_ref()) {
                ui.label(format!("pane 1: {auto}"));
            }
        });
}

/// Pushes `command` when `clicked`.
fn on_click(clicked: bool, commands: &mut Vec<Command>, command: impl Into<Command>) {
    if clicked {
        commands.push(command.into());
    }
}

/// A command showing or hiding overlays.
fn overlays(o: Overlays) -> Command {
    R::Overlays(o).into()
}

fn properties_panel(
    ui: &mut egui::Ui,
    state: &mut UiState,
    Shown { tools, review, .. }: Shown<'_>,
    commands: &mut Vec<Command>,
) {
    ui.vertical(|ui| {
        ui.heading("Selection");
        let Some(part) = review.selected else {
            ui.weak("nothing selected: click a part, or pick one in the structure");
            history_row(ui, review, commands);
            return;
        };
        let scene = &review.scene;
        let mesh = scene.part_mesh(part);
        let world = scene.part_world(part);
        let bounds = scene.part_world_bounds(part);
        let (scale, rotation, translation) = world.to_scale_rotation_translation();
        let (axis, angle) = rotation.to_axis_angle();
        egui::Grid::new("properties")
            .num_columns(2)
            .striped(true)
            .show(ui, |ui| {
                let mut row = |k: &str, v: String| {
                    ui.add(egui::Label::new(k).wrap_mode(egui::TextWrapMode::Extend));
                    ui.label(v);
                    ui.end_row();
                };
                row("name", scene.part_name(part).to_owned());
                row("id", format!("#{}", part.0));
                row("path", scene.part_path(part));
                row("triangles", mesh.triangle_count().to_string());
                row("chunks", mesh.chunks.len().to_string());
                row("bounds min", vec_text(bounds.min));
                row("bounds max", vec_text(bounds.max));
                row("size", vec_text(bounds.extent()));
                row("translation", vec_text(translation));
                row(
                    "rotation",
                    format!("{:.3}° about {}", angle.to_degrees(), vec_text(axis)),
                );
                row("scale", vec_text(scale));
                for (key, value) in scene.node_properties(scene.part(part).node) {
                    row(key, value.to_owned());
                }
            });
        ui.horizontal(|ui| {
            on_click(ui.button("hide").clicked(), commands, R::Hide(part));
            on_click(ui.button("isolate").clicked(), commands, R::Isolate(part));
            on_click(ui.button("show all").clicked(), commands, R::ShowAll);
        });
        ui.separator();
        ui.heading("Move");
        ui.horizontal(|ui| {
            for (v, name) in state.move_by.iter_mut().zip(["dx ", "dy ", "dz "]) {
                ui.add(egui::DragValue::new(v).speed(1.0).prefix(name));
            }
            let by = DVec3::from_array(state.move_by);
            on_click(ui.button("move").clicked(), commands, R::Translate(by));
        });
        ui.horizontal(|ui| {
            ui.add(
                egui::DragValue::new(&mut state.rotate_deg)
                    .speed(1.0)
                    .suffix("°"),
            );
            ui.label("about");
            for a in [Axis::X, Axis::Y, Axis::Z] {
                let clicked = ui
                    .button(a.name())
                    .on_hover_text("turn about this world axis through the box centre")
                    .clicked();
                let (axis, degrees) = (a.unit(), state.rotate_deg);
                on_click(clicked, commands, R::Rotate { axis, degrees });
            }
        });
        ui.horizontal(|ui| {
            ui.label("drag along");
            let mut axis = tools.drag_axis;
            ui.radio_value(&mut axis, None, "off");
            for a in [Axis::X, Axis::Y, Axis::Z] {
                ui.radio_value(&mut axis, Some(a), a.name());
            }
            if axis != tools.drag_axis {
                commands.push(R::DragAxis(axis).into());
            }
        });
        ui.horizontal(|ui| {
            let mut gizmo = tools.show_gizmo;
            if ui
                .checkbox(&mut gizmo, "gizmo")
                .on_hover_text("arrows move along an axis, squares in a plane, rings turn")
                .changed()
            {
                commands.push(R::ShowGizmo(gizmo).into());
            }
            let (mut step, mut degrees) = (tools.snap, tools.snap_deg);
            ui.add(
                egui::DragValue::new(&mut step)
                    .range(0.0..=*crate::gizmo::Snap::STEPS.end())
                    .prefix("snap ")
                    .suffix(" mm"),
            );
            ui.add(
                egui::DragValue::new(&mut degrees)
                    .range(0.0..=360.0)
                    .suffix("°"),
            )
            .on_hover_text("turns snap to this angle; hold Shift while dragging to move freely");
            if (step, degrees) != (tools.snap, tools.snap_deg) {
                commands.push(
                    R::Snap {
                        step: Some(step),
                        degrees: Some(degrees),
                    }
                    .into(),
                );
            }
        });
        history_row(ui, review, commands);
        ui.separator();
        ui.heading("Collision");
        ui.horizontal(|ui| {
            let mut live = review.live_collision;
            if ui.checkbox(&mut live, "live").changed() {
                commands.push(R::LiveCollision(live).into());
            }
            let mut clearance = review.settings.clearance;
            let changed = ui
                .add(
                    egui::DragValue::new(&mut clearance)
                        .range(0.0..=f64::MAX)
                        .prefix("clearance "),
                )
                .changed();
            on_click(changed, commands, R::Clearance(clearance));
            let mut markers = tools.show_clashes;
            if ui.checkbox(&mut markers, "markers").changed() {
                commands.push(overlays(Overlays {
                    clashes: Some(markers),
                    ..Overlays::default()
                }));
            }
        });
        ui.weak(format!(
            "{} clashes · {} part pairs tested · {:.2} ms",
            review.report.clashes.len(),
            review.report.part_pairs_tested,
            review.timings.check_ms
        ));
        for clash in &review.report.clashes {
            let other = if clash.a == part { clash.b } else { clash.a };
            ui.horizontal(|ui| {
                ui.colored_label(clash_colour(clash.kind), clash.kind.as_str());
                if ui
                    .link(review.scene.part_name(other))
                    .on_hover_text(review.scene.part_path(other))
                    .clicked()
                {
                    commands.push(V::Reveal(other).into());
                }
                ui.weak(format!("{:.3}", clash.distance));
            });
        }
    });
}

fn history_row(ui: &mut egui::Ui, review: &Review, commands: &mut Vec<Command>) {
    let (undo, redo) = review.history();
    ui.horizontal(|ui| {
        let button = |n: usize, name: &str| egui::Button::new(format!("{name} ({n})"));
        let clicked = ui.add_enabled(undo > 0, button(undo, "undo")).clicked();
        on_click(clicked, commands, R::Undo);
        let clicked = ui.add_enabled(redo > 0, button(redo, "redo")).clicked();
        on_click(clicked, commands, R::Redo);
    });
}

fn view_area(ui: &mut egui::Ui, shown: Shown<'_>, show: &PaneShow<'_>) -> ViewInput {
    let Shown {
        tools,
        review,
        overlay,
    } = shown;
    let (area, _) = ui.allocate_exact_size(ui.available_size(), Sense::hover());
    let ppp = f64::from(ui.ctx().pixels_per_point());
    let px = |v: f32| (f64::from(v) * ppp).round().max(0.0) as u32;
    let rects = crate::panes::layout(area, show.panes.len());
    let mut input = ViewInput {
        rects_px: rects
            .iter()
            .map(|r| (px(r.min.x), px(r.min.y), px(r.width()), px(r.height())))
            .collect(),
        ..ViewInput::default()
    };
    for (i, (&rect, pane)) in rects.iter().zip(show.panes.iter()).enumerate() {
        let response = ui.interact(
            rect,
            ui.scope_id().with(("dmu pane", i)),
            Sense::click_and_drag(),
        );
        let painter = ui.painter_at(rect);
        painter.image(
            show.textures[i],
            rect,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            Color32::WHITE,
        );
        pane_input(ui, &response, rect, ppp, i, &mut input);
        if pane.kind == PaneKind::Cells {
            crate::panes::paint_cells(
                &painter,
                rect,
                pane,
                &show.panes[0],
                &review.tree,
                show.drawn_cells,
            );
        }
        if tools.show_clashes {
            clash_markers(&painter, rect, review, &pane.nav);
        }
        if tools.show_tools {
            crate::tools_ui::paint(&painter, rect, ppp, tools, review, pane);
        }
        if show.panes.len() > 1 {
            let stroke = if i == show.active {
                egui::Stroke::new(1.5, Color32::from_rgb(90, 160, 255))
            } else {
                egui::Stroke::new(1.0, Color32::from_gray(70))
            };
            painter.rect_stroke(rect, 0.0, stroke, egui::StrokeKind::Inside);
            painter.text(
                rect.min + Vec2::new(8.0, 6.0),
                egui::Align2::LEFT_TOP,
                format!("{} {}", i + 1, pane.kind_name()),
                egui::FontId::proportional(13.0),
                Color32::from_gray(220),
            );
        }
        if tools.show_stats && i == show.active {
            stats_overlay(&painter, rect, overlay, review);
        }
    }
    if !ui.ctx().egui_wants_keyboard_input() {
        ui.input(|i| {
            let axis = |plus: egui::Key, minus: egui::Key| {
                f64::from(u8::from(i.key_down(plus))) - f64::from(u8::from(i.key_down(minus)))
            };
            input.keys = Keys {
                forward: axis(egui::Key::W, egui::Key::S),
                right: axis(egui::Key::D, egui::Key::A),
                up: axis(egui::Key::E, egui::Key::Q),
                boost: if i.modifiers.shift { 4.0 } else { 1.0 },
            };
            input.focus = i.key_pressed(egui::Key::F);
            input.frame_all = i.key_pressed(egui::Key::Home);
        });
        if input.keys.forward == 0.0 && input.keys.right == 0.0 && input.keys.up == 0.0 {
            input.keys = Keys::default();
        }
    }
    input
}

/// The pointer's doings in pane `index` (at `rect`) go into `input`; a pane
/// pressed, dragged or scrolled becomes `input.pane`.
fn pane_input(
    ui: &egui::Ui,
    response: &egui::Response,
    rect: Rect,
    ppp: f64,
    index: usize,
    input: &mut ViewInput,
) {
    let to_view = |p: Pos2| {
        (
            f64::from(p.x - rect.min.x) * ppp,
            f64::from(p.y - rect.min.y) * ppp,
        )
    };
    if let Some(p) = response.hover_pos() {
        input.hover = Some((index, to_view(p)));
    }
    let pointer = response.interact_pointer_pos().or(response.hover_pos());
    let primary = egui::PointerButton::Primary;
    let mut acted = false;
    if response.double_clicked() {
        input.double_clicked = pointer.map(to_view);
        acted = true;
    } else if response.clicked() {
        input.clicked = pointer.map(to_view);
        acted = true;
    }
    if response.drag_started_by(primary) {
        let origin = ui.input(|i| i.pointer.press_origin()).or(pointer);
        input.drag_started = origin.map(to_view);
        acted = true;
    }
    let delta = response.drag_delta();
    let delta = (f64::from(delta.x) * ppp, f64::from(delta.y) * ppp);
    if response.dragged_by(primary)
        && let Some(p) = pointer
    {
        input.dragging = Some((to_view(p), delta));
        acted = true;
    }
    if response.drag_stopped_by(primary) {
        input.drag_stopped = true;
        acted = true;
    }
    input.free |= ui.input(|i| i.modifiers.shift);
    if response.dragged_by(egui::PointerButton::Secondary) {
        input.look = delta;
        acted = true;
    }
    if response.dragged_by(egui::PointerButton::Middle) {
        input.pan = delta;
        acted = true;
    }
    if response.hovered() {
        let wheel = ui.input(|i| i.smooth_scroll_delta.y);
        if wheel != 0.0
            && let Some(p) = response.hover_pos()
        {
            input.wheel = Some((f64::from(wheel), to_view(p)));
            acted = true;
        }
    }
    if acted {
        input.pane = Some(index);
    }
}

/// Marks each clash point of the selection on the view.
fn clash_markers(painter: &egui::Painter, rect: Rect, review: &Review, nav: &Navigator) {
    if review.report.clashes.is_empty() || rect.width() < 1.0 || rect.height() < 1.0 {
        return;
    }
    let clip_from_world = crate::panes::clip_from_world(nav, rect);
    for clash in &review.report.clashes {
        let Some(at) = crate::panes::project(&clip_from_world, rect, clash.point) else {
            continue;
        };
        let colour = clash_colour(clash.kind);
        painter.circle_stroke(at, 7.0, egui::Stroke::new(2.0, colour));
        painter.circle_filled(at, 2.0, colour);
    }
}

fn stats_overlay(painter: &egui::Painter, rect: Rect, o: &Overlay, review: &Review) {
    let s = &o.frame;
    let text = format!(
        "frame {:.1} ms (avg {:.1}, {:.0} fps)\n\
         ui {:.1} · 3D {:.1} · paint {:.1} ms ({})\n\
         3D: {} culling · cpu {:.1} ms · gpu {:.1} ms\n\
         triangles {} drawn / {} in frustum / {} model\n\
         chunks {} drawn · proxies {} ({} stale) · {} queries in {} rounds · LOD {:.2} px · min {:.1} px\n\
         culled: frustum {} · coverage {} · occlusion {} · hidden {} · section {}\n\
         occlusion {} (cost {:.2} ms, saves {:.2} ms)\n\
         GPU geometry {:.1} MiB\n\
         move {:.0} µs · collision {:.2} ms",
        o.frame_ms,
        o.frame_ms_avg,
        1000.0 / o.frame_ms_avg.max(1e-3),
        o.ui_ms,
        o.view_ms,
        o.paint_ms,
        if o.painted_whole {
            "whole window"
        } else {
            "views only"
        },
        s.culling.name(),
        s.cpu_ms,
        s.gpu_ms,
        s.triangles_drawn,
        s.triangles_in_frustum,
        o.model_triangles,
        s.chunks_drawn,
        s.proxies_drawn,
        s.proxies_stale,
        s.queries,
        s.rounds,
        s.lod_error_px,
        s.min_pixels,
        s.culled_frustum,
        s.culled_coverage,
        s.culled_occlusion,
        s.hidden,
        s.culled_section,
        if s.occlusion.enabled { "on" } else { "off" },
        s.occlusion.cost_ms,
        s.occlusion.saved_ms,
        o.resident_bytes as f64 / (1u64 << 20) as f64,
        review.timings.move_us,
        review.timings.check_ms,
    );
    let text = match &o.far {
        Some(far) => format!("{text}\n{}", far.overlay_text()),
        None => text,
    };
    let font = egui::FontId::monospace(12.0);
    let galley = painter.layout_no_wrap(text, font, Color32::from_gray(230));
    let at = Pos2::new(rect.max.x - galley.size().x - 12.0, rect.min.y + 8.0);
    painter.rect_filled(
        Rect::from_min_size(at - Vec2::splat(6.0), galley.size() + Vec2::splat(12.0)),
        4.0,
        Color32::from_black_alpha(170),
    );
    painter.galley(at, galley, Color32::WHITE);
}

#[cfg(test)]
mod tests {
    use super::UiState;
    use std::path::Path;

    #[test]
    fn a_step_or_ifc_model_saves_to_a_store_beside_it_never_over_it() {
        let save = |p: &str| UiState::new(Some(Path::new(p))).save_path;
        assert_eq!(save("site/house.ifc"), "site/house.dmu");
        assert_eq!(save("cad/pump.STEP"), "cad/pump.dmu");
        assert_eq!(save("cad/pump.stp"), "cad/pump.dmu");
        assert_eq!(save("plant.glb"), "plant.glb");
        assert_eq!(UiState::new(None).save_path, "dmu-review.glb");
    }
}
