//! The protocol crate's integration tests, built as one binary.

mod clock;
mod examples;
mod fuzz;
mod golden;
mod python_client;
mod rejections;
mod roundtrip;
