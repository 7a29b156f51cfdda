//! Haptic rendering tests (issue 6): the shaped probe, the B-spline/mass-spring dual, field
//! forces with a contact model, and the sculpting reaction. One binary; tolerances are stated
//! next to each assertion with the reason.

mod alloc;
mod bspline;
mod continuity;
#[path = "../support/counting_alloc.rs"]
mod counting_alloc;
mod field;
#[path = "../support/plot_setup.rs"]
mod plot_setup;
mod plots;
mod probe;
mod reaction;
mod untrusted_input;
mod wire;

#[global_allocator]
static ALLOCATOR: counting_alloc::Counting = counting_alloc::Counting;
