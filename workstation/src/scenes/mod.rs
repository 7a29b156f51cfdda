//! Scenes the workstation can run: each a library type driven by `now`/`dt` and a cursor, with
//! a headless report; the window and the force-mapping thread attach to them later.

pub mod bspline_probe;
