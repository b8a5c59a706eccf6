//! `dmu pick --rays` end to end: one result per ray in input order, equal to
//! a loop of single `--ray` picks; standard input; errors naming the line.
//! Included from `tests.rs` as `mod pick_rays;`.

use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use dmu_samples::Rng;
use serde_json::Value;

use super::{dmu, json, path};

/// A 3x3x3 grid of boxes of side 4 at pitch 10 (box_i_j_k centred on
/// (10i, 10j, 10k)).
fn grid(dir: &Path) -> String {
    let file = path(dir, "grid.glb");
    json(&dmu(&[
        "generate", "grid", "--n", "3", "-o", &file, "--json",
    ]));
    file
}

/// stdout as JSON Lines, after checking that dmu succeeded.
fn json_lines(out: &Output) -> Vec<Value> {
    assert!(
        out.status.success(),
        "dmu failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

/// `dmu ARGS` with `input` on standard input.
fn dmu_with_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_dmu"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run dmu");
    let mut stdin = child.stdin.take().unwrap();
    let input = input.to_vec();
    // Written from a thread so that a full stdout pipe cannot block both sides.
    let writer = std::thread::spawn(move || stdin.write_all(&input));
    let out = child.wait_with_output().expect("wait for dmu");
    writer.join().unwrap().expect("write stdin");
    out
}

/// Random rays about the grid: aimed at a random point inside it (mostly hits)
/// or in a random direction (mostly misses).
fn random_rays(rng: &mut Rng, n: usize) -> Vec<[f64; 6]> {
    (0..n)
        .map(|_| {
            let o = [(); 3].map(|()| rng.range(-40.0, 60.0));
            let d = if rng.chance(0.5) {
                let target = [(); 3].map(|()| rng.range(-2.0, 22.0));
                [0, 1, 2].map(|i| target[i] - o[i])
            } else {
                [(); 3].map(|()| rng.range(-1.0, 1.0))
            };
            [o[0], o[1], o[2], d[0], d[1], d[2]]
        })
        .collect()
}

/// Each ray as a line, in both accepted forms, with blank lines between some.
fn rays_file(rays: &[[f64; 6]]) -> String {
    let mut text = String::new();
    for (i, r) in rays.iter().enumerate() {
        if i % 2 == 0 {
            let [ox, oy, oz, dx, dy, dz] = r;
            text +=
                &format!("{{\"origin\": [{ox}, {oy}, {oz}], \"direction\": [{dx}, {dy}, {dz}]}}\n");
        } else {
            text += &format!("{}\n", serde_json::to_string(r).unwrap());
        }
        if i % 7 == 3 {
            text += "  \n";
        }
    }
    text
}

fn comma_separated(r: &[f64; 6]) -> String {
    r.map(|v| v.to_string()).join(",")
}

/// The oracle: one `dmu pick --ray` process per ray gives what one `--rays`
/// run gives, ray by ray, in order, for the nearest hit and for `--all`.
#[test]
fn rays_give_what_single_picks_give_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path());
    let rays = random_rays(&mut Rng::new(18), 40);
    let file = path(dir.path(), "rays.jsonl");
    std::fs::write(&file, rays_file(&rays)).unwrap();
    for all in [false, true] {
        let mut args = vec!["pick", &grid, "--rays", &file, "--json"];
        if all {
            args.push("--all");
        }
        let out = dmu(&args);
        let bulk = json_lines(&out);
        assert_eq!(bulk.len(), rays.len(), "one result per ray");
        let text = String::from_utf8(out.stdout).unwrap();
        for ((ray, got), line) in rays.iter().zip(&bulk).zip(text.lines()) {
            let ray = comma_separated(ray);
            let mut args = vec!["pick", &grid, "--ray", &ray, "--json"];
            if all {
                args.push("--all");
            }
            let single = json(&dmu(&args));
            assert_eq!(got, &single, "ray {ray}, --all {all}");
            // Byte for byte what `--ray --json` prints, made compact.
            assert_eq!(line, serde_json::to_string(&single).unwrap(), "ray {ray}");
        }
        if !all {
            let hits = bulk.iter().filter(|v| v["hit"] == true).count();
            assert!(
                hits > 5 && hits < rays.len() - 5,
                "{hits} hits of {}: both hits and misses",
                rays.len()
            );
        }
    }
}

/// Over several blocks of 4096 rays, the results keep the input order: rays
/// up the grid's columns hit the bottom box at 98 (analytic, to rounding), rays between the
/// columns miss. The same input on standard input gives the same output.
#[test]
fn many_rays_keep_their_order_and_stdin_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path());
    let mut rng = Rng::new(7);
    let mut text = String::new();
    let mut want: Vec<Option<String>> = Vec::new();
    for _ in 0..10_000 {
        let (i, j) = (rng.below(3), rng.below(3));
        let (x, y) = (10.0 * i as f64, 10.0 * j as f64);
        if rng.chance(0.5) {
            // Within the column's footprint, side 4 about (x, y).
            let (dx, dy) = (rng.range(-1.9, 1.9), rng.range(-1.9, 1.9));
            text += &format!("[{}, {}, -100, 0, 0, 1]\n", x + dx, y + dy);
            want.push(Some(format!("box_{i}_{j}_0")));
        } else {
            // Between columns: x in (2, 8) past column i.
            text += &format!("[{}, {}, -100, 0, 0, 1]\n", x + rng.range(2.5, 7.5), y);
            want.push(None);
        }
    }
    let file = path(dir.path(), "column.jsonl");
    std::fs::write(&file, &text).unwrap();
    let out = dmu(&["pick", &grid, "--rays", &file, "--json"]);
    let got = json_lines(&out);
    assert_eq!(got.len(), want.len());
    for (n, (got, want)) in got.iter().zip(&want).enumerate() {
        match want {
            Some(part) => {
                assert_eq!(got["part"], part.as_str(), "ray {n}");
                let distance = got["distance"].as_f64().unwrap();
                assert!((distance - 98.0).abs() < 1e-9, "ray {n}: {distance}");
            }
            None => assert_eq!(got, &serde_json::json!({"hit": false}), "ray {n}"),
        }
    }
    let piped = dmu_with_stdin(&["pick", &grid, "--rays", "-", "--json"], text.as_bytes());
    assert!(piped.status.success());
    assert_eq!(piped.stdout, out.stdout, "stdin gives what the file gives");
}

