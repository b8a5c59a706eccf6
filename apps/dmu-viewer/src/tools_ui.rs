//! The review tools' panel (section, measurement, clash list, viewpoints) and
//! what they draw over the 3D view (the gizmo, section planes and box, the
//! measurement).

use std::path::PathBuf;

use dmu_collide::FindingKind;
use dmu_scene::MAX_WORLD_COORDINATE;
use egui::{Color32, Pos2, Rect, Stroke};
use glam::{DMat4, DVec2, DVec3};

use crate::command::{Command, ReviewCommand as R, ViewCommand as V};
use crate::gizmo::{Gizmo, HandleKind};
use crate::measure::{MeasureMode, MeasureTool};
use crate::panes::Pane;
use crate::review::Review;
use crate::section::Section;
use crate::tools::Tools;

/// Text fields of the tools panel.
#[derive(Debug)]
pub struct ToolFields {
    /// Path of a `dmu collide --json` report to load.
    pub clash_report: String,
    /// Name for the next saved viewpoint.
    pub viewpoint_name: String,
    /// Path of the BCF file issues go to and come from.
    pub bcf_path: String,
}

impl Default for ToolFields {
    fn default() -> Self {
        Self {
            clash_report: "collide.json".to_owned(),
            viewpoint_name: "view 1".to_owned(),
            bcf_path: "dmu-review.bcfzip".to_owned(),
        }
    }
}

/// Colour of section outlines.
const SECTION_COLOUR: Color32 = Color32::from_rgb(255, 140, 60);
/// Colour of measurements.
const MEASURE_COLOUR: Color32 = Color32::from_rgb(250, 235, 80);

/// The tools' sections of the side panel, each collapsible.
/// The buttons ask for commands (into `commands`).
pub fn panel(
    ui: &mut egui::Ui,
    fields: &mut ToolFields,
    tools: &Tools,
    review: &Review,
    commands: &mut Vec<Command>,
) {
    ui.separator();
    egui::CollapsingHeader::new("Section")
        .default_open(true)
        .show(ui, |ui| section_panel(ui, tools, review, commands));
    egui::CollapsingHeader::new("Measure")
        .default_open(true)
        .show(ui, |ui| measure_panel(ui, &tools.measure, commands));
    egui::CollapsingHeader::new(format!("Clash list ({})", review.clash_list.len()))
        .id_salt("clash list")
        .default_open(true)
        .show(ui, |ui| clash_panel(ui, fields, review, commands));
    egui::CollapsingHeader::new(format!("Viewpoints ({})", tools.viewpoints.len()))
        .id_salt("viewpoints")
        .default_open(true)
        .show(ui, |ui| viewpoint_panel(ui, fields, tools, commands));
}

fn section_panel(ui: &mut egui::Ui, tools: &Tools, review: &Review, commands: &mut Vec<Command>) {
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
            if add.clicked() {
                let (point, normal) = (centre, -normal);
                commands.push(R::SectionPlane { point, normal }.into());
            }
        }
        let mut on_face = tools.section_on_face;
        if ui
            .toggle_value(&mut on_face, "on face")
            .on_hover_text("the next click places a plane on the face under it")
            .changed()
        {
            commands.push(R::SectionOnFace(on_face).into());
        }
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
            let (min, max) = (b.min - margin, b.max + margin);
            commands.push(R::SectionBox { min, max }.into());
        }
        if ui.button("clear").clicked() {
            commands.push(R::Section(Section::Off).into());
        }
    });
    let step = (bounds.extent().length() / 500.0).max(1e-3);
    // The fields edit a copy, which a command sets when it differs.
    let mut section = review.section.clone();
    match &mut section {
        Section::Off => {
            ui.weak("nothing is cut");
        }
        Section::Planes(planes) => {
            let mut remove = None;
            for (i, p) in planes.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!("plane {} n {}", i + 1, vec_text(p.normal)));
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
                    section = Section::Off;
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
    if section != review.section {
        commands.push(R::Section(section).into());
    }
}

