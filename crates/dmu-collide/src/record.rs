//! Recorded manipulations (JSON Lines, see `docs/record-format.md`): their
//! reader, their writer, and their replay: parts moved through the tree step by
//! step, each step checked.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use dmu_scene::{PartId, Scene, SceneError};
use dmu_tree::Tree;
use glam::{DAffine3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::check::{Checker, Report, Settings};
use crate::sweep::{Motion, SweepDecision, SweepMode};

/// How far a rotation's length may stray from 1 before the line is refused:
/// loose enough for quaternions printed with 6 digits, tight enough to catch a
/// vector that is not a quaternion.
const UNIT_SLACK: f64 = 1e-3;

/// Errors reading a record. Lines are numbered from 1.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// The file could not be read.
    #[error("cannot read {}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A line is not a move: bad JSON, a missing, unknown or ill-typed field, a
    /// non-finite number, a rotation that is not a unit quaternion.
    #[error("line {line}: {message}")]
    Malformed {
        /// Line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The part named on a line does not exist or is ambiguous.
    #[error("line {line}: {cause}")]
    UnknownPart {
        /// Line number.
        line: usize,
        /// The scene's answer, naming the part.
        cause: SceneError,
    },
    /// One part moves twice at the same time.
    #[error("line {line}: part {part:?} already moves at t = {}", dmu_geom::Short(*t))]
    DuplicatePart {
        /// Line number of the second move.
        line: usize,
        /// The part as written.
        part: String,
        /// The time.
        t: f64,
    },
    /// Time goes backwards.
    #[error(
        "line {line}: t = {} comes after t = {}; lines must be in time order",
        dmu_geom::Short(*t),
        dmu_geom::Short(*previous)
    )]
    OutOfOrder {
        /// Line number.
        line: usize,
        /// Its time.
        t: f64,
        /// The time of the line before.
        previous: f64,
    },
}

/// One line: a part's absolute world pose from a time on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedMove {
    /// Line number in the record, from 1.
    pub line: usize,
    /// The part.
    pub part: PartId,
    /// The world pose: the recorded rotation and translation, with the part's
    /// scale from the model kept.
    pub world: DAffine3,
}

/// The moves that share a time.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// The time (seconds, or any unit: only the order matters).
    pub t: f64,
    /// One move per part.
    pub moves: Vec<RecordedMove>,
}

/// One line of a record as it is written and read: a part's absolute world
/// pose (rotation and translation; the part's scale stays the model's) from
/// time `t` on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordLine {
    /// The time (seconds, or any unit: only the order matters).
    pub t: f64,
    /// The part, as [`Scene::find_part`] accepts it (see [`record_part_name`]).
    pub part: String,
    /// World translation.
    pub translation: [f64; 3],
    /// World rotation, a unit quaternion `[x, y, z, w]`.
    pub rotation: [f64; 4],
}

impl RecordLine {
    /// The line placing `part` (named as in the file) at `world` from `t` on.
    pub fn new(t: f64, part: String, world: DAffine3) -> Self {
        let (_, rotation, translation) = world.to_scale_rotation_translation();
        Self {
            t,
            part,
            translation: translation.to_array(),
            rotation: rotation.normalize().to_array(),
        }
    }

    /// Writes the line as one line of JSON (the writer of [`parse_record`]'s
    /// format).
    pub fn write(&self, out: &mut impl Write) -> std::io::Result<()> {
        serde_json::to_writer(&mut *out, self)?;
        out.write_all(b"\n")
    }
}

/// How a record names `part`: its full assembly path when [`Scene::find_part`]
/// finds exactly it by that path, else `#id`.
pub fn record_part_name(scene: &Scene, part: PartId) -> String {
    let path = scene.part_path(part);
    match scene.find_part(&path) {
        Ok(found) if found == part => path,
        _ => format!("#{}", part.0),
    }
}

/// Writes `steps` as a record (the inverse of [`parse_record`]): one line per
/// move, in order, parts named by [`record_part_name`].
pub fn write_record(out: &mut impl Write, scene: &Scene, steps: &[Step]) -> std::io::Result<()> {
    for step in steps {
        for m in &step.moves {
            RecordLine::new(step.t, record_part_name(scene, m.part), m.world).write(out)?;
        }
    }
    Ok(())
}

/// Reads and parses a record file (see [`parse_record`]).
pub fn read_record(path: &Path, scene: &Scene) -> Result<Vec<Step>, RecordError> {
    let io = |source| RecordError::Io {
        path: path.to_owned(),
        source,
    };
    let bytes = dmu_scene::read_regular_file(path).map_err(io)?;
    let text = String::from_utf8(bytes)
        .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
    parse_record(&text, scene)
}

