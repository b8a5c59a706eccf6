//! Hostile input end to end (issue 20): every class found by a hostile sweep of
//! the CLI — data loss, reads outside the model, crashes, hangs, wrong answers,
//! unclear errors — gives a clear error with exit code 2, or the right answer.
//! Included from `tests.rs` as `mod hostile;`.

use std::os::unix::fs::FileTypeExt as _;
use std::path::Path;
use std::process::Output;

use serde_json::{Value, json};

use super::{dmu, json, path, render};

/// A refusal: exit code 2 (never 101, a panic, or a signal), one error on stderr
/// that says `needle`.
fn refused(out: &Output, needle: &str) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "expected a refusal: {err}");
    assert!(err.contains(needle), "{needle:?} not in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// The bytes of one triangle, (0,0,0) (1,0,0) (0,1,0), as little-endian f32.
fn triangle_bytes() -> Vec<u8> {
    [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// A glTF document of one triangle read from buffer `uri`, placed by `nodes`
/// (the last node holds the mesh; each node is the child of the one before).
fn gltf(uri: &str, nodes: &[Value]) -> Value {
    let mut nodes: Vec<Value> = nodes.to_vec();
    let last = nodes.len() - 1;
    nodes[last]["mesh"] = json!(0);
    for (i, node) in nodes[..last].iter_mut().enumerate() {
        node["children"] = json!([i + 1]);
    }
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": uri}],
    })
}

fn write_gltf(dir: &Path, name: &str, doc: &Value) -> String {
    let file = path(dir, name);
    std::fs::write(&file, serde_json::to_vec(doc).unwrap()).unwrap();
    file
}

/// A grid of n×n×n boxes generated into `dir` as `name`.
fn grid(dir: &Path, n: u32, name: &str) -> String {
    let file = path(dir, name);
    json(&dmu(&[
        "generate",
        "grid",
        "--n",
        &n.to_string(),
        "-o",
        &file,
        "--json",
    ]));
    file
}

fn named(name: &str) -> Value {
    json!({ "name": name })
}

/// `dmu move` onto its own store saves a store there (it used to leave glTF text
/// in place of the store), and an output of unknown type is refused untouched.
#[test]
fn move_writes_the_format_its_output_names() {
    let dir = tempfile::tempdir().unwrap();
    let store = grid(dir.path(), 2, "g.dmu");
    let moved = json(&dmu(&[
        "move",
        &store,
        "--part",
        "box_1_1_1",
        "--translate",
        "10,0,0",
        "-o",
        &store,
        "--json",
    ]));
    assert_eq!(moved["format"], "edits");
    assert!(std::fs::read(&store).unwrap().starts_with(b"DMUSTORE"));
    // Moving it back by nothing reports where it is now: where it was moved to.
    let again = json(&dmu(&[
        "move",
        &store,
        "--part",
        "box_1_1_1",
        "--translate",
        "0,0,0",
        "-o",
        &path(dir.path(), "copy.glb"),
        "--json",
    ]));
    assert_eq!(again["translation_before"], moved["translation_after"]);
    assert_eq!(again["format"], "gltf");
    let before = std::fs::read(&store).unwrap();
    let out = dmu(&[
        "move",
        &store,
        "--part",
        "box_1_1_1",
        "--translate",
        "1,0,0",
        "-o",
        &path(dir.path(), "g.txt"),
    ]);
    refused(&out, "unknown output format");
    assert!(!dir.path().join("g.txt").exists());
    assert_eq!(std::fs::read(&store).unwrap(), before);
    // Other writers: a PNG is never written over a model, nor a store over glTF.
    let glb = path(dir.path(), "copy.glb");
    let model = std::fs::read(&glb).unwrap();
    for args in [
        vec!["render", "--eye", "0,0,0", "--target", "1,0,0", "-o", &glb],
        vec!["import", &glb, "-o", &glb],
        vec![
            "generate",
            "grid",
            "--n",
            "2",
            "-o",
            &path(dir.path(), "g.txt"),
        ],
    ] {
        let err = String::from_utf8_lossy(&dmu(&args).stderr).into_owned();
        assert!(
            err.contains("give a name ending in") || err.contains("unknown output format"),
            "{args:?}: {err}"
        );
    }
    assert_eq!(std::fs::read(&glb).unwrap(), model);
    assert!(!dir.path().join("g.txt").exists());
}

/// A buffer URI may only name a regular file inside the model's folder: not a
/// parent folder's file, not an absolute path, not a link out, not a scheme,
/// not a pipe (which would block) — and nothing of the outside file reaches the
/// output.
#[test]
fn buffers_outside_the_model_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    let secret = dir.path().join("secret.bin");
    std::fs::write(&secret, triangle_bytes()).unwrap();
    std::os::unix::fs::symlink(&secret, model.join("link.bin")).unwrap();
    let fifo = model.join("fifo.bin");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let root = named("root");
    for (uri, needle) in [
        ("../secret.bin", "outside the model's folder"),
        (secret.to_str().unwrap(), "outside the model's folder"),
        ("link.bin", "outside the model's folder"),
        ("%2E%2E/secret.bin", "outside the model's folder"),
        ("file:///etc/passwd", "outside the model's folder"),
        ("fifo.bin", "not a regular file"),
        (".", "not a regular file"),
    ] {
        let file = write_gltf(&model, "m.gltf", &gltf(uri, std::slice::from_ref(&root)));
        let out = dmu(&[
            "move",
            &file,
            "--part",
            "root",
            "--translate",
            "1,0,0",
            "-o",
            &path(dir.path(), "out.glb"),
        ]);
        let err = refused(&out, needle);
        assert!(err.contains("buffers[0]"), "{err}");
        assert!(!dir.path().join("out.glb").exists(), "{uri}");
    }
    // Inside the folder the same bytes import.
    std::fs::copy(&secret, model.join("tri.bin")).unwrap();
    let file = write_gltf(&model, "m.gltf", &gltf("tri.bin", &[root]));
    assert_eq!(json(&dmu(&["info", &file, "--json"]))["triangles"], 1);
}

