//! The clash list: clashes of the session and of `dmu collide --json`
//! reports, one entry per part pair, named by its worst finding; showing one
//! frames both parts, isolates them and finds their closest points.

use std::path::Path;

use anyhow::Context as _;
use dmu_collide::{Finding, Separation};
use dmu_geom::Short;
use dmu_scene::{MAX_WORLD_COORDINATE, PartId};
use glam::DVec3;
use serde::Deserialize;

use crate::review::{ListedClash, Review, list_clash};

/// A `dmu collide --json` report: one record's clashes, or a batch's (at
/// least one of the two: an object with neither was read as an empty list).
/// Its findings are [`dmu_collide`]'s, the type the report is written from.
#[derive(Debug, Deserialize)]
struct CollideReport<'a> {
    #[serde(borrow)]
    clashes: Option<Vec<Finding<'a>>>,
    #[serde(borrow)]
    records: Option<Vec<RecordReport<'a>>>,
}

#[derive(Debug, Deserialize)]
struct RecordReport<'a> {
    #[serde(default)]
    record: Option<String>,
    #[serde(default, borrow)]
    clashes: Vec<Finding<'a>>,
}

/// Adds the clashes of a `dmu collide --json` report at `path` to the
/// review's list; how many entries the list gained. Parts are found by name
/// in the model; a name it lacks is an error naming the finding.
pub fn load_report(review: &mut Review, path: &Path) -> anyhow::Result<usize> {
    let bytes = dmu_scene::read_regular_file(path)
        .with_context(|| format!("reading clash report {}", path.display()))?;
    // A byte-order mark is skipped, as scripts and ray files skip it.
    let text = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(&bytes);
    let not_a_report = || {
        format!(
            "{}: not a `dmu collide --json` report (a JSON object with \"clashes\" or \"records\")",
            path.display()
        )
    };
    let report: CollideReport = serde_json::from_slice(text).with_context(not_a_report)?;
    anyhow::ensure!(
        report.clashes.is_some() || report.records.is_some(),
        "{}: it has neither",
        not_a_report()
    );
    let (clashes, records) = (
        report.clashes.unwrap_or_default(),
        report.records.unwrap_or_default(),
    );
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut found = Vec::new();
    let groups = std::iter::once((None, &clashes))
        .chain(records.iter().map(|r| (r.record.as_deref(), &r.clashes)));
    for (record, clashes) in groups {
        for (i, f) in clashes.iter().enumerate() {
            let at = || format!("{}: clashes[{i}]", path.display());
            let part = |n: &str| {
                review.scene.find_part(n).with_context(|| {
                    format!(
                        "{}: part {:?} is not in the model",
                        at(),
                        dmu_app::text::printable(n, 200)
                    )
                })
            };
            let (a, b) = (part(&f.a)?, part(&f.b)?);
            anyhow::ensure!(
                a != b,
                "{}: part {:?} clashes with itself",
                at(),
                dmu_app::text::printable(&f.a, 200)
            );
            // Distances are between surfaces: 0 for a hard clash, never less.
            anyhow::ensure!(
                f.distance.is_finite() && f.distance >= 0.0,
                "{}: distance {} must be a finite number, not negative",
                at(),
                Short(f.distance)
            );
            anyhow::ensure!(
                dmu_geom::is_within(DVec3::from_array(f.point), MAX_WORLD_COORDINATE),
                "{}: point {} must be finite and within ±{MAX_WORLD_COORDINATE:e}",
                at(),
                Short(f.point)
            );
            found.push(ListedClash {
                a,
                b,
                kind: f.kind,
                others: Vec::new(),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> anyhow::Result<usize> {
        let mut review = Review::new(dmu_samples::grid(2, 10.0, 4.0, 2048), None);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.json");
        std::fs::write(&path, text).unwrap();
        load_report(&mut review, &path)
    }

    fn finding(a: &str, b: &str, kind: &str, distance: &str) -> String {
        format!(
            r#"{{"step": 0, "t": 0, "kind": "{kind}", "a": "{a}", "b": "{b}", "a_id": 0, "b_id": 1,
               "distance": {distance}, "toi": null, "point": [1, 2, 3], "normal": [0, 0, 1]}}"#
        )
    }

    /// Issue 48: a part clashing with itself, a negative distance, an
    /// unknown kind and an object with neither `clashes` nor `records` were
    /// read (the last as an empty list); a byte-order mark was "expected
    /// value at line 1 column 1" where scripts and ray files skip it.
    #[test]
    fn issue_48_reports_are_checked_and_a_byte_order_mark_is_skipped() {
        let ok = finding("box_0_0_0", "box_1_0_0", "soft", "0.5");
        assert_eq!(load(&format!(r#"{{"clashes": [{ok}]}}"#)).unwrap(), 1);
        assert_eq!(
            load(&format!(
                "\u{feff}{{\"records\": [{{\"record\": \"r\", \"clashes\": [{ok}]}}]}}"
            ))
            .unwrap(),
            1
        );
        for (text, says) in [
            (
                format!(
                    r#"{{"clashes": [{}]}}"#,
                    finding("box_0_0_0", "box_0_0_0", "hard", "0")
                ),
                "clashes with itself",
            ),
            (
                format!(
                    r#"{{"clashes": [{}]}}"#,
                    finding("box_0_0_0", "box_1_0_0", "soft", "-1")
                ),
                "not negative",
            ),
            (
                format!(
                    r#"{{"clashes": [{}]}}"#,
                    finding("box_0_0_0", "box_1_0_0", "bad", "0")
                ),
                "unknown variant",
            ),
            (r#"{"clash": []}"#.to_owned(), "neither"),
            ("[]".to_owned(), "not a `dmu collide --json` report"),
        ] {
            let err = format!("{:#}", load(&text).unwrap_err());
            assert!(err.contains(says), "{text}: {err}");
        }
    }
}
