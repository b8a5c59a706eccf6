#[path = "../../../fuzz/bodies/gltf_import.rs"]
mod fuzz_gltf_import;
#[path = "../../../fuzz/replay.rs"]
mod fuzz_replay;
mod import;
mod nodes;
mod real_models;
mod runs;
mod support;
