//! `haptics-server`: the binary. Thin: parse, configure, start [`Server`], wait for Ctrl-C.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::{Parser, Subcommand};
use haptics_server::check::calibration::{Aabb, Fit};
use haptics_server::check::{self, CheckOptions, Operator};
use haptics_server::config::{DeviceKind, ServerConfig};
use haptics_server::server::{Server, ServerOptions, TransportKind};
use haptics_server::{inventory, loop_bench, setup, tls};

/// The haptic device server: owns the device, runs the 1 kHz servo loop with its safety
/// stages, and serves one workstation at a time over UDP or QUIC.
///
/// First run: `haptics-server --device fake --transport udp --listen 127.0.0.1:7700` starts a
/// simulated stylus and listens on loopback; a self-signed certificate is created at the
/// default location on first start, and the workstation pins that file.
/// Every setting lives in a TOML file (`--config`, see deploy/haptics-server.example.toml);
/// flags override it.
///
/// Day one on a lab PC: `haptics-server devices` shows what is attached, which `--device`
/// drives it and why it cannot be opened if it cannot; `haptics-server check --device KIND
/// [--force-test]` reads the stylus and tests force direction and the safety stages before
/// the first session (deploy/README.md walks through it).
#[derive(Debug, Parser)]
#[command(name = "haptics-server", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    dev: DeviceArgs,
    /// Transport: udp = TLS-over-TCP control + MAC'd UDP datagrams on one port; quic = QUIC
    /// (one bidi stream for control, unreliable datagrams) [default: udp, or network.transport].
    #[arg(long, value_enum)]
    transport: Option<TransportKind>,
    /// Listen address [default: 127.0.0.1:7700, or network.listen].
    #[arg(long, value_name = "ADDR")]
    listen: Option<SocketAddr>,
    /// Record every servo tick (positions, buttons, forces, timing) to FILE for `--device replay`.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Certificate (PEM) [default: $XDG_CONFIG_HOME/haptics-server/cert.pem, created on first
    /// start if neither it nor the key exists].
    #[arg(long, value_name = "FILE", requires = "key")]
    cert: Option<PathBuf>,
    /// Private key (PEM) matching --cert.
    #[arg(long, value_name = "FILE", requires = "cert")]
    key: Option<PathBuf>,
    /// Print the effective configuration as TOML and exit.
    #[arg(long)]
    print_config: bool,
}

/// The device and servo flags shared by the server's run and `check` (given before or after
/// the subcommand).
#[derive(Debug, Clone, Default, clap::Args)]
struct DeviceArgs {
    /// Device backend [default: fake, or the config's device.kind]. `haptics-server devices`
    /// shows which one drives what is attached.
    #[arg(long, value_enum)]
    device: Option<DeviceKind>,
    /// TOML configuration file; every option and its default is in
    /// deploy/haptics-server.example.toml [default: built-in defaults].
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The recording `--device replay` plays [default: device.replay.file].
    #[arg(long, value_name = "FILE")]
    replay_file: Option<PathBuf>,
    /// Fake hand path: idle, circle, line, press, or file (with --fake-path-file)
    /// [default: circle, or device.fake.path; `check`: idle instead of circle].
    #[arg(long, value_name = "PATH")]
    fake_path: Option<String>,
    /// Path file for `--fake-path file`: lines `t_s x y z [buttons]` (`workstation demo`
    /// writes one for its scripted session).
    #[arg(long, value_name = "FILE")]
    fake_path_file: Option<PathBuf>,
    /// Fake device wired wrong, to see `check --force-test` catch it: where commanded +x, +y,
    /// +z really push, e.g. `-x,z,y` (x inverted, y and z swapped) [default: x,y,z, or
    /// device.fake.axes].
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    fake_axes: Option<String>,
    /// The OpenHaptics HD library: a name the loader searches, or a path [default: libHD.so,
    /// or device.openhaptics.library].
    #[arg(long, value_name = "FILE")]
    openhaptics_library: Option<String>,
    /// The Force Dimension DHD library: a name the loader searches, or a path [default:
    /// libdhd.so, or device.dhd.library].
    #[arg(long, value_name = "FILE")]
    dhd_library: Option<String>,
    /// Servo rate, Hz [default: 1000, or servo.rate_hz].
    #[arg(long, value_name = "HZ")]
    rate_hz: Option<u32>,
    /// Do not ask for SCHED_FIFO (servo.realtime_priority = 0).
    #[arg(long)]
    no_realtime: bool,
}

