//! The report of an automated run: the model and load facts the run began
//! with, each scripted action's entry, each scripted frame's record, and the
//! run's summaries. Each part is a serde struct, so each field is defined
//! once.

use dmu_collide::Report;
use dmu_render::FrameStats;
use serde::Serialize;
use serde_json::Value;

use super::App;
use crate::gfx::{Gfx, Presented};
use crate::nav::Navigator;
use crate::panes::PaneKind;
use crate::review::Review;
use crate::ui::RectPx;

/// Count, mean, median, 95th percentile and maximum of some values (only
/// the count when there are none).
#[derive(Clone, Copy, Debug, Serialize)]
pub(crate) struct Summary {
    count: usize,
    #[serde(flatten)]
    spread: Option<Spread>,
}

#[derive(Clone, Copy, Debug, Serialize)]
struct Spread {
    mean: f64,
    median: f64,
    p95: f64,
    max: f64,
}

impl Summary {
    /// The summary of `values`.
    pub(crate) fn of(values: &[f64]) -> Self {
        let mut scratch = values.to_vec();
        let mut at = |q: f64| dmu_geom::percentile(&mut scratch, q);
        Self {
            count: values.len(),
            spread: (!values.is_empty()).then(|| Spread {
                mean: values.iter().sum::<f64>() / values.len() as f64,
                median: at(0.5),
                p95: at(0.95),
                max: at(1.0),
            }),
        }
    }

    fn median(&self) -> Option<f64> {
        self.spread.map(|s| s.median)
    }

    fn p95(&self) -> Option<f64> {
        self.spread.map(|s| s.p95)
    }
}

/// A clash in a report: part ids, kind, distance.
#[derive(Debug, Serialize)]
struct ClashFacts {
    a: u32,
    b: u32,
    kind: dmu_collide::FindingKind,
    distance: f64,
}

/// The clashes of a report.
fn clash_facts(report: &Report) -> Vec<ClashFacts> {
    report
        .clashes
        .iter()
        .map(|c| ClashFacts {
            a: c.a.0,
            b: c.b.0,
            kind: c.kind.into(),
            distance: c.distance,
        })
        .collect()
}

/// [`clash_facts`] as JSON.
pub(crate) fn clashes_json(report: &Report) -> Value {
    to_value(clash_facts(report))
}

/// The selection's transform and clashes, and the last step's timings.
#[derive(Debug, Serialize)]
struct SelectionFacts<'a> {
    part_id: Option<u32>,
    #[serde(flatten)]
    selected: Option<Selected<'a>>,
}

#[derive(Debug, Serialize)]
struct Selected<'a> {
    part: &'a str,
    path: String,
    translation: [f64; 3],
    matrix3: [f64; 9],
    clashes: Vec<ClashFacts>,
    move_us: f64,
    check_ms: f64,
}

/// The selection's transform and clashes, and the last step's timings, for
/// reports (the desktop's script steps and `--xr`'s grab alike).
pub(crate) fn selection_json(review: &Review) -> Value {
    let scene = &review.scene;
    to_value(SelectionFacts {
        part_id: review.selected.map(|p| p.0),
        selected: review.selected.map(|part| {
            let world = scene.part_world(part);
            Selected {
                part: scene.part_name(part),
                path: scene.part_path(part),
                translation: world.translation.to_array(),
                matrix3: world.matrix3.to_cols_array(),
                clashes: clash_facts(&review.report),
                move_us: review.timings.move_us,
                check_ms: review.timings.check_ms,
            }
        }),
    })
}

/// A camera in the report: eye, view direction, vertical field of view.
#[derive(Debug, Serialize)]
struct CameraFacts {
    eye: [f64; 3],
    forward: [f64; 3],
    fov_y_deg: f64,
    near: f64,
}

impl CameraFacts {
    fn of(nav: &Navigator) -> Self {
        Self {
            eye: nav.eye.to_array(),
            forward: nav.forward().to_array(),
            fov_y_deg: nav.fov_y_rad.to_degrees(),
            near: nav.near,
        }
    }
}

/// [`CameraFacts`] as JSON.
pub(super) fn camera_json(nav: &Navigator) -> Value {
    to_value(CameraFacts::of(nav))
}

/// A window rectangle in the report.
#[derive(Debug, Serialize)]
pub(super) struct Rect {
    x: u32,
    y: u32,
    width: u32,
    height: u32,
}