/// A buffer's declared length bounds what is read: a 256 MiB file behind a
/// 36-byte `byteLength` costs 36 bytes, and only they reach the output.
#[test]
fn declared_lengths_bound_what_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.bin");
    let f = std::fs::File::create(&big).unwrap();
    std::io::Write::write_all(&mut &f, &triangle_bytes()).unwrap();
    f.set_len(256 << 20).unwrap(); // sparse: costs no disk
    let file = write_gltf(dir.path(), "m.gltf", &gltf("big.bin", &[named("root")]));
    let out = path(dir.path(), "out.glb");
    json(&dmu(&[
        "move",
        &file,
        "--part",
        "root",
        "--translate",
        "1,0,0",
        "-o",
        &out,
        "--json",
    ]));
    let written = std::fs::metadata(&out).unwrap().len();
    assert!(written < 4096, "the output holds {written} bytes");
}

/// Finite node values whose product overflows (1e200 scales on a parent and a
/// child; a 1e308 offset on a part) are an import error naming the node's path.
#[test]
fn transforms_that_overflow_are_import_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tri.bin"), triangle_bytes()).unwrap();
    let scaled = |name: &str| json!({"name": name, "scale": [1e200, 1e200, 1e200]});
    let file = write_gltf(
        dir.path(),
        "scale.gltf",
        &gltf("tri.bin", &[scaled("parent"), scaled("child")]),
    );
    let err = refused(&dmu(&["info", &file]), "parent/child");
    assert!(err.contains("not finite"), "{err}");
    let far = json!({"name": "far", "translation": [1.7e308, 0, 0], "scale": [1e308, 1, 1]});
    let file = write_gltf(dir.path(), "far.gltf", &gltf("tri.bin", &[far]));
    refused(&dmu(&["info", &file]), "world box is not finite");
    // A typed move past f64's range is refused, the file untouched.
    let grid = grid(dir.path(), 2, "g.glb");
    let far = [
        "move",
        &grid,
        "--part",
        "box_0_0_0",
        "--translate",
        "6e14,0,0",
        "-o",
        &grid,
    ];
    json(&dmu(&[&far[..], &["--json"]].concat()));
    let before = std::fs::read(&grid).unwrap();
    refused(&dmu(&far), "beyond");
    assert_eq!(std::fs::read(&grid).unwrap(), before);
}