/// Parses a record against a scene: one JSON object per line, blank lines
/// skipped, lines in time order, consecutive lines with the same `t` forming
/// one step. Parts are named as [`Scene::find_part`] accepts.
pub fn parse_record(text: &str, scene: &Scene) -> Result<Vec<Step>, RecordError> {
    let mut steps: Vec<Step> = Vec::new();
    // A record moves a few parts over many lines: each is looked up once
    // (a lookup by name compares every part's name).
    let mut found: HashMap<String, PartId> = HashMap::new();
    // Editors on some systems start UTF-8 files with a byte-order mark.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        if raw.trim().is_empty() {
            continue;
        }
        let malformed = |message: String| RecordError::Malformed { line, message };
        if !raw.trim_start().starts_with('{') {
            return Err(malformed(
                "a line must be one JSON object {\"t\": …, \"part\": …, …}".into(),
            ));
        }
        let parsed: RecordLine = serde_json::from_str(raw).map_err(|e| {
            // serde_json counts lines within the one line it was given.
            let mut message = e.to_string();
            if let Some(at) = message.rfind(" at line ") {
                message.truncate(at);
            }
            malformed(format!("{message} (column {})", e.column()))
        })?;
        let numbers = [parsed.t]
            .into_iter()
            .chain(parsed.translation)
            .chain(parsed.rotation);
        if numbers.into_iter().any(|v| !v.is_finite()) {
            return Err(malformed("numbers must be finite".into()));
        }
        let q = DQuat::from_array(parsed.rotation);
        if (q.length() - 1.0).abs() > UNIT_SLACK {
            return Err(malformed(format!(
                "rotation {} is not a unit quaternion [x, y, z, w] (length {})",
                dmu_geom::Short(&parsed.rotation[..]),
                dmu_geom::Short(q.length())
            )));
        }
        let part = match found.get(&parsed.part) {
            Some(&part) => part,
            None => {
                let part = scene
                    .find_part(&parsed.part)
                    .map_err(|cause| RecordError::UnknownPart { line, cause })?;
                found.insert(parsed.part.clone(), part);
                part
            }
        };
        let scale = scene.part_world(part).to_scale_rotation_translation().0;
        let world = DAffine3::from_scale_rotation_translation(
            scale,
            q.normalize(),
            DVec3::from_array(parsed.translation),
        );
        if !scene.is_valid_world(part, &world) {
            return Err(malformed(format!(
                "the pose of {} puts it beyond ±{:e} model units",
                parsed.part,
                dmu_scene::MAX_WORLD_COORDINATE
            )));
        }
        let moved = RecordedMove { line, part, world };
        match steps.last_mut() {
            Some(step) if step.t == parsed.t => {
                if step.moves.iter().any(|m| m.part == part) {
                    return Err(RecordError::DuplicatePart {
                        line,
                        part: parsed.part,
                        t: parsed.t,
                    });
                }
                step.moves.push(moved);
            }
            Some(step) if step.t > parsed.t => {
                return Err(RecordError::OutOfOrder {
                    line,
                    t: parsed.t,
                    previous: step.t,
                });
            }
            _ => {
                steps.push(Step {
                    t: parsed.t,
                    moves: vec![moved],
                });
            }
        }
    }
    Ok(steps)
}

/// One replayed step, as [`replay`] hands it over.
#[derive(Debug)]
pub struct StepOutcome<'a> {
    /// Step number, from 0.
    pub index: usize,
    /// The step.
    pub step: &'a Step,
    /// The scene at the step's poses (for names and paths).
    pub scene: &'a Scene,
    /// What the checks found at the step's poses (and, when swept, along the
    /// motions into them).
    pub report: &'a Report,
    /// Why the step was swept under [`SweepMode::Auto`]: the parts that moved
    /// more than their thickness (empty when not swept, or swept always).
    pub swept_because: &'a [SweepDecision],
}

/// Totals of a replay.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Steps replayed.
    pub steps: usize,
    /// Part pairs and chunk pairs that reached the narrow phase, over all steps.
    pub part_pairs_tested: u64,
    /// See `part_pairs_tested`.
    pub chunk_pairs_tested: u64,
    /// Clashes over all steps (a pair clashing in three steps counts three).
    pub clashes: u64,
    /// Impacts over all steps.
    pub impacts: u64,
    /// Wall time of the moves and checks (not of `on_step`), seconds.
    pub seconds: f64,
}

/// Replays steps: each step's parts move through the tree to their poses, then
/// the moved parts are checked there, and, as `sweep` says, also along their
/// motions from the poses before (the first motion of a part starts at its
/// pose in the model). `on_step` sees every step's report.
pub fn replay(
    scene: &mut Scene,
    tree: &mut Tree,
    checker: &mut Checker,
    steps: &[Step],
    settings: &Settings,
    sweep: SweepMode,
    mut on_step: impl FnMut(&StepOutcome<'_>),
) -> Summary {
    let mut summary = Summary::default();
    let mut report = Report::default();
    let mut motions: Vec<Motion> = Vec::new();
    let mut moved: Vec<PartId> = Vec::new();
    let mut because: Vec<SweepDecision> = Vec::new();
    for (index, step) in steps.iter().enumerate() {
        let start = Instant::now();
        motions.clear();
        motions.extend(step.moves.iter().map(|m| Motion {
            part: m.part,
            from: scene.part_world(m.part),
            to: m.world,
        }));
        moved.clear();
        moved.extend(step.moves.iter().map(|m| m.part));
        because.clear();
        if sweep == SweepMode::Auto {
            because.extend(motions.iter().filter_map(|m| SweepDecision::of(scene, m)));
        }
        for m in &step.moves {
            tree.move_part(scene, m.part, m.world);
        }
        checker.check(scene, tree, &moved, settings, &mut report);
        if sweep == SweepMode::Always || !because.is_empty() {
            checker.sweep(scene, tree, &motions, settings, &mut report);
        }
        summary.seconds += start.elapsed().as_secs_f64();
        summary.steps += 1;
        summary.part_pairs_tested += report.part_pairs_tested;
        summary.chunk_pairs_tested += report.chunk_pairs_tested;
        summary.clashes += report.clashes.len() as u64;
        summary.impacts += report.impacts.len() as u64;
        on_step(&StepOutcome {
            index,
            step,
            scene,
            report: &report,
            swept_because: &because,
        });
    }
    summary
}
