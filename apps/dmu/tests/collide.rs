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

/// The command exited with `code`; its output is shown when it did not.
fn assert_exit(out: &Output, code: i32) {
    assert_eq!(
        out.status.code(),
        Some(code),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
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
    assert_exit(&out, 1);
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
    assert_exit(&out, 0);
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
fn collide_sweeps_a_jump_through_a_part_and_explains_why() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    // Two short steps (1 mm, less than the box's 4 mm), then one from x = -2
    // to x = 20 in one step: through box_1_0_0, clear at both ends.
    let lines = [
        at(0.0, "box_0_0_0", -1.0),
        at(1.0, "box_0_0_0", -2.0),
        at(2.0, "box_0_0_0", 20.0),
    ];
    let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
    let moves = record(dir.path(), "jump.jsonl", &lines);
    // Never swept: the jump is missed.
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "1",
        "--discrete",
    ]);
    assert_exit(&out, 0);
    // By default the large step, and only it, is swept, and --explain says why.
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "1",
        "--explain",
        "--json",
    ]);
    assert_exit(&out, 1);
    let v = parse(&out);
    assert_eq!(v["sweep"], "auto");
    assert_eq!(v["summary"]["impacts"], 1);
    assert_eq!(v["clashes"][0]["b"], "box_1_0_0");
    let explain = v["explain"].as_array().expect("an explain array");
    assert_eq!(explain.len(), 1, "{explain:?}");
    assert_eq!(
        explain[0],
        "step 2 (t=2): part box_0_0_0 moved 22 model units, more than its thickness 4: \
         continuous (swept) check"
    );
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "1",
        "--explain",
    ]);
    assert_exit(&out, 1);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("explain: step 2 (t=2): part box_0_0_0 moved 22 model units"),
        "{text}"
    );
    // Every step swept: the same impact, found 6 of the 22 mm into the jump.
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
    // The faces (x = 2 and x = 8) meet after 8 of the 22 mm travelled from x = -2.
    assert!(
        (impact["toi"].as_f64().unwrap() - 8.0 / 22.0).abs() < 1e-6,
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

/// A report (a batch's and its records') without its timings, which differ
/// from run to run.
fn untimed(mut report: Value) -> Value {
    for key in ["check_ms", "load_ms", "tree_build_ms", "wall_ms"] {
        if let Some(summary) = report["summary"].as_object_mut() {
            summary.remove(key);
        }
    }
    if let Some(records) = report.get_mut("records").and_then(Value::as_array_mut) {
        for record in records {
            *record = untimed(record.take());
        }
    }
    report
}

/// Three records on the 2x2x2 grid, each moving box_0_0_0 from the model's
/// pose, so a record that started where the one before left the box would
/// report otherwise: a clear one ending far away, a soft then a hard clash, and a jump
/// through box_1_0_0 found only by the sweep (whose time of impact depends on
/// where the box starts).
fn three_records(dir: &Path) -> Vec<String> {
    std::fs::create_dir(dir.join("records")).unwrap();
    let clear = [at(0.0, "box_0_0_0", -10.0), at(1.0, "box_0_0_0", -30.0)];
    let hard = [at(0.0, "box_0_0_0", 5.5), at(1.0, "box_0_0_0", 7.0)];
    let jump = [at(0.0, "box_0_0_0", 20.0)];
    [
        ("records/a_clear.jsonl", &clear[..]),
        ("records/b_hard.jsonl", &hard[..]),
        ("records/c_jump.jsonl", &jump[..]),
    ]
    .map(|(name, lines)| {
        let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
        record(dir, name, &lines)
    })
    .to_vec()
}

/// The oracle: a batch over three records reports, record by record, what
/// three single runs report, in the order given, whatever the number of jobs
/// and whether the records are listed or named by their folder.
#[test]
fn a_batch_reports_what_single_runs_report() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let records = three_records(dir.path());
    // Not a record: ignored in the folder.
    std::fs::write(dir.path().join("records/notes.txt"), "not a record").unwrap();
    let options = ["--clearance", "1", "--continuous", "--json"];
    let single: Vec<Value> = records
        .iter()
        .map(|r| {
            let mut args = vec!["collide", &model, "--record", r];
            args.extend(options);
            untimed(parse(&dmu(&args)))
        })
        .collect();
    assert_eq!(single[0]["summary"]["clashes"], 0);
    assert_eq!(single[1]["summary"]["clashes"], 2, "{}", single[1]);
    assert_eq!(single[2]["clashes"][0]["kind"], "impact");
    assert!(
        (single[2]["clashes"][0]["toi"].as_f64().unwrap() - 0.3).abs() < 1e-6,
        "{}",
        single[2]
    );

    let folder = path(dir.path(), "records");
    let listed: Vec<&str> = records.iter().map(String::as_str).collect();
    let mut batches = Vec::new();
    for (named, jobs) in [
        (&listed[..], "1"),
        (&listed[..], "2"),
        (&[&folder[..]][..], "3"),
    ] {
        let mut args = vec!["collide", &model, "--record"];
        args.extend(named);
        args.extend(options);
        args.extend(["--jobs", jobs]);
        let out = dmu(&args);
        assert_eq!(out.status.code(), Some(1), "a record clashes");
        let batch = parse(&out);
        assert_eq!(batch["jobs"], jobs.parse::<u64>().unwrap());
        let batch = untimed(batch);
        assert_eq!(
            batch["records"],
            Value::from(single.clone()),
            "--jobs {jobs}, records {named:?}"
        );
        let summary = &batch["summary"];
        assert_eq!(summary["records"], 3);
        assert_eq!(summary["records_with_findings"], 2);
        assert_eq!(summary["steps"], 5);
        assert_eq!(summary["clashes"], 2);
        assert_eq!(summary["impacts"], 2);
        batches.push(batch);
    }
    let jobs = |v: &mut Value| v["jobs"] = Value::Null;
    batches.iter_mut().for_each(jobs);
    assert_eq!(batches[0], batches[1], "--jobs 1 equals --jobs 2");
    assert_eq!(batches[0], batches[2], "the folder equals the list");
}

