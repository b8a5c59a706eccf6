//! Recording a manipulation session in the collision issue's JSON Lines format
//! (docs/record-format.md, written by dmu-collide's `RecordLine`, beside its
//! reader), so `dmu collide --record` replays it and finds the clashes the
//! viewer showed.
//!
//! Every placement of a part (a drag step, a typed move or rotation, an undo
//! or a redo) is one line and one step: its absolute world pose, the time in
//! seconds since the recording began, the part by its full assembly path (or
//! `#id` where the path does not name it alone).
//!
//! Lines are written and flushed by a thread of the recording's own, so the
//! frame that places a part never waits on the disk (the VR loop must not);
//! a write error stops the recording at the next placement.

use std::collections::HashMap;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
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
    /// Lines to the writer thread (`None` once finished).
    lines_out: Option<mpsc::Sender<Vec<u8>>>,
    writer: Option<JoinHandle<()>>,
    /// The writer's first error.
    error: Arc<Mutex<Option<String>>>,
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
        let (lines_out, lines_in) = mpsc::channel::<Vec<u8>>();
        let error = Arc::new(Mutex::new(None));
        let (shown, failed) = (path.display().to_string(), error.clone());
        let writer = std::thread::Builder::new()
            .name("dmu record".into())
            .spawn(move || {
                let mut out = BufWriter::new(file);
                for line in lines_in {
                    if let Err(e) = out.write_all(&line).and_then(|()| out.flush()) {
                        *failed.lock().unwrap_or_else(|p| p.into_inner()) =
                            Some(format!("writing {shown}: {e}"));
                        return;
                    }
                }
            })
            .context("starting the recording's writer thread")?;
        Ok(Self {
            path: path.to_owned(),
            lines_out: Some(lines_out),
            writer: Some(writer),
            error,
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

    /// Records `part` placed at `world` as one step, handed to the writer
    /// thread, which writes and flushes it at once (so the file is complete
    /// whenever the viewer stops). An error: the writer failed before.
    pub fn pose(&mut self, scene: &Scene, part: PartId, world: DAffine3) -> anyhow::Result<()> {
        self.writer_error()?;
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
        let mut line = Vec::new();
        RecordLine::new(t, name.clone(), world)
            .write(&mut line)
            .with_context(|| format!("writing {}", self.path.display()))?;
        let sent = self.lines_out.as_ref().map(|s| s.send(line));
        if !matches!(sent, Some(Ok(()))) {
            self.writer_error()?;
            anyhow::bail!("writing {}: the writer thread ended", self.path.display());
        }
        self.lines += 1;
        Ok(())
    }

    /// The writer thread's error, if it had one.
    fn writer_error(&self) -> anyhow::Result<()> {
        match &*self.error.lock().unwrap_or_else(|p| p.into_inner()) {
            Some(e) => anyhow::bail!("{e}"),
            None => Ok(()),
        }
    }

    /// Waits until every line is written; the writer's error, if any.
    pub fn finish(mut self) -> anyhow::Result<()> {
        self.stop();
        self.writer_error()
    }

    /// Closes the line channel and waits for the writer thread.
    fn stop(&mut self) {
        self.lines_out = None;
        if let Some(writer) = self.writer.take() {
            // The thread only writes; a panic there left its error unset.
            if writer.join().is_err() {
                *self.error.lock().unwrap_or_else(|p| p.into_inner()) = Some(format!(
                    "writing {}: the writer thread panicked",
                    self.path.display()
                ));
            }
        }
    }
}

impl Drop for Recorder {
    /// The file is complete once the recorder is gone.
    fn drop(&mut self) {
        self.stop();
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

    /// The writer thread has written every line once the recorder is
    /// dropped (the desktop's "stop recording" reads the file right after).
    #[test]
    fn dropping_the_recorder_completes_the_file() {
        let scene = dmu_samples::grid(2, 10.0, 4.0, 2048);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("many.jsonl");
        let mut rec = Recorder::create(&path).unwrap();
        let part = scene.find_part("box_0_0_0").unwrap();
        for i in 0..2000 {
            let world = DAffine3::from_translation(DVec3::new(f64::from(i), 0.0, 0.0));
            rec.pose(&scene, part, world).unwrap();
        }
        drop(rec);
        let steps = dmu_collide::read_record(&path, &scene).unwrap();
        assert_eq!(steps.len(), 2000);
        assert_eq!(steps[1999].moves[0].world.translation.x, 1999.0);
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
        rec.finish().unwrap();
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
