//! `dmu collide --bcf` and `dmu bcf show` end to end: a topic per clashing
//! pair and record at the step of its worst finding, the parts selected by
//! name, snapshots of the asked size; `bcf show` refuses hostile files with one line. The
//! third-party reader (bcf-client) checks the same files in
//! crates/dmu-py/tests/test_bcf.py.

use std::path::Path;
use std::process::Output;

use serde_json::Value;

use super::{dmu, json, path};

/// A 2x2x2 grid of boxes of side 4 at pitch 10 (box_x_y_z at 10·(x, y, z)).
fn grid(dir: &Path) -> String {
    let file = path(dir, "grid.glb");
    json(&dmu(&[
        "generate", "grid", "--n", "2", "-o", &file, "--json",
    ]));
    file
}

fn pose(t: usize, part: &str, at: [f64; 3]) -> String {
    format!(
        r#"{{"t": {t}, "part": "{part}", "translation": [{}, {}, {}], "rotation": [0, 0, 0, 1]}}"#,
        at[0], at[1], at[2]
    )
}

fn record(dir: &Path, name: &str, lines: &[String]) -> String {
    let file = path(dir, name);
    std::fs::write(&file, lines.join("\n")).unwrap();
    file
}

/// stdout as JSON whatever the exit code (1: clashes found).
fn report(out: &Output) -> Value {
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Whether the run wrote its snapshots; without a GPU adapter it says so on
/// stderr, and the snapshot checks skip (a failure under `CI=true`).
fn snapshots_rendered(out: &Output) -> bool {
    let err = String::from_utf8_lossy(&out.stderr);
    let rendered = !err.contains("without snapshots");
    if !rendered {
        dmu_testkit::skip(format!("snapshots: no Vulkan adapter ({err})"));
    }
    rendered
}

/// A 3,000-step record pressing box_0_0_0 against box_1_0_0 (contact at every
/// step from step 10), then into box_0_1_0 at step 2,000: two topics, each at
/// its pair's first step; `bcf show` reads them back.
#[test]
fn a_topic_per_pair_at_its_first_step() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let mut lines: Vec<String> = (0..10)
        .map(|t| pose(t, "box_0_0_0", [-10.0, 0.0, 0.0]))
        .collect();
    lines.extend((10..2000).map(|t| pose(t, "box_0_0_0", [6.0, 0.0, 0.0])));
    lines.extend((2000..3000).map(|t| pose(t, "box_0_0_0", [0.0, 7.0, 0.0])));
    let moves = record(dir.path(), "long.jsonl", &lines);
    let bcf = path(dir.path(), "long.bcfzip");
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "0",
        "--discrete",
        "--json",
        "--bcf",
        &bcf,
        "--bcf-snapshot",
        "320x200",
    ]);
    let run = report(&out);
    let rendered = snapshots_rendered(&out);
    assert_eq!(run["summary"]["clashes"], 2990);
    assert_eq!(run["bcf"]["path"], bcf.as_str());
    assert_eq!(run["bcf"]["topics"], 2);
    let shown = json(&dmu(&["bcf", "show", &bcf, "--json"]));
    let topics = shown["topics"].as_array().unwrap();
    let titles: Vec<&str> = topics
        .iter()
        .map(|t| t["title"].as_str().unwrap())
        .collect();
    assert_eq!(
        titles,
        [
            "contact: box_0_0_0 × box_1_0_0 at step 10 (t=10)",
            "hard: box_0_0_0 × box_0_1_0 at step 2000 (t=2000)",
        ]
    );
    assert!(
        topics[0]["description"]
            .as_str()
            .unwrap()
            .contains("findings at 1990 steps, the last at step 1999"),
        "{}",
        topics[0]["description"]
    );
    for (topic, other) in topics.iter().zip(["box_1_0_0", "box_0_1_0"]) {
        assert_eq!(topic["topic_type"], "Clash");
        let v = &topic["viewpoints"][0];
        let names: Vec<&str> = v["selected"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                assert_eq!(c["originating_system"], "dmu");
                c["authoring_tool_id"].as_str().unwrap()
            })
            .collect();
        assert_eq!(names, ["box_0_0_0", other]);
        assert_eq!(v["camera"]["projection"], "perspective");
        if rendered {
            assert_eq!(v["snapshot"]["format"], "png");
            assert_eq!(
                (
                    v["snapshot"]["width"].as_u64(),
                    v["snapshot"]["height"].as_u64()
                ),
                (Some(320), Some(200))
            );
        }
    }
    assert_eq!(run["bcf"]["snapshots"], if rendered { 2 } else { 0 });
}