/// Every size a user types has a limit, refused with the range (exit 2), where
/// zero used to panic and huge values to hang.
#[test]
fn sizes_out_of_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = path(dir.path(), "x.glb");
    let png = path(dir.path(), "x.png");
    for args in [
        vec![
            "render", "--eye", "0,0,0", "--target", "1,0,0", "--near", "0", "-o", &png,
        ],
        vec![
            "render", "--eye", "0,0,0", "--target", "1,0,0", "--fov", "180", "-o", &png,
        ],
        vec!["walk", "--fps", "0"],
        vec!["walk", "--range", "5..5"],
        vec!["walk", "--width", "0"],
        vec!["bench", "tree", "--triangles", "0"],
        vec!["bench", "tree", "--rays", "0"],
        vec!["bench", "pick", "--rays", "0"],
        vec!["bench", "pick", "--threads", "0"],
        vec!["bench", "pick", "--metre", "0"],
        vec!["bench", "pick", "--metre", "nan"],
        vec!["generate", "grid", "--n", "100000", "-o", &out],
        vec!["generate", "plant", "--triangles", "5G", "-o", &out],
        vec!["info", "--plant-triangles", "0"],
        vec!["info", "--chunk-triangles", "4000000000"],
        vec!["collide", "--record", "r.jsonl", "--clearance", "inf"],
    ] {
        let result = dmu(&args);
        let err = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("out of range") || err.contains("not in") || err.contains("invalid value"),
            "{args:?}: {err}"
        );
    }
}

/// A ray's direction may have any finite non-zero length: 1e-300 and 1e160
/// find the same part at the same distance (to rounding) as a unit direction
/// (they used to hit another part at distance 0, and report `"distance": null`).
#[test]
fn pick_directions_of_any_length_agree() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path(), 2, "g.glb");
    let pick = |d: &str| {
        json(&dmu(&[
            "pick",
            &grid,
            "--ray",
            &format!("-20,0,0,{d},0,0"),
            "--json",
        ]))
    };
    let unit = pick("1");
    assert_eq!(unit["part"], "box_0_0_0");
    assert_eq!(unit["distance"], 18.0);
    for d in ["1e-300", "4.9e-324", "1e160", "1.7e308"] {
        let hit = pick(d);
        assert_eq!(hit["part"], unit["part"], "{d}");
        let distance = hit["distance"].as_f64().unwrap();
        assert!((distance - 18.0).abs() < 1e-12, "{d}: {distance}");
    }
    refused(&dmu(&["pick", &grid, "--ray", "0,0,0,0,0,0"]), "non-zero");
}

/// A store named `.glb` is read as the store it is; a UTF-8 byte-order mark does
/// not break a record; the OS's reason appears once, not twice.
#[test]
fn misnamed_files_and_marks_read_and_errors_say_things_once() {
    let dir = tempfile::tempdir().unwrap();
    let store = grid(dir.path(), 2, "g.dmu");
    let misnamed = path(dir.path(), "g.glb");
    std::fs::copy(&store, &misnamed).unwrap();
    assert_eq!(json(&dmu(&["info", &misnamed, "--json"]))["parts"], 8);

    let record = path(dir.path(), "r.jsonl");
    std::fs::write(
        &record,
        // Down, away from the grid: the 100 mm jump is swept (longer than
        // the box) and meets nothing.
        "\u{feff}{\"t\": 0, \"part\": \"box_0_0_0\", \"translation\": [0, 0, -100], \"rotation\": [0, 0, 0, 1]}\n",
    )
    .unwrap();
    let out = dmu(&["collide", &store, "--record", &record, "--json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let not_gltf = path(dir.path(), "list.gltf");
    std::fs::write(&not_gltf, "[]").unwrap();
    refused(&dmu(&["info", &not_gltf]), "not a glTF document");
    let err = refused(
        &dmu(&["info", &path(dir.path(), "missing.glb")]),
        "missing.glb",
    );
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

/// A headless render prints nothing on stderr (Mesa's device-select layer used
/// to print `XDG_RUNTIME_DIR is invalid` twice), and its PNG replaces the old
/// one whole.
#[test]
fn a_headless_render_says_only_what_it_means() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let png = path(dir.path(), "r.png");
        let args = [
            "--plant-triangles",
            "20k",
            "--eye",
            "0,0,0",
            "--target",
            "1,0,0",
            "-o",
            &png,
        ];
        let out = render(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert_eq!(err, "", "a headless render prints no warnings");
        let image = std::fs::read(&png).unwrap();
        assert!(image.starts_with(b"\x89PNG"));
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary file left"
        );
    });
}

