//! What every PNG plot of a report command needs: a font plotters can draw text with.
//!
//! The font is the window's own (epaint's embedded Ubuntu Light), so plots need no system
//! font package and look the same on every machine.

use std::sync::OnceLock;

use plotters::style::FontStyle;

/// Register the plot font under plotters' `sans-serif` family (once per process; later calls
/// return the first call's result).
pub fn register_font() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .map_err(|_| "the embedded plot font is not a usable TrueType font".to_string())
    })
    .clone()
}
