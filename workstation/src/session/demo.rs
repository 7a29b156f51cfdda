//! `workstation demo`: the networked demo, README command 1.
//!
//! Starts a `haptics-server` with the fake device on loopback in this process (its own servo
//! and network threads, real sockets; or connects to one with `--server`), whose simulated hand
//! follows the scene's strokes ([`hand_path`]); starts the workstation's threads against it;
//! drives the session's phases ([`drive_phases`]: each stroke ends when the button lets go, each
//! operation runs on the simulation thread); prints a line per phase; writes `summary.json`,
//! `final.ply`, `final_mesh.{ply,obj,stl}` and PNG frames into `--out`.
//!
//! [`command`] shows it in the window ([`crate::view`]) when a display is present: the demo
//! drives the session on a thread, the window is its rendering thread. The window knows
//! nothing of the demo; the demo hands it a [`Link`].

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glam::Vec3;
use haptics_client::TransportKind;
use serde::Serialize;

use crate::live::net::NetConfig;
use crate::live::phases::{PhaseReport, drive_phases, hand_path, write_hand_path};
use crate::live::scene_file::{DEMO_IMAGE, DEMO_SCENE, SceneFile};
use crate::live::shared::PercentilesUs;
use crate::live::{CursorSource, LiveStats, Workstation, save};
use crate::share::station::Station;
use crate::view::{self, Exit, Link};

/// Seconds the hand rests before the first stroke (the session comes up meanwhile).
pub const LEAD_IN_S: f64 = 1.5;

/// Arguments of `workstation demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// Connect to this running server instead of starting one in-process. Its fake device must
    /// follow the demo's hand path: `workstation hand-path` writes it, then
    /// `haptics-server --device fake --fake-path file --fake-path-file FILE`.
    #[arg(long, value_name = "ADDR")]
    pub server: Option<SocketAddr>,
    /// The server's certificate (PEM) to pin; required with --server.
    #[arg(long, value_name = "FILE", requires = "server")]
    pub cert: Option<PathBuf>,
    /// Transport.
    #[arg(long, value_enum, default_value_t = TransportKind::Udp)]
    pub transport: TransportKind,
    /// Scene file [default: the built-in demo, examples/live/demo.toml].
    #[arg(long, value_name = "SCENE.toml")]
    pub scene: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 110.0)]
    pub timeout_s: f64,
    /// Stay headless even when a display is present (the window opens by default then).
    #[arg(long)]
    pub no_window: bool,
    /// Joining a shared scene (the built-in scene's name is `demo`).
    #[command(flatten)]
    pub share: crate::share::station::ShareArgs,
}

/// What a caller that shows the demo (the window) hooks into [`run_with`].
#[derive(Debug, Default)]
pub struct DemoHooks {
    /// Receives the session's link once the workstation has started.
    pub started: Option<std::sync::mpsc::Sender<Link>>,
    /// Set to stop the demo between phases (the window was closed).
    pub cancelled: Arc<AtomicBool>,
    /// Receives every progress line too.
    pub log: Option<Arc<Mutex<Vec<String>>>>,
}

/// `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// PNG frames written.
    pub frames: u64,
    /// Force-mapping ticks per second over the session.
    pub force_loop_hz: f64,
    /// Its tick-to-tick period (µs).
    pub force_loop_period_us: PercentilesUs,
    /// Simulation steps per second.
    pub sim_hz: f64,
    /// Cursor → force round trip measured at the server (µs).
    pub rtt_us: PercentilesUs,
    /// Baseline in the same run: a bare UDP ping-pong of 64-byte datagrams between two loopback
    /// sockets (µs), taken right after the session under the same load.
    pub baseline_udp_rtt_us: PercentilesUs,
    /// The age of the command each servo tick applied (also in `stats`): the fraction of ticks
    /// that applied the answer to the previous tick's cursor, one or more ticks later, or none.
    pub applied_age_ticks: protocol::AppliedAgeFractions,
    /// Points in the final model.
    pub points: usize,
    /// Triangles of its meshed zero set.
    pub triangles: usize,
    /// The phases, in order.
    pub phases: Vec<PhaseReport>,
    /// Transport used.
    pub transport: TransportKind,
    /// Server address.
    pub server: SocketAddr,
    /// Wall time of the session (s).
    pub seconds: f64,
    /// Everything else measured.
    pub stats: LiveStats,
    /// The shared scene, with `--share`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub share: Option<crate::share::station::ShareSummary>,
}

