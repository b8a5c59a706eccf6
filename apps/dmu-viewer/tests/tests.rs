//! The real `dmu-viewer` binary, run under Xvfb on lavapipe.

mod session;
mod support;
mod xvfb;
#[path = "../../../fuzz/bodies/script_parse.rs"]
mod fuzz_script_parse;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