/// Text output names each ray's line; a miss says so.
#[test]
fn rays_as_text_name_their_lines() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path());
    let input = b"[0, 0, -100, 0, 0, 1]\n\n[5, 5, -100, 0, 0, 1]\n";
    let out = dmu_with_stdin(&["pick", &grid, "--rays", "-"], input);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("line 1: box_0_0_0 (#"), "{text}");
    assert!(lines[1].starts_with("  path "), "{text}");
    assert_eq!(lines[2], "line 3: no hit", "{text}");
}

/// A bad line stops the run with one line naming the file, the line and the
/// reason, exit 2, and no results for its block; --ray and --rays exclude each
/// other.
#[test]
fn bad_ray_lines_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path());
    let ok = "[0, 0, -100, 0, 0, 1]";
    let long = format!("[0, 0, -100, 0, 0, 1{}]", " ".repeat(5000));
    let cases: [(&[u8], &str); 9] = [
        (b"[1, 2, 3]", "line 2: invalid length 3"),
        (
            b"{\"origin\": [0, 0, 0]}",
            "line 2: missing field `direction`",
        ),
        (
            b"{\"origin\": [0, 0, 0], \"direction\": [1, 0, 0], \"up\": 1}",
            "line 2: unknown field `up`",
        ),
        (
            b"[0, 0, 0, 0, 0, 0]",
            "line 2: origin and direction must be finite and the direction non-zero",
        ),
        (b"[0, 0, 0, 1e999, 0, 0]", "line 2: number out of range"),
        (b"0 0 0 1 0 0", "line 2: expected {\"origin\""),
        (b"[0, 0, 0, 1, 0, \"z\"]", "line 2: invalid type"),
        (b"[0, 0, 0, 1, 0, \xff]", "line 2: not UTF-8"),
        (long.as_bytes(), "line 2: longer than 4096 bytes"),
    ];
    for (bad, want) in cases {
        let mut input = format!("{ok}\n").into_bytes();
        input.extend_from_slice(bad);
        input.extend_from_slice(format!("\n{ok}\n").as_bytes());
        let file = dir.path().join("bad.jsonl");
        std::fs::write(&file, &input).unwrap();
        let out = dmu(&["pick", &grid, "--rays", file.to_str().unwrap(), "--json"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{want}: {err}");
        assert!(
            err.contains("bad.jsonl: ") && err.contains(want) && err.lines().count() == 1,
            "{err:?} should name {want:?} in one line"
        );
        assert!(
            out.stdout.is_empty(),
            "{want}: nothing of the block printed"
        );
        let piped = dmu_with_stdin(&["pick", &grid, "--rays", "-"], &input);
        assert_eq!(piped.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&piped.stderr).contains(&format!("<stdin>: {want}")));
    }
    let missing = path(dir.path(), "missing.jsonl");
    let out = dmu(&["pick", &grid, "--rays", &missing]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.jsonl"));
    // A folder (as a pipe or a device) is refused before it is read.
    let folder = dir.path().to_str().unwrap();
    let out = dmu(&["pick", &grid, "--rays", folder]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a regular file"));
    let out = dmu(&["pick", &grid, "--rays", &missing, "--ray", "0,0,0,1,0,0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
    let out = dmu(&["pick", &grid]);
    assert_eq!(out.status.code(), Some(2), "a ray or rays are required");
}

/// `dmu bench pick` checks a sample of its picks against a brute force over
/// every triangle (and fails when one differs): on the built-in plant, every
/// random ray (aimed at a triangle) hits, and no checked pick differs.
#[test]
fn bench_pick_agrees_with_a_brute_force() {
    let out = dmu(&[
        "bench",
        "pick",
        "--triangles",
        "100k",
        "--rays",
        "400",
        "--sample",
        "40",
        "--threads",
        "2",
        "--json",
    ]);
    let report = json(&out);
    for kind in ["random", "camera"] {
        let r = &report[kind];
        assert_eq!(r["wrong"], serde_json::json!([]), "{kind}: {r}");
        assert_eq!(r["checked_by_brute_force"], 40, "{kind}");
        assert!(r["warm_us_per_ray_per_core"].as_f64().unwrap() > 0.0);
        assert!(r["chunk_bvhs_built"].as_u64().unwrap() > 0, "{kind}");
    }
    assert_eq!(report["random"]["hits"], report["random"]["rays"]);
    let camera_hits = report["camera"]["hits"].as_u64().unwrap();
    assert!(camera_hits > 0 && camera_hits < 400, "{camera_hits} of 400");
}
