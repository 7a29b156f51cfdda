//! Integration tests of the dynamic sculpting model (issue 5): integrators and their limits,
//! rollback, points following the field, tools, CSG, resampling, scenes. One binary.

mod alloc;
mod common;
#[path = "../support/counting_alloc.rs"]
mod counting_alloc;
mod csg;
mod grid_limits;
mod integrators;
#[path = "../support/plot_setup.rs"]
mod plot_setup;
mod plots;
mod resample;
mod rope;
mod scene;
mod shell;
mod tool_inputs;
mod tools;

#[global_allocator]
static ALLOCATOR: counting_alloc::Counting = counting_alloc::Counting;
