//! What the dmu applications share: opening a model (a glTF file, a store or the
//! built-in plant) from the same command-line arguments, parsing the numbers
//! people type, and reporting pick hits.
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
//!     model: dmu::load::ModelArgs,
//! }
//! let cli = Cli::parse_from(["app", "--plant-triangles", "200k"]);
//! let loaded = dmu::load::load(&cli.model)?;
//! assert!(loaded.scene.triangle_count() <= 200_000);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod hits;
pub mod load;
pub mod units;
