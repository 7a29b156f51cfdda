//! The workstation process of seed 000 Fig. 7: network, force-mapping, simulation and rendering
//! threads around one scene.
//!
//! ```text
//!  haptics-server ──cursor 1 kHz──▶ [net: tokio] ──ring──▶ [force] ──ForceCommand──▶ server
//!                                         ▲                 │  ▲ field grid, samples, tool
//!                           clock pings,  │          events │  │ (ArcSwap, newest wins)
//!                           Stats         │            ring ▼  │
//!                                                      [simulation] ──RenderSnapshot──▶ [frames]
//! ```
//!
//! Each thread's core is deterministic and testable without the others: [`force::ForceMapper`],
//! [`sim::SimCore`], [`frames::FrameMaker`]; the drivers ([`force::run`], [`sim::run`],
//! [`net::run`], [`frames::run`]) are thin. Hand-off policies are in [`shared`]. The force thread
//! never waits for the simulation: it reads the newest immutable snapshot, whatever its age.
//!
//! [`Workstation::start`] loads the scene and starts the threads; [`Workstation::finish`]
//! stops them and returns the simulation core for saving ([`save`]).
//!
//! Layers, arrows pointing down only (the commands that drive a session, `demo` and `run`,
//! are [`crate::session`]'s, above this module and the window):
//! ```text
//!  phases                    a scene's scripted strokes: the fake hand's path, the phase driver
//!    ▼
//!  Workstation (here)        starts and stops the threads
//!    ▼
//!  sim, force, net, mouse, frames        the threads' cores and drivers (sim's driver times
//!                                        its loop with force's LoopTimer)
//!    ▼
//!  shared, scene_file, transform         hand-offs, scene files, the device frame
//! ```

pub mod force;
pub mod frames;
pub mod mouse;
pub mod neighbours;
pub mod net;
pub mod phases;
pub mod points;
pub mod scene_file;
pub mod shared;
pub mod sim;
pub mod snapshot_png;
pub mod transform;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use serde::Serialize;

use crate::sculpt::script::Op;
use frames::FrameCount;
use net::NetConfig;
use scene_file::{SceneFile, ToolKind};
use shared::{CURSOR_RING, EVENT_RING, PercentilesUs, Shared};
pub use sim::{Saved, save};
use sim::{SimCommand, SimCore, SimReport};

/// Where the cursor comes from.
#[derive(Debug, Clone)]
pub enum CursorSource {
    /// A haptics server's device, over the network.
    Server(NetConfig),
    /// The window's mouse ([`mouse`]): no device, no server.
    Mouse(Arc<mouse::MouseHand>),
}

impl From<NetConfig> for CursorSource {
    fn from(cfg: NetConfig) -> Self {
        Self::Server(cfg)
    }
}

