//! The review tools' panel (section, measurement, clash list, viewpoints) and
//! what they draw over the 3D view (the gizmo, section planes and box, the
//! measurement).

use dmu_scene::MAX_WORLD_COORDINATE;
use egui::{Color32, Pos2, Rect, Stroke};
use glam::{DMat4, DVec2, DVec3};
use serde_json::{Value, json};

use crate::gizmo::{Gizmo, HandleKind};
use crate::measure::{MeasureMode, MeasureTool, Measurement};
use crate::panes::Pane;
use crate::review::Review;
use crate::section::Section;
use crate::ui::UiState;
use crate::viewpoints::Viewpoint;

/// Text fields of the tools panel.
#[derive(Debug)]
pub struct ToolFields {
    /// Path of a `dmu collide --json` report to load.
    pub clash_report: String,
    /// Name for the next saved viewpoint.
    pub viewpoint_name: String,
    /// Path of the BCF file issues go to and come from.
    pub bcf_path: String,
    /// The panel asked for this BCF action (the app carries it out: an
    /// export takes a frame per topic).
    pub bcf_request: Option<BcfRequest>,
}

/// A BCF action asked for in the panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BcfRequest {
    /// Write the clash list and the viewpoints.
    Export,
    /// Read topics as viewpoints.
    Import,
}

impl Default for ToolFields {
    fn default() -> Self {
        Self {
            clash_report: "collide.json".to_owned(),
            viewpoint_name: "view 1".to_owned(),
            bcf_path: "dmu-review.bcfzip".to_owned(),
            bcf_request: None,
        }
    }
}

/// Colour of section outlines.
const SECTION_COLOUR: Color32 = Color32::from_rgb(255, 140, 60);
/// Colour of measurements.
const MEASURE_COLOUR: Color32 = Color32::from_rgb(250, 235, 80);

/// Shows clash `index` of the list in `pane`: its two parts alone, framed,
/// their closest points measured. Its report entry.
pub fn show_clash(
    review: &mut Review,
    measure: &mut MeasureTool,
    pane: &mut Pane,
    index: usize,
) -> anyhow::Result<Value> {
    let (a, b, separation) = crate::clashes::show(review, index)?;
    pane.nav.frame(&crate::clashes::pair_bounds(review, a, b));
    pane.view.reset_visibility();
    if let Some(s) = separation {
        measure.result = Some(Measurement::Parts(a, b, s));
    }
    let c = &review.clash_list[index];
    Ok(json!({
        "a": review.scene.part_name(a),
        "b": review.scene.part_name(b),
        "kind": c.kind,
        "source": c.source,
        "distance": separation.map(|s| s.distance),
        "point_a": separation.map(|s| s.point_a.to_array()),
        "point_b": separation.map(|s| s.point_b.to_array()),
    }))
}

/// Goes back to viewpoint `v` in `pane`.
pub fn go_to(v: &Viewpoint, review: &mut Review, pane: &mut Pane) {
    v.apply(&mut pane.nav, review);
    pane.view.reset_visibility();
}

/// The tools' sections of the side panel, each collapsible.
pub fn panel(ui: &mut egui::Ui, state: &mut UiState, review: &mut Review, pane: &mut Pane) {
    ui.separator();
    egui::CollapsingHeader::new("Section")
        .default_open(true)
        .show(ui, |ui| section_panel(ui, state, review));
    egui::CollapsingHeader::new("Measure")
        .default_open(true)
        .show(ui, |ui| measure_panel(ui, state));
    egui::CollapsingHeader::new(format!("Clash list ({})", review.clash_list.len()))
        .id_salt("clash list")
        .default_open(true)
        .show(ui, |ui| clash_panel(ui, state, review, pane));
    egui::CollapsingHeader::new(format!("Viewpoints ({})", state.viewpoints.len()))
        .id_salt("viewpoints")
        .default_open(true)
        .show(ui, |ui| viewpoint_panel(ui, state, review, pane));
}

