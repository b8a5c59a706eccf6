//! The clash list: clashes of the session and of `dmu collide --json`
//! reports, one entry per part pair and kind; showing one frames both parts,
//! isolates them and finds their closest points.

use std::path::Path;

use anyhow::Context as _;
use dmu_collide::Separation;
use dmu_scene::PartId;
use glam::DVec3;
use serde::Deserialize;

use crate::review::{ListedClash, Review, list_clash};

/// A finding as `dmu collide --json` prints it (the fields the list needs).
#[derive(Debug, Deserialize)]
struct Finding {
    step: usize,
    kind: String,
    a: String,
    b: String,
    distance: f64,
    point: [f64; 3],
}

/// A `dmu collide --json` report: one record's clashes, or a batch's.
#[derive(Debug, Deserialize)]
struct CollideReport {
    #[serde(default)]
    clashes: Vec<Finding>,
    #[serde(default)]
    records: Vec<RecordReport>,
}

#[derive(Debug, Deserialize)]
struct RecordReport {
    #[serde(default)]
    record: Option<String>,
    #[serde(default)]
    clashes: Vec<Finding>,
}

/// Adds the clashes of a `dmu collide --json` report at `path` to the
/// review's list; how many entries the list gained. Parts are found by name
/// in the model; a name it lacks is an error naming the finding.
pub fn load_report(review: &mut Review, path: &Path) -> anyhow::Result<usize> {
    let bytes = dmu_scene::read_regular_file(path)
        .with_context(|| format!("reading clash report {}", path.display()))?;
    let report: CollideReport = serde_json::from_slice(&bytes).with_context(|| {
        format!(
            "{}: not a `dmu collide --json` report (a JSON object with \"clashes\" or \"records\")",
            path.display()
        )
    })?;
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut found = Vec::new();
    let groups = std::iter::once((None, &report.clashes)).chain(
        report
            .records
            .iter()
            .map(|r| (r.record.as_deref(), &r.clashes)),
    );
    for (record, clashes) in groups {
        for (i, f) in clashes.iter().enumerate() {
            let part = |n: &str| {
                review.scene.find_part(n).with_context(|| {
                    format!(
                        "{}: clashes[{i}]: part {n:?} is not in the model",
                        path.display()
                    )
                })
            };
            let (a, b) = (part(&f.a)?, part(&f.b)?);
            anyhow::ensure!(
                f.distance.is_finite() && f.point.iter().all(|v| v.is_finite()),
                "{}: clashes[{i}]: distance and point must be finite numbers",
                path.display()
            );
            found.push(ListedClash {
                a,
                b,
                kind: f.kind.clone(),
                distance: f.distance,
                point: DVec3::from_array(f.point),
                source: match record {
                    Some(r) => format!("{name} {r} step {}", f.step),
                    None => format!("{name} step {}", f.step),
                },
            });
        }
    }
    let before = review.clash_list.len();
    for c in found {
        list_clash(&mut review.clash_list, c);
    }
    Ok(review.clash_list.len() - before)
}

/// Shows clash `index` of the list: isolates its two parts (every other part
/// hidden), selects the first, and returns their closest points (or `None`
/// when a part has no triangles). The caller frames [`pair_bounds`].
pub fn show(
    review: &mut Review,
    index: usize,
) -> anyhow::Result<(PartId, PartId, Option<Separation>)> {
    let c = review.clash_list.get(index).with_context(|| {
        format!(
            "clash {index}: the list has {} clashes",
            review.clash_list.len()
        )
    })?;
    let (a, b) = (c.a, c.b);
    for p in review.scene.part_ids() {
        review.scene.set_part_hidden(p, p != a && p != b);
    }
    review.select(Some(a));
    Ok((a, b, review.distance(a, b)))
}

/// The world box of two parts together.
pub fn pair_bounds(review: &Review, a: PartId, b: PartId) -> dmu_geom::Aabb3d {
    review
        .scene
        .part_world_bounds(a)
        .union(review.scene.part_world_bounds(b))
}