/// `check`'s flags (documented on the subcommand).
#[derive(Debug, clap::Args)]
struct CheckArgs {
    #[command(flatten)]
    dev: DeviceArgs,
    /// Seconds to read the stylus.
    #[arg(long, default_value_t = 3.0, value_name = "S")]
    seconds: f64,
    /// Also test force output along each axis (asks first: see --yes).
    #[arg(long)]
    force_test: bool,
    /// Do not ask before the force test (a rig where nobody holds the stylus); required
    /// for --force-test when stdin is not a terminal.
    #[arg(long, requires = "force_test")]
    yes: bool,
    /// Force of the test along each axis, N (0.1 … 3; the clamp limit still applies).
    #[arg(long, default_value_t = 1.0, value_name = "N")]
    force_n: f32,
    /// Write the whole report as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// A scene region MINX,MINY,MINZ,MAXX,MAXY,MAXZ (m, e.g. a scene's [region] min and
    /// max): print the scene file's [device] transform mapping the workspace onto it.
    #[arg(long, value_name = "BOX", value_parser = parse_region, allow_hyphen_values = true)]
    region: Option<Aabb>,
    /// cover: the whole region is reachable; inside: the workspace stays inside it.
    #[arg(long, value_enum, default_value_t = Fit::Cover)]
    fit: Fit,
}