/// Second sweep: no input or output that is not a regular file (a pipe would
/// block, a device never ends or is replaced); a bare file name's buffers are
/// found in the current folder; a meshopt view cannot ask for more than its
/// byteLength; an eye beyond the world is refused.
#[test]
fn pipes_devices_bare_names_meshopt_counts_and_far_eyes() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.dmu");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let pipe = fifo.to_str().unwrap();
    // Each would block forever on the pipe (the test would hang, not fail).
    refused(&dmu(&["info", pipe]), "not a regular file");
    let pipe_glb = dir.path().join("pipe.glb");
    std::process::Command::new("mkfifo")
        .arg(&pipe_glb)
        .status()
        .unwrap();
    let store = path(dir.path(), "x.dmu");
    refused(
        &dmu(&["import", pipe_glb.to_str().unwrap(), "-o", &store]),
        "not a regular file",
    );
    let grid = grid(dir.path(), 2, "g.glb");
    refused(
        &dmu(&["collide", &grid, "--record", pipe]),
        "not a regular file",
    );
    refused(
        &dmu(&["generate", "grid", "--n", "2", "-o", pipe]),
        "not a regular file",
    );
    let png_pipe = dir.path().join("pipe.png");
    std::process::Command::new("mkfifo")
        .arg(&png_pipe)
        .status()
        .unwrap();
    refused(
        &dmu(&[
            "render",
            "--plant-triangles",
            "20k",
            "--eye",
            "0,0,0",
            "--target",
            "1,0,0",
            "-o",
            png_pipe.to_str().unwrap(),
        ]),
        "not a regular file",
    );
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    // `dmu info model.gltf` from the model's folder.
    std::fs::write(dir.path().join("tri.bin"), triangle_bytes()).unwrap();
    write_gltf(dir.path(), "m.gltf", &gltf("tri.bin", &[named("root")]));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dmu"))
        .current_dir(dir.path())
        .args(["info", "m.gltf", "--json"])
        .output()
        .unwrap();
    assert_eq!(json(&out)["triangles"], 1);

    // A meshopt view whose count x byteStride is not its byteLength (it asked
    // for 51 GB and the allocation aborted the process).
    let mut doc = gltf("tri.bin", &[named("root")]);
    doc["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
    doc["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
    doc["bufferViews"][0]["extensions"] = json!({"EXT_meshopt_compression": {
        "buffer": 0, "byteOffset": 0, "byteLength": 36, "byteStride": 12,
        "count": 4294967295u64, "mode": "ATTRIBUTES"}});
    let file = write_gltf(dir.path(), "meshopt.gltf", &doc);
    refused(&dmu(&["info", &file]), "is not the view's byteLength");

    refused(
        &dmu(&[
            "render",
            &grid,
            "--eye",
            "1e160,0,0",
            "--target",
            "0,0,0",
            "-o",
            &path(dir.path(), "r.png"),
        ]),
        "within",
    );
}

/// A generated plant placed at the edge of the world is refused, not a panic.
#[test]
fn a_plant_beyond_the_world_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = path(dir.path(), "p.dmu");
    let args = [
        "generate",
        "plant",
        "--triangles",
        "10k",
        "--origin",
        "1e15,0,0",
        "-o",
        &out,
    ];
    refused(&dmu(&args), "--origin must lie within");
    assert!(!dir.path().join("p.dmu").exists());
}

