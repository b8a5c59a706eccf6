mod files;
mod residency;
mod round_trip;
mod support;
#[path = "../../../fuzz/bodies/store_open.rs"]
mod fuzz_store_open;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
