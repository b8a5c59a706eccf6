//! Far fields in the main 3D view (`--far-field on|auto`): each frame the
//! far field of the eye's viewpoint cell, read from the store
//! ([`FarFieldSet`]), drawn beyond its cull box (always, or where `auto`
//! times that it pays); far fields that moved parts made stale are captured
//! again in the background, one a frame at most, once the view is calm.
//!
//! Design choices:
//! - A capture draws into [`dmu_render::CAPTURE_FORMAT`] with the renderer's
//!   pipelines, and the viewer's renderer draws in the window's format (often
//!   BGRA): so rebuilds have a renderer of their own, made on the first one
//!   with the options `dmu farfield build` captures with (chunk levels, no
//!   proxies, no tints), and a rebuilt far field is made as a built one is.
//!   It costs a second GPU copy of the chunks the captures draw; one code
//!   path whatever the window's format.
//! - Calm: no drag of a part, the gizmo or a section, no camera moved by keys
//!   or the pointer, and the same moved parts as the frame before, so a run of
//!   edits is captured once, after the last. The nearest stale far field to
//!   the eye goes first.
//! - Rebuilt far fields replace the set's copies in memory
//!   ([`FarFieldSet::replace`]); the store keeps those of the poses it was
//!   built from (a saved edit makes them refused on the next open, until
//!   `dmu farfield build` runs again).
//! - Under `--memory-budget` far fields are refused: captures draw
//!   everything outside a cull box, which a skeleton has not loaded.

use std::collections::BTreeSet;
use std::sync::Arc;

use dmu_app::farfield::{FarAuto, FarFieldSet, FarUse};
use dmu_render::{FarField, FrameStats, Renderer, RendererOptions};
use glam::DVec3;
use serde::Serialize;
use serde_json::Value;

use crate::app::to_value;

use crate::review::Review;

/// Why the main view's last frame drew no far field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NotDrawn {
    /// The index has no far field for the eye's cell.
    NoCell,
    /// The eye's cell's far field is being read.
    Loading,
    /// `auto` chose to draw without (or timed a frame without).
    ByAuto,
    /// Handed to the renderer, which found it does not serve the eye.
    NotServing,
}

/// The far-field facts of the last frame, for the stats overlay, the "Why"
/// section and the report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FarReport {
    /// `on` or `auto`.
    pub mode: &'static str,
    /// The main view drew a far field.
    pub drawn: bool,
    /// Why it did or did not, in words.
    pub why: String,
    /// Triangles of the far field's depth meshes drawn.
    pub triangles: u64,
    /// Parts drawn as geometry because they moved (or were left out of the
    /// far field).
    pub moved_parts: u64,
    /// Far fields in memory that moved parts made stale (after this frame's
    /// rebuild, if any).
    pub stale: u64,
    /// Far fields captured again so far.
    pub rebuilds: u64,
    /// The last rebuild's capture and meshing time, ms.
    pub last_rebuild_ms: Option<f64>,
    /// With `auto`: its choice now, in one sentence (the overlay's, not
    /// the frame record's).
    #[serde(skip)]
    pub auto: Option<String>,
}

impl FarReport {
    /// The overlay's lines.
    pub fn overlay_text(&self) -> String {
        let drawn = if self.drawn {
            format!(
                "far field in pane 1 ({}): drawn, {} triangles",
                self.mode, self.triangles
            )
        } else {
            format!(
                "far field in pane 1 ({}): not drawn, {}",
                self.mode, self.why
            )
        };
        let rebuilt = match self.last_rebuild_ms {
            Some(ms) => format!("{} rebuilt, last {ms:.1} ms", self.rebuilds),
            None => "none rebuilt".to_owned(),
        };
        format!(
            "{drawn} · {} moved parts as geometry\nfar fields: {} stale · {rebuilt}",
            self.moved_parts, self.stale
        )
    }

    /// The frame's record in the report.
    pub fn json(&self) -> Value {
        to_value(self)
    }
}

/// The main view's far fields.
pub struct FarFields {
    mode: FarUse,
    set: FarFieldSet,
    auto: FarAuto,
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The renderer captures are made with, from the first rebuild.
    capture: Option<Renderer>,
    /// The moved parts as of the last frame.
    moved: BTreeSet<u32>,
    /// This frame's time goes to `auto`.
    timed: bool,
    /// Why this frame draws none, as far as known before it is drawn.
    not_drawn: Option<NotDrawn>,
    /// Frames of the main view that drew one.
    frames_with_far_field: u64,
    report: FarReport,
}

impl std::fmt::Debug for FarFields {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FarFields")
            .field("mode", &self.mode)
            .field("report", &self.report)
            .finish_non_exhaustive()
    }
}

impl FarFields {
    /// The far fields of `set`, drawn as `mode` says (not [`FarUse::Off`]),
    /// rebuilt on `device`.
    pub fn new(set: FarFieldSet, mode: FarUse, device: wgpu::Device, queue: wgpu::Queue) -> Self {
        debug_assert!(mode != FarUse::Off, "no far fields are made for off");
        Self {
            mode,
            set,
            auto: FarAuto::default(),
            device,
            queue,
            capture: None,
            moved: BTreeSet::new(),
            timed: false,
            not_drawn: None,
            frames_with_far_field: 0,
            report: FarReport {
                mode: mode.name(),
                ..FarReport::default()
            },
        }
    }

    /// The last frame's facts.
    pub fn report(&self) -> &FarReport {
        &self.report
    }

