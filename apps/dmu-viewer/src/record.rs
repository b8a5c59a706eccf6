//! Recording a manipulation session in the collision issue's JSON Lines format
//! (docs/record-format.md, written by dmu-collide's `RecordLine`, beside its
//! reader), so `dmu collide --record` replays it and finds the clashes the
//! viewer showed.
//!
//! Every placement of a part (a drag step, a typed move or rotation, an undo
//! or a redo) is one line and one step: its absolute world pose, the time in
//! seconds since the recording began, the part by its full assembly path (or
//! `#id` where the path does not name it alone).

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use dmu_collide::{RecordLine, record_part_name};
use dmu_scene::{PartId, Scene};
use glam::DAffine3;

/// Times of consecutive lines differ by at least this (seconds), so every
/// placement stays a step of its own even when two fall in one clock tick.
const MIN_STEP_S: f64 = 1e-6;

/// An open recording.
#[derive(Debug)]
pub struct Recorder {
    path: PathBuf,
    out: BufWriter<File>,
    start: Instant,
    last_t: Option<f64>,
    lines: u64,
    /// How each part recorded so far is named in the file.
    names: HashMap<PartId, String>,
}

impl Recorder {
    /// Starts a recording into a new file `path`; an existing file is refused
    /// (a recording never overwrites a record, a store or anything else).
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .with_context(|| {
                format!(
                    "creating the recording {} (it must be a new file)",
                    path.display()
                )
            })?;
        Ok(Self {
            path: path.to_owned(),
            out: BufWriter::new(file),
            start: Instant::now(),
            last_t: None,
            lines: 0,
            names: HashMap::new(),
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Lines written so far (one per step).
    pub fn lines(&self) -> u64 {
        self.lines
    }

    /// Records `part` placed at `world` as one step, flushed at once so the
    /// file is complete whenever the viewer stops.
    pub fn pose(&mut self, scene: &Scene, part: PartId, world: DAffine3) -> anyhow::Result<()> {
        let now = self.start.elapsed().as_secs_f64();
        let t = match self.last_t {
            Some(last) if now < last + MIN_STEP_S => last + MIN_STEP_S,
            _ => now,
        };
        self.last_t = Some(t);
        let name = self
            .names
            .entry(part)
            .or_insert_with(|| record_part_name(scene, part));
        let line = RecordLine::new(t, name.clone(), world);
        line.write(&mut self.out)
            .and_then(|()| self.out.flush())
            .with_context(|| format!("writing {}", self.path.display()))?;
        self.lines += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};

    /// Saving the model onto the file being recorded is refused (the save
    /// replaced the recording).
    #[test]
    fn issue_20_a_save_never_replaces_the_recording() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("session.dmu");
        let mut review = crate::review::Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        review.recorder = Some(Recorder::create(&path).unwrap());
        let err = review.save(&path).unwrap_err();
        assert!(format!("{err:#}").contains("recording"), "{err:#}");
        assert!(review.save(&dir.path().join("model.dmu")).is_ok());
    }

    /// A recording never overwrites a file (it truncated one before).
    #[test]
    fn issue_20_an_existing_file_is_not_overwritten() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("keep.jsonl");
        std::fs::write(&path, b"PRECIOUS\n").unwrap();
        let err = Recorder::create(&path).unwrap_err();
        assert!(format!("{err:#}").contains("must be a new file"), "{err:#}");
        assert_eq!(std::fs::read(&path).unwrap(), b"PRECIOUS\n");
    }

    /// Recorded poses parse back with dmu-collide's reader to the same
    /// transforms, one step per line, in time order.
    #[test]
    fn poses_read_back_exactly() {
        let scene = dmu_samples::grid(2, 10.0, 4.0, 2048);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("session.jsonl");
        let mut rec = Recorder::create(&path).unwrap();
        let a = scene.find_part("box_0_0_0").unwrap();
        let b = scene.find_part("box_1_1_0").unwrap();
        let poses = [
            (a, DAffine3::from_translation(DVec3::new(1.5, 0.0, 0.0))),
            (a, DAffine3::from_translation(DVec3::new(3.25, 0.0, 0.0))),
            (
                b,
                DAffine3::from_rotation_translation(
                    DQuat::from_rotation_z(0.5),
                    DVec3::new(10.0, 10.0, 0.0),
                ),
            ),
        ];
        for (part, world) in poses {
            rec.pose(&scene, part, world).unwrap();
        }
        assert_eq!(rec.lines(), 3);
        let steps = dmu_collide::read_record(&path, &scene).unwrap();
        assert_eq!(steps.len(), 3);
        assert!(steps.windows(2).all(|w| w[0].t < w[1].t));
        for (step, (part, world)) in steps.iter().zip(poses) {
            assert_eq!(step.moves.len(), 1);
            assert_eq!(step.moves[0].part, part);
            let (got, want) = (step.moves[0].world, world);
            assert_eq!(got.translation, want.translation);
            assert!(got.matrix3.abs_diff_eq(want.matrix3, 1e-12), "{got:?}");
        }
    }
}