impl From<RectPx> for Rect {
    fn from((x, y, width, height): RectPx) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }
}

/// [`Rect`] as JSON.
pub(super) fn rect_json(r: RectPx) -> Value {
    to_value(Rect::from(r))
}

/// A pane in the report: kind, rectangle, camera, triangles drawn and, for
/// cells panes, the main pane's drawn cells.
#[derive(Debug, Serialize)]
struct PaneFacts {
    kind: &'static str,
    rect: Rect,
    camera: CameraFacts,
    triangles_drawn: u64,
    culled_frustum: u64,
    #[serde(flatten)]
    cells: Option<CellFacts>,
}

#[derive(Debug, Serialize)]
struct CellFacts {
    cells_drawn: usize,
    cells_culled: usize,
    drawn_cell_ids: Vec<u32>,
}

/// The main pane's last frame.
#[derive(Debug, Serialize)]
struct LastFrame {
    triangles_drawn: u64,
    chunks_drawn: u64,
    culled_frustum: u64,
    culled_occlusion: u64,
}

/// A frame's times, ms.
#[derive(Clone, Copy, Debug)]
pub(super) struct FrameTimes {
    /// The whole frame.
    pub frame_ms: f64,
    /// Running the panels.
    pub ui_ms: f64,
    /// Drawing the 3D views.
    pub view_ms: f64,
    /// Painting and presenting.
    pub paint_ms: f64,
}

/// A scripted frame's record.
#[derive(Debug, Serialize)]
struct FrameRecord<'a> {
    frame: u64,
    action: &'static str,
    step: u32,
    frame_ms: f64,
    ui_ms: f64,
    view_ms: f64,
    paint_ms: f64,
    painted_whole: bool,
    panels_stale: bool,
    render_cpu_ms: f64,
    render_gpu_ms: f64,
    culling: &'a str,
    triangles_drawn: u64,
    chunks_drawn: u64,
    proxies_drawn: u64,
    proxies_stale: u64,
    /// Nodes drawn coarser than the LOD bound asks while their stored
    /// proxies load.
    lod_coarse: u64,
    /// Chunk instances drawn as their boxes (under a memory budget).
    standins_drawn: u64,
    culled_section: u64,
    draw_calls: u64,
    lod_error_px: f64,
    min_pixels: f64,
    queries: u64,
    rss_bytes: Option<u64>,
    t_s: f64,
    move_us: f64,
    check_ms: f64,
    clashes: Vec<ClashFacts>,
    #[serde(skip_serializing_if = "Option::is_none")]
    memory: Option<Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    far_field: Option<Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pane_triangles_drawn: Option<Vec<u64>>,
}

/// The frame split of a run: each part's summary over the scripted frames.
#[derive(Debug, Serialize)]
struct FrameSplit {
    frame: Summary,
    ui: Summary,
    view: Summary,
    paint: Summary,
    frames_painted_whole: usize,
}

/// The geometry the tools loaded on demand.
#[derive(Debug, Serialize)]
struct ToolGeometry {
    bytes: u64,
    peak_bytes: u64,
    mesh_loads: u64,
}

/// The report entry of an action that names a part (or none): a selection,
/// a hover, an undo or redo.
#[derive(Debug, Serialize)]
pub(super) struct PartEntry {
    /// The part's id.
    pub part_id: Option<u32>,
}

/// The report entry of a search: the parts listed, first ones named.
#[derive(Debug, Serialize)]
pub(super) struct SearchEntry<'a> {
    /// Parts listed.
    pub count: usize,
    /// The first 100 of them.
    pub parts: Vec<SearchedPart<'a>>,
}

/// A part a search lists.
#[derive(Debug, Serialize)]
pub(super) struct SearchedPart<'a> {
    /// Its id.
    pub part_id: u32,
    /// Its name.
    pub name: &'a str,
    /// Its properties.
    pub properties: std::collections::BTreeMap<&'a str, &'a str>,
}

/// The report entry of a file written: a screenshot, or a BCF export
/// (with its topics).
#[derive(Debug, Serialize)]
pub(super) struct FileEntry<'a> {
    /// The file.
    pub path: &'a std::path::Path,
    /// A BCF file's topics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub topics: Option<usize>,
    /// A saved model's format.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub format: Option<dmu_store::SavedFormat>,
}