impl DeviceArgs {
    /// These flags, with `other`'s filling the ones not given here.
    fn or(&self, other: &DeviceArgs) -> DeviceArgs {
        DeviceArgs {
            device: self.device.or(other.device),
            config: self.config.clone().or_else(|| other.config.clone()),
            replay_file: self
                .replay_file
                .clone()
                .or_else(|| other.replay_file.clone()),
            fake_path: self.fake_path.clone().or_else(|| other.fake_path.clone()),
            fake_path_file: self
                .fake_path_file
                .clone()
                .or_else(|| other.fake_path_file.clone()),
            fake_axes: self.fake_axes.clone().or_else(|| other.fake_axes.clone()),
            openhaptics_library: self
                .openhaptics_library
                .clone()
                .or_else(|| other.openhaptics_library.clone()),
            dhd_library: self
                .dhd_library
                .clone()
                .or_else(|| other.dhd_library.clone()),
            rate_hz: self.rate_hz.or(other.rate_hz),
            no_realtime: self.no_realtime || other.no_realtime,
        }
    }
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write a self-signed certificate and key for the server (the workstation pins the
    /// certificate), or with --client a workstation's client identity (the server lists the
    /// certificate in its authorized clients).
    ///
    /// Two machines: run `gen-cert` on the haptics PC and copy its cert.pem to the workstation;
    /// run `gen-cert --client --out DIR` on the workstation and append DIR/client.pem to the
    /// server's authorized_clients.pem (or pass --authorize FILE where both are on one machine).
    GenCert {
        /// Directory for the files [default: $XDG_CONFIG_HOME/haptics-server].
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Overwrite existing files.
        #[arg(long)]
        force: bool,
        /// Write a workstation's client identity (client.pem, client.key) instead.
        #[arg(long)]
        client: bool,
        /// With --client: also append client.pem to this authorized-clients file.
        #[arg(long, value_name = "FILE", requires = "client")]
        authorize: Option<PathBuf>,
    },
    /// What is attached and which backend drives it: HID devices of known vendors
    /// (3Dconnexion, 3D Systems; every HID device with --all), USB devices of Force Dimension,
    /// the Novint Falcon and 3D Systems' serial Touch, and whether the OpenHaptics (libHD.so)
    /// and Force Dimension (libdhd.so) libraries load.
    ///
    /// A device that is there but cannot be opened says why: a node this user may not open
    /// (install deploy/70-haptics.rules and join the haptics group; the exact commands are
    /// printed), or a library that does not load (which file names were looked for, and in
    /// which directories). Next step: `haptics-server check --device KIND`.
    Devices {
        /// List every HID device, not only those of known vendors.
        #[arg(long)]
        all: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// TOML configuration file (for device.openhaptics.library and device.dhd.library).
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// The OpenHaptics HD library to probe [default: libHD.so, or the config's].
        #[arg(long, value_name = "FILE")]
        openhaptics_library: Option<String>,
        /// The Force Dimension DHD library to probe [default: libdhd.so, or the config's].
        #[arg(long, value_name = "FILE")]
        dhd_library: Option<String>,
    },
    /// A guided self-test of a new installation: does the server read the stylus right, does
    /// force come out the right way, do the safety stages hold.
    ///
    /// 1. Reads the stylus for --seconds with no force: the rate achieved, position range and
    ///    noise, buttons pressed, orientation validity. Move the stylus through the whole
    ///    workspace, turn it and press each button meanwhile.
    ///
    /// 2. With --force-test, and only after the person holding the stylus types `yes` (or
    ///    with --yes on a rig where nobody holds it; without a terminal and without --yes it
    ///    refuses): ramps --force-n newtons along +x, -x, +y, -y, +z, -z through the servo
    ///    loop's own safety stages (ramp-in, clamp, slew limit, watchdog) and reports the
    ///    motion each produced against the command ("commanded +x, moved mostly -x: axis x
    ///    inverted", "axes y and z swapped"); then stops commanding and checks the watchdog
    ///    fades the force to zero in time.
    ///
    /// 3. Prints the workspace the device declares and the range seen; with --region, the
    ///    `[device]` table (scale, translation, rotation_deg) a workstation scene file needs to
    ///    map the workspace onto that region.
    ///
    /// The summary goes to stdout, --out FILE.json keeps the whole report. Exit code: 0 every
    /// check passed (warnings allowed), 1 a check failed, 2 the check could not run (device
    /// not opened, force test refused).
    ///
    /// Example: `haptics-server check --device dhd --force-test --region
    /// -0.05,0,-0.05,0.05,0.06,0.05 --out day-one.json`; try it without hardware with
    /// `--device fake` (and `--fake-axes -x,z,y` to see a wiring error caught).
    Check(Box<CheckArgs>),
    /// Run the servo driver loop alone (fake device, no network) for N seconds, then a bare
    /// sleep-then-spin loop, and print start lateness p50/p99/p99.9/max of both.
    LoopBench {
        /// Seconds per loop.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Loop rate, Hz.
        #[arg(long, default_value_t = 1000)]
        rate_hz: u32,
        /// Spin before each deadline, µs.
        #[arg(long, default_value_t = 50)]
        spin_us: u32,
        /// Do not ask for SCHED_FIFO.
        #[arg(long)]
        no_realtime: bool,
        /// Pin both loops to this CPU.
        #[arg(long)]
        cpu: Option<usize>,
    },
}

fn main() -> ExitCode {
    let filter =
        tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into());
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(ansi)
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    if let Some(Command::Check(_)) = &cli.command {
        return check_command(&cli);
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("haptics-server: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn parse_region(text: &str) -> Result<Aabb, String> {
    Aabb::parse(text)
}

/// The configuration file (or the defaults) with the device flags applied, not yet validated.
fn device_config(d: &DeviceArgs) -> anyhow::Result<ServerConfig> {
    let mut cfg = match &d.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            ServerConfig::from_toml(&text, &p.display().to_string())?
        }
        None => ServerConfig::default(),
    };
    if let Some(k) = d.device {
        cfg.device.kind = k;
    }
    if d.replay_file.is_some() {
        cfg.device.replay.file = d.replay_file.clone();
    }
    if let Some(p) = &d.fake_path {
        cfg.device.fake.path = p.clone();
    }
    if d.fake_path_file.is_some() {
        cfg.device.fake.path_file = d.fake_path_file.clone();
    }
    if let Some(a) = &d.fake_axes {
        cfg.device.fake.axes = a.clone();
    }
    if let Some(l) = &d.openhaptics_library {
        cfg.device.openhaptics.library = l.clone();
    }
    if let Some(l) = &d.dhd_library {
        cfg.device.dhd.library = l.clone();
    }
    if let Some(r) = d.rate_hz {
        cfg.servo.rate_hz = r;
    }
    if d.no_realtime {
        cfg.servo.realtime_priority = 0;
    }
    Ok(cfg)
}

