//! Fuzz target `script_parse` (body in `fuzz/bodies/script_parse.rs`, shared with the corpus
//! replay test).
#![no_main]

#[path = "../bodies/script_parse.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
