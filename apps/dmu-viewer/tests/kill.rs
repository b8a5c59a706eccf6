//! The viewer's save killed with SIGKILL at 20 moments drawn from a fixed
//! seed (issue 48, with `dmu import` and `dmu farfield build` in
//! `apps/dmu/tests/kill.rs`): a script moves a part 1 mm and saves, over and
//! over; after each kill the saved model opens and holds one whole save (the
//! part moved a whole number of millimetres), and the next save leaves no
//! temporary file behind.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::json;

use crate::support::{LVP_ICD, with_viewer, xvfb_lock};

/// Saves in the script: enough that its save loop outlasts a kill's moment.
const SAVES: usize = 400;

/// The pid of the `dmu-viewer` process whose arguments name `marker`.
fn viewer_pid(marker: &str) -> Option<u32> {
    std::fs::read_dir("/proc").ok()?.find_map(|e| {
        let pid: u32 = e.ok()?.file_name().to_str()?.parse().ok()?;
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).ok()?;
        let cmdline = String::from_utf8_lossy(&cmdline);
        (cmdline.contains("dmu-viewer")
            && cmdline.contains(marker)
            && !cmdline.contains("xvfb-run"))
        .then_some(pid)
    })
}

/// The part's x offset in the saved model at `path`, against `x0`.
fn moved(path: &Path, part: &str, x0: f64) -> f64 {
    let (scene, _) = dmu_scene::import_gltf(path, &Default::default())
        .unwrap_or_else(|e| panic!("the saved model does not open: {e}"));
    let id = scene.find_part(part).unwrap();
    scene.part_world(id).translation.x - x0
}

#[test]
fn issue_48_a_killed_save_leaves_one_whole_save() {
    with_viewer(|| {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("model.glb");
        dmu_scene::export_gltf(&dmu_samples::grid(6, 10.0, 4.0, 2048), &model).unwrap();
        let part = "box_2_3_4";
        let out_dir = dir.path().join("out");
        std::fs::create_dir(&out_dir).unwrap();
        let saved = out_dir.join("saved.glb");
        let mut actions = vec![json!({"select": part})];
        for _ in 0..SAVES {
            actions.push(json!({"move": [1.0, 0.0, 0.0]}));
            actions.push(json!({"save": saved}));
        }
        let script = dir.path().join("save-loop.json");
        std::fs::write(&script, serde_json::to_vec(&actions).unwrap()).unwrap();
        let marker = script.to_string_lossy().into_owned();
        let x0 = {
            let (scene, _) = dmu_scene::import_gltf(&model, &Default::default()).unwrap();
            scene
                .part_world(scene.find_part(part).unwrap())
                .translation
                .x
        };
        let mut rng = 0x4848_4848_4848_4848u64;
        let mut seen = Vec::new();
        let one_at_a_time = xvfb_lock();
        for round in 0..20 {
            let _ = std::fs::remove_file(&saved);
            let mut child = Command::new("xvfb-run")
                .args(["-a", "-s", "-screen 0 800x600x24"])
                .arg(env!("CARGO_BIN_EXE_dmu-viewer"))
                .arg(&model)
                .args(["--width", "320", "--height", "240", "--script"])
                .arg(&script)
                .env("WGPU_BACKEND", "vulkan")
                .env("VK_ICD_FILENAMES", LVP_ICD)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            // The loop is under way once the first save is there; then a moment
            // drawn from 0 to 2 s (a save of this model takes tens of ms).
            let start = Instant::now();
            while !saved.exists() {
                assert!(
                    start.elapsed() < Duration::from_secs(120),
                    "round {round}: no save in two minutes"
                );
                assert!(
                    child.try_wait().unwrap().is_none(),
                    "round {round}: the viewer ended"
                );
                std::thread::sleep(Duration::from_millis(5));
            }
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            std::thread::sleep(Duration::from_micros(rng % 2_000_000));
            let pid = viewer_pid(&marker).expect("the viewer's process");
            let killed = Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .status();
            assert!(killed.unwrap().success(), "round {round}: kill -KILL {pid}");
            let status = child.wait().unwrap();
            assert!(
                !status.success(),
                "round {round}: the viewer was not killed"
            );
            let x = moved(&saved, part, x0);
            assert!(
                x >= 1.0 && (x - x.round()).abs() < 1e-9 && x <= SAVES as f64,
                "round {round}: the part moved {x} mm, not a whole save"
            );
            seen.push(x);
        }
        drop(one_at_a_time);
        eprintln!("killed saves left the part moved by {seen:?} mm");
        // The killed writers' temporary files go with the next save.
        let once = dir.path().join("once.json");
        let actions = json!([{"select": part}, {"move": [1.0, 0.0, 0.0]}, {"save": saved}]);
        std::fs::write(&once, serde_json::to_vec(&actions).unwrap()).unwrap();
        let before = moved(&saved, part, x0);
        crate::support::viewer(&[
            saved.to_str().unwrap(),
            "--width",
            "320",
            "--height",
            "240",
            "--script",
            once.to_str().unwrap(),
        ]);
        assert_eq!(moved(&saved, part, x0), before + 1.0, "the next save");
        let names: Vec<_> = std::fs::read_dir(&out_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["saved.glb"], "leftovers after a save");
    });
}
