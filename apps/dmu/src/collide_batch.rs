//! `dmu collide` over many records: a worker per thread, each with its own
//! scene, cell tree and checker, the records handed out from a shared queue
//! and their reports passed on in the records' order as they complete.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use dmu_collide::{Checker, Settings, Step, StepOutcome, Summary, SweepMode, replay};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::DAffine3;

/// One record replayed.
#[derive(Debug)]
pub struct Checked<T> {
    /// What `collect` kept of its steps, in step order.
    pub findings: Vec<T>,
    /// The replay's totals.
    pub summary: Summary,
    /// Wall time to build the cell tree of the worker that replayed it (each
    /// worker builds one and reuses it for its records), milliseconds.
    pub tree_build_ms: f64,
    /// The choices made by measurement, one line each: the steps swept because
    /// a part moved more than its thickness.
    pub explain: Vec<String>,
}

/// A batch's records: how many, and how to read record `i` against a scene
/// at the model's poses.
pub struct Records<F> {
    pub count: usize,
    pub load: F,
}

/// Replays `records` from the scene's own poses on up to `jobs` workers.
///
/// Each worker holds a copy of `scene` (the first takes `scene` itself), its
/// own tree and its own checker (whose collision meshes it builds as its
/// records need them), and takes the next record from a shared queue until
/// none is left, reading it then: a batch holds the steps of the records
/// under way only (every record's steps held from the start took 8 kB a
/// record of 40 steps, 240 MB for 30,000; issue 48's soak); `load`'s error
/// stops the run like `emit`'s; after a record it moves the record's parts back to their
/// poses in the model, so every record starts from the model as loaded.
/// `collect` sees each step's outcome and keeps what the report needs. `emit`
/// runs on the calling thread with each record's index and result, in the
/// records' order, as soon as the records before it are done; its first error
/// stops the run (records under way finish, no new one starts) and is returned.
/// Returns the number of workers started: `jobs`, at most one per record.
pub fn check_records<T: Send>(
    scene: Scene,
    records: Records<impl Fn(usize, &Scene) -> anyhow::Result<Vec<Step>> + Sync>,
    settings: &Settings,
    sweep: SweepMode,
    jobs: usize,
    collect: impl Fn(&StepOutcome<'_>, &mut Vec<T>) + Sync,
    mut emit: impl FnMut(usize, Checked<T>) -> anyhow::Result<()>,
) -> anyhow::Result<usize> {
    let Records { count, load } = records;
    let workers = jobs.clamp(1, count.max(1));
    let poses: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
    let mut scenes: Vec<Scene> = (1..workers).map(|_| scene.clone()).collect();
    scenes.push(scene);
    let queue = AtomicUsize::new(0);
    let (sender, receiver) = mpsc::channel();
    std::thread::scope(|s| {
        for mut scene in scenes {
            let sender = sender.clone();
            let (queue, poses, collect, load) = (&queue, &poses, &collect, &load);
            s.spawn(move || {
                let start = Instant::now();
                let mut tree = Tree::build(&scene, TreeOptions::default());
                let tree_build_ms = start.elapsed().as_secs_f64() * 1e3;
                let mut checker = Checker::new(&scene);
                let mut moved: Vec<PartId> = Vec::new();
                loop {
                    let index = queue.fetch_add(1, Ordering::Relaxed);
                    if index >= count {
                        break;
                    }
                    let steps = match load(index, &scene) {
                        Ok(steps) => steps,
                        Err(e) => {
                            // The caller stops at this record, in order.
                            let _ = sender.send((index, Err(e)));
                            break;
                        }
                    };
                    let mut findings = Vec::new();
                    let mut explain = Vec::new();
                    let summary = replay(
                        &mut scene,
                        &mut tree,
                        &mut checker,
                        &steps,
                        settings,
                        sweep,
                        |o| {
                            collect(o, &mut findings);
                            explain.extend(o.swept_because.iter().map(|d| {
                                format!(
                                    "step {} (t={}): {}",
                                    o.index,
                                    o.step.t,
                                    d.describe(o.scene)
                                )
                            }));
                        },
                    );
                    moved.clear();
                    moved.extend(steps.iter().flat_map(|s| s.moves.iter().map(|m| m.part)));
                    moved.sort_unstable();
                    moved.dedup();
                    for &part in &moved {
                        tree.move_part(&mut scene, part, poses[part.index()]);
                    }
                    debug_assert!(
                        tree.validate_against(&scene).is_ok(),
                        "the tree follows the restored poses"
                    );
                    let checked = Checked {
                        findings,
                        summary,
                        tree_build_ms,
                        explain,
                    };
                    if sender.send((index, Ok(checked))).is_err() {
                        break; // the caller stopped on an error
                    }
                }
            });
        }
        drop(sender);
        // Records finish in any order; each waits here until those before it
        // have been emitted. Leaving the loop on an error drops the receiver,
        // which tells the workers to stop.
        let mut done = BTreeMap::new();
        let mut next = 0;
        for (index, checked) in receiver {
            done.insert(index, checked);
            while let Some(checked) = done.remove(&next) {
                emit(next, checked?)?;
                next += 1;
            }
        }
        Ok(workers)
    })
}
