//! Tests of the C ABI from Rust: the thesis design's tables (the Rust
//! firmware's generated files) through the C functions, against the
//! run-time's types built as the firmware builds them.

mod equal;
mod errors;
mod fixtures;
mod loops;
