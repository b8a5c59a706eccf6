//! Faults during long work (issue 48): `dmu import` and `dmu farfield build`
//! killed with SIGKILL at 20 moments each, drawn from a fixed seed over the
//! time an uninterrupted run takes. After each kill the previous file is
//! whole and opens (or, for a kill after the rename, the finished one); the
//! next run succeeds and leaves no temporary file behind. A full disk (a
//! small tmpfs) gives a one-line error and leaves the previous file whole.
//! (The viewer's save is killed the same way in
//! `apps/dmu-viewer/tests/session.rs`.)

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::{dmu, path};

/// Kills per writer.
const KILLS: usize = 20;

/// A xorshift stream of fractions in [0, 1), from a fixed seed.
struct Moments(u64);

impl Moments {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `dmu ARGS` run to the end; how long it took.
fn timed(args: &[&str]) -> Duration {
    let start = Instant::now();
    let out = dmu(args);
    assert!(
        out.status.success(),
        "dmu {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    start.elapsed()
}

/// Starts `dmu ARGS`, kills it with SIGKILL after `after`; whether it was
/// still running then (a kill that came after the end tests nothing).
fn kill_after(args: &[&str], after: Duration) -> bool {
    let mut child = Command::new(env!("CARGO_BIN_EXE_dmu"))
        .args(args)
        .env_remove("NODEVICE_SELECT")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start dmu");
    std::thread::sleep(after);
    let running = child.try_wait().expect("wait for dmu").is_none();
    child.kill().expect("SIGKILL"); // no destructor, no cleanup runs
    child.wait().expect("reap dmu");
    running
}

/// The file names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Kills `args` at [`KILLS`] moments over `span`; after each, `check` sees
/// the output. How many kills came while the writer ran.
fn kill_rounds(args: &[&str], span: Duration, seed: u64, mut check: impl FnMut(usize)) -> usize {
    let mut moments = Moments(seed);
    let mut mid_run = 0;
    for round in 0..KILLS {
        let after = span.mul_f64(moments.next());
        mid_run += usize::from(kill_after(args, after));
        check(round);
    }
    mid_run
}

/// `dmu import` killed at 20 moments: the store it replaces is either the
/// previous one, byte for byte, or the finished import, byte for byte, and
/// opens; the next import succeeds and leaves only the store.
#[test]
fn issue_48_a_killed_import_leaves_the_previous_store() {
    let dir = tempfile::tempdir().unwrap();
    let (small, big) = (path(dir.path(), "small.glb"), path(dir.path(), "big.glb"));
    timed(&["generate", "grid", "--n", "3", "-o", &small]);
    timed(&["generate", "plant", "--triangles", "300k", "-o", &big]);
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let store = path(&out_dir, "model.dmu");
    // The finished import's bytes, and how long it takes.
    let reference = path(dir.path(), "reference.dmu");
    let span = timed(&["import", &big, "-o", &reference]);
    let finished = std::fs::read(&reference).unwrap();
    timed(&["import", &small, "-o", &store]);
    let previous = std::fs::read(&store).unwrap();
    let args = ["import", big.as_str(), "-o", store.as_str()];
    let mid_run = kill_rounds(&args, span.mul_f64(0.9), 48, |round| {
        let now = std::fs::read(&store).unwrap();
        assert!(
            now == previous || now == finished,
            "round {round}: the store is neither the previous nor the finished one"
        );
        let info = dmu(&["info", &store, "--json"]);
        assert!(info.status.success(), "round {round}: does not open");
    });
    eprintln!("import: {mid_run} of {KILLS} kills came mid-run ({span:?} a run)");
    assert!(mid_run >= KILLS / 2, "too few kills mid-run: {mid_run}");
    timed(&["import", &big, "-o", &store]);
    assert_eq!(std::fs::read(&store).unwrap(), finished);
    assert_eq!(names(&out_dir), ["model.dmu"], "temporary files left");
}

/// `dmu farfield build` killed at 20 moments: the store stays the previous
/// one (its far fields as they were) or the finished build, and opens with
/// every segment whole; the next build succeeds and leaves only the store.
#[test]
fn issue_48_a_killed_far_field_build_leaves_the_previous_store() {
    dmu_testkit::with_gpu(|_| {
        let dir = tempfile::tempdir().unwrap();
        let store = super::generated_plant(dir.path(), "100k");
        let build = |cell_size: &'static str| {
            [
                "farfield",
                "build",
                store.as_str(),
                "--cell-size",
                cell_size,
                "--triangle-budget",
                "20k",
                "--resolution",
                "64",
            ]
        };
        // A first build is the previous state; the killed ones build others.
        let out = super::on_gpu("farfield", &build("40000")[1..]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let cells = |what: &str| {
            let s =
                dmu_store::Store::open(Path::new(&store)).unwrap_or_else(|e| panic!("{what}: {e}"));
            for c in 0..s.far_field_cells() {
                s.far_field_cell(c as u32)
                    .unwrap_or_else(|e| panic!("{what}: cell {c}: {e}"));
            }
            s.load_scene().unwrap_or_else(|e| panic!("{what}: {e}"));
            s.far_field_cells()
        };
        let previous_cells = cells("the first build");
        let previous = std::fs::read(&store).unwrap();
        // The finished build of the cells the kills interrupt, on a copy.
        let copy = path(dir.path(), "copy.dmu");
        std::fs::copy(&store, &copy).unwrap();
        let mut finish = build("20000");
        finish[2] = copy.as_str();
        let span = timed(&finish);
        let finished_cells = dmu_store::Store::open(Path::new(&copy))
            .unwrap()
            .far_field_cells();
        assert_ne!(previous_cells, finished_cells, "the builds differ");
        std::fs::remove_file(&copy).unwrap();
        let args = build("20000");
        let mid_run = kill_rounds(&args, span.mul_f64(0.9), 4848, |round| {
            let n = cells(&format!("round {round}"));
            if n == previous_cells {
                assert_eq!(
                    std::fs::read(&store).unwrap(),
                    previous,
                    "round {round}: the previous store changed"
                );
            } else {
                assert_eq!(n, finished_cells, "round {round}: a build half there");
            }
        });
        eprintln!("farfield build: {mid_run} of {KILLS} kills came mid-run ({span:?} a run)");
        assert!(mid_run >= KILLS / 2, "too few kills mid-run: {mid_run}");
        timed(&args);
        assert_eq!(cells("the last build"), finished_cells);
        assert_eq!(names(dir.path()), ["p.dmu"], "temporary files left");
    });
}

/// An import onto a full disk (a 2 MiB tmpfs) fails with one line naming the
/// file and "No space left", and leaves the previous store whole. Needs root
/// to mount; outside CI it skips saying so, under `CI=true` it fails.
#[test]
fn issue_48_a_full_disk_leaves_the_previous_store() {
    let dir = tempfile::tempdir().unwrap();
    let big = path(dir.path(), "big.glb");
    timed(&["generate", "plant", "--triangles", "200k", "-o", &big]);
    let small = path(dir.path(), "small.glb");
    timed(&["generate", "grid", "--n", "2", "-o", &small]);
    let disk = dir.path().join("disk");
    std::fs::create_dir(&disk).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=2m", "tmpfs"])
        .arg(&disk)
        .output();
    let found = match mounted {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(String::from_utf8_lossy(&o.stderr).into_owned()),
        Err(e) => Err(e.to_string()),
    };
    let found = found.map_err(|why| format!("cannot mount a tmpfs (needs root): {why}"));
    dmu_testkit::require(found, |()| {
        // Unmounted however the test ends.
        struct Unmount<'a>(&'a Path);
        impl Drop for Unmount<'_> {
            fn drop(&mut self) {
                let _ = Command::new("umount").arg(self.0).status();
            }
        }
        let _unmount = Unmount(&disk);
        let store = path(&disk, "model.dmu");
        timed(&["import", &small, "-o", &store]);
        let previous = std::fs::read(&store).unwrap();
        let out = dmu(&["import", &big, "-o", &store]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "one line: {err}");
        assert!(
            lines[0].starts_with("dmu: error:") && lines[0].contains("model.dmu"),
            "{err}"
        );
        assert!(lines[0].contains("No space left"), "{err}");
        assert_eq!(
            std::fs::read(&store).unwrap(),
            previous,
            "the store changed"
        );
        assert_eq!(names(&disk), ["model.dmu"], "temporary files left");
    });
}