/// Second sweep, lenient inputs now refused: a node matrix that is not affine,
/// a record line that is an array, an allow pair of one part, a zero memory
/// budget.
#[test]
fn lenient_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tri.bin"), triangle_bytes()).unwrap();
    let projective =
        json!({"name": "p", "matrix": [1, 0, 0, 10, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 2]});
    let file = write_gltf(dir.path(), "m.gltf", &gltf("tri.bin", &[projective]));
    refused(&dmu(&["info", &file]), "not [0, 0, 0, 1]");
    let grid = grid(dir.path(), 2, "g.glb");
    let record = path(dir.path(), "r.jsonl");
    std::fs::write(&record, "[0, \"box_0_0_0\", [0, 0, 9], [0, 0, 0, 1]]\n").unwrap();
    refused(
        &dmu(&["collide", &grid, "--record", &record]),
        "one JSON object",
    );
    std::fs::write(
        &record,
        "{\"t\": 0, \"part\": \"box_0_0_0\", \"translation\": [0, 0, 9], \"rotation\": [0, 0, 0, 1]}\n",
    )
    .unwrap();
    refused(
        &dmu(&[
            "collide",
            &grid,
            "--record",
            &record,
            "--allow",
            "box_0_0_0,#0",
        ]),
        "names one part twice",
    );
    let out = dmu(&["walk", "--memory-budget", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("more than 0 bytes"));
}

/// One part moved far away makes the model's diagonal huge; the default near
/// plane (a fraction of it) used to clip away everything near the eye, so the
/// render came out empty.
#[test]
fn a_far_part_does_not_clip_what_is_near() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let grid = grid(dir.path(), 3, "g.dmu");
        let far = path(dir.path(), "far.dmu");
        let args = [
            "move",
            &grid,
            "--part",
            "#1",
            "--translate",
            "1e6,0,0",
            "-o",
            &far,
            "--json",
        ];
        json(&dmu(&args));
        let png = path(dir.path(), "r.png");
        let args = [
            &far, "--eye", "50,50,50", "--target", "0,0,0", "--size", "64x64", "-o", &png, "--json",
        ];
        let out = render(&args);
        let frames = json(&out)["frames"].clone();
        let drawn = frames[0]["triangles_drawn"].as_u64().unwrap();
        assert!(drawn > 100, "{drawn} triangles drawn near the eye");
    });
}

/// `dmu import` reads the JSON as a stream (issue 14): a document cut short,
/// counts far beyond the file, and broken accessors and nodes each give one
/// line naming the file and the element (exit 2), and no store.
#[test]
fn a_streamed_import_names_the_broken_element() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tri.bin"), triangle_bytes()).unwrap();
    let store = path(dir.path(), "out.dmu");
    let nodes: Vec<Value> = (0..200).map(|i| named(&format!("n{i}"))).collect();
    let good = gltf("tri.bin", &nodes);
    let text = serde_json::to_vec(&good).unwrap();
    let cut = text.windows(6).position(|w| w == b"\"n100\"").unwrap();
    let mut cases: Vec<(Vec<u8>, &'static str)> = vec![(text[..cut].to_vec(), "EOF while parsing")];
    let mut edit = |change: &dyn Fn(&mut Value), needle: &'static str| {
        let mut doc = good.clone();
        change(&mut doc);
        cases.push((serde_json::to_vec(&doc).unwrap(), needle));
    };
    edit(
        &|d: &mut Value| d["accessors"][0]["count"] = json!(4_000_000_000u64),
        "accessors[0]: 4000000000 elements",
    );
    // A count near 2^64 used to overflow the streaming import's batch estimate
    // (a panic in a debug build).
    edit(
        &|d: &mut Value| d["accessors"][0]["count"] = json!(10_000_000_000_000_000_000u64),
        "accessors[0]: 10000000000000000000 elements",
    );
    edit(
        &|d: &mut Value| d["nodes"][0]["children"] = json!([1_000_000_000_000_000u64]),
        "nodes[0].children 1000000000000000 is out of range",
    );
    edit(
        &|d: &mut Value| d["accessors"][0]["bufferView"] = json!(9),
        "accessors[0]: bufferView 9 does not exist",
    );
    edit(
        &|d: &mut Value| d["nodes"][199]["mesh"] = json!(7),
        "nodes[199].mesh: mesh 7 does not exist",
    );
    edit(&|d: &mut Value| d["nodes"][5] = json!("n5"), "nodes[5]");
    edit(
        &|d: &mut Value| {
            d["nodes"][3]["matrix"] = json!([1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
        },
        "nodes[3].matrix: the last row",
    );
    for (i, (bytes, needle)) in cases.iter().enumerate() {
        let name = format!("case{i}.gltf");
        let file = path(dir.path(), &name);
        std::fs::write(&file, bytes).unwrap();
        let err = refused(&dmu(&["import", &file, "-o", &store]), needle);
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(&name), "{err}");
        assert!(!Path::new(&store).exists(), "{name}: a store was written");
    }
    // The unbroken file imports.
    let file = write_gltf(dir.path(), "good.gltf", &good);
    json(&dmu(&["import", &file, "-o", &store, "--json"]));
}

