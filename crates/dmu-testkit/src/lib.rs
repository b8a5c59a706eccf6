//! dmu's test harness: whether a test runs, skips loudly or fails is decided
//! here, once.
//!
//! Design choices:
//! - A test states what it needs ([`require`], [`with_data`], and with the
//!   `gpu` feature `with_gpu` and `GpuTest`) and gets it as an argument; the
//!   harness owns the decision, so no test body carries its own early return.
//! - A missing prerequisite prints `SKIPPED <test>: <reason>` on a developer's
//!   machine and fails under `CI=true`, where scripts/test.sh installs lavapipe,
//!   Xvfb and the test data: a CI run that skipped would hide a broken setup.
//! - One device per test binary (`gpu()`): opening a device costs more than
//!   most tests, and wgpu devices are shared across threads by design.
//! - What a test expects of an adapter is declared beside it
//!   (`GpuTest::fails_on`), as wgpu's test harness does, so a known driver
//!   bug is a visible line in the output, not a silent pass or a red run.
//!
//! ```
//! dmu_testkit::require(Ok::<_, String>(2), |two| assert_eq!(two, 2));
//! ```

use std::fmt::Display;
use std::io::Write;
use std::path::{Path, PathBuf};

#[cfg(feature = "gpu")]
mod gpu;
#[cfg(feature = "weed")]
pub mod weed;
#[cfg(feature = "gpu")]
pub use gpu::{Adapter, Gpu, GpuTest, gpu, with_gpu};

/// Whether this is a CI run (`CI=true`), where every prerequisite is installed.
pub fn ci() -> bool {
    std::env::var("CI").as_deref() == Ok("true")
}

/// The running test's name, as the test harness names its thread.
pub fn test_name() -> String {
    std::thread::current().name().unwrap_or("test").to_owned()
}

/// Ends what needs a missing prerequisite: under `CI=true` it fails with
/// `reason`; elsewhere it prints `SKIPPED <test>: <reason>` and returns.
pub fn skip(reason: impl Display) {
    let test = test_name();
    assert!(
        !ci(),
        "{test}: {reason} (CI=true: a missing prerequisite is a failure)"
    );
    shout(&format!("SKIPPED {test}: {reason}"));
}

/// Writes `line` to the real standard error: libtest captures `eprintln!` of
/// passing tests, and a skip must show in every run's output.
fn shout(line: &str) {
    // Nothing to do if standard error itself is gone.
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Runs `body` with what a prerequisite check `found`, or [`skip`]s with its
/// reason.
pub fn require<T>(found: Result<T, impl Display>, body: impl FnOnce(T)) {
    match found {
        Ok(it) => body(it),
        Err(reason) => skip(reason),
    }
}

/// The workspace's root folder.
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Where tests leave the images they make, to be looked at:
/// `target/test-images/<name>`.
pub fn image_path(name: &str) -> PathBuf {
    let dir = workspace().join("target/test-images");
    std::fs::create_dir_all(&dir).expect("create target/test-images");
    dir.join(name)
}

/// Test data kept outside the repository.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Data {
    /// `../shared/data` beside the workspace: real models made by others (its
    /// README.md lists them); it exists beside the project checkout in CI.
    Shared,
    /// The glTF2 folder of Debian's assimp-testmodels, which
    /// scripts/fetch-testdata.sh unpacks into `target/testdata`.
    Assimp,
}

impl Data {
    /// Where the data is, present or not.
    pub fn path(self) -> PathBuf {
        let root = workspace();
        match self {
            Data::Shared => root.join("../shared/data"),
            Data::Assimp => root.join("target/testdata/assimp/usr/share/assimp/models/glTF2"),
        }
    }

    fn missing(self) -> &'static str {
        match self {
            Data::Shared => {
                "../shared/data is absent (it exists beside the project checkout in CI)"
            }
            Data::Assimp => "Debian's assimp-testmodels are absent (run scripts/fetch-testdata.sh)",
        }
    }
}

/// Runs `body` with the folder of `data`, or [`skip`]s when it is absent, as
/// in a user's clone.
pub fn with_data(data: Data, body: impl FnOnce(&Path)) {
    let dir = data.path();
    let found = if dir.is_dir() {
        Ok(dir.as_path())
    } else {
        Err(data.missing())
    };
    require(found, body);
}