/// `workstation demo`: with the window when a display is present (and not `--no-window`): the
/// demo drives the session on a thread, the window shows it on this one and stays open on the
/// result until closed. Closing the window early stops the demo.
pub fn command(args: &DemoArgs) -> anyhow::Result<()> {
    if args.no_window || !view::display_available() {
        return run(args).map(|_| ());
    }
    if let Err(e) = view::window_gpu() {
        println!("demo: no window ({e:#}); running headless");
        return run(args).map(|_| ());
    }
    let (link_tx, link_rx) = std::sync::mpsc::channel();
    let cancelled = Arc::new(AtomicBool::new(false));
    let log: Arc<Mutex<Vec<String>>> = Arc::default();
    let hooks = DemoHooks {
        started: Some(link_tx),
        cancelled: Arc::clone(&cancelled),
        log: Some(Arc::clone(&log)),
    };
    let demo_args = args.clone();
    let worker = std::thread::Builder::new()
        .name("demo".into())
        .spawn(move || run_with(&demo_args, hooks))
        .context("starting the demo thread")?;
    let shown = match link_rx.recv() {
        Ok(mut link) => {
            link.log = log;
            view::open(
                link,
                None,
                args.out.clone(),
                Exit::default(),
                (1280, 800),
                "workstation demo",
            )
        }
        Err(_) => Ok(()), // the demo failed before its session started: its error follows
    };
    cancelled.store(true, Ordering::Relaxed);
    let result = worker
        .join()
        .map_err(|_| anyhow::anyhow!("the demo thread panicked"))?;
    shown?;
    match result {
        Ok(_) => Ok(()),
        Err(e) if e.to_string().starts_with("interrupted") => {
            println!("demo: the window was closed before the end");
            Ok(())
        }
        Err(e) => Err(e),
    }
}

/// Run the demo headless; see the module doc.
pub fn run(args: &DemoArgs) -> anyhow::Result<Summary> {
    run_with(args, DemoHooks::default())
}

