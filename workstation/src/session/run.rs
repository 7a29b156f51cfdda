//! `workstation run`: the workstation process against a running `haptics-server`, and
//! `workstation hand-path`: a scene's strokes as the fake device's path file.
//!
//! `run` loads the scene, connects (reconnecting whenever the session drops), and runs until
//! Ctrl-C or `--seconds`, printing one status line a second. If the scene has phases, they are
//! driven as in the demo (strokes end at the button's release). On exit it saves the model to
//! `--out`. With `--share` it joins a shared scene (`crate::share`); without `--server` it is
//! then a station without a device: it follows the scene (and saves it) but has no hand.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::live::phases::{drive_phases, hand_path, write_hand_path};
use crate::live::scene_file::load_scene;
use crate::live::{CursorSource, Workstation, save};
use crate::share::station::{ShareArgs, Station};

/// Arguments of `workstation run`.
#[derive(Debug, Clone, clap::Args)]
pub struct RunArgs {
    /// Where and how to connect.
    #[command(flatten)]
    pub connect: crate::live::net::ConnectArgs,
    /// The scene (TOML; see examples/live/README.md), or a point or mesh file to sculpt, opened
    /// as `workstation view` opens one.
    #[arg(long, value_name = "SCENE.toml|MODEL")]
    pub scene: PathBuf,
    /// Where the model and frames are saved on exit.
    #[arg(long, default_value = "out/run")]
    pub out: PathBuf,
    /// Write a PNG frame every `render.interval_s` into OUT/frames.
    #[arg(long)]
    pub frames: bool,
    /// Stop after this many seconds [default: at Ctrl-C].
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Perceptual deadband on the force commands (Weber fraction K in [0, 1]; 0 = send one
    /// per cursor): a command goes out only when its force changed by more than K of itself
    /// (or K × 0.5 N), its local model changed, or 5 ms passed. 0.1 cuts a steady contact's
    /// commands by ~90 % (see docs/BENCHMARKS.md, "What delay does to touch").
    #[arg(long, value_name = "K", default_value_t = 0.0)]
    pub force_deadband: f64,
    /// Joining a shared scene.
    #[command(flatten)]
    pub share: ShareArgs,
}

/// Arguments of `workstation hand-path`.
#[derive(Debug, Clone, clap::Args)]
pub struct HandPathArgs {
    /// The scene whose strokes the hand follows.
    pub scene: PathBuf,
    /// The path file to write (`t_s x y z buttons` per line).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Seconds the hand rests before the first stroke. The server's hand starts with the
    /// server: start `workstation run` within this time (it fits the scene first).
    #[arg(long, default_value_t = 15.0)]
    pub lead_in: f64,
}

/// `workstation hand-path`.
pub fn hand_path_command(args: &HandPathArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene)?;
    anyhow::ensure!(
        args.lead_in.is_finite() && (0.0..=3600.0).contains(&args.lead_in),
        "--lead-in must be 0..=3600 s (got {})",
        args.lead_in
    );
    let path = hand_path(&scene, args.lead_in);
    write_hand_path(&args.out, &path)?;
    println!(
        "wrote {} ({} points, {:.1} s, first stroke after {:.0} s); serve it with: haptics-server --device fake --fake-path file --fake-path-file {}\nthen start `workstation run --scene …` within {:.0} s",
        args.out.display(),
        path.len(),
        path.iter().rev().nth(1).map_or(0.0, |p| p.0),
        args.lead_in,
        args.out.display(),
        args.lead_in
    );
    Ok(())
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_sigint(_: libc::c_int) {
    INTERRUPTED.store(true, Ordering::Relaxed);
}

/// Let Ctrl-C (SIGINT) end the process's work gracefully: [`interrupted`] turns true.
pub fn catch_interrupt() {
    // SAFETY: installs an async-signal-safe handler that only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGINT, on_sigint as *const () as libc::sighandler_t);
    }
}

/// Whether Ctrl-C was pressed since [`catch_interrupt`].
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

