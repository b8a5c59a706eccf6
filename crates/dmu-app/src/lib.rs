//! What the dmu applications (the `dmu` command line and the `dmu-viewer`
//! window) share: opening a model (a glTF file, a store or the built-in plant)
//! from the same command-line arguments, parsing the numbers people type,
//! reporting pick hits and progress, and streaming a store's chunks into the
//! renderer a frame at a time ([`resident::StreamedFrames`]), and putting the choices made by
//! measurement into words ([`explain`]), and reading and writing BCF issue
//! files ([`bcf`]).
//!
//! Design choices:
//! - The `dmu` command line and the `dmu-viewer` window open models through one
//!   function ([`load::load`]) and one set of clap arguments
//!   ([`load::ModelArgs`]), so a file or `--plant-triangles 10M` means the same
//!   model in both, and a pick in one can be checked against the other.
//!
//! Conventions: model units as in `dmu-scene` (millimetres for the plant); counts
//! take k/M/G suffixes (powers of 1000), byte sizes KiB/MiB/GiB or kB/MB/GB.
//!
//! ```no_run
//! use clap::Parser;
//!
//! #[derive(Parser)]
//! struct Cli {
//!     #[command(flatten)]
//!     model: dmu_app::load::ModelArgs,
//! }
//! let cli = Cli::parse_from(["app", "--plant-triangles", "200k"]);
//! let loaded = dmu_app::load::load(&cli.model)?;
//! assert!(loaded.scene.triangle_count() <= 200_000);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod bcf;
pub mod explain;
pub mod farfield;
pub mod hits;
pub mod load;
pub mod lod;
pub mod progress;
pub mod remote;
pub mod resident;
pub mod text;
pub mod units;

/// Turns off Mesa's device-select Vulkan layer unless the user set it up: the
/// applications choose their adapter themselves, and the layer, only to order
/// GPUs, opens a Wayland connection that prints `error: XDG_RUNTIME_DIR is invalid or not
/// set` twice on every machine without Wayland although nothing is wrong.
///
/// # Safety
/// It sets an environment variable: call it first in `main`, while the process
/// has one thread (as [`std::env::set_var`] requires).
#[expect(
    unsafe_code,
    reason = "setting an environment variable is sound before any thread starts"
)]
pub unsafe fn quiet_device_select() {
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: the caller guarantees the process has one thread.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}
