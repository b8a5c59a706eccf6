//! Fuzz target `store_open` (body in `fuzz/bodies/store_open.rs`, shared with the corpus
//! replay test).
#![no_main]

#[path = "../bodies/store_open.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