/// Text prints a block per record and the totals; CSV adds a `record` column;
/// clear records exit 0; one record named as a file prints as it always has.
#[test]
fn a_batch_prints_a_part_per_record() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let records = three_records(dir.path());
    let (clear, hard) = (&records[0], &records[1]);
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        clear,
        hard,
        "--clearance",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], format!("record {clear}"), "{text}");
    assert!(lines[1].starts_with("2 steps, "), "{text}");
    assert_eq!(lines[2], format!("record {hard}"), "{text}");
    assert!(
        lines[3].starts_with("t=0 soft    box_0_0_0 box_1_0_0"),
        "{text}"
    );
    assert!(
        lines[4].starts_with("t=1 hard    box_0_0_0 box_1_0_0"),
        "{text}"
    );
    assert!(lines[5].starts_with("2 steps, "), "{text}");
    assert!(
        lines[6].starts_with("2 records (1 with clashes or impacts), 4 steps, 2 clashes"),
        "{text}"
    );
    assert_eq!(lines.len(), 7, "{text}");

    let out = dmu(&[
        "collide",
        &model,
        "--record",
        clear,
        hard,
        "--clearance",
        "1",
        "--csv",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let csv = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(
        rows[0],
        "record,step,t,kind,part_a,part_b,distance,toi,x,y,z"
    );
    assert_eq!(rows.len(), 3, "{csv}");
    for row in &rows[1..] {
        assert!(row.starts_with(&format!("{hard},")), "{row}");
    }
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("{clear}: 2 steps")), "{err}");

    let out = dmu(&[
        "collide",
        &model,
        "--record",
        clear,
        clear,
        "--clearance",
        "1",
        "--jobs",
        "2",
    ]);
    assert_exit(&out, 0);

    let out = dmu(&[
        "collide",
        &model,
        "--record",
        hard,
        "--clearance",
        "1",
        "--csv",
    ]);
    let csv = String::from_utf8_lossy(&out.stdout);
    assert!(csv.starts_with("step,t,kind,"), "{csv}");
}

/// A bad record among several stops the batch before any is checked, naming
/// the record and the line; so does a folder without records.
#[test]
fn a_bad_record_in_a_batch_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let records = three_records(dir.path());
    let ok = at(0.0, "box_0_0_0", 0.0);
    let bad = record(dir.path(), "bad.jsonl", &[&ok, "{\"t\": 1}"]);
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &records[0],
        &bad,
        &records[1],
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.jsonl: line 2: missing field"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "nothing checked before every record is read"
    );

    std::fs::create_dir(dir.path().join("empty")).unwrap();
    let out = dmu(&["collide", &model, "--record", &path(dir.path(), "empty")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("empty: no *.jsonl records"), "{err}");

    let out = dmu(&["collide", &model, "--record", &records[0], "--jobs", "0"]);
    assert_eq!(out.status.code(), Some(2));
}
