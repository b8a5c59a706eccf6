//! The `dmu` binary end to end: generate, info, errors and exit codes; the
//! modules below take one command each (collide, bulk picks) or hostile input.

mod bcf;
mod collide;
mod explain;
mod farfield;
mod hostile;
mod kill;
mod pick_rays;
mod remote;
mod stereo_far;
mod tradeoffs;
mod walk_compare;

use std::path::Path;
use std::process::{Command, Output, Stdio};

use serde_json::Value;

fn dmu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dmu"))
        .args(args)
        .output()
        .expect("run dmu")
}

fn json(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "dmu failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

fn path(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

/// The built-in plant of `triangles` (e.g. "100k") as the store `p.dmu` in
/// `dir`, by `dmu generate`; its path.
fn generated_plant(dir: &Path, triangles: &str) -> String {
    let store = path(dir, "p.dmu");
    let out = dmu(&["generate", "plant", "--triangles", triangles, "-o", &store]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    store
}

/// `dmu render ARGS` as on a user's machine (without the `NODEVICE_SELECT` that
/// the test script sets for in-process GPU tests). Callers run inside
/// `dmu_testkit::with_gpu`: where this process has a device, so has `dmu`.
fn render(args: &[&str]) -> Output {
    on_gpu("render", args)
}

/// `dmu COMMAND ARGS` for a command that renders, as [`render`].
fn on_gpu(command: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dmu"))
        .env_remove("NODEVICE_SELECT")
        .arg(command)
        .args(args)
        .output()
        .expect("run dmu")
}

#[test]
fn generate_grid_then_info_reports_the_analytic_counts_and_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let file = path(dir.path(), "grid.glb");
    let gen_out = json(&dmu(&[
        "generate", "grid", "--n", "3", "-o", &file, "--json",
    ]));
    assert_eq!(gen_out["parts"], 27);
    let info = json(&dmu(&["info", &file, "--json"]));
    assert_eq!(info["parts"], 27);
    assert_eq!(info["instances"], 27);
    assert_eq!(info["meshes"], 1, "instancing survives the file");
    assert_eq!(info["triangles"], 27 * 12);
    assert_eq!(info["chunks"], 1);
    assert_eq!(info["chunk_instances"], 27);
    assert_eq!(info["materials"], 1);
    assert_eq!(info["assembly_depth"], 2);
    // Boxes of side 4 centred on a lattice of pitch 10: from -2 to 22.
    assert_eq!(info["bounds"]["min"], serde_json::json!([-2.0, -2.0, -2.0]));
    assert_eq!(info["bounds"]["max"], serde_json::json!([22.0, 22.0, 22.0]));
    let import_ms = info["import_ms"].as_f64().unwrap();
    assert!(
        import_ms.is_finite() && import_ms > 0.0,
        "import took {import_ms} ms"
    );
}

#[test]
fn generate_plant_hits_its_triangle_target() {
    let dir = tempfile::tempdir().unwrap();
    let file = path(dir.path(), "plant.gltf");
    json(&dmu(&[
        "generate",
        "plant",
        "--triangles",
        "50k",
        "--seed",
        "3",
        "-o",
        &file,
        "--json",
    ]));
    let info = json(&dmu(&["info", &file, "--json"]));
    let triangles = info["triangles"].as_f64().unwrap();
    assert!(
        (triangles - 50_000.0).abs() <= 0.05 * 50_000.0,
        "{triangles}"
    );
    assert!(info["parts"].as_u64().unwrap() > 10);
}

#[test]
fn info_without_a_file_uses_the_built_in_plant() {
    let info = json(&dmu(&["info", "--json"]));
    assert_eq!(info["source"], "built-in plant");
    assert!(info["triangles"].as_u64().unwrap() > 0);
}

#[test]
fn errors_name_the_file_and_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let missing = path(dir.path(), "missing.glb");
    let out = dmu(&["info", &missing]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("missing.glb") && err.contains("error"),
        "{err}"
    );

    let corrupt = path(dir.path(), "corrupt.glb");
    std::fs::write(&corrupt, b"glTF\x02\0\0\0\xff\xff\xff\xffnot really").unwrap();
    let out = dmu(&["info", &corrupt]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("corrupt.glb"));

    let out = dmu(&["info", &path(dir.path(), "model.obj")]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown file type"));

    let out = dmu(&[
        "generate",
        "plant",
        "--triangles",
        "ten",
        "-o",
        &path(dir.path(), "x.glb"),
    ]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "clap usage errors exit with 2 too"
    );
}

#[test]
fn a_failed_write_keeps_the_previous_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = path(dir.path(), "keep.glb");
    json(&dmu(&[
        "generate", "grid", "--n", "2", "-o", &file, "--json",
    ]));
    let before = std::fs::read(&file).unwrap();
    // Writing into a directory that does not exist fails before anything is touched.
    let bad = path(dir.path(), "no/such/dir/x.glb");
    assert_eq!(
        dmu(&["generate", "grid", "--n", "3", "-o", &bad])
            .status
            .code(),
        Some(2)
    );
    assert_eq!(std::fs::read(&file).unwrap(), before);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "no temporary files left: {leftovers:?}");
}

