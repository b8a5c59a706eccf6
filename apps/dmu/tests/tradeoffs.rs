//! `dmu tradeoffs --quick` end to end: the JSON's schema, the plots on disk
//! (each well-formed SVG, parsed by quick-xml), every knob's reference setting
//! at error 0, every figure finite. Included from `tests.rs`.

use std::path::Path;

use serde_json::Value;

use super::{dmu, json, path};

/// Whether `file` is well-formed XML whose root element is `<svg>`.
fn is_svg(file: &Path) -> bool {
    let text = std::fs::read_to_string(file).unwrap();
    let mut reader = quick_xml::Reader::from_str(&text);
    let mut root = None;
    let mut depth = 0usize;
    loop {
        match reader.read_event() {
            Ok(quick_xml::events::Event::Start(e)) => {
                if depth == 0 && root.is_none() {
                    root = Some(e.name().as_ref().to_vec());
                }
                depth += 1;
            }
            Ok(quick_xml::events::Event::End(_)) => depth -= 1,
            Ok(quick_xml::events::Event::Empty(e)) if depth == 0 && root.is_none() => {
                root = Some(e.name().as_ref().to_vec());
            }
            Ok(quick_xml::events::Event::Eof) => break,
            Ok(_) => {}
            Err(e) => panic!("{}: not well-formed XML: {e}", file.display()),
        }
    }
    depth == 0 && root.as_deref() == Some(b"svg".as_slice())
}

fn number(v: &Value, what: &str) -> f64 {
    let x = v
        .as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"));
    assert!(x.is_finite(), "{what} is not finite: {x}");
    x
}

