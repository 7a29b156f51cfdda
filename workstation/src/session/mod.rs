//! The commands that drive a live session: `workstation demo` ([`demo`], README command 1) and
//! `workstation run` / `hand-path` ([`run`]). They start a [`crate::live::Workstation`], drive
//! its phases, print and save; the demo also opens the window ([`crate::view`]) on it.
//!
//! Arrows point down only: `session` → `view` → `live`, and `session` → `live`. The window
//! knows nothing of the commands (they hand it a [`crate::view::Link`]), and `live` (the
//! threads and their cores) knows nothing of either.

pub mod demo;
pub mod run;