fn section_panel(ui: &mut egui::Ui, state: &mut UiState, review: &mut Review) {
    let bounds = review.tree.bounds();
    let centre = review.selected.map_or(bounds.center(), |p| {
        review.scene.part_world_bounds(p).center()
    });
    ui.horizontal(|ui| {
        ui.label("add plane");
        for (name, normal) in [("x", DVec3::X), ("y", DVec3::Y), ("z", DVec3::Z)] {
            let add = ui.button(name).on_hover_text(
                "through the selection's centre (or the model's), keeping the side below",
            );
            if add.clicked()
                && let Err(e) = review.section.add_plane(centre, -normal)
            {
                state.status = format!("{e:#}");
            }
        }
        ui.toggle_value(&mut state.section_on_face, "on face")
            .on_hover_text("the next click places a plane on the face under it");
    });
    ui.horizontal(|ui| {
        if ui
            .button("box")
            .on_hover_text("a section box around the selection (or the model)")
            .clicked()
        {
            let b = review
                .selected
                .map_or(bounds, |p| review.scene.part_world_bounds(p));
            let margin = b.extent() * 0.25 + DVec3::splat(1.0);
            if let Err(e) = review.section.set_box(b.min - margin, b.max + margin) {
                state.status = format!("{e:#}");
            }
        }
        if ui.button("clear").clicked() {
            review.section = Section::Off;
        }
    });
    let step = (bounds.extent().length() / 500.0).max(1e-3);
    match &mut review.section {
        Section::Off => {
            ui.weak("nothing is cut");
        }
        Section::Planes(planes) => {
            let mut remove = None;
            for (i, p) in planes.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!(
                        "plane {} n {}",
                        i + 1,
                        crate::ui::vec_text(p.normal)
                    ));
                    // d moves the plane along its normal: drag to slide it.
                    ui.add(
                        egui::DragValue::new(&mut p.d)
                            .speed(step)
                            .range(-MAX_WORLD_COORDINATE..=MAX_WORLD_COORDINATE)
                            .prefix("d "),
                    );
                    if ui.small_button("x").clicked() {
                        remove = Some(i);
                    }
                });
            }
            if let Some(i) = remove {
                planes.remove(i);
                if planes.is_empty() {
                    review.section = Section::Off;
                }
            }
        }
        Section::Box(b) => {
            for (label, corner) in [("min", &mut b.min), ("max", &mut b.max)] {
                ui.horizontal(|ui| {
                    ui.label(label);
                    for c in 0..3 {
                        ui.add(
                            egui::DragValue::new(&mut corner[c])
                                .speed(step)
                                .range(-MAX_WORLD_COORDINATE..=MAX_WORLD_COORDINATE),
                        );
                    }
                });
            }
            // Dragging a handle past the other keeps the box valid.
            let (lo, hi) = (b.min.min(b.max), b.min.max(b.max));
            (b.min, b.max) = (lo, hi);
        }
    }
}

fn measure_panel(ui: &mut egui::Ui, state: &mut UiState) {
    let mut mode = state.measure.mode;
    ui.horizontal(|ui| {
        ui.radio_value(&mut mode, MeasureMode::Off, "off");
        ui.radio_value(&mut mode, MeasureMode::Points, "points");
        ui.radio_value(&mut mode, MeasureMode::Parts, "parts");
        ui.radio_value(&mut mode, MeasureMode::Angle, "angle");
    });
    if mode != state.measure.mode {
        state.measure.set_mode(mode);
    }
    match (&state.measure.first, &state.measure.result) {
        (Some(first), _) => {
            ui.weak(format!(
                "first point on a {} at {}: click the second",
                first.snap.name(),
                crate::ui::vec_text(first.point)
            ));
        }
        (None, Some(m)) => {
            ui.label(egui::RichText::new(m.label()).strong());
            let (a, b) = m.ends();
            ui.weak(format!(
                "{} to {}",
                crate::ui::vec_text(a),
                crate::ui::vec_text(b)
            ));
        }
        (None, None) if mode != MeasureMode::Off => {
            ui.weak("click two points (vertices and edges snap)");
        }
        (None, None) => {}
    }
}

