//! `dmu-viewer --xr` on a real OpenXR runtime: `scripts/xr-check.sh` runs
//! Monado (null compositor, simulated headset and controllers) in the trixie
//! chroot that `scripts/xr-setup.sh` makes and checks the session (FOCUSED,
//! 120 frames, a clean exit), both eye images (the plant, the analytic
//! parallax), the controllers' actions (bindings, sync, poses), the scripted
//! grab against the same drag in the desktop viewer, the haptic pulse on the
//! hard clash, the recording replayed by `dmu collide --record`, the
//! thumbsticks' locomotion, and the frame budget of a second session.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The chroot, as the setup script places it.
fn xr_root() -> PathBuf {
    std::env::var_os("DMU_XR_ROOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/var/lib/dmu-xr/trixie"))
}

#[test]
fn xr_session_on_monado_passes_the_check() {
    let _shared = crate::support::sharing_the_machine();
    let root = xr_root();
    let ready = root.join(".dmu-xr-ready");
    let found = if ready.exists() {
        Ok(())
    } else {
        Err(format!(
            "no Monado chroot at {} (scripts/xr-setup.sh makes it; scripts/test.sh runs it)",
            root.display()
        ))
    };
    dmu_testkit::require(found, |()| {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let out = tempfile::tempdir().unwrap();
        let run = Command::new(repo.join("scripts/xr-check.sh"))
            .arg(out.path())
            .env("DMU_VIEWER", env!("CARGO_BIN_EXE_dmu-viewer"))
            .env("DMU_BIN", crate::support::dmu_cli())
            .output()
            .expect("run scripts/xr-check.sh");
        let stdout = String::from_utf8_lossy(&run.stdout);
        let stderr = String::from_utf8_lossy(&run.stderr);
        eprintln!("{stdout}{stderr}");
        assert!(run.status.success(), "xr-check.sh failed: {stderr}");
        let check: Value =
            serde_json::from_str(&std::fs::read_to_string(out.path().join("check.json")).unwrap())
                .unwrap();
        assert_eq!(check["ok"], true, "{check:#}");
        for name in [
            "focused",
            "frames",
            "clean_exit",
            "left_shows_plant",
            "right_shows_plant",
            "parallax",
            "grab_equals_desktop",
            "undo_restores",
            "hand_moved_by_the_script",
            "bindings_accepted",
            "actions_synced",
            "recording_replays",
            "haptic_on_hard_clash",
            "locomotion",
            "comfort_budget",
            "culled_once_timed",
        ] {
            assert_eq!(check["checks"][name]["ok"], true, "{name}: {check:#}");
        }
        let report: Value =
            serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
                .unwrap();
        // The report carries what the issue asks of it.
        for field in [
            "runtime",
            "max_session_state",
            "frames_submitted",
            "eye_fov",
            "grabbed_part",
            "clashes",
            "exit",
            "haptic_pulses",
            "controllers",
            "recording",
            "frames",
            "frames_late",
            "stereo",
        ] {
            assert!(!report[field].is_null(), "report lacks {field}: {report:#}");
        }
        assert!(report["runtime"].as_str().unwrap().contains("Monado"));
        // The simulated headset's eyes are about 63 mm apart.
        let ipd = report["ipd_m"].as_f64().unwrap();
        assert!((0.055..0.075).contains(&ipd), "ipd {ipd} m");
    });
}
