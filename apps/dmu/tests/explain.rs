//! `--explain` on `dmu render`: the occlusion decisions it prints agree, frame
//! for frame, with the per-frame stats the same run reports. (`dmu collide
//! --explain` is tested with the sweep in `collide.rs`.) Included from
//! `tests.rs`.

use serde_json::Value;

use super::{path, render};

#[test]
fn render_explain_names_every_occlusion_switch_with_its_figures() {
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
            "--culling",
            "chc",
            "--frames",
            "24",
            "--size",
            "160x90",
            "--explain",
            "--json",
            "-o",
            &png,
        ];
        let out = render(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let frames = v["frames"].as_array().unwrap();
        let explain: Vec<&str> = v["explain"]
            .as_array()
            .expect("an explain array")
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        // The oracle: the frames where the reported decision changes, from the
        // per-frame stats, plus the first and the last.
        let enabled: Vec<bool> = frames
            .iter()
            .map(|f| f["occlusion"]["enabled"].as_bool().unwrap())
            .collect();
        let mut expected: Vec<usize> = (0..enabled.len())
            .filter(|&i| i == 0 || i + 1 == enabled.len() || enabled[i] != enabled[i - 1])
            .collect();
        expected.dedup();
        assert_eq!(explain.len(), expected.len(), "{explain:#?}");
        for (line, &i) in explain.iter().zip(&expected) {
            let o = &frames[i]["occlusion"];
            assert!(line.starts_with(&format!("frame {}: ", i + 1)), "{line}");
            if enabled[i] {
                assert!(line.contains("occlusion queries on"), "{line}");
            } else {
                assert!(line.contains("occlusion queries off"), "{line}");
                let cost = format!("{:.3} ms", o["cost_ms"].as_f64().unwrap());
                let saved = format!("{:.3} ms", o["saved_ms"].as_f64().unwrap());
                assert!(line.contains(&cost) && line.contains(&saved), "{line}: {o}");
            }
        }
        // Without occlusion culling nothing is chosen by measurement, and it says so.
        let frustum: Vec<&str> = args
            .iter()
            .map(|a| if *a == "chc" { "frustum" } else { a })
            .collect();
        let out = render(&frustum);
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["explain"].as_array().unwrap().len(), 1);
        assert!(
            v["explain"][0]
                .as_str()
                .unwrap()
                .contains("not asked for (culling frustum)")
        );
    });
}