/// A running workstation.
#[derive(Debug)]
pub struct Workstation {
    /// What the threads share (statistics, snapshots).
    pub shared: Arc<Shared>,
    commands: mpsc::Sender<SimCommand>,
    reports: mpsc::Receiver<SimReport>,
    threads: Vec<(&'static str, JoinHandle<()>)>,
    frames: Arc<FrameCount>,
    started: Instant,
}

impl Workstation {
    /// Load and fit the scene (relative files against `dir`), then start the simulation,
    /// force-mapping, network (or mouse) and (with `frames`) rendering threads.
    pub fn start(
        scene: &SceneFile,
        dir: PathBuf,
        source: impl Into<CursorSource>,
        frames_dir: Option<PathBuf>,
    ) -> anyhow::Result<Self> {
        let source = source.into();
        // Everything that can fail comes before the first thread starts.
        let core = SimCore::new(scene, dir)?;
        let mapper = force::ForceMapper::new(scene)?;
        let frames = match frames_dir {
            Some(dir) => {
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
                Some((dir, frames::FrameMaker::new(&scene.render)?))
            }
            None => None,
        };
        let shared = Shared::new();
        let (cursor_tx, cursor_rx) = rtrb::RingBuffer::new(CURSOR_RING);
        let (sender_tx, sender_rx) = rtrb::RingBuffer::new(4);
        let (event_tx, event_rx) = rtrb::RingBuffer::new(EVENT_RING);
        let (cmd_tx, cmd_rx) = mpsc::channel();
        let (rep_tx, rep_rx) = mpsc::channel();
        let mut threads = Vec::new();
        let spawn = |name: &'static str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(f)
                .with_context(|| format!("starting the {name} thread"))
        };
        // The first field snapshot is there before any cursor arrives.
        let mut core = core;
        shared.field.store(core.publish_field());
        shared.render.store(Some(Arc::new(core.render_snapshot())));
        let s = Arc::clone(&shared);
        threads.push((
            "simulation",
            spawn(
                "simulation",
                Box::new(move || sim::run(core, event_rx, cmd_rx, rep_tx, s)),
            )?,
        ));
        let force = force::ForceLoop::new(mapper, event_tx);
        let s = Arc::clone(&shared);
        let quic = matches!(&source, CursorSource::Server(cfg) if cfg.transport == haptics_client::TransportKind::Quic);
        match source {
            // QUIC: the network thread maps forces itself (`net::Answer::Inline`).
            CursorSource::Server(cfg) if quic => {
                let ports = net::NetPorts {
                    answer: net::Answer::Inline(Box::new(force)),
                };
                threads.push((
                    "network",
                    spawn("network", Box::new(move || net::run(cfg, ports, s)))?,
                ));
            }
            source => {
                let ports = force::ForcePorts {
                    cursors: cursor_rx,
                    senders: sender_rx,
                };
                let f = spawn(
                    "force-mapping",
                    Box::new(move || force::run(force, ports, s)),
                )?;
                let force_thread = f.thread().clone();
                threads.push(("force-mapping", f));
                let s = Arc::clone(&shared);
                match source {
                    CursorSource::Server(cfg) => {
                        let ports = net::NetPorts {
                            answer: net::Answer::Thread {
                                cursors: cursor_tx,
                                senders: sender_tx,
                                force_thread,
                            },
                        };
                        threads.push((
                            "network",
                            spawn("network", Box::new(move || net::run(cfg, ports, s)))?,
                        ));
                    }
                    CursorSource::Mouse(hand) => {
                        drop(sender_tx); // no session, no sender: forces are shown, not sent
                        let ports = mouse::MousePorts {
                            cursors: cursor_tx,
                            force_thread,
                        };
                        let sampler = mouse::MouseSampler::new(scene.device.transform());
                        threads.push((
                            "mouse",
                            spawn(
                                "mouse",
                                Box::new(move || mouse::run(hand, sampler, ports, s)),
                            )?,
                        ));
                    }
                }
            }
        }
        let count = Arc::new(FrameCount::default());
        if let Some((dir, maker)) = frames {
            let (s, c) = (Arc::clone(&shared), Arc::clone(&count));
            let interval = Duration::from_secs_f64(scene.render.interval_s);
            threads.push((
                "rendering",
                spawn(
                    "rendering",
                    Box::new(move || frames::run(maker, dir, interval, c, s)),
                )?,
            ));
        }
        Ok(Self {
            shared,
            commands: cmd_tx,
            reports: rep_rx,
            threads,
            frames: count,
            started: Instant::now(),
        })
    }

    /// Select the tool for later presses.
    pub fn select(&self, tool: ToolKind) -> anyhow::Result<()> {
        self.send(SimCommand::Select(tool))
    }

    /// Send a command to the simulation thread (answers come on the command's channel).
    pub fn send(&self, cmd: SimCommand) -> anyhow::Result<()> {
        self.commands
            .send(cmd)
            .ok()
            .context("the simulation thread has stopped")
    }

    /// A handle that sends commands to the simulation thread from elsewhere (the window).
    pub fn commander(&self) -> mpsc::Sender<SimCommand> {
        self.commands.clone()
    }

    /// Run an operation on the simulation thread and wait for it.
    /// Returns the operation's kind and a one-line summary.
    pub fn run_op(&self, op: &Op) -> anyhow::Result<(&'static str, String)> {
        let (tx, rx) = mpsc::channel();
        self.commands
            .send(SimCommand::Op(Box::new(op.clone()), tx))
            .context("the simulation thread has stopped")?;
        rx.recv().context("the simulation thread has stopped")?
    }

    /// The next report from the simulation, waiting up to `timeout`.
    pub fn next_report(&self, timeout: Duration) -> Option<SimReport> {
        self.reports.recv_timeout(timeout).ok()
    }

    /// Whether a session with the server is up.
    pub fn connected(&self) -> bool {
        self.shared.net.connected.load(Ordering::Acquire)
    }

