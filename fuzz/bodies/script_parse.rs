//! Fuzz body of `script_parse`: the bytes as a viewer script. Errors are fine;
//! a panic is a finding.

/// Parses `data` (when it is UTF-8) as a script and asks each action its frames.
pub fn run(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(actions) = dmu_viewer::script::parse(text)
    {
        for a in &actions {
            let _ = (a.frames(), a.name());
        }
    }
}

/// The committed corpus replayed through [`run`], in the test suite of the
/// crate that includes this file (with `fuzz/replay.rs` as `fuzz_replay`).
#[cfg(test)]
#[test]
fn corpus_never_panics() {
    crate::fuzz_replay::corpus("script_parse", run);
}