fn load_config(cli: &Cli) -> anyhow::Result<ServerConfig> {
    let mut cfg = device_config(&cli.dev)?;
    if let Some(t) = cli.transport {
        cfg.network.transport = t;
    }
    if let Some(l) = cli.listen {
        cfg.network.listen = l;
    }
    if cli.record.is_some() {
        cfg.telemetry.record = cli.record.clone();
    }
    if cli.cert.is_some() {
        cfg.network.cert = cli.cert.clone();
        cfg.network.key = cli.key.clone();
    }
    cfg.validate()?;
    Ok(cfg)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match &cli.command {
        Some(Command::GenCert {
            out,
            force,
            client,
            authorize,
        }) => return gen_cert(out.clone(), *force, *client, authorize.as_deref()),
        Some(Command::Devices {
            all,
            json,
            config,
            openhaptics_library,
            dhd_library,
        }) => {
            let args = DeviceArgs {
                config: config.clone(),
                openhaptics_library: openhaptics_library.clone(),
                dhd_library: dhd_library.clone(),
                ..DeviceArgs::default()
            }
            .or(&cli.dev);
            return devices(&device_config(&args)?, *all, *json);
        }
        Some(Command::Check(_)) => unreachable!("handled in main"),
        Some(Command::LoopBench {
            seconds,
            rate_hz,
            spin_us,
            no_realtime,
            cpu,
        }) => {
            let mut cfg = load_config(&cli)?;
            cfg.servo.rate_hz = *rate_hz;
            cfg.servo.spin_us = *spin_us;
            cfg.servo.cpu = *cpu;
            if *no_realtime {
                cfg.servo.realtime_priority = 0;
            }
            cfg.validate()?;
            let d = setup::driver_config(&cfg);
            let b = loop_bench::run(*seconds, &d)?;
            print!("{}", loop_bench::report(&b, *rate_hz, d.spin));
            return Ok(());
        }
        None => {}
    }
    let cfg = load_config(&cli)?;
    if cli.print_config {
        print!("{}", toml::to_string(&cfg)?);
        return Ok(());
    }
    serve(cfg)
}