#[test]
fn tradeoffs_quick_writes_plots_and_every_reference_setting_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let out = path(dir.path(), "report");
    // A smaller plant than --quick's 2M: the debug build's brute-force picks
    // and tree builds would take minutes on it.
    let v = json(&dmu(&[
        "tradeoffs",
        "--quick",
        "--plant-triangles",
        "200k",
        "--out",
        &out,
        "--json",
    ]));
    let skipped = v["skipped"].as_array().expect("skipped list");
    for s in skipped {
        // Rendering needs an adapter (lavapipe will do); CI has one.
        dmu_testkit::skip(format!("section skipped: {s}"));
    }
    let report = Path::new(v["report"].as_str().expect("report path"));
    assert_eq!(report, Path::new(&out).join("README.md"));
    let markdown = std::fs::read_to_string(report).unwrap();
    let knobs = v["knobs"].as_array().expect("knobs");
    let names: Vec<String> = knobs
        .iter()
        .map(|k| {
            format!(
                "{}: {}",
                k["section"].as_str().unwrap(),
                k["name"].as_str().unwrap()
            )
        })
        .collect();
    let mut wanted = vec![
        "loading: memory budget",
        "loading: load order",
        "tree: cell size, pick",
        "tree: cell size, move",
        "tree: chunk size",
        "collision: discrete step",
        "collision: continuous step",
        "collision: clearance",
        "collision: contact tolerance",
        "numerics: pick distance",
        "numerics: clearance",
        "numerics: transform",
        "numerics: store quantization",
    ];
    if skipped.is_empty() {
        wanted.extend([
            "rendering: coverage threshold",
            "rendering: occlusion re-check interval",
            "rendering: occlusion rounds",
            "rendering: proxy aim",
            "rendering: far field",
            "rendering: far field resolution",
            "rendering: far field mesh error",
            "rendering: far field skins",
            "rendering: stereo pair",
            "loading: predicted view",
        ]);
    }
    for w in &wanted {
        assert!(names.iter().any(|n| n == w), "no knob {w} in {names:?}");
    }
    for k in knobs {
        let name = k["name"].as_str().unwrap();
        for field in ["reference", "error_unit", "reading"] {
            assert!(
                k[field].as_str().is_some_and(|s| !s.is_empty()),
                "{name}: {field}"
            );
        }
        // Categories (load orders, stored types) have labels and no unit.
        let categorical = k["points"][0]["label"].is_string();
        assert!(
            k["unit"]
                .as_str()
                .is_some_and(|u| categorical || !u.is_empty()),
            "{name}: unit"
        );
        let points = k["points"].as_array().expect("points");
        assert!(points.len() >= 2, "{name}: {} points", points.len());
        for p in points {
            number(&p["setting"], "setting");
            assert!(number(&p["time_ms"], "time_ms") >= 0.0, "{name}: {p}");
            assert!(number(&p["error"], "error") >= 0.0, "{name}: {p}");
            assert!(p["error_unit"].as_str().is_some(), "{name}: {p}");
        }
        // The setting that is the reference itself has no error.
        if let Some(exact) = k["exact_setting"].as_f64() {
            let p = points
                .iter()
                .find(|p| p["setting"].as_f64() == Some(exact))
                .unwrap_or_else(|| panic!("{name}: no point at its reference setting {exact}"));
            assert_eq!(p["error"].as_f64(), Some(0.0), "{name}: {p}");
        }
        let plot = Path::new(k["plot"].as_str().expect("plot path"));
        assert!(is_svg(plot), "{}: not an SVG document", plot.display());
        let file = plot.file_name().unwrap().to_string_lossy();
        assert!(
            markdown.contains(&format!("]({file})")),
            "README lacks {file}"
        );
    }
    let svgs = std::fs::read_dir(&out)
        .unwrap()
        .filter(|e| {
            let p = e.as_ref().unwrap().path();
            p.extension().is_some_and(|x| x == "svg") && is_svg(&p)
        })
        .count();
    assert!(svgs >= 10, "{svgs} plots");
    // Swept checks miss nothing at any step; a discrete one misses boxes
    // once its steps outgrow the 8 mm window where the boxes overlap.
    let knob = |n: &str| knobs.iter().find(|k| k["name"] == n).unwrap();
    for n in [
        "continuous step",
        "auto step (swept past the part's thickness)",
    ] {
        assert!(
            knob(n)["points"]
                .as_array()
                .unwrap()
                .iter()
                .all(|p| p["error"] == 0.0),
            "{n}"
        );
    }
    // Far fields: every setting but none draws a fraction of the chunk
    // triangles, and the depth meshes are stored and drawn.
    if skipped.is_empty() {
        let far = knob("far field")["points"].as_array().unwrap();
        let extra = |p: &Value, e: &str| number(&p["extra"][e], e);
        let chunks = |p: &Value| extra(p, "chunk triangles a frame");
        assert_eq!(far[0]["label"], "none");
        for p in &far[1..] {
            assert!(chunks(p) * 2.0 < chunks(&far[0]), "{p}");
        }
        let meshes = far.iter().find(|p| p["label"] == "depth meshes").unwrap();
        assert!(
            extra(meshes, "far-field triangles a frame") > 12.0,
            "{meshes}"
        );
        assert!(extra(meshes, "bytes per cell") > 0.0, "{meshes}");
        assert!(extra(meshes, "build per cell, ms") > 0.0, "{meshes}");
    }
    // The stereo pair: the full pair, the far part shared at two errors and
    // the reprojected right eye, which differs from the full pair's (its
    // gaps are filled, not drawn).
    if skipped.is_empty() {
        let stereo = knob("stereo pair")["points"].as_array().unwrap();
        let labels: Vec<&str> = stereo
            .iter()
            .map(|p| p["label"].as_str().unwrap())
            .collect();
        assert_eq!(
            labels,
            [
                "pair in full",
                "far part shared within 0.5 px",
                "far part shared within 2 px",
                "right eye reprojected"
            ]
        );
        let reprojected = &stereo[3];
        assert!(
            number(&reprojected["error"], "error") > 0.0,
            "{reprojected}"
        );
        assert!(
            number(&reprojected["extra"]["gaps filled, %"], "gaps") > 0.0,
            "{reprojected}"
        );
    }
    let discrete = knob("discrete step")["points"].as_array().unwrap();
    let last = discrete.last().unwrap();
    assert!(
        last["setting"].as_f64().unwrap() > 8.0 && last["error"].as_f64().unwrap() > 0.0,
        "{last}"
    );
    assert!(
        !std::fs::read_dir(&out).unwrap().any(|e| e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .starts_with(".tradeoffs-scratch")),
        "the scratch folder is removed"
    );
}