/// `dmu collide --bcf` of `lines` on the grid with a clearance of 0.1, no
/// snapshots: its report and `dmu bcf show`'s of the file.
fn clearance_run(lines: &[String]) -> (Value, Value) {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let moves = record(dir.path(), "moves.jsonl", lines);
    let bcf = path(dir.path(), "moves.bcfzip");
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &moves,
        "--clearance",
        "0.1",
        "--discrete",
        "--json",
        "--bcf",
        &bcf,
        "--bcf-snapshot",
        "none",
    ]);
    (report(&out), json(&dmu(&["bcf", "show", &bcf, "--json"])))
}

/// Issue 47: a pair going from a 0.05 soft clash to a hard clash and back is
/// one topic titled with its hard clash (it was titled "soft", its first
/// finding), at the hard step's poses, listing the soft clash.
#[test]
fn a_pair_topic_is_titled_with_its_worst_finding() {
    // box_1_0_0 spans x 8..12: box_0_0_0 (side 4) at x 5.95 is 0.05 away.
    let (run, shown) = clearance_run(&[
        pose(0, "box_0_0_0", [-30.0, 0.0, 0.0]),
        pose(1, "box_0_0_0", [5.95, 0.0, 0.0]),
        pose(2, "box_0_0_0", [7.0, 0.0, 0.0]),
        pose(3, "box_0_0_0", [5.95, 0.0, 0.0]),
    ]);
    let kinds: Vec<&str> = run["clashes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["soft", "hard", "soft"]);
    assert_eq!(run["bcf"]["topics"], 1);
    let topic = &shown["topics"][0];
    assert_eq!(
        topic["title"],
        "hard: box_0_0_0 × box_1_0_0 at step 2 (t=2)"
    );
    let description = topic["description"].as_str().unwrap();
    assert!(
        description.contains("Also soft at 2 steps from step 1 (t=1).")
            && description.contains("findings at 3 steps, the last at step 3"),
        "{description}"
    );
    assert_eq!(
        topic["labels"],
        serde_json::json!(["hard", "soft", "dmu collide"])
    );
}

/// A pair's topic names its parts as its worst finding does: when the other
/// part moves into the first (a hard clash after the first part's soft
/// one), the title and the framing follow the part that moved then (they
/// named the pair's first mover).
#[test]
fn a_pair_topic_names_the_mover_of_its_worst_finding() {
    // box_1_0_0 at x 3 spans 1..5, into box_0_0_0 standing at 5.95 (3.95..7.95).
    let (run, shown) = clearance_run(&[
        pose(0, "box_0_0_0", [5.95, 0.0, 0.0]),
        pose(1, "box_1_0_0", [3.0, 0.0, 0.0]),
    ]);
    let found: Vec<(&str, &str, &str)> = run["clashes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["kind"].as_str().unwrap(),
                f["a"].as_str().unwrap(),
                f["b"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        found,
        [
            ("soft", "box_0_0_0", "box_1_0_0"),
            ("hard", "box_1_0_0", "box_0_0_0")
        ]
    );
    let topic = &shown["topics"][0];
    assert_eq!(
        topic["title"],
        "hard: box_1_0_0 × box_0_0_0 at step 1 (t=1)"
    );
    let selected: Vec<&str> = topic["viewpoints"][0]["selected"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["authoring_tool_id"].as_str().unwrap())
        .collect();
    assert_eq!(selected, ["box_1_0_0", "box_0_0_0"]);
}

/// Several records: topics from each, titled with the record's file name;
/// `--bcf-snapshot none` writes none; a clear run writes an empty file.
#[test]
fn records_name_their_topics_and_snapshots_can_be_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let model = grid(dir.path());
    let a = record(
        dir.path(),
        "a.jsonl",
        &[pose(0, "box_0_0_0", [7.0, 0.0, 0.0])],
    );
    let b = record(
        dir.path(),
        "b.jsonl",
        &[
            pose(0, "box_0_0_0", [-30.0, 0.0, 0.0]),
            pose(1, "box_1_1_1", [10.0, 10.0, 3.0]),
        ],
    );
    let bcf = path(dir.path(), "two.bcfzip");
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &a,
        &b,
        "--json",
        "--bcf",
        &bcf,
        "--bcf-snapshot",
        "none",
    ]);
    let run = report(&out);
    assert_eq!(run["bcf"]["topics"], 2);
    assert_eq!(run["bcf"]["snapshots"], 0);
    let shown = json(&dmu(&["bcf", "show", &bcf, "--json"]));
    let titles: Vec<&str> = shown["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            assert!(t["viewpoints"][0]["snapshot"].is_null());
            t["title"].as_str().unwrap()
        })
        .collect();
    assert_eq!(
        titles,
        [
            "a.jsonl: hard: box_0_0_0 × box_1_0_0 at step 0 (t=0)",
            "b.jsonl: hard: box_1_1_1 × box_1_1_0 at step 1 (t=1)",
        ]
    );
    // Text output says where the file went.
    let clear = record(
        dir.path(),
        "clear.jsonl",
        &[pose(0, "box_0_0_0", [-30.0, 0.0, 0.0])],
    );
    let empty = path(dir.path(), "empty.bcfzip");
    let out = dmu(&["collide", &model, "--record", &clear, "--bcf", &empty]);
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains(&format!(
        "bcf: 0 topics (0 with snapshots) written to {empty}"
    )));
    assert_eq!(
        json(&dmu(&["bcf", "show", &empty, "--json"]))["topics"],
        serde_json::json!([])
    );
    // --bcf wants a .bcfzip name.
    let out = dmu(&[
        "collide",
        &model,
        "--record",
        &clear,
        "--bcf",
        &path(dir.path(), "x.zip"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains(".bcfzip"));
}

/// `bcf show` on hostile files: one line naming the file, exit 2.
#[test]
fn bcf_show_refuses_hostile_files_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let not_zip = path(dir.path(), "junk.bcfzip");
    std::fs::write(&not_zip, b"PK\x03\x04 not really").unwrap();
    for file in [
        not_zip.as_str(),
        dir.path().to_str().unwrap(),
        &path(dir.path(), "missing.bcfzip"),
    ] {
        let out = dmu(&["bcf", "show", file]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with("dmu: error: ") && err.contains(file),
            "{err}"
        );
    }
}