    /// Whether frames should go on while the window has no input: the eye's
    /// cell's far field is loading, or one is stale (captured again on a
    /// frame once the view is calm).
    pub fn wants_frames(&self) -> bool {
        self.report.stale > 0 || self.not_drawn == Some(NotDrawn::Loading)
    }

    /// The far field the main view draws this frame with its eye at `eye`
    /// (asking the loader for the cell and its neighbours); a far field that
    /// failed to load is an error.
    pub fn for_frame(&mut self, eye: DVec3) -> anyhow::Result<Option<Arc<FarField>>> {
        self.timed = false;
        let Some(field) = self.set.for_eye(eye)? else {
            self.not_drawn = Some(if self.set.has_cell_at(eye) {
                NotDrawn::Loading
            } else {
                NotDrawn::NoCell
            });
            return Ok(None);
        };
        self.not_drawn = None;
        let draw = match self.mode {
            FarUse::Off => false,
            FarUse::On => true,
            FarUse::Auto => {
                self.timed = true;
                self.auto.next_frame()
            }
        };
        if !draw {
            self.not_drawn = Some(NotDrawn::ByAuto);
        }
        Ok(draw.then_some(field))
    }

    /// Takes the main view's stats of the frame numbered `frame`: `auto`'s
    /// timing, and what was drawn.
    pub fn after_render(&mut self, stats: &FrameStats, frame: u64) {
        if self.timed {
            // What `auto` weighs: the frame without its uploads.
            let frame = usize::try_from(frame).unwrap_or(usize::MAX);
            self.auto.after(stats.cpu_ms - stats.upload_ms, frame);
        }
        if stats.far_field {
            self.frames_with_far_field += 1;
        }
        let why = self.why_text(stats.far_field);
        let auto = (self.mode == FarUse::Auto).then(|| self.auto.now());
        let r = &mut self.report;
        r.drawn = stats.far_field;
        r.triangles = stats.far_field_triangles;
        r.moved_parts = stats.far_field_moved_parts;
        r.why = why;
        r.auto = auto;
    }

    /// Why the frame drew a far field (`drawn`) or not, in words.
    fn why_text(&self, drawn: bool) -> String {
        if drawn {
            return "the eye's cell has one".to_owned();
        }
        match self.not_drawn.unwrap_or(NotDrawn::NotServing) {
            NotDrawn::NoCell => "none built for this cell".to_owned(),
            NotDrawn::Loading => "loading".to_owned(),
            NotDrawn::NotServing => "the cell's far field does not serve the eye".to_owned(),
            NotDrawn::ByAuto => match self.auto.last() {
                Some((off, on)) if !self.auto.uses_far() => {
                    format!("off by auto ({on:.1} ms a frame with it, {off:.1} ms without)")
                }
                _ => "off by auto while it times frames without".to_owned(),
            },
        }
    }

    /// Counts the far fields in memory that `moved` (the renderer's moved
    /// parts) made stale and, when the view is `calm` and the moved parts
    /// are those of the last frame, captures the one nearest `eye` again
    /// and puts it in the set in place of the stale one.
    pub fn rebuild(
        &mut self,
        review: &Review,
        moved: BTreeSet<u32>,
        calm: bool,
        eye: DVec3,
    ) -> anyhow::Result<()> {
        let settled = moved == self.moved;
        self.moved = moved;
        let stale: Vec<Arc<FarField>> = self
            .set
            .loaded()
            .into_iter()
            .map(|(_, f)| f)
            .filter(|f| f.is_stale(&self.moved))
            .collect();
        self.report.stale = stale.len() as u64;
        let nearest = stale.iter().min_by(|a, b| {
            (a.center - eye)
                .length()
                .total_cmp(&(b.center - eye).length())
        });
        let Some(old) = nearest.filter(|_| calm && settled) else {
            return Ok(());
        };
        let (scene, tree) = (&review.scene, &review.tree);
        let (device, queue) = (&self.device, &self.queue);
        let renderer = self.capture.get_or_insert_with(|| {
            Renderer::new(
                device,
                queue,
                scene,
                tree,
                RendererOptions {
                    lod_levels: true,
                    ..Default::default()
                },
            )
        });
        let options = self.set.index().capture_options();
        let (field, _) = renderer.capture_far_field(
            scene,
            tree,
            scene,
            dmu_render::FarFieldRegion {
                cell: old.cell,
                near_box: old.near_box,
                excluded: &self.moved,
            },
            &options,
        )?;
        let ms = field.build_ms;
        anyhow::ensure!(
            self.set.replace(Arc::new(field)).is_some(),
            "a far field captured again matches no cell of the store's index"
        );
        self.report.rebuilds += 1;
        self.report.last_rebuild_ms = Some(ms);
        self.report.stale -= 1;
        Ok(())
    }

    /// The run's far-field facts for the report.
    pub fn json(&self) -> Value {
        let index = self.set.index();
        to_value(FarFacts {
            mode: self.mode.name(),
            cells: index.cells.len(),
            cell_size: index.cell_size,
            resolution: index.resolution,
            frames_with_far_field: self.frames_with_far_field,
            rebuilds: self.report.rebuilds,
            last_rebuild_ms: self.report.last_rebuild_ms,
            stale: self.report.stale,
            auto_changes: self.auto.changes(),
        })
    }
}

/// The run's far-field facts ([`FarFields::json`]).
#[derive(Debug, Serialize)]
struct FarFacts<'a> {
    mode: &'static str,
    cells: usize,
    cell_size: f64,
    resolution: u32,
    frames_with_far_field: u64,
    rebuilds: u64,
    last_rebuild_ms: Option<f64>,
    stale: u64,
    auto_changes: &'a [String],
}
