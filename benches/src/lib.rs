//! Criterion benchmarks live in `main.rs`; this crate has no library code.