/// A zip of `(name, bytes)` entries, stored.
fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
    use std::io::Write as _;
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, bytes) in entries {
        zip.start_file(*name, zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// Issue 48: `dmu bcf show` printed untrusted titles raw (terminal escape
/// codes, and a newline that forged a `dmu: error:` line), and a NUL byte of
/// an entry name reached the terminal through the error. Both are escaped:
/// nothing the file holds becomes a control character on the terminal or a
/// line of its own.
#[test]
fn issue_48_bcf_show_escapes_what_the_file_says() {
    let dir = tempfile::tempdir().unwrap();
    let markup = "<Markup><Topic Guid=\"t1\"><Title>pump&#10;dmu: error: forged \u{9b}2J \u{202e}x</Title>\
        <CreationAuthor>a&#13;b&#9;c</CreationAuthor></Topic></Markup>";
    let file = path(dir.path(), "hostile.bcfzip");
    std::fs::write(
        &file,
        zip_of(&[
            ("bcf.version", br#"<Version VersionId="2.1"/>"#),
            ("t1/markup.bcf", markup.as_bytes()),
        ]),
    )
    .unwrap();
    let out = dmu(&["bcf", "show", &file]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        text.lines().count(),
        2,
        "a line for the file, one for the topic:\n{text}"
    );
    assert!(
        !text.lines().any(|l| l.starts_with("dmu: error")),
        "a forged line:\n{text}"
    );
    assert!(
        !text.chars().any(|c| c.is_control() && c != '\n'),
        "a control character reached the terminal:\n{text:?}"
    );
    assert!(
        text.contains("pump\\ndmu: error: forged \\u{9b}2J \\u{202e}x"),
        "{text}"
    );
    // The JSON keeps the text as it is (JSON escapes it itself).
    let v = json(&dmu(&["bcf", "show", &file, "--json"]));
    assert_eq!(v["topics"][0]["author"], "a\rb\tc");

    let nul = path(dir.path(), "nul.bcfzip");
    std::fs::write(&nul, zip_of(&[("t1/mark\0up.bcf", b"<Markup/>")])).unwrap();
    let out = dmu(&["bcf", "show", &nul]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err:?}");
    assert!(
        !err.contains('\0') && err.contains("mark\\0up.bcf"),
        "{err:?}"
    );
}