    /// Wait until a session is up (and the first cursor has arrived).
    pub fn wait_connected(&self, timeout: Duration) -> anyhow::Result<()> {
        let t0 = Instant::now();
        while !self.connected() {
            anyhow::ensure!(
                t0.elapsed() < timeout,
                "no session with the server after {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames.0.load(Ordering::Relaxed)
    }

    /// Statistics now.
    pub fn stats(&self) -> LiveStats {
        let s = &self.shared;
        let n = &s.net;
        LiveStats {
            seconds: self.started.elapsed().as_secs_f64(),
            force_loop_hz: s.force_loop.rate_hz(),
            force_loop_period_us: s.force_loop.period_us.get(),
            force_loop_work_us: s.force_loop.work_us.get(),
            sim_hz: s.sim_loop.rate_hz(),
            sim_step_us: s.sim_loop.work_us.get(),
            field_step_us: s.field_loop.work_us.get(),
            sim_steps: s.sim_steps.load(Ordering::Relaxed),
            rtt_us: n.force_rtt_us.get(),
            clock_offset_us: n.clock_offset_ns.get() / 1e3,
            clock_uncertainty_us: n.clock_uncertainty_ns.get() / 1e3,
            ping_rtt_us: n.ping_rtt_ns.load(Ordering::Relaxed) as f64 / 1e3,
            sessions: n.sessions.load(Ordering::Relaxed),
            cursors: n.cursors.load(Ordering::Relaxed),
            cursors_dropped: n.cursors_dropped.load(Ordering::Relaxed),
            cursors_skipped: n.cursors_skipped.load(Ordering::Relaxed),
            cursors_late: n.cursors_late.load(Ordering::Relaxed),
            forces_sent: n.forces_sent.load(Ordering::Relaxed),
            events_dropped: s.events_dropped.load(Ordering::Relaxed),
            frames: self.frames(),
            applied_age_ticks: n.applied.get().fractions(),
        }
    }

    /// Stop every thread and hand back the simulation core (for saving).
    pub fn finish(mut self) -> anyhow::Result<SimCore> {
        let (tx, rx) = mpsc::channel();
        let sent = self.send(SimCommand::Finish(tx)).is_ok();
        let core = if sent {
            rx.recv_timeout(Duration::from_secs(60)).ok()
        } else {
            None
        };
        self.shared.request_stop();
        for (name, t) in self.threads.drain(..) {
            t.thread().unpark();
            if t.join().is_err() {
                tracing::error!("the {name} thread panicked");
            }
        }
        core.context("the simulation thread stopped before the end (see the log)")
    }
}

impl Drop for Workstation {
    fn drop(&mut self) {
        self.shared.request_stop();
        for (_, t) in self.threads.drain(..) {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// Statistics of a running workstation.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LiveStats {
    /// Since start (s).
    pub seconds: f64,
    /// Force-mapping ticks per second.
    pub force_loop_hz: f64,
    /// Force-mapping tick-to-tick period (µs).
    pub force_loop_period_us: PercentilesUs,
    /// Force-mapping work per tick (µs).
    pub force_loop_work_us: PercentilesUs,
    /// Simulation steps per second.
    pub sim_hz: f64,
    /// Simulation work per step (µs).
    pub sim_step_us: PercentilesUs,
    /// The field's part of a step, until the snapshot is published (µs).
    pub field_step_us: PercentilesUs,
    /// Simulation steps run.
    pub sim_steps: u64,
    /// Cursor → force round trip measured by the server (µs).
    pub rtt_us: PercentilesUs,
    /// Clock offset server − workstation (µs) …
    pub clock_offset_us: f64,
    /// … and its bound (µs).
    pub clock_uncertainty_us: f64,
    /// Round trip of the clock ping behind the estimate (µs).
    pub ping_rtt_us: f64,
    /// Sessions opened (1 + reconnects).
    pub sessions: u64,
    /// Cursor samples received.
    pub cursors: u64,
    /// Cursors dropped (force ring full).
    pub cursors_dropped: u64,
    /// Cursors skipped by the force thread (a newer one was waiting).
    pub cursors_skipped: u64,
    /// Cursors refused as older than one already mapped (reordered by the network).
    pub cursors_late: u64,
    /// The age of the command each servo tick applied, in ticks after the cursor it answers
    /// (every cursor received; goal on loopback ≥ 99.9 % `next_tick`).
    pub applied_age_ticks: protocol::AppliedAgeFractions,
    /// Force commands sent.
    pub forces_sent: u64,
    /// Input events dropped (simulation ring full).
    pub events_dropped: u64,
    /// PNG frames written.
    pub frames: u64,
}
