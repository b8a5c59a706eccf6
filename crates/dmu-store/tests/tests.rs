mod farfield;
mod files;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
#[path = "../../../fuzz/bodies/store_open.rs"]
mod fuzz_store_open;
mod import;
mod levels;
mod remote;
mod residency;
mod round_trip;
mod support;
