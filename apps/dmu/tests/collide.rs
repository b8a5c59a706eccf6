//! `dmu collide` end to end: findings, exit codes 0 / 1 / 2, allow list,
//! continuous check, CSV. Included from `tests.rs` as `mod collide;`.

use std::path::Path;
use std::process::Output;

use serde_json::Value;

use super::{dmu, json, path};

/// A 2x2x2 grid of boxes of side 4 at pitch 10: box_0_0_0 spans [-2, 2]^3,
/// box_1_0_0 spans x in [8, 12].
fn grid(dir: &Path) -> String {
    let file = path(dir, "grid.glb");
    json(&dmu(&[
        "generate", "grid", "--n", "2", "-o", &file, "--json",
    ]));
    file
}

fn record(dir: &Path, name: &str, lines: &[&str]) -> String {
    let file = path(dir, name);
    std::fs::write(&file, lines.join("\n")).unwrap();
    file
}

fn at(t: f64, part: &str, x: f64) -> String {
    format!(
        r#"{{"t": {t}, "part": "{part}", "translation": [{x}, 0, 0], "rotation": [0, 0, 0, 1]}}"#
    )
}

/// stdout as JSON whatever the exit code.
fn parse(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}): {}\nstderr: {}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

#[test]
fn collide_reports_clashes_with_exit_1_and_clear_runs_with_exit_0() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    // Gap 6 (clear), then 3 (soft), 0 (contact), -1 (hard).
    let steps = [
        at(0.0, "box_0_0_0", 0.0),
        at(1.0, "box_0_0_0", 3.0),
        at(2.0, "box_0_0_0", 6.0),
        at(3.0, "#0", 7.0),
    ];
    let steps: Vec<&str> = steps.iter().map(String::as_str).collect();
    let moves = record(dir.path(), "moves.jsonl", &steps);
    let out = dmu(&["collide", &model, "--record", &moves, "--json"]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = parse(&out);
    let found: Vec<(u64, &str, &str, &str, f64)> = v["clashes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["step"].as_u64().unwrap(),
                c["kind"].as_str().unwrap(),
                c["a"].as_str().unwrap(),
                c["b"].as_str().unwrap(),
                c["distance"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        found,
        [
            (1, "soft", "box_0_0_0", "box_1_0_0", 3.0),
            (2, "contact", "box_0_0_0", "box_1_0_0", 0.0),
            (3, "hard", "box_0_0_0", "box_1_0_0", 0.0),
        ]
    );
    assert_eq!(v["summary"]["steps"], 4);
    assert_eq!(v["summary"]["clashes"], 3);
    assert!(v["summary"]["part_pairs_tested"].as_u64().unwrap() >= 3);
    let check_ms = v["summary"]["check_ms"].as_f64().unwrap();
    assert!(
        check_ms.is_finite() && check_ms > 0.0,
        "checks took {check_ms} ms"
    );

    // A smaller clearance and the pair allowed: clear, exit 0.
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "1",
        "--allow",
        "box_0_0_0,box_1_0_0",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("4 steps"));

    // CSV: a header and one row per clash; the summary on stderr.
    let out = dmu(&["collide", &model, "--record", &moves, "--csv"]);
    assert_eq!(out.status.code(), Some(1));
    let csv = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "step,t,kind,part_a,part_b,distance,toi,x,y,z");
    assert_eq!(rows.len(), 4);
    assert!(
        rows[1].starts_with("1,1,soft,box_0_0_0,box_1_0_0,3,,"),
        "{}",
        rows[1]
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("3 clashes"));
}

#[test]
fn collide_finds_a_jump_through_a_part_only_when_continuous() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    // From x = 0 to x = 20 in one step: through box_1_0_0, clear at both ends.
    let jump = at(1.0, "box_0_0_0", 20.0);
    let moves = record(dir.path(), "jump.jsonl", &[&jump]);
    let out = dmu(&["collide", &model, "--record", &moves, "--clearance", "1"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "1",
        "--continuous",
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let v = parse(&out);
    let impact = &v["clashes"][0];
    assert_eq!(impact["kind"], "impact");
    assert_eq!(impact["b"], "box_1_0_0");
    // The faces (x = 2 and x = 8) meet after 6 of the 20 mm travelled.
    assert!(
        (impact["toi"].as_f64().unwrap() - 0.3).abs() < 1e-6,
        "{impact}"
    );
    assert_eq!(v["summary"]["impacts"], 1);
}

#[test]
fn collide_errors_name_the_line_and_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let ok = at(0.0, "box_0_0_0", 0.0);
    let cases = [
        (
            vec![ok.clone(), at(1.0, "no_such_part", 0.0)],
            "line 2: unknown part \"no_such_part\"",
        ),
        (vec!["{\"t\": 0, \"part\": ".to_owned()], "line 1: "),
        (
            vec![
                ok.clone(),
                String::new(),
                r##"{"t": 1, "part": "#0", "translation": [0, 0, 0]}"##.to_owned(),
            ],
            "line 3: missing field `rotation`",
        ),
    ];
    for (lines, want) in cases {
        let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
        let moves = record(dir.path(), "bad.jsonl", &lines);
        let out = dmu(&["collide", &model, "--record", &moves]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(want) && err.contains("bad.jsonl"),
            "{err:?} should name {want:?}"
        );
        assert!(
            out.stdout.is_empty(),
            "nothing checked before the record is read"
        );
    }
    let missing = path(dir.path(), "missing.jsonl");
    assert_eq!(
        dmu(&["collide", &model, "--record", &missing])
            .status
            .code(),
        Some(2)
    );
    let moves = record(dir.path(), "ok.jsonl", &[&ok]);
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--allow",
        "box_0_0_0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--allow"));
    let out = dmu(&["collide", &model, "--record", &moves, "--clearance", "-1"]);
    assert_eq!(out.status.code(), Some(2));
}
