//! The `workstation` binary: thin command-line glue over the `workstation` library.
//!
//! Each subcommand lives in its own module of the library; `main` only parses arguments,
//! sets up logging (`RUST_LOG`) and maps errors to an exit code.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Networked haptic sculpting: the workstation side.
///
/// Fits point sets into implicit surfaces, simulates sculpting, maps forces for the haptics
/// server and reports measurements. Logs go to stderr; set RUST_LOG=debug for more.
#[derive(Debug, Parser)]
#[command(name = "workstation", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The networked demo: an in-process haptics server with a fake device on loopback, a
    /// scripted session (rope, paint, probe, CSG, emboss) through the real network path;
    /// writes summary.json, final.ply, final_mesh.* and PNG frames to --out. Opens the window
    /// when a display is present (--no-window keeps it headless).
    Demo(workstation::session::demo::DemoArgs),
    /// Open the interactive window on a scene: splat view, control panel, live plots. Without
    /// --server the mouse is the stylus on the surface under it (left button presses; rope:
    /// drag pulls out, Shift + drag pushes in; wheel: the tool's depth; Ctrl + wheel zooms).
    View(workstation::view::ViewArgs),
    /// Run the workstation against a haptics server: network, force-mapping, simulation and
    /// rendering threads on a scene; saves the model on exit (Ctrl-C or --seconds).
    Run(workstation::session::run::RunArgs),
    /// A shared scene's router for one site (an embedded Zenoh router holding each scene's
    /// truth): stations join with `--share ENDPOINT` on demo, run and view; other sites' zenohd
    /// routers link to it. See docs/SHARING.md.
    ShareRouter(workstation::share::router::RouterArgs),
    /// Make a station's (or the router's) certificate and key for a shared scene's mutual TLS.
    ShareIdentity(workstation::share::identity::IdentityArgs),
    /// Write a scene's strokes as a fake-device path file for `haptics-server --fake-path file`.
    HandPath(workstation::session::run::HandPathArgs),
    /// Render a point or mesh file (PLY, OFF, OBJ, STL, XYZ) headless to a PNG.
    Render(workstation::live::snapshot_png::RenderArgs),
    /// Print what this build can do and how to start.
    Status,
    /// Fit points (a file or gen:sphere:R:N) into an implicit surface; time it, measure its error.
    Fit(workstation::fit::FitArgs),
    /// Measure any mesh against a reference both ways (mesh → reference finds spurious pieces,
    /// reference → mesh finds holes): the metric `fit` reports, for comparing other tools.
    MeshError(workstation::fit::MeshErrorArgs),
    /// Time one sculpting step per stage (tools, integrator, points, publish) with its field error.
    BenchSim(workstation::bench_sim::BenchSimArgs),
    /// Run a scripted sculpting session headless; write PLY points and meshes to --out.
    Sculpt(workstation::sculpt::SculptArgs),
    /// Measure what the network does to the cursor → force loop: round trip, one-way delays
    /// (with their bound), jitter, loss, reordering, against a bare UDP ping-pong of the same
    /// size and rate in the same run. Writes report.json, samples.csv, rtt.hgrm, PNG plots and
    /// summary.md to --out. Without --server it measures an in-process server over loopback.
    Latency(workstation::latency::LatencyArgs),
    /// A delayed, lossy link on any machine: forward the UDP hot path (and QUIC) datagram by
    /// datagram with delay, jitter, loss, reordering and duplication, and the TCP control
    /// connection with the same delay, from --listen to --to (a haptics server). Point the
    /// workstation at --listen; neither end knows. For kernels without netem.
    Relay(workstation::relay::RelayArgs),
    /// Echo UDP datagrams: the baseline peer for `latency --echo ADDR` on the server's machine.
    UdpEcho(workstation::latency::UdpEchoArgs),
    /// Big scans: load, fit and sculpt dense mesh samplings (--points 100000,1000000) on the
    /// real simulation, force and renderer threads against a 7k-point baseline of the same
    /// run: fit time and memory, step and force-loop rates, frame preparation.
    BenchView(workstation::bench_view::BenchViewArgs),
    /// Time the haptic queries (field force, shaped probe, B-spline sculpt tick) with their force error.
    BenchForce(workstation::bench_force::BenchForceArgs),
    /// What network delay and loss do to a stiff contact, per rendering method (held force,
    /// EWMA, local model, local model + passivity), on a virtual clock; writes a report and
    /// plots to --out.
    #[cfg(feature = "demo-server")]
    DelayStudy(workstation::delay_study::DelayStudyArgs),
}

fn main() -> ExitCode {
    quiet_mesa_device_select();
    workstation::logging::init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Mesa's Vulkan device-select layer asks the Wayland compositor which GPU is the default one.
/// Without a login session (`XDG_RUNTIME_DIR` unset: ssh, a service, a container) there is no
/// compositor to ask, and libwayland prints "error: XDG_RUNTIME_DIR is invalid or not set in
/// the environment." twice on the first GPU probe, which reads like a failure of ours (the
/// demo then runs fine). So without a session the layer is switched off (`NODEVICE_SELECT`),
/// unless the user set it or chose a device with it (`MESA_VK_DEVICE_SELECT`).
fn quiet_mesa_device_select() {
    let unset = |name: &str| std::env::var_os(name).is_none();
    if unset("XDG_RUNTIME_DIR") && unset("NODEVICE_SELECT") && unset("MESA_VK_DEVICE_SELECT") {
        // SAFETY: the first thing `main` does, before any other thread exists, so nothing can
        // read the environment concurrently.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Relay(args) => workstation::relay::run(&args),
        Command::Demo(args) => workstation::session::demo::command(&args),
        Command::View(args) => workstation::view::run(&args),
        Command::Run(args) => workstation::session::run::run(&args),
        Command::ShareRouter(args) => workstation::share::router::share_router_command(&args),
        Command::ShareIdentity(args) => workstation::share::identity::share_identity_command(&args),
        Command::HandPath(args) => workstation::session::run::hand_path_command(&args),
        Command::Render(args) => workstation::live::snapshot_png::run(&args),
        Command::MeshError(args) => {
            let report = workstation::fit::run_mesh_error(&args)?;
            workstation::fit::print_mesh_error(&report, args.json)
        }
        Command::Fit(args) => {
            let report = workstation::fit::run(&args)?;
            workstation::fit::print(&report, args.json)
        }
        Command::Sculpt(args) => {
            let report = workstation::sculpt::run(&args)?;
            workstation::sculpt::print(&report, args.json)
        }
        Command::BenchSim(args) => {
            let report = workstation::bench_sim::run(&args)?;
            workstation::bench_sim::print(&report, args.json)
        }
        Command::BenchView(args) => {
            let report = workstation::bench_view::run(&args)?;
            workstation::bench_view::print(&report, args.json)
        }
        Command::BenchForce(args) => {
            let report = workstation::bench_force::run(&args)?;
            workstation::bench_force::print(&report, args.json)
        }
        Command::Latency(args) => {
            let report = workstation::latency::run(&args)?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", workstation::latency::report::summary(&report));
                println!("\nwrote {}", args.out.display());
            }
            Ok(())
        }
        Command::UdpEcho(args) => workstation::latency::udp_echo(&args),
        #[cfg(feature = "demo-server")]
        Command::DelayStudy(args) => {
            let report = workstation::delay_study::run(&args)?;
            workstation::delay_study::print(&report, args.json)
        }
        Command::Status => {
            workstation::status::print();
            Ok(())
        }
    }
}
