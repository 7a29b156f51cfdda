//! Logging setup shared by the workstation's commands: `tracing` to stderr, filtered by `RUST_LOG`.

use tracing_subscriber::EnvFilter;

/// Install a stderr subscriber honouring `RUST_LOG` (default `info`, without the Vulkan
/// loader's own lines from `wgpu_hal`: a missing driver is reported once by us, with what to
/// install). Safe to call twice.
pub fn init() {
    let filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info,wgpu_hal=off"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
