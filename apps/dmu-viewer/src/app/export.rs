//! A BCF export takes a frame per issue (each issue's view shown and its
//! snapshot cropped from the window), then writes the file and restores the
//! view; an import adds the topics as viewpoints.

use std::path::PathBuf;

use serde_json::Value;

use super::App;
use super::report::{FileEntry, FirstImported, Imported, to_value};
use crate::command::ReviewCommand;
use crate::script::Overlays;

/// A BCF export in progress.
#[derive(Debug)]
pub(super) struct Export {
    path: PathBuf,
    issues: Vec<crate::issues::Issue>,
    /// The issue whose snapshot is being taken.
    next: usize,
    /// Frames drawn for it (a snapshot waits for occlusion culling to settle).
    pub(super) frames: u32,
    /// The view to go back to, and the overlays shown, when done.
    restore: crate::viewpoints::Viewpoint,
    overlays: Overlays,
}

/// Frames an export waits at most for a view to settle before its snapshot.
pub(super) const SNAPSHOT_SETTLE_FRAMES: u32 = 8;

impl App {
    /// Starts writing the review's issues (listed clashes, saved viewpoints)
    /// to a BCF file at `path`: each issue's view is shown for a frame or a
    /// few, its snapshot taken, then the file written and the view restored.
    /// How many topics it will hold. A name not ending in `.bcfzip` is
    /// refused before anything is shown (the export wrote over the model it
    /// had open).
    pub(super) fn start_export(&mut self, path: PathBuf) -> anyhow::Result<usize> {
        dmu_app::bcf::check_output_name(&path)?;
        let nav = &self.panes[self.active].nav;
        let issues = crate::issues::issues(&self.review, &self.tools.viewpoints, nav.near);
        let n = issues.len();
        self.export = Some(Export {
            path,
            issues,
            next: 0,
            frames: 0,
            restore: crate::viewpoints::Viewpoint::capture("", nav, &self.review),
            overlays: self.tools.overlays(),
        });
        self.edit(ReviewCommand::Overlays(Overlays {
            stats: Some(false),
            clashes: Some(false),
            tools: Some(false),
        }))?;
        self.ui.status = format!("writing {n} issues…");
        Ok(n)
    }

    /// Shows the view of the issue being exported (its first frame), or ends
    /// the export when every snapshot is in.
    pub(super) fn export_view(&mut self) {
        let Some(e) = self.export.as_mut() else {
            return;
        };
        if let Some(issue) = e.issues.get(e.next) {
            // Snapshots show the model, not where the pointer rests.
            self.hovered = None;
            if e.frames == 0 {
                let view = issue.view.clone();
                self.go_to(&view);
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
        self.go_to(&e.restore);
        self.tools.set_overlays(e.overlays);
        match written {
            Ok(()) => {
                self.ui.status = format!("{} issues written to {}", topics.len(), e.path.display());
                self.facts["bcf_export"] = to_value(FileEntry {
                    path: &e.path,
                    topics: Some(topics.len()),
                    format: None,
                });
            }
            Err(err) if self.options.automated() => self.error = Some(err.into()),
            Err(err) => self.ui.status = format!("{err:#}"),
        }
    }

    /// The active pane's pixels of `window` as the snapshot of the issue
    /// being exported.
    pub(super) fn export_snapshot(&mut self, window: &image::RgbaImage) -> anyhow::Result<()> {
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
    pub(super) fn import_bcf(&mut self, path: &std::path::Path) -> anyhow::Result<Value> {
        let topics = dmu_app::bcf::read_bcfzip(path, self.options.unit.per_metre())?;
        let imported = crate::issues::import(&self.review, &topics, self.pivot_distance())?;
        for v in &imported.viewpoints {
            self.tools.save_viewpoint(v.clone());
        }
        let first = imported.viewpoints.first().cloned();
        if let Some(v) = &first {
            self.go_to(v);
        }
        self.ui.status = format!(
            "{} viewpoints from {} ({} topics skipped, {} parts not in the model)",
            imported.viewpoints.len(),
            path.display(),
            imported.skipped_topics,
            imported.unknown_components
        );
        Ok(to_value(Imported {
            topics: topics.len(),
            viewpoints: imported.viewpoints.len(),
            skipped_topics: imported.skipped_topics,
            unknown_components: imported.unknown_components,
            first: first.map(|v| FirstImported {
                view: v.json(),
                section: v.section.json(),
                selected: v
                    .selected
                    .map(|p| self.review.scene.part_name(p).to_owned()),
            }),
        }))
    }
}
