//! Integration tests of the point-set surface, built into one binary. Run the numerics with
//! `cargo test -p sim-core --profile ci`.

mod coarse_grid;
mod common;
mod even_neighbourhoods;
mod field_api;
mod gaps;
mod hard_cases;
mod io_formats;
mod meshing;
mod misfit;
mod planar_fits;
mod real_scan;
mod trusted;
mod untrusted_input;