fn serve(cfg: ServerConfig) -> anyhow::Result<()> {
    let (identity, cert_path, generated) = setup::identity(&cfg).context("certificate")?;
    if generated {
        tracing::warn!(cert = %cert_path.display(), "generated a new self-signed certificate; the workstation must pin this file");
    }
    let (authorized, authorized_path, local_client, created) =
        setup::authorized_clients(&cfg).context("authorized clients")?;
    if created {
        tracing::warn!(
            list = %authorized_path.display(),
            "created a client identity for this machine's workstation next to the certificate (client.pem, client.key) and authorized it"
        );
    }
    tracing::info!(
        list = %authorized_path.display(),
        clients = authorized.len(),
        "only workstations presenting one of these client certificates get a session"
    );
    let device = setup::open_device(&cfg).context("opening the device")?;
    let info = device.info().clone();
    let driver = setup::driver_config(&cfg);
    let rt = driver.rt;
    let opts = ServerOptions {
        transport: cfg.network.transport,
        listen: cfg.network.listen,
        identity,
        authorized,
        local_client,
        driver,
        net: setup::net_settings(&cfg),
    };
    let server = Server::start(device, opts).context("starting the server")?;
    let transport = match cfg.network.transport {
        TransportKind::Udp => {
            "udp (control: TLS over TCP, hot path: MAC'd UDP datagrams, same port)"
        }
        TransportKind::Quic => "quic (control: one bidi stream, hot path: unreliable datagrams)",
    };
    tracing::info!(
        device = %info.name,
        max_force_n = info.max_force_n.min(cfg.safety.max_force_n),
        rate_hz = cfg.servo.rate_hz,
        "haptics-server listening on {} via {transport}; certificate {} (the workstation pins it)",
        server.local_addr(),
        cert_path.display()
    );
    tracing::info!(
        ?rt,
        "servo thread requests (warnings above if refused); force output stays zero until a workstation connects and ramps in"
    );
    if let Some(r) = &cfg.telemetry.record {
        tracing::info!(file = %r.display(), "recording every tick for --device replay");
    }
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    runtime
        .block_on(tokio::signal::ctrl_c())
        .context("waiting for Ctrl-C")?;
    tracing::info!("Ctrl-C: shutting down (force to zero)");
    let s = server.servo_stats();
    tracing::info!(
        ticks = s.ticks,
        overruns = s.overruns,
        sessions = server.sessions_started(),
        "servo: tick cost p50 {} ns p99 {} ns max {} ns; lateness p99 {} ns",
        s.tick_cost_ns.p50,
        s.tick_cost_ns.p99,
        s.tick_cost_ns.max,
        s.lateness_ns.p99
    );
    server.shutdown();
    std::thread::sleep(Duration::from_millis(10));
    Ok(())
}

fn gen_cert(
    out: Option<PathBuf>,
    force: bool,
    client: bool,
    authorize: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    let dir = out.unwrap_or_else(setup::default_cert_dir);
    if client {
        let (cert, key) = (dir.join(tls::CLIENT_FILES.0), dir.join(tls::CLIENT_FILES.1));
        if !force && (cert.exists() || key.exists()) {
            bail!(
                "{} or {} exists; pass --force to overwrite",
                cert.display(),
                key.display()
            );
        }
        let id = tls::generate_client()?;
        tls::write_pem(&id, &cert, &key)?;
        println!(
            "wrote {} (the server lists it in network.authorized_clients)\nwrote {} (keep private; the workstation reads it with --client-key)\nfingerprint {}",
            cert.display(),
            key.display(),
            tls::fingerprint(&id.cert)
        );
        match authorize {
            Some(list) => {
                tls::append_certificate(list, &id.cert)?;
                println!("authorized: appended it to {}", list.display());
            }
            None => println!(
                "authorize it on the haptics PC: cat client.pem >> authorized_clients.pem (next to the server's cert.pem, or network.authorized_clients)"
            ),
        }
        return Ok(());
    }
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    if !force && (cert.exists() || key.exists()) {
        bail!(
            "{} or {} exists; pass --force to overwrite",
            cert.display(),
            key.display()
        );
    }
    let id = tls::generate()?;
    tls::write_pem(&id, &cert, &key)?;
    println!(
        "wrote {} (give this to the workstation to pin)\nwrote {} (keep private)",
        cert.display(),
        key.display()
    );
    Ok(())
}

fn devices(cfg: &ServerConfig, all: bool, json: bool) -> anyhow::Result<()> {
    let inv = inventory::scan(
        all,
        &cfg.device.openhaptics.library,
        &cfg.device.dhd.library,
    );
    if json {
        println!("{}", inv.to_json());
    } else {
        print!("{}", inv.summary());
        println!(
            "next: `haptics-server check --device KIND` reads the stylus (add --force-test for \
             the force axes and safety stages)"
        );
    }
    Ok(())
}

