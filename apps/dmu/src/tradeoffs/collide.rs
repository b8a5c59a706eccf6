//! Collision knobs on a controlled case: in the built-in grid (boxes of side 4
//! at pitch 10) the corner box is dragged along its row, through every box in
//! it, in steps of a given length. The reference is a continuous check at a
//! fine step: it meets every box of the row. A discrete check sees a box only
//! where a step ends inside it, so steps longer than the 8 mm overlap window
//! can jump boxes.

use std::collections::BTreeSet;

use dmu_collide::{
    Checker, ClashKind, DEFAULT_CONTACT_TOLERANCE, RecordedMove, Settings, Step, Summary,
    SweepMode, replay,
};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};

use super::{Bench, Knob, Point};

const PITCH: f64 = 10.0;
const SIDE: f32 = 4.0;
/// Step of the reference sweep, mm.
const FINE_STEP: f64 = 0.25;
// The quick settings are a subset of the full ones, on the same grid, so the
// two runs can be compared point for point.
const STEPS_QUICK: &[f64] = &[1.0, 4.0, 16.0];
const STEPS_FULL: &[f64] = &[0.5, 1.0, 2.0, 4.0, 8.0, 12.0, 16.0, 32.0];
const CLEARANCES_QUICK: &[f64] = &[0.0, 2.0, 8.0];
const CLEARANCES_FULL: &[f64] = &[0.0, 0.5, 1.0, 2.0, 5.0, 8.0, 12.0];
const CONTACT_TOLERANCES: &[f64] = &[1e-9, 1e-6, 1e-4, 1e-2, 3e-2, 1e-1];

pub fn steps(quick: bool) -> u64 {
    let (s, c) = if quick {
        (STEPS_QUICK, CLEARANCES_QUICK)
    } else {
        (STEPS_FULL, CLEARANCES_FULL)
    };
    (3 * s.len() + c.len() + CONTACT_TOLERANCES.len()) as u64
}

/// The corner box's drag along x from its home to half a pitch past the last
/// box of its row, in steps of `step` (the last one shorter).
fn drag(part: PartId, n: u32, step: f64) -> Vec<Step> {
    let end = PITCH * f64::from(n - 1) + PITCH / 2.0;
    let count = (end / step).ceil() as usize;
    (1..=count)
        .map(|i| Step {
            t: i as f64,
            moves: vec![RecordedMove {
                line: i,
                part,
                world: DAffine3::from_translation(DVec3::X * (step * i as f64).min(end)),
            }],
        })
        .collect()
}

/// One replay from the grid's own poses: what the dragged box met, as (step,
/// other part, kind) for clashes and (other part) for impacts, and the totals.
struct Met {
    clashes: BTreeSet<(usize, PartId, ClashKind)>,
    parts: BTreeSet<PartId>,
    summary: Summary,
}

fn replayed(scene: &Scene, steps: &[Step], settings: &Settings, mode: SweepMode) -> Met {
    let mut scene = scene.clone();
    let mut tree = Tree::build(&scene, TreeOptions::default());
    let mut checker = Checker::new(&scene);
    let mut clashes = BTreeSet::new();
    let mut parts = BTreeSet::new();
    let summary = replay(
        &mut scene,
        &mut tree,
        &mut checker,
        steps,
        settings,
        mode,
        |o| {
            for c in &o.report.clashes {
                clashes.insert((o.index, c.b, c.kind));
                if c.kind != ClashKind::Soft {
                    parts.insert(c.b);
                }
            }
            parts.extend(o.report.impacts.iter().map(|i| i.b));
        },
    );
    Met {
        clashes,
        parts,
        summary,
    }
}

fn point(setting: f64, met: &Met, reference: &BTreeSet<PartId>) -> Point {
    let s = &met.summary;
    Point::new(
        setting,
        s.seconds * 1e3,
        reference.difference(&met.parts).count() as f64,
        "boxes missed",
    )
    .extra("steps/s", s.steps as f64 / s.seconds.max(1e-12))
}

pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let n = bench.scale.collide_grid;
    let scene = dmu_samples::grid(n, PITCH, SIDE, dmu_scene::DEFAULT_CHUNK_TRIANGLES);
    let part = scene.find_part("box_0_0_0")?;
    let touching = Settings::default();
    let reference = replayed(
        &scene,
        &drag(part, n, FINE_STEP),
        &touching,
        SweepMode::Always,
    )
    .parts;
    anyhow::ensure!(
        reference.len() == n as usize - 1,
        "the reference sweep met {} boxes, not the {} of the row",
        reference.len(),
        n - 1
    );
    let (step_settings, clearances) = if bench.scale.quick {
        (STEPS_QUICK, CLEARANCES_QUICK)
    } else {
        (STEPS_FULL, CLEARANCES_FULL)
    };
    let reference_name = format!(
        "a continuous (swept) check at {FINE_STEP} mm steps, which meets all {} boxes of the row",
        n - 1
    );
    let knob = |name: &str, note: &str, exact: Option<f64>, log_x: bool, points| Knob {
        section: "collision",
        name: name.to_owned(),
        unit: "mm".to_owned(),
        note: note.to_owned(),
        reference: reference_name.clone(),
        time: "check time of the drag".to_owned(),
        error_unit: "boxes missed".to_owned(),
        exact_setting: exact,
        log_x,
        log_error: false,
        points,
    };
    let mut knobs = Vec::new();
    for (name, mode) in [
        ("discrete step", SweepMode::Off),
        ("continuous step", SweepMode::Always),
        (
            "auto step (swept past the part's thickness)",
            SweepMode::Auto,
        ),
    ] {
        let points = step_settings
            .iter()
            .map(|&s| {
                bench.progress.inc(1);
                point(
                    s,
                    &replayed(&scene, &drag(part, n, s), &touching, mode),
                    &reference,
                )
            })
            .collect();
        // Swept checks meet every box at any step; discrete ones at steps
        // shorter than the 8 mm overlap window.
        let exact = (mode != SweepMode::Off).then_some(step_settings[0]);
        knobs.push(knob(
            name,
            "length of the drag's steps",
            exact,
            false,
            points,
        ));
    }
    let steps = drag(part, n, 1.0);
    let points = clearances
        .iter()
        .map(|&c| {
            bench.progress.inc(1);
            let settings = Settings::with_clearance(c);
            point(
                c,
                &replayed(&scene, &steps, &settings, SweepMode::Off),
                &reference,
            )
        })
        .collect();
    knobs.push(knob(
        "clearance",
        "1 mm discrete steps",
        Some(0.0),
        false,
        points,
    ));
    // Contact tolerance: the same findings, told apart by kind; errors are the
    // findings whose kind differs from the default tolerance's. Fine steps, so
    // shallow crossings (a quarter millimetre) are among the poses.
    let steps = drag(part, n, FINE_STEP);
    let base = replayed(&scene, &steps, &touching, SweepMode::Off).clashes;
    let points = CONTACT_TOLERANCES
        .iter()
        .map(|&tol| {
            bench.progress.inc(1);
            let settings = Settings {
                contact_tolerance: tol,
                ..Settings::default()
            };
            let met = replayed(&scene, &steps, &settings, SweepMode::Off);
            let s = &met.summary;
            Point::new(
                tol,
                s.seconds * 1e3,
                met.clashes.symmetric_difference(&base).count() as f64,
                "findings of another kind",
            )
            .extra("steps/s", s.steps as f64 / s.seconds.max(1e-12))
        })
        .collect();
    knobs.push(Knob {
        section: "collision",
        name: "contact tolerance".to_owned(),
        unit: "x part size".to_owned(),
        note: format!("{FINE_STEP} mm discrete steps, clearance 0"),
        reference: format!("the default tolerance {DEFAULT_CONTACT_TOLERANCE:e}"),
        time: "check time of the drag".to_owned(),
        error_unit: "findings of another kind".to_owned(),
        exact_setting: Some(DEFAULT_CONTACT_TOLERANCE),
        log_x: true,
        log_error: false,
        points,
    });
    Ok(knobs)
}
