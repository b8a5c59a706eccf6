//! Fuzz target `bcf_read` (body in `fuzz/bodies/bcf_read.rs`, shared with the corpus
//! replay test).
#![no_main]

#[path = "../bodies/bcf_read.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
