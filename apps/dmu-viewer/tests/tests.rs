//! The real `dmu-viewer` binary, run under Xvfb on lavapipe.

mod budget;
mod farfield;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
#[path = "../../../fuzz/bodies/script_parse.rs"]
mod fuzz_script_parse;
mod kill;
mod review_tools;
mod session;
mod soak;
mod support;
mod xr;
mod xvfb;