/// Issue 48: an empty glTF (no nodes) panicked `dmu tradeoffs`, `dmu
/// farfield build` (a near plane of infinity) and `dmu bench tree`
/// (`below(0)`). Every command on it answers or refuses in one line, exit 0
/// or 2, never a panic; those that need triangles say so.
#[test]
fn issue_48_an_empty_model_is_refused_where_triangles_are_needed() {
    let dir = tempfile::tempdir().unwrap();
    let empty = write_gltf(
        dir.path(),
        "empty.gltf",
        &json!({"asset": {"version": "2.0"}}),
    );
    let store = path(dir.path(), "empty.dmu");
    assert!(dmu(&["import", &empty, "-o", &store]).status.success());
    let out_dir = path(dir.path(), "tradeoffs");
    for (args, needs) in [
        (
            vec!["tradeoffs", &empty, "--quick", "--out", &out_dir],
            true,
        ),
        (vec!["bench", "tree", &empty], true),
        (vec!["bench", "pick", &empty], true),
        (vec!["farfield", "build", &store], true),
        (vec!["info", &store], false),
        (vec!["pick", &empty, "--ray", "0,0,0,1,0,0"], false),
    ] {
        let out = dmu(&args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        if needs {
            let err = refused(&out, "no triangles");
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        } else {
            assert!(
                out.status.code() == Some(0) || out.status.code() == Some(2),
                "{args:?}: {:?} {err}",
                out.status
            );
        }
    }
}

/// Issue 48: `dmu farfield build --cell-size` within its documented range
/// listed every grid cell with no cap (7.5 GB in 15 s at 1e-9): refused at
/// once, saying which cell size would do.
#[test]
fn issue_48_a_tiny_far_field_cell_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let store = super::generated_plant(dir.path(), "10k");
    let started = std::time::Instant::now();
    let out = dmu(&["farfield", "build", &store, "--cell-size", "1e-9"]);
    let err = refused(&out, "larger cell size");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(started.elapsed().as_secs() < 60, "{:?}", started.elapsed());
}

/// Issue 48: errors printed numbers in full (`1e300` as 301 digits); every
/// number in a message has at most six significant digits.
#[test]
fn issue_48_numbers_in_errors_are_short() {
    let dir = tempfile::tempdir().unwrap();
    let grid = grid(dir.path(), 2, "grid.glb");
    let record = path(dir.path(), "far.jsonl");
    std::fs::write(
        &record,
        "{\"t\": 0, \"part\": \"box_0_0_0\", \"translation\": [0, 0, 0], \"rotation\": [1e300, 0, 0, 1]}\n",
    )
    .unwrap();
    for args in [
        vec!["collide", &grid, "--record", &record],
        vec![
            "collide",
            &grid,
            "--record",
            &record,
            "--clearance",
            "1e300",
        ],
    ] {
        let out = dmu(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let digits = err
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(digits <= 12, "{args:?}: a {digits}-digit number: {err}");
    }
}