/// The report entry of a pick: the pixel, the pane and its rectangle, the
/// ray, and the hit (`{"hit": false}` for none).
#[derive(Debug, Serialize)]
pub(super) struct PickEntry {
    pub pixel: [f64; 2],
    pub viewport: Rect,
    pub pane: usize,
    pub ray: RayFacts,
    pub hit: Value,
}

/// A ray in the report.
#[derive(Debug, Serialize)]
pub(super) struct RayFacts {
    pub origin: [f64; 3],
    pub dir: [f64; 3],
}

/// A click that hit nothing.
#[derive(Debug, Serialize)]
pub(super) struct Missed {
    /// Always false.
    pub hit: bool,
}

/// A section plane placed on a face.
#[derive(Debug, Serialize)]
pub(super) struct FacePlane {
    pub point: [f64; 3],
    pub normal: [f64; 3],
    pub section: String,
}

/// The first click of a measurement.
#[derive(Debug, Serialize)]
pub(super) struct FirstPoint {
    pub first: [f64; 3],
    pub snap: &'static str,
}

/// A listed clash shown.
#[derive(Debug, Serialize)]
pub(super) struct ClashShown<'a, K: Serialize> {
    pub a: &'a str,
    pub b: &'a str,
    pub kind: &'a K,
    pub source: &'a str,
    pub distance: Option<f64>,
    pub point_a: Option<[f64; 3]>,
    pub point_b: Option<[f64; 3]>,
}

/// Clashes loaded from a report into the list.
#[derive(Debug, Serialize)]
pub(super) struct ClashesLoaded {
    pub added: usize,
    pub listed: usize,
}

/// A BCF file read.
#[derive(Debug, Serialize)]
pub(super) struct Imported {
    pub topics: usize,
    pub viewpoints: usize,
    pub skipped_topics: usize,
    pub unknown_components: usize,
    pub first: Option<FirstImported>,
}

/// The first viewpoint of a BCF file read.
#[derive(Debug, Serialize)]
pub(super) struct FirstImported {
    pub view: Value,
    pub section: Value,
    pub selected: Option<String>,
}

/// Serializes a report part (plain data: it always serializes).
pub(crate) fn to_value(part: impl Serialize) -> Value {
    serde_json::to_value(part).expect("report parts are plain data")
}

