//! `dmu tradeoffs`: what accuracy costs in time. Each knob of the program is
//! swept over its settings on one model, each setting measured for time and
//! for its error against an exact reference, and the whole written as a
//! Markdown report with one plot per knob.
//!
//! Design choices:
//! - **One knob, one entry.** A section (`render`, `far_field`, `loading`,
//!   `tree`, `collide`, `numerics`) measures and returns [`Knob`]s; the
//!   report, the JSON and the plots are written once for all of them, so a
//!   new knob (the renderer's LOD error) is one more entry in its section's
//!   list. Far fields are a section of their own (a setting there is a capture
//!   per viewpoint cell, not a view's culling) whose knobs the report shows
//!   under rendering.
//! - **Errors against a reference, never against the previous setting**: each
//!   knob names its reference (culling `none`, a fine continuous sweep, a brute
//!   force pick, an analytic distance), and where one setting *is* the
//!   reference its error must be 0 ([`Knob::exact_setting`], checked by the
//!   tests).
//! - **The reading is computed from the figures**, not written by hand, so a
//!   regenerated report cannot contradict its plots.

mod collide;
mod farfield;
mod loading;
mod numerics;
mod plot;
mod render;
mod report;
mod stereo;
mod tree;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

pub use report::{Machine, Run, reading, write_report};

/// The built-in plant's size, as the other commands' default (`--plant-triangles 2M`).
pub const DEFAULT_PLANT_TRIANGLES: u64 = 2_000_000;

/// How big the sweeps are: `--quick` for CI (small models, few points), the
/// full run for the committed report.
#[derive(Clone, Copy, Debug)]
pub struct Scale {
    pub quick: bool,
    /// Triangles of the built-in plant.
    pub plant_triangles: u64,
    /// Rendered image size and frames of the camera path.
    pub render_size: (u32, u32),
    pub render_frames: usize,
    /// Viewpoint cells the far-field knobs capture (each at every setting).
    pub far_field_cells: usize,
    /// Frames of the residency walks.
    pub walk_frames: usize,
    /// Rays picked per tree setting (each checked against a brute force).
    pub rays: usize,
    /// Timed part moves per tree setting.
    pub moves: usize,
    /// Boxes per side of the collision grid (the same in both runs, so they
    /// compare).
    pub collide_grid: u32,
    /// Repetitions of each numerics measurement (for its time).
    pub numerics_reps: usize,
}

impl Scale {
    /// The two runs share the model, the image size, the camera path and the
    /// collision grid, so a knob measured in both agrees within noise; the
    /// full run has more settings, rays, repetitions and far-field cells.
    pub fn new(quick: bool, plant_triangles: Option<u64>) -> Self {
        let plant_triangles = plant_triangles.unwrap_or(DEFAULT_PLANT_TRIANGLES);
        if quick {
            Self {
                quick,
                plant_triangles,
                render_size: (320, 180),
                render_frames: 8,
                far_field_cells: 2,
                walk_frames: 600,
                rays: 100,
                moves: 1000,
                collide_grid: 6,
                numerics_reps: 200,
            }
        } else {
            Self {
                quick,
                plant_triangles,
                render_size: (320, 180),
                render_frames: 8,
                far_field_cells: 4,
                walk_frames: 600,
                rays: 1000,
                moves: 1000,
                collide_grid: 6,
                numerics_reps: 20_000,
            }
        }
    }
}

/// One measured setting of a knob.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    /// The setting, in the knob's unit (categories: their index).
    pub setting: f64,
    /// The setting's name where it is a category (a load order).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// What the setting costs, milliseconds (the knob says of what).
    pub time_ms: f64,
    /// Its error against the knob's reference, in `error_unit`.
    pub error: f64,
    pub error_unit: String,
    /// Further figures of the setting (bytes loaded, steps a second), by name.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub extra: BTreeMap<String, f64>,
}

impl Point {
    pub fn new(setting: f64, time_ms: f64, error: f64, error_unit: &str) -> Self {
        Self {
            setting,
            label: None,
            time_ms,
            error,
            error_unit: error_unit.to_owned(),
            extra: BTreeMap::new(),
        }
    }