/// Run the demo with hooks for a window.
pub fn run_with(args: &DemoArgs, hooks: DemoHooks) -> anyhow::Result<Summary> {
    let say = |line: String| {
        println!("{line}");
        if let Some(log) = &hooks.log
            && let Ok(mut l) = log.lock()
        {
            l.push(line);
        }
    };
    let started = Instant::now();
    anyhow::ensure!(
        args.timeout_s.is_finite() && (1.0..=86_400.0).contains(&args.timeout_s),
        "--timeout-s must be 1..=86400 s (got {})",
        args.timeout_s
    );
    let deadline = started + Duration::from_secs_f64(args.timeout_s);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (text, dir) = match &args.scene {
        Some(p) => (
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
            p.parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
        ),
        None => {
            std::fs::write(args.out.join("ring.png"), DEMO_IMAGE)?;
            (DEMO_SCENE.to_owned(), args.out.clone())
        }
    };
    let scene = SceneFile::parse(&text).map_err(|e| anyhow::anyhow!("scene: {e}"))?;
    let path = hand_path(&scene, LEAD_IN_S);
    write_hand_path(&args.out.join("hand_path.txt"), &path)?;
    let n_phases = scene.phase.len();
    say(format!(
        "demo: {} phases; fitting the scene's objects (relative files from {})",
        n_phases,
        dir.display()
    ));
    // Fit first (seconds), then start the server: the hand's clock starts with the server.
    let server_and_cfg = |_: ()| -> anyhow::Result<(Option<ServerGuard>, NetConfig)> {
        match NetConfig::from_flags(args.server, args.cert.as_deref(), args.transport)? {
            Some(cfg) => Ok((None, cfg)),
            None => embedded_server(args.transport, path.clone()),
        }
    };
    let frames_dir = args.out.join("frames");
    let _ = std::fs::remove_dir_all(&frames_dir);
    let ws_and_server = {
        let core_scene = scene.clone();
        let (server, cfg) = server_and_cfg(())?;
        let addr = cfg.server;
        let source = CursorSource::Server(cfg);
        let ws = Workstation::start(&core_scene, dir.clone(), source.clone(), Some(frames_dir))?;
        let scene_path = args
            .scene
            .clone()
            .unwrap_or_else(|| PathBuf::from("demo.toml"));
        let station = args
            .share
            .resolve(&scene_path, false)?
            .map(|c| Station::start(c, ws.commander(), Arc::clone(&ws.shared)))
            .transpose()?;
        if let Some(tx) = &hooks.started {
            let mut link = Link::to(&ws, &core_scene, dir, &source);
            link.remote = station.as_ref().map(|s| Arc::clone(&s.stats));
            let _ = tx.send(link);
        }
        (ws, server, addr, station)
    };
    let (ws, server, addr, station) = ws_and_server;
    ws.wait_connected(Duration::from_secs(10))?;
    if let Some(st) = &station {
        let t0 = Instant::now();
        while !st.joined() {
            anyhow::ensure!(
                t0.elapsed() < Duration::from_secs(20),
                "the shared scene was not joined within 20 s (is `workstation share-router` running at {}?)",
                args.share.share.as_deref().unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let joined = st.summary();
        say(format!(
            "demo: joined the shared scene `{}` (version {})",
            joined.scene, joined.version
        ));
    }
    say(format!(
        "demo: connected to {addr} over {:?}{}",
        args.transport,
        if server.is_some() {
            " (in-process haptics server, fake device)"
        } else {
            ""
        }
    ));
    ws.shared
        .force_loop
        .reset
        .store(true, std::sync::atomic::Ordering::Relaxed);
    let phases = drive_phases(
        &ws,
        &scene,
        deadline,
        || hooks.cancelled.load(Ordering::Relaxed),
        |i, r| {
            say(format!(
                "[{}/{n_phases}] {} ({}, {:.1} s): {}",
                i + 1,
                r.name,
                r.kind,
                r.seconds,
                r.summary
            ));
        },
    )?;
    // One last frame of the result.
    std::thread::sleep(Duration::from_secs_f64(scene.render.interval_s * 1.5));
    let stats = ws.stats();
    let share = station.map(|st| {
        st.settle(Duration::from_secs(10));
        st.stop()
    });
    let core = ws.finish()?;
    drop(server);
    let baseline_udp_rtt_us = udp_baseline(2000)?;
    let saved = save(&core, &args.out, scene.mesh_resolution)?;
    let summary = Summary {
        frames: stats.frames,
        force_loop_hz: stats.force_loop_hz,
        force_loop_period_us: stats.force_loop_period_us,
        sim_hz: stats.sim_hz,
        rtt_us: stats.rtt_us,
        baseline_udp_rtt_us,
        applied_age_ticks: stats.applied_age_ticks,
        points: saved.points,
        triangles: saved.triangles,
        phases,
        transport: args.transport,
        server: addr,
        seconds: started.elapsed().as_secs_f64(),
        stats,
        share,
    };
    std::fs::write(
        args.out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    say(format!(
        "demo: done in {:.1} s. force loop {:.0} Hz (period p50 {:.0} µs, p99 {:.0} µs), simulation {:.0} Hz, cursor→force round trip p50 {:.0} µs p99 {:.0} µs (bare UDP ping-pong p50 {:.0} µs), {:.2} % of servo ticks applied the answer to the previous tick's cursor, {} frames; wrote {}",
        summary.seconds,
        summary.force_loop_hz,
        summary.force_loop_period_us.p50,
        summary.force_loop_period_us.p99,
        summary.sim_hz,
        summary.rtt_us.p50,
        summary.rtt_us.p99,
        summary.baseline_udp_rtt_us.p50,
        summary.applied_age_ticks.next_tick * 100.0,
        summary.frames,
        args.out.display()
    ));
    Ok(summary)
}

/// A bare UDP ping-pong on loopback, `n` round trips of a 64-byte datagram, the echo on its own
/// thread: the baseline the cursor → force round trip is compared with.
pub fn udp_baseline(n: usize) -> anyhow::Result<PercentilesUs> {
    use std::net::UdpSocket;
    let a = UdpSocket::bind("127.0.0.1:0")?;
    let b = UdpSocket::bind("127.0.0.1:0")?;
    a.connect(b.local_addr()?)?;
    b.connect(a.local_addr()?)?;
    b.set_read_timeout(Some(Duration::from_secs(1)))?;
    a.set_read_timeout(Some(Duration::from_secs(1)))?;
    let echo = std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        for _ in 0..n {
            if b.recv(&mut buf).is_err() || b.send(&buf).is_err() {
                break;
            }
        }
    });
    let mut h = hdrhistogram::Histogram::<u64>::new_with_bounds(100, 10_000_000_000, 3)?;
    let mut buf = [0u8; 64];
    for _ in 0..n {
        let t0 = Instant::now();
        a.send(&buf)?;
        a.recv(&mut buf)?;
        h.saturating_record(t0.elapsed().as_nanos() as u64);
    }
    let _ = echo.join();
    Ok(crate::live::force::percentiles_us(&h))
}

/// Keeps the in-process server alive.
#[cfg(feature = "demo-server")]
type ServerGuard = haptics_server::server::Server;
#[cfg(not(feature = "demo-server"))]
type ServerGuard = ();

/// A server with the fake device following `path`, on loopback, port chosen by the OS.
#[cfg(feature = "demo-server")]
pub fn embedded_server(
    transport: TransportKind,
    path: Vec<(f32, Vec3, u16)>,
) -> anyhow::Result<(Option<ServerGuard>, NetConfig)> {
    use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
    use haptics_server::server::{Server, ServerOptions};
    let device = FakeDevice::new(FakeParams {
        path: HandPath::Recorded(path.into()),
        ..FakeParams::default()
    });
    let mut opts = ServerOptions::for_tests(transport)?;
    // Real-time servo when the OS allows it (else it warns and runs SCHED_OTHER).
    opts.driver.rt.fifo_priority = Some(crate::live::force::SERVO_FIFO_PRIORITY);
    let server = Server::start(device, opts)?;
    let cfg = NetConfig::to_in_process(&server, transport);
    Ok((Some(server), cfg))
}

/// Built without the `demo-server` feature: a server must be given.
#[cfg(not(feature = "demo-server"))]
pub fn embedded_server(
    _transport: TransportKind,
    _path: Vec<(f32, Vec3, u16)>,
) -> anyhow::Result<(Option<ServerGuard>, NetConfig)> {
    anyhow::bail!(
        "this workstation was built without the in-process server (feature `demo-server`): give --server and --cert"
    )
}