fn clash_panel(ui: &mut egui::Ui, state: &mut UiState, review: &mut Review, pane: &mut Pane) {
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut state.tools.clash_report).desired_width(150.0));
        if ui
            .button("load")
            .on_hover_text("add the clashes of a `dmu collide --json` report")
            .clicked()
        {
            let path = std::path::PathBuf::from(&state.tools.clash_report);
            state.status = match crate::clashes::load_report(review, &path) {
                Ok(n) => format!("{n} clashes added from {}", path.display()),
                Err(e) => format!("{e:#}"),
            };
        }
    });
    if review.clash_list.is_empty() {
        ui.weak("no clashes yet: move a part into another, or load a report");
        return;
    }
    let mut show = None;
    egui::Grid::new("clash list").striped(true).show(ui, |ui| {
        for (i, c) in review.clash_list.iter().enumerate() {
            ui.colored_label(crate::ui::clash_colour(c.kind), c.kind.as_str())
                .on_hover_text(others_text(&c.others));
            let text = format!(
                "{} · {}",
                review.scene.part_name(c.a),
                review.scene.part_name(c.b)
            );
            if ui.link(text).on_hover_text(&c.source).clicked() {
                show = Some(i);
            }
            ui.weak(format!("{:.3}", c.distance));
            ui.end_row();
        }
    });
    if let Some(i) = show
        && let Err(e) = show_clash(review, &mut state.measure, pane, i)
    {
        state.status = format!("{e:#}");
    }
}

fn viewpoint_panel(ui: &mut egui::Ui, state: &mut UiState, review: &mut Review, pane: &mut Pane) {
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut state.tools.viewpoint_name).desired_width(150.0));
        if ui.button("save").clicked() {
            let name = state.tools.viewpoint_name.clone();
            state.viewpoints.retain(|v| v.name != name);
            state
                .viewpoints
                .push(Viewpoint::capture(&name, &pane.nav, review));
            state.tools.viewpoint_name = format!("view {}", state.viewpoints.len() + 1);
        }
    });
    let mut go = None;
    for (i, v) in state.viewpoints.iter().enumerate() {
        if ui
            .link(&v.name)
            .on_hover_text(v.section.describe())
            .clicked()
        {
            go = Some(i);
        }
    }
    if let Some(i) = go {
        go_to(&state.viewpoints[i], review, pane);
    }
    ui.horizontal(|ui| {
        ui.label("BCF");
        ui.add(egui::TextEdit::singleline(&mut state.tools.bcf_path).desired_width(130.0));
        if ui
            .button("export")
            .on_hover_text("a topic per listed clash and per viewpoint, each with its snapshot")
            .clicked()
        {
            state.tools.bcf_request = Some(BcfRequest::Export);
        }
        if ui
            .button("import")
            .on_hover_text(
                "each topic's camera, selection, visibility and clipping planes as a viewpoint",
            )
            .clicked()
        {
            state.tools.bcf_request = Some(BcfRequest::Import);
        }
    });
}

/// What else a listed pair showed, for the hover text of its kind.
fn others_text(others: &[dmu_collide::FindingKind]) -> String {
    if others.is_empty() {
        return "its only kind of finding".to_owned();
    }
    let names: Vec<&str> = others.iter().map(|k| k.as_str()).collect();
    format!("also {}", names.join(", "))
}

/// Draws the gizmo, the section and the measurement over pane `pane` at
/// `rect` (`ppp`: physical pixels per point).
pub fn paint(
    painter: &egui::Painter,
    rect: Rect,
    ppp: f64,
    state: &UiState,
    review: &Review,
    pane: &Pane,
) {
    if rect.width() < 1.0 || rect.height() < 1.0 {
        return;
    }
    let camera = pane.nav.camera();
    let clip_from_world = crate::panes::clip_from_world(&pane.nav, rect);
    paint_section(painter, rect, &clip_from_world, review);
    paint_measurement(painter, rect, &clip_from_world, &state.measure);
    if let Some(part) = review.selected.filter(|_| state.show_gizmo)
        && let Some(g) = Gizmo::new(
            &camera,
            pane.view.size,
            review.scene.part_world_bounds(part).center(),
        )
    {
        paint_gizmo(painter, rect, ppp, &g, state.gizmo_hot);
    }
}