#[test]
fn pick_and_move_on_the_grid() {
    let dir = tempfile::tempdir().unwrap();
    let file = path(dir.path(), "grid.glb");
    json(&dmu(&[
        "generate", "grid", "--n", "3", "-o", &file, "--json",
    ]));
    // Up the first column: box_0_0_0 spans z in [-2, 2].
    let hit = json(&dmu(&["pick", &file, "--ray", "0,0,-100,0,0,2", "--json"]));
    assert_eq!(hit["hit"], true);
    assert_eq!(hit["part"], "box_0_0_0");
    assert_eq!(
        hit["distance"], 98.0,
        "distance in world units whatever |dir|"
    );
    assert_eq!(hit["point"], serde_json::json!([0.0, 0.0, -2.0]));
    let all = json(&dmu(&[
        "pick",
        &file,
        "--ray",
        "0,0,-100,0,0,1",
        "--all",
        "--json",
    ]));
    let distances: Vec<f64> = all["hits"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| h["distance"].as_f64().unwrap())
        .collect();
    assert_eq!(distances, [98.0, 102.0, 108.0, 112.0, 118.0, 122.0]);
    let miss = json(&dmu(&["pick", &file, "--ray", "5,5,-100,0,0,1", "--json"]));
    assert_eq!(miss["hit"], false);

    let moved = path(dir.path(), "moved.glb");
    let m = json(&dmu(&[
        "move",
        &file,
        "--part",
        "box_0_0_0",
        "--translate",
        "500,0,0",
        "--rotate-deg",
        "0,0,1,90",
        "-o",
        &moved,
        "--json",
    ]));
    assert_eq!(m["translation_after"], serde_json::json!([500.0, 0.0, 0.0]));
    let hit = json(&dmu(&["pick", &moved, "--ray", "0,0,-100,0,0,1", "--json"]));
    assert_eq!(
        (hit["part"].as_str(), hit["distance"].as_f64()),
        (Some("box_0_0_1"), Some(108.0))
    );
    let hit = json(&dmu(&[
        "pick",
        &moved,
        "--ray",
        "500,0,-100,0,0,1",
        "--json",
    ]));
    assert_eq!(
        (hit["part"].as_str(), hit["distance"].as_f64()),
        (Some("box_0_0_0"), Some(98.0))
    );

    let out = dmu(&["move", &file, "--part", "nope", "-o", &moved]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown part \"nope\""));
}

/// A reader that goes away (`dmu info --json | head -c 1`) ends dmu quietly:
/// no panic message, no panic exit code (101).
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_dmu"))
        .args(["info", "--plant-triangles", "10k", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run dmu");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for dmu");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_ne!(out.status.code(), Some(101), "{stderr}");
}

/// A malformed viewpoint is refused before any model or device is opened,
/// naming the option and the expected form.
#[test]
fn render_names_a_malformed_eye() {
    let out = dmu(&["render", "--eye", "1,2", "--target", "0,0,0", "-o", "x.png"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--eye") && stderr.contains("x,y,z"),
        "{stderr}"
    );
}