    pub fn label(mut self, label: &str) -> Self {
        self.label = Some(label.to_owned());
        self
    }

    pub fn extra(mut self, name: &str, value: f64) -> Self {
        self.extra.insert(name.to_owned(), value);
        self
    }

    /// The setting as the report prints it.
    pub fn setting_text(&self) -> String {
        self.label
            .clone()
            .unwrap_or_else(|| report::number(self.setting))
    }
}

/// One knob swept: its settings, what each costs and what it gets wrong.
#[derive(Clone, Debug, Serialize)]
pub struct Knob {
    /// Section of the report: rendering, loading, tree, collision, numerics.
    pub section: &'static str,
    pub name: String,
    /// Unit of the setting (empty for categories).
    pub unit: String,
    /// What else the reader must know of the settings (what 0 means, the
    /// conditions held fixed); may be empty.
    pub note: String,
    /// What the error is measured against.
    pub reference: String,
    /// What `time_ms` measures.
    pub time: String,
    /// Unit of the error.
    pub error_unit: String,
    /// The setting that is the reference itself (its error must be 0).
    pub exact_setting: Option<f64>,
    /// Plot the setting on a log scale.
    #[serde(skip)]
    pub log_x: bool,
    /// Plot the error on a log scale.
    #[serde(skip)]
    pub log_error: bool,
    pub points: Vec<Point>,
}

impl Knob {
    /// The file name of its plot: the name made safe.
    pub fn plot_file(&self) -> String {
        let slug: String = format!("{} {}", self.section, self.name)
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() {
                    c.to_ascii_lowercase()
                } else {
                    '-'
                }
            })
            .collect();
        let mut out = String::new();
        for part in slug.split('-').filter(|s| !s.is_empty()) {
            if !out.is_empty() {
                out.push('-');
            }
            out.push_str(part);
        }
        format!("{out}.svg")
    }
}

/// What every section is handed.
#[derive(Debug)]
pub struct Bench<'a> {
    pub scale: Scale,
    /// The model (loaded once) and its name.
    pub scene: &'a dmu_scene::Scene,
    /// How it was opened (the tree section opens it again at other chunk sizes).
    pub model_args: &'a dmu_app::load::ModelArgs,
    /// A scratch folder (stores written for the loading and numerics sections).
    pub scratch: &'a Path,
    pub progress: &'a indicatif::ProgressBar,
}

/// A section's result: its knobs, or why it could not run.
pub type SectionResult = anyhow::Result<Vec<Knob>>;

/// Every section in report order, each with its name; the adapter's name
/// comes back from the rendering section.
pub fn run_sections(bench: &Bench<'_>) -> (Vec<Knob>, Vec<(String, String)>, Option<String>) {
    let mut knobs = Vec::new();
    let mut skipped = Vec::new();
    let mut adapter = None;
    let mut keep = |name: &str, result: SectionResult| match result {
        Ok(k) => knobs.extend(k),
        Err(e) => skipped.push((name.to_owned(), format!("{e:#}"))),
    };
    bench.progress.set_message("rendering");
    keep(
        "rendering",
        render::run(bench).map(|(k, name)| {
            adapter = Some(name);
            k
        }),
    );
    bench.progress.set_message("far fields");
    keep("far fields", farfield::run(bench));
    bench.progress.set_message("loading");
    keep("loading", loading::run(bench));
    bench.progress.set_message("loading, rendered");
    keep("loading, rendered", loading::run_predicted(bench));
    bench.progress.set_message("tree");
    keep("tree", tree::run(bench));
    bench.progress.set_message("collision");
    keep("collision", collide::run(bench));
    bench.progress.set_message("numerics");
    keep("numerics", numerics::run(bench));
    (knobs, skipped, adapter)
}

/// Steps of the progress bar: one per measured setting (per knob in numerics).
pub fn steps(quick: bool) -> u64 {
    render::steps(quick)
        + farfield::steps(quick)
        + loading::steps(quick)
        + tree::steps(quick)
        + collide::steps(quick)
        + numerics::steps()
}

/// Milliseconds of `f`, and its result.
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed().as_secs_f64() * 1e3)
}
