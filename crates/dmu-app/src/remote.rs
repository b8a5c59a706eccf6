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

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use dmu_scene::ChunkId;
    use dmu_store::remote::RemoteOptions;
    use dmu_store::{Class, LoadOrder, Pacing, Request, ResidencyOptions, Store};
    use dmu_testkit::require;
    use dmu_testkit::weed::Weed;

    use super::*;

    /// The server killed: the load fails, the chunk stays absent (not
    /// broken), the warning is said once; the server back: the chunk loads,
    /// and the note is said once.
    #[test]
    fn a_server_going_away_and_coming_back_is_said_once_each() {
        require(Weed::new(), |mut weed| {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("plant.dmu");
            let scene = dmu_samples::plant(&dmu_samples::PlantOptions {
                triangles: 20_000,
                ..Default::default()
            });
            dmu_store::write_scene(&scene, &path, Default::default()).unwrap();
            weed.put("plant.dmu", &std::fs::read(&path).unwrap());
            let options = RemoteOptions {
                endpoint: Some(weed.endpoint.clone()),
                region: "us-east-1".into(),
                credentials: None,
                cache_dir: None,
                cache_budget: 0,
                part_bytes: None,
            };
            let url = Path::new("s3://models/plant.dmu");
            let store = Arc::new(Store::open_with(url, &options).unwrap());
            let residency = Residency::new(
                store,
                ResidencyOptions {
                    budget_bytes: u64::MAX,
                    loader_threads: 1,
                    order: LoadOrder::Visibility,
                    pacing: Pacing::Granted,
                },
            );
            let load = |chunk: u32| {
                residency.request(&[Request {
                    chunk: ChunkId(chunk),
                    class: Class::Visible,
                    area_px: 100.0,
                }]);
                residency.load_granted(u64::MAX / 4);
            };
            let mut watch = OutageWatch::default();
            load(0);
            assert!(residency.is_resident(ChunkId(0)));
            assert_eq!(watch.update(&residency, url), None);

            weed.stop();
            load(1);
            assert!(!residency.is_resident(ChunkId(1)));
            let warning = watch.update(&residency, url).expect("a warning");
            assert!(
                warning.starts_with("warning: s3://models/plant.dmu: reading failed")
                    && warning.contains("stand-ins")
                    && !warning.contains('\n'),
                "{warning}"
            );
            assert_eq!(watch.update(&residency, url), None, "said once");
            assert_eq!(residency.stats().failures, 0, "nothing marked broken");

            weed.start().unwrap();
            // Past the pause after the failure.
            std::thread::sleep(dmu_store::RETRY_MOST);
            load(1);
            assert!(residency.is_resident(ChunkId(1)));
            assert_eq!(
                watch.update(&residency, url).as_deref(),
                Some("note: s3://models/plant.dmu: reading again")
            );
            assert_eq!(watch.update(&residency, url), None);
        });
    }
}