fn measure_panel(ui: &mut egui::Ui, measure: &MeasureTool, commands: &mut Vec<Command>) {
    let mut mode = measure.mode;
    ui.horizontal(|ui| {
        ui.radio_value(&mut mode, MeasureMode::Off, "off");
        ui.radio_value(&mut mode, MeasureMode::Points, "points");
        ui.radio_value(&mut mode, MeasureMode::Parts, "parts");
        ui.radio_value(&mut mode, MeasureMode::Angle, "angle");
    });
    if mode != measure.mode {
        commands.push(R::MeasureMode(mode).into());
    }
    match (&measure.first, &measure.result) {
        (Some(first), _) => {
            ui.weak(format!(
                "first point on a {} at {}: click the second",
                first.snap.name(),
                vec_text(first.point)
            ));
        }
        (None, Some(m)) => {
            ui.label(egui::RichText::new(m.label()).strong());
            let (a, b) = m.ends();
            ui.weak(format!("{} to {}", vec_text(a), vec_text(b)));
        }
        (None, None) if mode != MeasureMode::Off => {
            ui.weak("click two points (vertices and edges snap)");
        }
        (None, None) => {}
    }
}

fn clash_panel(
    ui: &mut egui::Ui,
    fields: &mut ToolFields,
    review: &Review,
    commands: &mut Vec<Command>,
) {
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut fields.clash_report).desired_width(150.0));
        if ui
            .button("load")
            .on_hover_text("add the clashes of a `dmu collide --json` report")
            .clicked()
        {
            let path = PathBuf::from(&fields.clash_report);
            commands.push(R::LoadClashes(path).into());
        }
    });
    if review.clash_list.is_empty() {
        ui.weak("no clashes yet: move a part into another, or load a report");
        return;
    }
    let mut show = None;
    egui::Grid::new("clash list").striped(true).show(ui, |ui| {
        for (i, c) in review.clash_list.iter().enumerate() {
            ui.colored_label(clash_colour(c.kind), c.kind.as_str())
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
    if let Some(i) = show {
        commands.push(V::ShowClash(i).into());
    }
}

fn viewpoint_panel(
    ui: &mut egui::Ui,
    fields: &mut ToolFields,
    tools: &Tools,
    commands: &mut Vec<Command>,
) {
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut fields.viewpoint_name).desired_width(150.0));
        if ui.button("save").clicked() {
            let name = fields.viewpoint_name.clone();
            let new = !tools.viewpoints.iter().any(|v| v.name == name);
            let saved = tools.viewpoints.len() + usize::from(new);
            commands.push(V::SaveViewpoint(name).into());
            fields.viewpoint_name = format!("view {}", saved + 1);
        }
    });
    for v in &tools.viewpoints {
        if ui
            .link(&v.name)
            .on_hover_text(v.section.describe())
            .clicked()
        {
            commands.push(V::GoTo(v.name.clone()).into());
        }
    }
    ui.horizontal(|ui| {
        ui.label("BCF");
        ui.add(egui::TextEdit::singleline(&mut fields.bcf_path).desired_width(130.0));
        let path = PathBuf::from(&fields.bcf_path);
        if ui
            .button("export")
            .on_hover_text("a topic per listed clash and per viewpoint, each with its snapshot")
            .clicked()
        {
            commands.push(V::ExportBcf(path.clone()).into());
        }
        if ui
            .button("import")
            .on_hover_text(
                "each topic's camera, selection, visibility and clipping planes as a viewpoint",
            )
            .clicked()
        {
            commands.push(V::ImportBcf(path).into());
        }
    });
}

/// What else a listed pair showed, for the hover text of its kind.
fn others_text(others: &[FindingKind]) -> String {
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
    tools: &Tools,
    review: &Review,
    pane: &Pane,
) {
    if rect.width() < 1.0 || rect.height() < 1.0 {
        return;
    }
    let camera = pane.nav.camera();
    let clip_from_world = crate::panes::clip_from_world(&pane.nav, rect);
    paint_section(painter, rect, &clip_from_world, review);
    paint_measurement(painter, rect, &clip_from_world, &tools.measure);
    if let Some(part) = review.selected.filter(|_| tools.show_gizmo)
        && let Some(g) = Gizmo::new(
            &camera,
            pane.view.size,
            review.scene.part_world_bounds(part).center(),
        )
    {
        paint_gizmo(painter, rect, ppp, &g, tools.gizmo_hot);
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

/// Marker colour of a kind of finding (an impact as a hard clash).
pub fn clash_colour(kind: impl Into<FindingKind>) -> Color32 {
    match kind.into() {
        FindingKind::Hard | FindingKind::Impact => Color32::from_rgb(255, 40, 40),
        FindingKind::Contact => Color32::from_rgb(255, 200, 0),
        FindingKind::Soft => Color32::from_rgb(80, 180, 255),
    }
}

/// A vector as the panels write it.
pub(crate) fn vec_text(v: DVec3) -> String {
    format!("{:.3}, {:.3}, {:.3}", v.x, v.y, v.z)
}
