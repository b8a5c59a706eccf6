//! Replays a fuzz target's committed corpus (`fuzz/corpus/<target>`) through its
//! body, on stable and without cargo-fuzz, naming every file that panics.
//! Included by `#[path]` from the corpus tests of the crates the targets call.

use std::path::Path;

/// Runs `body` on every file of `fuzz/corpus/<target>`; fails naming the files
/// on which it panicked.
pub fn corpus(target: &str, body: impl Fn(&[u8]) + std::panic::RefUnwindSafe) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.expect("corpus entry").path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{} holds no corpus", dir.display());
    let panicked: Vec<String> = files
        .iter()
        .filter(|file| {
            let data = std::fs::read(file).expect("corpus file");
            std::panic::catch_unwind(|| body(&data)).is_err()
        })
        .map(|file| file.display().to_string())
        .collect();
    assert!(panicked.is_empty(), "{target} panicked on {panicked:?}");
}
