//! Fuzz body of `script_parse`: the bytes as a viewer script and as an XR
//! script (`--xr-script`). Errors are fine; a panic is a finding.

/// Parses `data` (when it is UTF-8) as a script and as an XR script, and asks
/// each action its frames.
pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(actions) = dmu_viewer::script::parse(text) {
        for a in &actions {
            let _ = (a.frames(), a.name());
        }
    }
    if let Ok(script) = dmu_viewer::xr_script::parse(text) {
        for a in &script.actions {
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
