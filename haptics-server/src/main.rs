//! `haptics-server`: the binary. Thin: parse, configure, start [`Server`], wait for Ctrl-C.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::{Parser, Subcommand};
use haptics_server::config::{DeviceKind, ServerConfig};
use haptics_server::server::{Server, ServerOptions, TransportKind};
use haptics_server::{loop_bench, setup, tls};

/// The haptic device server: owns the device, runs the 1 kHz servo loop with its safety
/// stages, and serves one workstation at a time over UDP or QUIC.
///
/// First run: `haptics-server --device fake --transport udp --listen 127.0.0.1:7700` starts a
/// simulated stylus and listens on loopback; a self-signed certificate is created at the
/// default location on first start, and the workstation pins that file.
/// Every setting lives in a TOML file (`--config`, see deploy/haptics-server.example.toml);
/// flags override it.
#[derive(Debug, Parser)]
#[command(name = "haptics-server", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Device backend [default: fake, or the config's device.kind].
    #[arg(long, value_enum)]
    device: Option<DeviceKind>,
    /// Transport: udp = TLS-over-TCP control + MAC'd UDP datagrams on one port; quic = QUIC
    /// (one bidi stream for control, unreliable datagrams) [default: udp, or network.transport].
    #[arg(long, value_enum)]
    transport: Option<TransportKind>,
    /// Listen address [default: 127.0.0.1:7700, or network.listen].
    #[arg(long, value_name = "ADDR")]
    listen: Option<SocketAddr>,
    /// TOML configuration file; every option and its default is in
    /// deploy/haptics-server.example.toml [default: built-in defaults].
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Record every servo tick (positions, buttons, forces, timing) to FILE for `--device replay`.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The recording `--device replay` plays [default: device.replay.file].
    #[arg(long, value_name = "FILE")]
    replay_file: Option<PathBuf>,
    /// Fake hand path: idle, circle, line, press, or file (with --fake-path-file)
    /// [default: circle, or device.fake.path].
    #[arg(long, value_name = "PATH")]
    fake_path: Option<String>,
    /// Path file for `--fake-path file`: lines `t_s x y z [buttons]` (`workstation demo`
    /// writes one for its scripted session).
    #[arg(long, value_name = "FILE")]
    fake_path_file: Option<PathBuf>,
    /// Certificate (PEM) [default: $XDG_CONFIG_HOME/haptics-server/cert.pem, created on first
    /// start if neither it nor the key exists].
    #[arg(long, value_name = "FILE", requires = "key")]
    cert: Option<PathBuf>,
    /// Private key (PEM) matching --cert.
    #[arg(long, value_name = "FILE", requires = "cert")]
    key: Option<PathBuf>,
    /// Servo rate, Hz [default: 1000, or servo.rate_hz].
    #[arg(long, value_name = "HZ")]
    rate_hz: Option<u32>,
    /// Do not ask for SCHED_FIFO (servo.realtime_priority = 0).
    #[arg(long)]
    no_realtime: bool,
    /// Print the effective configuration as TOML and exit.
    #[arg(long)]
    print_config: bool,
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
    /// List attached HID devices and whether the OpenHaptics library can be loaded.
    Devices,
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
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("haptics-server: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn load_config(cli: &Cli) -> anyhow::Result<ServerConfig> {
    let mut cfg = match &cli.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            ServerConfig::from_toml(&text, &p.display().to_string())?
        }
        None => ServerConfig::default(),
    };
    if let Some(d) = cli.device {
        cfg.device.kind = d;
    }
    if let Some(t) = cli.transport {
        cfg.network.transport = t;
    }
    if let Some(l) = cli.listen {
        cfg.network.listen = l;
    }
    if cli.record.is_some() {
        cfg.telemetry.record = cli.record.clone();
    }
    if cli.replay_file.is_some() {
        cfg.device.replay.file = cli.replay_file.clone();
    }
    if let Some(p) = &cli.fake_path {
        cfg.device.fake.path = p.clone();
    }
    if cli.fake_path_file.is_some() {
        cfg.device.fake.path_file = cli.fake_path_file.clone();
    }
    if cli.cert.is_some() {
        cfg.network.cert = cli.cert.clone();
        cfg.network.key = cli.key.clone();
    }
    if let Some(r) = cli.rate_hz {
        cfg.servo.rate_hz = r;
    }
    if cli.no_realtime {
        cfg.servo.realtime_priority = 0;
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
        Some(Command::Devices) => return devices(),
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

fn devices() -> anyhow::Result<()> {
    println!("fake: always available (simulated stylus)");
    match haptics_server::device::hid::list() {
        Ok(list) if list.is_empty() => println!("hid: no HID devices attached"),
        Ok(list) => {
            println!("hid:");
            for d in list {
                println!("  {d}");
            }
        }
        Err(e) => println!("hid: cannot enumerate: {e}"),
    }
    match haptics_server::device::openhaptics::probe("libHD.so") {
        Ok(()) => println!("openhaptics: libHD.so loads and exports every function needed"),
        Err(e) => println!("openhaptics: {e}"),
    }
    Ok(())
}
