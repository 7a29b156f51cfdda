//! What every plot generator of sim-core needs before drawing (included with `#[path]` by the
//! plot tests and the fit-sweep example): a registered TrueType font and the docs/plots folder.

use plotters::style::FontStyle;

/// Register the font plotters draws text with: `PLOT_FONT`, else DejaVu Sans (Debian
/// `fonts-dejavu-core`). plotters keeps the bytes for the life of the process.
pub fn register_font() -> Result<(), String> {
    let path = std::env::var("PLOT_FONT")
        .unwrap_or_else(|_| "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf".into());
    let bytes = std::fs::read(&path).map_err(|e| format!("plot font {path}: {e}"))?;
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| format!("plot font {path}: not a usable TrueType font"))
}

/// `docs/plots/NAME` in the repository, creating the folder.
#[allow(dead_code)] // the fit-sweep example writes where `--out` says
pub fn docs_plot(name: &str) -> String {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/plots");
    std::fs::create_dir_all(dir).expect("docs/plots");
    format!("{dir}/{name}")
}