fn paint_section(painter: &egui::Painter, rect: Rect, clip_from_world: &DMat4, review: &Review) {
    let stroke = Stroke::new(1.5, SECTION_COLOUR);
    let size = review.tree.bounds().extent().length();
    let handles = review.section.handles(&review.tree.bounds());
    // The handles that slide planes and box faces.
    for &(point, dir) in &handles {
        if let Some(p) = crate::panes::project(clip_from_world, rect, point) {
            painter.circle_filled(p, 5.0, SECTION_COLOUR);
            let tip = crate::panes::project(clip_from_world, rect, point + dir * size * 0.02);
            if let Some(tip) = tip {
                painter.line_segment([p, tip], stroke);
            }
        }
    }
    match &review.section {
        Section::Off => {}
        Section::Box(b) => crate::panes::box_edges(painter, clip_from_world, rect, b, stroke),
        Section::Planes(planes) => {
            // Each plane as a square about its handle (the point nearest the
            // model's centre), a quarter of the model across.
            let half = size * 0.25;
            for (p, &(c, _)) in planes.iter().zip(&handles) {
                let u = p.normal.any_orthonormal_vector();
                let v = p.normal.cross(u);
                let corners: Vec<Option<Pos2>> =
                    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                        .iter()
                        .map(|&(a, b)| {
                            crate::panes::project(clip_from_world, rect, c + (u * a + v * b) * half)
                        })
                        .collect();
                for i in 0..4 {
                    if let (Some(a), Some(b)) = (corners[i], corners[(i + 1) % 4]) {
                        painter.line_segment([a, b], stroke);
                    }
                }
            }
        }
    }
}

fn paint_measurement(
    painter: &egui::Painter,
    rect: Rect,
    clip_from_world: &DMat4,
    measure: &MeasureTool,
) {
    let at = |p| crate::panes::project(clip_from_world, rect, p);
    if let Some(first) = measure.first
        && let Some(p) = at(first.point)
    {
        painter.circle_filled(p, 4.0, MEASURE_COLOUR);
    }
    let Some(m) = measure.result else {
        return;
    };
    let (a, b) = m.ends();
    if let (Some(pa), Some(pb)) = (at(a), at(b)) {
        painter.line_segment([pa, pb], Stroke::new(2.0, MEASURE_COLOUR));
        painter.circle_filled(pa, 3.5, MEASURE_COLOUR);
        painter.circle_filled(pb, 3.5, MEASURE_COLOUR);
        let mid = pa + (pb - pa) * 0.5;
        let galley =
            painter.layout_no_wrap(m.label(), egui::FontId::proportional(14.0), Color32::BLACK);
        let box_rect = Rect::from_min_size(mid + egui::vec2(6.0, -18.0), galley.size()).expand(3.0);
        painter.rect_filled(box_rect, 3.0, MEASURE_COLOUR);
        painter.galley(box_rect.min + egui::vec2(3.0, 3.0), galley, Color32::BLACK);
    }
}

fn paint_gizmo(
    painter: &egui::Painter,
    rect: Rect,
    ppp: f64,
    g: &Gizmo,
    hot: Option<crate::gizmo::Handle>,
) {
    let to_screen = |p: DVec2| rect.min + egui::vec2((p.x / ppp) as f32, (p.y / ppp) as f32);
    for h in crate::gizmo::Handle::ALL.into_iter().rev() {
        let [r, gr, b] = h.rgb();
        let colour = if hot == Some(h) {
            Color32::from_rgb(255, 230, 60)
        } else {
            Color32::from_rgb(r, gr, b)
        };
        let pts: Vec<Pos2> = g
            .outline(h)
            .iter()
            .filter_map(|&p| g.project(p))
            .map(to_screen)
            .collect();
        match h.kind() {
            HandleKind::Arrow => {
                if let [a, b] = pts[..] {
                    painter.line_segment([a, b], Stroke::new(3.0, colour));
                    painter.circle_filled(b, 5.0, colour);
                }
            }
            HandleKind::Plane => {
                if pts.len() >= 4 {
                    painter.add(egui::Shape::convex_polygon(
                        pts[..4].to_vec(),
                        colour.gamma_multiply(0.45),
                        Stroke::new(1.0, colour),
                    ));
                }
            }
            HandleKind::Ring => {
                painter.add(egui::Shape::line(pts, Stroke::new(2.0, colour)));
            }
        }
    }
}