/// `workstation run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene)?;
    if let Some(s) = args.seconds {
        anyhow::ensure!(
            s.is_finite() && s > 0.0 && s <= 1e7,
            "--seconds must be positive and at most 1e7 (got {s})"
        );
    }
    anyhow::ensure!(
        args.force_deadband.is_finite() && (0.0..=1.0).contains(&args.force_deadband),
        "--force-deadband must be in [0, 1] (got {})",
        args.force_deadband
    );
    let dir = args
        .scene
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let cfg = args.connect.resolve()?;
    let share = args.share.resolve(&args.scene, cfg.is_none())?;
    anyhow::ensure!(
        cfg.is_some() || share.is_some(),
        "give --server and --cert, or --config FILE (or --share ENDPOINT to follow a shared scene without a device)"
    );
    let server = cfg.as_ref().map(|c| (c.server, c.transport));
    catch_interrupt();
    let frames = args.frames.then(|| args.out.join("frames"));
    let source = match cfg {
        Some(cfg) => CursorSource::Server(cfg),
        // A station without a device: a hand that never moves.
        None => CursorSource::Mouse(Default::default()),
    };
    let ws = Workstation::start(&scene, dir, source, frames)?;
    ws.shared.net.force_deadband.set(args.force_deadband);
    let station = share
        .map(|c| Station::start(c, ws.commander(), std::sync::Arc::clone(&ws.shared)))
        .transpose()?;
    match server {
        Some((server, transport)) => {
            println!("workstation: connecting to {server} over {transport:?}")
        }
        None => println!("workstation: no device, following the shared scene"),
    }
    let started = Instant::now();
    let done = || {
        INTERRUPTED.load(Ordering::Relaxed)
            || args
                .seconds
                .is_some_and(|s| started.elapsed().as_secs_f64() >= s)
    };
    // Phases run once a session is up; Ctrl-C or --seconds end them (the model is saved
    // either way, and an error is reported after saving).
    let mut outcome = Ok(());
    if !scene.phase.is_empty() && server.is_some() {
        let deadline = started + Duration::from_secs_f64(args.seconds.unwrap_or(1e7));
        while !(done() || ws.connected() && station.as_ref().is_none_or(Station::joined)) {
            std::thread::sleep(Duration::from_millis(20));
        }
        if !done() {
            outcome = drive_phases(&ws, &scene, deadline, done, |i, r| {
                println!(
                    "[{}/{}] {}: {}",
                    i + 1,
                    scene.phase.len(),
                    r.name,
                    r.summary
                );
            })
            .map(|_| ());
        }
    }
    let mut last = Instant::now();
    while outcome.is_ok() && !done() && !ws.shared.stopping() {
        std::thread::sleep(Duration::from_millis(50));
        if last.elapsed() >= Duration::from_secs(1) {
            last = Instant::now();
            let s = ws.stats();
            let shared = station.as_ref().map_or(String::new(), |st| {
                let v = st.summary();
                if st.joined() {
                    format!(
                        " · shared `{}` v{} (took {}, proposed {}, refused {})",
                        v.scene, v.version, v.adopted, v.proposed, v.refused
                    )
                } else {
                    format!(
                        " · shared `{}`: not joined yet (is `workstation share-router` running at {}?)",
                        v.scene,
                        args.share.share.as_deref().unwrap_or_default()
                    )
                }
            });
            println!(
                "{} force {:.0} Hz (p99 {:.0} µs) · sim {:.0} Hz · rtt p50 {:.0} µs · clock offset {:.0} ± {:.0} µs · sessions {}",
                if server.is_none() {
                    "no device:".to_owned()
                } else if ws.connected() {
                    "connected".to_owned()
                } else {
                    match ws.shared.net.connect_error.load_full() {
                        Some(why) => format!("not connected ({why})"),
                        None => "waiting for the server".to_owned(),
                    }
                },
                s.force_loop_hz,
                s.force_loop_period_us.p99,
                s.sim_hz,
                s.rtt_us.p50,
                s.clock_offset_us,
                s.clock_uncertainty_us,
                s.sessions,
            );
            if !shared.is_empty() {
                println!("  {}", shared.trim_start_matches(" · "));
            }
        }
    }
    let never_connected = server.is_some() && ws.stats().sessions == 0;
    let why = ws.shared.net.connect_error.load_full();
    if let Some(st) = station {
        // What was sculpted last is on the bus before the session ends.
        st.settle(Duration::from_secs(10));
        let summary = st.stop();
        std::fs::create_dir_all(&args.out)?;
        let path = args.out.join("share.json");
        std::fs::write(&path, serde_json::to_string_pretty(&summary)?)?;
        println!(
            "shared scene `{}`: version {}, took {} states, proposed {} ({} refused); {}",
            summary.scene,
            summary.version,
            summary.adopted,
            summary.proposed,
            summary.refused,
            path.display()
        );
    }
    let core = ws.finish()?;
    let saved = save(&core, &args.out, scene.mesh_resolution)?;
    println!(
        "saved {} points, {} triangles into {}",
        saved.points,
        saved.triangles,
        args.out.display()
    );
    if never_connected {
        anyhow::bail!(
            "never had a session: {}",
            why.as_deref().map_or_else(
                || format!(
                    "{} did not answer",
                    server.map_or(String::new(), |s| s.0.to_string())
                ),
                |w| w.to_string()
            )
        );
    }
    outcome
}
