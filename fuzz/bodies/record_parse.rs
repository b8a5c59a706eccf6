//! Fuzz body of `record_parse`: the bytes as a record (JSON Lines) parsed
//! against a 2×2×2 grid of boxes. Errors are fine; a panic is a finding.

use std::sync::LazyLock;

use dmu_scene::Scene;

static SCENE: LazyLock<Scene> = LazyLock::new(|| dmu_samples::grid(2, 10.0, 4.0, 2048));

/// Parses `data` (when it is UTF-8) as a record.
pub fn run(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = dmu_collide::parse_record(text, &SCENE);
    }
}

/// The committed corpus replayed through [`run`], in the test suite of the
/// crate that includes this file (with `fuzz/replay.rs` as `fuzz_replay`).
#[cfg(test)]
#[test]
fn corpus_never_panics() {
    crate::fuzz_replay::corpus("record_parse", run);
}