/// `check`: its own exit codes (0 passed, 1 a check failed, 2 could not run).
fn check_command(cli: &Cli) -> ExitCode {
    let Some(Command::Check(args)) = &cli.command else {
        return ExitCode::from(2);
    };
    let CheckArgs {
        dev,
        seconds,
        force_test,
        yes,
        force_n,
        out,
        region,
        fit,
    } = &**args;
    let interactive = std::io::IsTerminal::is_terminal(&std::io::stdin());
    let result = (|| -> anyhow::Result<check::report::Report> {
        if *force_test && !*yes && !interactive {
            bail!(
                "--force-test moves the stylus, so the person holding it must confirm on this \
                 terminal, and stdin is not a terminal; on a test rig where nothing can be hurt, \
                 pass --yes"
            );
        }
        if !(0.1..=3.0).contains(force_n) {
            bail!("--force-n {force_n}: the test force must be 0.1 … 3 N");
        }
        if !(seconds.is_finite() && (0.2..=600.0).contains(seconds)) {
            bail!("--seconds {seconds}: must be 0.2 … 600");
        }
        let args = dev.or(&cli.dev);
        let mut cfg = device_config(&args)?;
        if args.fake_path.is_none() && cfg.device.fake.path == "circle" {
            // A hand that holds still (unless a path was asked for): motion then comes from
            // the test force alone.
            cfg.device.fake.path = "idle".into();
        }
        cfg.validate()?;
        let device = setup::open_device(&cfg).context("opening the device")?;
        let driver = setup::driver_config(&cfg);
        let report = haptics_server::servo::rt::setup_current_thread(driver.rt);
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        let opts = CheckOptions {
            kind: cfg.device.kind,
            seconds: *seconds,
            force_n: force_test.then_some(*force_n),
            params: driver.params,
            spin: driver.spin,
            region: *region,
            fit: *fit,
        };
        let mut device = device;
        let mut operator = Terminal {
            ask: interactive && !*yes,
        };
        Ok(check::run_check(&mut *device, &opts, &mut operator)?)
    })();
    let report = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("haptics-server check: error: {e:#}");
            return ExitCode::from(2);
        }
    };
    print!("{}", report.summary());
    if let Some(path) = out {
        if let Err(e) = std::fs::write(path, report.to_json() + "\n") {
            eprintln!("haptics-server check: cannot write {}: {e}", path.display());
            return ExitCode::from(2);
        }
        println!("report: {}", path.display());
    }
    if report.passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// The person at the terminal (or a rig with --yes).
struct Terminal {
    /// Prompt on stdin (a terminal, no --yes).
    ask: bool,
}

impl Terminal {
    fn line(&self) -> String {
        let mut s = String::new();
        let _ = std::io::stdin().read_line(&mut s);
        s.trim().to_lowercase()
    }
}

impl Operator for Terminal {
    fn before_read(&mut self, seconds: f64) {
        eprintln!(
            "check: reading the stylus for {seconds:.1} s with no force: move it through the \
             whole workspace, turn it, and press each button."
        );
        if self.ask {
            eprint!("press Enter to start: ");
            let _ = self.line();
        }
    }

    fn confirm_force(&mut self, force_n: f32, duration_s: f64) -> bool {
        if !self.ask {
            eprintln!("check: --yes: starting the force test without asking");
            return true;
        }
        eprintln!(
            "check: the force test pushes the stylus with up to {force_n:.1} N along +x, -x, +y, \
             -y, +z, -z for about {duration_s:.0} s, through the servo loop's safety stages.\n\
             Hold the stylus lightly near the centre of the workspace and let it move; keep the \
             area around the device clear."
        );
        eprint!("type yes and Enter to start (anything else skips the force test): ");
        matches!(self.line().as_str(), "yes" | "y")
    }

    fn progress(&mut self, line: &str) {
        eprintln!("check: {line}");
    }
}
