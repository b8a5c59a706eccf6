//! Models on object storage or a web server (`s3://bucket/key`,
//! `https://…`): the command line's cache settings, and the one-line
//! warnings a walk or the viewer prints while the server is away.

use std::path::{Path, PathBuf};

use dmu_store::Residency;

/// Where remote stores' blocks are cached (every command that opens a model).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RemoteArgs {
    /// Remote stores (s3://, https://): the folder of the read-through
    /// cache [default: $DMU_CACHE_DIR, else $XDG_CACHE_HOME/dmu, else
    /// ~/.cache/dmu].
    #[arg(long, global = true, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Remote stores: the most the cache keeps on disk, e.g. 2GiB; 0 turns
    /// it off [default: $DMU_CACHE_BUDGET, else 4GiB].
    #[arg(long, global = true, value_name = "BYTES", value_parser = crate::units::parse_bytes)]
    pub cache_budget: Option<u64>,
}

impl RemoteArgs {
    /// Makes these the process's settings (call once, before opening).
    pub fn apply(&self) {
        dmu_store::remote::set_cache(self.cache_dir.clone(), self.cache_budget);
    }
}

/// Says, once each time, when loads start failing for I/O (the server
/// away: chunks are drawn as stand-ins) and when they succeed again.
#[derive(Debug, Default)]
pub struct OutageWatch {
    down: bool,
}

impl OutageWatch {
    /// The line to print now, if the state changed since the last call.
    pub fn update(&mut self, residency: &Residency, model: &Path) -> Option<String> {
        match (residency.outage(), self.down) {
            (Some(e), false) => {
                self.down = true;
                Some(format!(
                    "warning: {}: reading failed ({e}); drawing stand-ins and trying again",
                    model.display()
                ))
            }
            (None, true) => {
                self.down = false;
                Some(format!("note: {}: reading again", model.display()))
            }
            _ => None,
        }
    }
}
