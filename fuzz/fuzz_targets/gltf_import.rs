//! Fuzz target `gltf_import` (body in `fuzz/bodies/gltf_import.rs`, shared with the corpus
//! replay test).
#![no_main]

#[path = "../bodies/gltf_import.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