impl App {
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
        report["adapter"] = to_value(gfx.map(|g| g.adapter.clone()));
        report["window"] = to_value(gfx.map(Gfx::size));
        report["frames_drawn"] = to_value(self.frames_drawn);
        report["steps"] = Value::Array(parsed(&self.runner.results));
        let moved: Vec<u32> = self.review.moved_parts().iter().map(|p| p.0).collect();
        report["moved_parts"] = to_value(moved);
        // The run's peak, before the records are parsed back for the report.
        report["peak_rss_bytes"] = to_value(dmu_app::progress::peak_rss_bytes());
        let frames = parsed(&self.runner.frames);
        report["first_frame_ms"] = to_value(self.first_frame_ms);
        report["first_complete_frame_ms"] = to_value(self.first_complete_frame_ms);
        report["first_faithful_frame_ms"] = to_value(self.first_faithful_frame_ms);
        let times = Summary::of(&self.frame_times);
        report["median_frame_ms"] = to_value(times.median());
        report["p95_frame_ms"] = to_value(times.p95());
        // Proxies (merged subtrees, a store's level-of-detail nodes) drawn
        // over the scripted frames.
        report["lod_nodes_drawn"] = to_value(
            frames
                .iter()
                .filter_map(|f| f["proxies_drawn"].as_u64())
                .sum::<u64>(),
        );
        // Frames that drew some node coarser than the LOD bound asks.
        report["frames_lod_coarse"] = to_value(
            frames
                .iter()
                .filter(|f| f["lod_coarse"].as_u64().is_some_and(|n| n > 0))
                .count(),
        );
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
            let (bytes, peak_bytes) = g.bytes();
            report["tool_geometry"] = to_value(ToolGeometry {
                bytes,
                peak_bytes,
                mesh_loads: g.loads(),
            });
        }
        let drag: Vec<f64> = frames
            .iter()
            .filter(|f| matches!(f["action"].as_str(), Some("drag" | "mouse_drag")))
            .filter_map(|f| f["frame_ms"].as_f64())
            .collect();
        report["drag_frame_ms"] = to_value(Summary::of(&drag));
        let all = |key: &str| -> Summary {
            let values: Vec<f64> = frames.iter().filter_map(|f| f[key].as_f64()).collect();
            Summary::of(&values)
        };
        report["frame_split_ms"] = to_value(FrameSplit {
            frame: all("frame_ms"),
            ui: all("ui_ms"),
            view: all("view_ms"),
            paint: all("paint_ms"),
            frames_painted_whole: frames.iter().filter(|f| f["painted_whole"] == true).count(),
        });
        report["frames"] = Value::Array(frames);
        Ok(Some(report))
    }

    /// Keeps the record of a scripted frame (action `label`) that took
    /// `times`, presented as `presented`, whose panes drew `stats`.
    pub(super) fn record_frame(
        &mut self,
        (action, step): (&'static str, u32),
        times: FrameTimes,
        presented: &Presented,
        stats: &[FrameStats],
    ) {
        let main = &stats[0];
        let memory = self.streaming.as_ref().map(|s| {
            let renderer = self.renderer.as_mut().expect("made with the window");
            s.frame_json(renderer.geometry_pool())
        });
        let record = FrameRecord {
            frame: self.frames_drawn,
            action,
            step,
            frame_ms: times.frame_ms,
            ui_ms: times.ui_ms,
            view_ms: times.view_ms,
            paint_ms: times.paint_ms,
            painted_whole: presented.painted_whole,
            panels_stale: presented.panels_stale,
            render_cpu_ms: main.cpu_ms,
            render_gpu_ms: main.gpu_ms,
            culling: main.culling.name(),
            triangles_drawn: main.triangles_drawn,
            chunks_drawn: main.chunks_drawn,
            proxies_drawn: main.proxies_drawn,
            proxies_stale: main.proxies_stale,
            lod_coarse: main.lod_coarse,
            standins_drawn: self.streaming.as_ref().map_or(0, |s| s.last_misses().1),
            culled_section: main.culled_section,
            draw_calls: main.draw_calls,
            lod_error_px: main.lod_error_px,
            min_pixels: main.min_pixels,
            queries: main.queries,
            rss_bytes: dmu_app::progress::rss_bytes(),
            t_s: self.options.started.elapsed().as_secs_f64(),
            move_us: self.review.timings.move_us,
            check_ms: self.review.timings.check_ms,
            clashes: clash_facts(&self.review.report),
            memory,
            far_field: self.far.as_ref().map(|f| f.report().json()),
            pane_triangles_drawn: (stats.len() > 1)
                .then(|| stats.iter().map(|s| s.triangles_drawn).collect()),
        };
        let text = serde_json::to_string(&record).expect("report parts are plain data");
        self.runner.frames.push(text.into_boxed_str());
    }

    /// Notes the run's last frame, whose panes drew `stats`: the main view's
    /// rectangle, the active camera, the main pane's counts and each pane.
    pub(super) fn note_last_frame(&mut self, stats: &[FrameStats]) {
        let main = &stats[0];
        self.facts["viewport"] = rect_json(self.pane_rects[0]);
        self.facts["camera"] = camera_json(&self.panes[self.active].nav);
        self.facts["last_frame"] = to_value(LastFrame {
            triangles_drawn: main.triangles_drawn,
            chunks_drawn: main.chunks_drawn,
            culled_frustum: main.culled_frustum,
            culled_occlusion: main.culled_occlusion,
        });
        let tree = &self.review.tree;
        let panes: Vec<PaneFacts> = self
            .panes
            .iter()
            .zip(stats)
            .enumerate()
            .map(|(i, (pane, s))| PaneFacts {
                kind: pane.kind_name(),
                rect: self.pane_rects[i].into(),
                camera: CameraFacts::of(&pane.nav),
                triangles_drawn: s.triangles_drawn,
                culled_frustum: s.culled_frustum,
                cells: (pane.kind == PaneKind::Cells).then(|| {
                    let (cells_drawn, cells_culled) =
                        crate::panes::cell_counts(tree, &self.drawn_cells);
                    CellFacts {
                        cells_drawn,
                        cells_culled,
                        drawn_cell_ids: tree
                            .cell_ids()
                            .filter(|c| self.drawn_cells.get(c.0 as usize) == Some(&true))
                            .map(|c| c.0)
                            .collect(),
                    }
                }),
            })
            .collect();
        self.facts["panes"] = to_value(panes);
    }
}

/// Records kept as JSON text, parsed back.
fn parsed(records: &[Box<str>]) -> Vec<Value> {
    records
        .iter()
        .map(|r| serde_json::from_str(r).expect("a record serde_json wrote"))
        .collect()
}
