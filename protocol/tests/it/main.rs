//! The protocol crate's integration tests, built as one binary.

mod clock;
mod examples;
mod fuzz;
mod golden;
mod rejections;
mod roundtrip;
