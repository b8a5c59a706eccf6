mod analytic;
mod continuous;
#[path = "../../../fuzz/bodies/record_parse.rs"]
mod fuzz_record_parse;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
mod property;
mod record;
mod support;
mod triangles;
