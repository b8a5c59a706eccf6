//! The one test binary of dmu-app.

mod bcf;
#[path = "../../../fuzz/bodies/bcf_read.rs"]
mod fuzz_bcf_read;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
mod levels;
mod visibility;
