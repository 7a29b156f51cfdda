//! A station's side of a shared scene: the `share` thread (its own single-threaded tokio
//! runtime and Zenoh client session) between the simulation thread and the bus.
//!
//! - **Joining**: asks the scene's current state (`…/state`) and hands it to the simulation to
//!   adopt; with no state yet, it proposes the station's own points as the scene's first.
//! - **Committing**: every local commit the simulation reports (a shaping or painting stroke's
//!   release, an operation) is proposed (`…/propose/<station>`), named after the state it was
//!   made from ([`Book`]).
//! - **Following**: every ordered state (`…/edits`) another station made is adopted, after the
//!   local stroke in progress if there is one; a refusal (`…/verdicts/<station>`) is logged (the
//!   stroke is undone by the newer state, which comes as an edit).
//! - **Catching up**: the keeper's status (`…/keeper`, twice a second) names the scene's
//!   version; a station behind it (an edit missed while its link was down) asks for the state
//!   again. A restarted station joins as above.
//! - **Telemetry**: the station's cursor, force, buttons, tool, loop rates and round trip, JSON
//!   at 125 Hz on `…/telemetry/<station>` (dropped, never queued, when the link is congested).
//!
//! The force loop never waits for any of this: a state is taken by the simulation thread,
//! which publishes a new field snapshot the force loop reads as it does after a local commit.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context as _;
use glam::DVec3;
use zenoh::qos::CongestionControl;

use super::book::{Book, OnOrdered};
use super::bus::{self, StationTls};
use super::wire::{self, Kind, SharedState, StateId};
use super::{KeeperStatus, Keys, Telemetry, VerdictMessage};
use crate::live::shared::Shared;
use crate::live::sim::{SharedPoints, SimCommand};

/// Telemetry samples per second (125: a loaded machine's skipped ticks still leave ≥ 100).
pub const TELEMETRY_HZ: f64 = 125.0;

/// Where and as whom a station joins.
#[derive(Debug, Clone)]
pub struct StationConfig {
    /// The router (`tcp/HOST:PORT` or `tls/HOST:PORT`).
    pub endpoint: String,
    /// This station's name (its certificate's common name under TLS).
    pub station: String,
    /// The scene (its file's stem).
    pub scene: String,
    /// Mutual-TLS files for a `tls/` endpoint.
    pub tls: Option<StationTls>,
    /// A viewer: follows and records, never proposes (no device, or `view --share` watching).
    pub viewer: bool,
}

/// What a station's share thread counts (read by reports and `summary.json`).
#[derive(Debug, Default)]
pub struct ShareStats {
    /// The scene version held.
    pub version: AtomicU64,
    /// States of other stations taken.
    pub adopted: AtomicU64,
    /// Own commits proposed.
    pub proposed: AtomicU64,
    /// Own commits the keeper ordered.
    pub accepted: AtomicU64,
    /// Own commits the keeper refused (undone by a newer state).
    pub refused: AtomicU64,
    /// Commits made before a newer state was taken (never proposed; undone by it).
    pub superseded: AtomicU64,
    /// Bytes put on the bus (proposals and telemetry).
    pub bytes_out: AtomicU64,
    /// Bytes taken from the bus (states, verdicts, status).
    pub bytes_in: AtomicU64,
    /// Telemetry samples sent.
    pub telemetry: AtomicU64,
    /// Whether the session is open and the scene joined.
    pub joined: AtomicBool,
    /// Edit propagation: author's commit → this station's field updated (ms, author's clock;
    /// one machine or synchronised clocks), one per adopted state.
    pub propagation_ms: Mutex<Vec<f64>>,
    /// Edit arrival: author's commit → the state received here (ms, as above), one per state
    /// of another station received; the rest of the propagation is the refit of the field.
    pub arrival_ms: Mutex<Vec<f64>>,
    /// The other stations' newest telemetry and when it came (the window draws their cursors).
    pub others: Mutex<std::collections::BTreeMap<String, (Telemetry, Instant)>>,
}

impl ShareStats {
    /// The other stations heard from within `fresh`.
    pub fn others_heard(&self, fresh: Duration) -> Vec<String> {
        let others = self.others.lock().expect("not poisoned");
        others
            .iter()
            .filter(|(_, (_, at))| at.elapsed() <= fresh)
            .map(|(name, _)| name.clone())
            .collect()
    }

    /// The other stations heard from within `fresh`: name and cursor (scene frame).
    pub fn other_cursors(&self, fresh: Duration) -> Vec<(String, [f64; 3])> {
        let others = self.others.lock().expect("not poisoned");
        others
            .iter()
            .filter(|(_, (_, at))| at.elapsed() <= fresh)
            .filter_map(|(name, (t, _))| Some((name.clone(), t.cursor?)))
            .collect()
    }
}

/// A summary of a station's share, for `summary.json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ShareSummary {
    /// The station.
    pub station: String,
    /// The scene.
    pub scene: String,
    /// The version held at the end.
    pub version: u64,
    /// Counts as in [`ShareStats`].
    pub adopted: u64,
    /// Own commits proposed.
    pub proposed: u64,
    /// Own commits ordered.
    pub accepted: u64,
    /// Own commits refused.
    pub refused: u64,
    /// Commits superseded before proposing.
    pub superseded: u64,
    /// Bytes out and in.
    pub bytes_out: u64,
    /// Bytes in.
    pub bytes_in: u64,
    /// Telemetry samples sent.
    pub telemetry: u64,
    /// Edit propagation to this station, p50 and p99 (ms; absent before any).
    pub propagation_ms_p50: Option<f64>,
    /// p99.
    pub propagation_ms_p99: Option<f64>,
    /// Every propagation measured (ms).
    pub propagation_ms: Vec<f64>,
    /// Edit arrival (commit → received, before the refit), p50 (ms).
    pub arrival_ms_p50: Option<f64>,
    /// p99.
    pub arrival_ms_p99: Option<f64>,
    /// Every arrival measured (ms).
    pub arrival_ms: Vec<f64>,
}

/// A running share thread.
#[derive(Debug)]
pub struct Station {
    config: StationConfig,
    /// Its counts.
    pub stats: Arc<ShareStats>,
    stop: Arc<AtomicBool>,
    /// Set by the thread as it ends.
    ended: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

fn unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    (!sorted.is_empty()).then(|| sorted[((sorted.len() - 1) as f64 * q).round() as usize])
}

impl Station {
    /// Open the session and join (the thread keeps it up; a router that is away is retried).
    /// `commands` is the simulation thread's; `shared` is read for telemetry.
    pub fn start(
        config: StationConfig,
        commands: mpsc::Sender<SimCommand>,
        shared: Arc<Shared>,
    ) -> anyhow::Result<Self> {
        anyhow::ensure!(
            wire::valid_name(&config.station),
            "station name `{}`: use 1-200 letters, digits, - _ or .",
            config.station
        );
        anyhow::ensure!(
            wire::valid_name(&config.scene),
            "scene name `{}` (the scene file's stem): use 1-200 letters, digits, - _ or .",
            config.scene
        );
        let zenoh_config = bus::client_config(&config.endpoint, config.tls.as_ref())?;
        let stats = Arc::new(ShareStats::default());
        let stop = Arc::new(AtomicBool::new(false));
        // Zenoh needs a multi-thread runtime; one worker is enough.
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("share-io")
            .enable_all()
            .build()
            .context("starting the share thread's runtime")?;
        let task = Task {
            config: config.clone(),
            commands,
            shared,
            stats: Arc::clone(&stats),
            stop: Arc::clone(&stop),
            book: Book::new(&config.station, unix_ns() / 1_000),
            t0: Instant::now(),
            unanswered: Vec::new(),
        };
        let ended = Arc::new(AtomicBool::new(false));
        let end = Arc::clone(&ended);
        let thread = std::thread::Builder::new()
            .name("share".into())
            .spawn(move || {
                if let Err(e) = runtime.block_on(task.run(zenoh_config)) {
                    tracing::error!("shared scene stopped: {e:#}");
                }
                end.store(true, Ordering::Release);
            })
            .context("starting the share thread")?;
        Ok(Self {
            config,
            stats,
            stop,
            ended,
            thread: Some(thread),
        })
    }

    /// Whether the scene is joined.
    pub fn joined(&self) -> bool {
        self.stats.joined.load(Ordering::Acquire)
    }

    /// What it counted.
    pub fn summary(&self) -> ShareSummary {
        let s = &self.stats;
        let mut p = s.propagation_ms.lock().expect("not poisoned").clone();
        p.sort_by(f64::total_cmp);
        let mut a = s.arrival_ms.lock().expect("not poisoned").clone();
        a.sort_by(f64::total_cmp);
        ShareSummary {
            station: self.config.station.clone(),
            scene: self.config.scene.clone(),
            version: s.version.load(Ordering::Relaxed),
            adopted: s.adopted.load(Ordering::Relaxed),
            proposed: s.proposed.load(Ordering::Relaxed),
            accepted: s.accepted.load(Ordering::Relaxed),
            refused: s.refused.load(Ordering::Relaxed),
            superseded: s.superseded.load(Ordering::Relaxed),
            bytes_out: s.bytes_out.load(Ordering::Relaxed),
            bytes_in: s.bytes_in.load(Ordering::Relaxed),
            telemetry: s.telemetry.load(Ordering::Relaxed),
            propagation_ms_p50: percentile(&p, 0.5),
            propagation_ms_p99: percentile(&p, 0.99),
            propagation_ms: p,
            arrival_ms_p50: percentile(&a, 0.5),
            arrival_ms_p99: percentile(&a, 0.99),
            arrival_ms: a,
        }
    }

    /// Wait until every own commit has been answered by the keeper and nothing is waiting to be
    /// adopted (or `timeout`): call before finishing, so what was sculpted last is on the bus.
    pub fn settle(&self, timeout: Duration) {
        let t0 = Instant::now();
        let s = &self.stats;
        while t0.elapsed() < timeout {
            let answered = s.accepted.load(Ordering::Acquire) + s.refused.load(Ordering::Acquire);
            if answered >= s.proposed.load(Ordering::Acquire) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        tracing::warn!("shared scene: some commits were not answered within {timeout:?}");
    }

    /// Leave the scene.
    pub fn stop(mut self) -> ShareSummary {
        self.leave();
        self.summary()
    }

    /// Stop the thread: it ends within a telemetry tick once joined; while Zenoh is still
    /// trying to reach a router that is not there, its session cannot be interrupted, and the
    /// thread is left to end with the process.
    fn leave(&mut self) {
        self.stop.store(true, Ordering::Release);
        let t0 = Instant::now();
        while !self.ended.load(Ordering::Acquire) && t0.elapsed() < Duration::from_secs(3) {
            std::thread::sleep(Duration::from_millis(10));
        }
        match self.thread.take() {
            Some(t) if self.ended.load(Ordering::Acquire) => {
                let _ = t.join();
            }
            Some(_) => tracing::warn!(
                "left the shared scene without reaching its router at {}",
                self.config.endpoint
            ),
            None => {}
        }
    }
}

impl Drop for Station {
    fn drop(&mut self) {
        self.leave();
    }
}

/// A proposal sent again when no answer came within this (its link dropped meanwhile).
const RESEND_AFTER: Duration = Duration::from_secs(2);

/// The share thread's state.
struct Task {
    config: StationConfig,
    commands: mpsc::Sender<SimCommand>,
    shared: Arc<Shared>,
    stats: Arc<ShareStats>,
    stop: Arc<AtomicBool>,
    book: Book,
    t0: Instant,
    /// Proposals without an answer yet: their bytes and when they were last sent (`None`: not
    /// to be sent again, made from a state another station's replaced).
    unanswered: Vec<(StateId, Vec<u8>, Option<Instant>)>,
}

/// The station's handles on the bus.
struct Bus {
    keys: Keys,
    proposals: zenoh::pubsub::Publisher<'static>,
    state: zenoh::query::Querier<'static>,
}

fn zerr(e: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

impl Task {
    async fn run(mut self, zenoh_config: zenoh::Config) -> anyhow::Result<()> {
        let keys = Keys::new(&self.config.scene);
        let session = bus::open(zenoh_config, "station").await?;
        let edits = session
            .declare_subscriber(keys.edits())
            .await
            .map_err(zerr)?;
        let verdicts = session
            .declare_subscriber(keys.verdicts(&self.config.station))
            .await
            .map_err(zerr)?;
        let status = session
            .declare_subscriber(keys.keeper())
            .await
            .map_err(zerr)?;
        let others = session
            .declare_subscriber(keys.all_telemetry())
            .await
            .map_err(zerr)?;
        let telemetry = session
            .declare_publisher(keys.telemetry(&self.config.station))
            .congestion_control(CongestionControl::Drop)
            .express(true)
            .await
            .map_err(zerr)?;
        let bus = Bus {
            proposals: session
                .declare_publisher(keys.propose(&self.config.station))
                .congestion_control(CongestionControl::Block)
                .await
                .map_err(zerr)?,
            state: session
                .declare_querier(keys.state())
                .timeout(Duration::from_secs(5))
                .await
                .map_err(zerr)?,
            keys,
        };
        let (outbox_tx, mut outbox) = tokio::sync::mpsc::unbounded_channel();
        let (tx, rx) = mpsc::channel();
        self.commands
            .send(SimCommand::Share(outbox_tx, tx))
            .ok()
            .context("the simulation thread has stopped")?;
        let now = tokio::task::spawn_blocking(move || rx.recv())
            .await?
            .context("the simulation thread has stopped")??;
        // A put or a query before the router has told this session about the keeper would go
        // nowhere: wait until both are matched.
        let waiting = Instant::now();
        let mut said = false;
        loop {
            let proposing = bus
                .proposals
                .matching_status()
                .await
                .map_err(zerr)?
                .matching();
            let asking = bus.state.matching_status().await.map_err(zerr)?.matching();
            if proposing && asking {
                break;
            }
            if self.stop.load(Ordering::Acquire) {
                return Ok(());
            }
            if !said && waiting.elapsed() > Duration::from_secs(3) {
                tracing::warn!(
                    "waiting for the scene's keeper at {} (is `workstation share-router` running there?)",
                    self.config.endpoint
                );
                said = true;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        // Join: the current state, or ours as the scene's first.
        if !self.catch_up(&bus, false).await? && !self.config.viewer {
            self.propose(&bus, now).await?;
        }
        self.stats.joined.store(true, Ordering::Release);
        tracing::info!(
            "joined shared scene `{}` as `{}` at version {}",
            self.config.scene,
            self.config.station,
            self.book.version()
        );
        let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / TELEMETRY_HZ));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        while !self.stop.load(Ordering::Acquire) {
            tokio::select! {
                s = edits.recv_async() => {
                    let s = s.map_err(zerr)?;
                    self.on_state(&s.payload().to_bytes(), false);
                }
                v = verdicts.recv_async() => {
                    let v = v.map_err(zerr)?;
                    if self.on_verdict(&v.payload().to_bytes()) {
                        // Refused as made from a state that is not the scene's: take the
                        // scene's, whatever its version (a restarted keeper numbers anew).
                        self.catch_up(&bus, true).await?;
                    }
                }
                k = status.recv_async() => {
                    let k = k.map_err(zerr)?;
                    let b = k.payload().to_bytes();
                    self.stats.bytes_in.fetch_add(b.len() as u64, Ordering::Relaxed);
                    match serde_json::from_slice::<KeeperStatus>(&b) {
                        Ok(k) if k.version > self.book.version() => {
                            tracing::info!("shared scene at version {}, this station at {}: catching up", k.version, self.book.version());
                            self.catch_up(&bus, false).await?;
                        }
                        Ok(_) => {}
                        Err(e) => tracing::warn!("a keeper status that is not one: {e}"),
                    }
                }
                t = others.recv_async() => {
                    let t = t.map_err(zerr)?;
                    let from = super::station_of(t.key_expr().as_str()).map(str::to_owned);
                    if let Some(from) = from.filter(|f| *f != self.config.station)
                        && let Ok(t) = serde_json::from_slice::<Telemetry>(&t.payload().to_bytes())
                    {
                        let mut o = self.stats.others.lock().expect("not poisoned");
                        if o.len() < 64 || o.contains_key(&from) {
                            o.insert(from, (t, Instant::now()));
                        }
                    }
                }
                p = outbox.recv() => {
                    let Some(p) = p else { break };
                    if !self.config.viewer {
                        self.propose(&bus, p).await?;
                    }
                }
                _ = tick.tick() => {
                    let json = serde_json::to_vec(&self.telemetry()).expect("telemetry serialises");
                    self.stats.bytes_out.fetch_add(json.len() as u64, Ordering::Relaxed);
                    self.stats.telemetry.fetch_add(1, Ordering::Relaxed);
                    telemetry.put(json).await.map_err(zerr)?;
                    self.resend(&bus).await?;
                }
            }
        }
        session.close().await.map_err(zerr)?;
        Ok(())
    }

    /// Ask for the scene's current state and take it: if newer, or with `any`, whatever its
    /// version. Whether the scene has one.
    async fn catch_up(&mut self, bus: &Bus, any: bool) -> anyhow::Result<bool> {
        let replies = bus
            .state
            .get()
            .await
            .map_err(|e| anyhow::anyhow!("asking the scene's state: {e}"))?;
        let mut found = false;
        while let Ok(r) = replies.recv_async().await {
            match r.result() {
                Ok(s) => {
                    found = true;
                    self.on_state(&s.payload().to_bytes(), any);
                }
                Err(e) => tracing::warn!("the scene's state: {:?}", e.payload().try_to_string()),
            }
        }
        Ok(found)
    }

    /// An ordered state arrived (an edit, or the answer to a catch-up: `current`).
    fn on_state(&mut self, bytes: &[u8], current: bool) {
        self.stats
            .bytes_in
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let s = match wire::decode(bytes) {
            Ok(s) if s.kind == Kind::Ordered && s.scene == self.config.scene => s,
            Ok(s) => {
                tracing::warn!(
                    "an edit of kind {:?} for scene `{}` ignored",
                    s.kind,
                    s.scene
                );
                return;
            }
            Err(e) => {
                tracing::warn!("a malformed edit ({}) ignored: {e}", e.name());
                return;
            }
        };
        let what = if current {
            self.book.take_current(&s.id, s.seq)
        } else {
            self.book.on_ordered(&s.id, s.seq)
        };
        match what {
            OnOrdered::Ignore => {}
            OnOrdered::Mine => {
                self.answered(&s.id, true);
                self.stats.version.store(s.seq, Ordering::Relaxed);
            }
            OnOrdered::Adopt => {
                // Whatever of ours is waiting was made from an older state: its refusal comes;
                // it is not sent again.
                for u in &mut self.unanswered {
                    u.2 = None;
                }
                self.stats.version.store(s.seq, Ordering::Relaxed);
                let arrived = unix_ns().saturating_sub(s.t_unix_ns) as f64 / 1e6;
                self.stats
                    .arrival_ms
                    .lock()
                    .expect("not poisoned")
                    .push(arrived);
                let points = SharedPoints {
                    version: s.seq,
                    object: s.object,
                    visible: s.visible,
                    positions: s.positions,
                    normals: s
                        .normals
                        .iter()
                        .map(|n| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64))
                        .collect(),
                    colors: s.colors,
                };
                let (tx, rx) = mpsc::channel();
                if self
                    .commands
                    .send(SimCommand::Adopt(Box::new(points), tx))
                    .is_err()
                {
                    return;
                }
                let (stats, committed, id) = (Arc::clone(&self.stats), s.t_unix_ns, s.id);
                // Taken after the local stroke in progress; a newer state may replace it first.
                tokio::task::spawn_blocking(move || match rx.recv() {
                    Ok(Ok(())) => {
                        let ms = unix_ns().saturating_sub(committed) as f64 / 1e6;
                        stats.adopted.fetch_add(1, Ordering::Relaxed);
                        stats.propagation_ms.lock().expect("not poisoned").push(ms);
                        tracing::debug!("took {id} ({ms:.1} ms after its commit)");
                    }
                    Ok(Err(e)) => tracing::error!("the shared state {id} was not taken: {e:#}"),
                    Err(_) => {
                        tracing::debug!("{id} was replaced by a newer state before it was taken")
                    }
                });
            }
        }
    }

    /// A verdict on one of this station's proposals. Whether it was refused as stale.
    fn on_verdict(&mut self, bytes: &[u8]) -> bool {
        self.stats
            .bytes_in
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let v = match serde_json::from_slice::<VerdictMessage>(bytes) {
            Ok(v) => v,
            Err(e) => {
                tracing::warn!("a verdict that is not one: {e}");
                return false;
            }
        };
        let id = match (v.station, v.counter) {
            (Some(station), Some(counter)) => Some(StateId { station, counter }),
            _ => None,
        };
        let first = id.as_ref().is_some_and(|id| self.answered(id, v.accepted));
        if v.accepted || !first {
            return false; // accepted, or an answer to a proposal sent again
        }
        tracing::warn!(
            "the keeper refused {} ({}): {}; the scene's state replaces it",
            v.id.as_deref().unwrap_or("a commit"),
            v.reason.as_deref().unwrap_or("?"),
            v.message.as_deref().unwrap_or("")
        );
        if let Some(id) = &id {
            self.book.on_refused(id);
        }
        v.reason.as_deref() == Some("stale")
    }

    /// Count the answer to proposal `id` (the keeper's verdict, or its ordered state seen
    /// first), once: whether this was the first.
    fn answered(&mut self, id: &StateId, accepted: bool) -> bool {
        let Some(at) = self.unanswered.iter().position(|u| u.0 == *id) else {
            return false;
        };
        self.unanswered.remove(at);
        let count = if accepted {
            &self.stats.accepted
        } else {
            &self.stats.refused
        };
        count.fetch_add(1, Ordering::Release);
        true
    }

    async fn propose(&mut self, bus: &Bus, p: SharedPoints) -> anyhow::Result<()> {
        let made_from = self.book.expected_version();
        let Some((id, parent)) = self.book.commit(p.version) else {
            self.stats.superseded.fetch_add(1, Ordering::Relaxed);
            tracing::info!(
                "a stroke made before another station's newer state was taken: undone by it"
            );
            return Ok(());
        };
        let state = SharedState {
            kind: Kind::Proposal,
            seq: made_from,
            t_unix_ns: unix_ns(),
            scene: self.config.scene.clone(),
            object: p.object,
            visible: p.visible,
            id,
            parent,
            positions: p.positions,
            normals: p.normals.iter().map(|n| n.as_vec3().to_array()).collect(),
            colors: p.colors,
        };
        let bytes = wire::encode(&state);
        self.stats.proposed.fetch_add(1, Ordering::Release);
        self.unanswered
            .push((state.id.clone(), bytes.clone(), Some(Instant::now())));
        self.send(bus, &bytes).await
    }

    async fn send(&self, bus: &Bus, bytes: &[u8]) -> anyhow::Result<()> {
        self.stats
            .bytes_out
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        bus.proposals.put(bytes.to_vec()).await.map_err(|e| {
            anyhow::anyhow!(
                "proposing on {}: {e}",
                bus.keys.propose(&self.config.station)
            )
        })
    }

    /// Send again the proposals whose answer is overdue (the keeper answers a repeat as it did).
    async fn resend(&mut self, bus: &Bus) -> anyhow::Result<()> {
        let now = Instant::now();
        for i in 0..self.unanswered.len() {
            if self.unanswered[i]
                .2
                .is_some_and(|t| now.duration_since(t) >= RESEND_AFTER)
            {
                tracing::info!("no answer to {} yet: sent again", self.unanswered[i].0);
                self.unanswered[i].2 = Some(now);
                let bytes = self.unanswered[i].1.clone();
                self.send(bus, &bytes).await?;
            }
        }
        Ok(())
    }

    fn telemetry(&self) -> Telemetry {
        let s = &self.shared;
        let h = &s.haptic;
        let cursor = [h.cursor[0].get(), h.cursor[1].get(), h.cursor[2].get()];
        Telemetry {
            station: self.config.station.clone(),
            t_ns: self.t0.elapsed().as_nanos() as u64,
            cursor: cursor.iter().all(|c| c.is_finite()).then_some(cursor),
            force: [h.force[0].get(), h.force[1].get(), h.force[2].get()],
            buttons: h.buttons.load(Ordering::Relaxed) as u16,
            tool: s
                .render
                .load()
                .as_ref()
                .and_then(|r| r.tool)
                .map(|t| t.name().to_owned()),
            force_loop_hz: s.force_loop.rate_hz(),
            sim_hz: s.sim_loop.rate_hz(),
            rtt_us: s.net.force_rtt_us.get().p50,
            version: self.book.version(),
        }
    }
}

/// The flags that join a shared scene (on `demo`, `run` and `view`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ShareArgs {
    /// Join the shared scene named by the scene file's stem through the router at ENDPOINT
    /// (`workstation share-router`, or a site's zenohd): tcp/HOST:PORT, or tls/HOST:PORT with
    /// --share-ca, --share-cert and --share-key. See docs/SHARING.md.
    #[arg(long, value_name = "ENDPOINT")]
    pub share: Option<String>,
    /// This station's name on the bus [default: the host name]; under TLS, its certificate's
    /// common name.
    #[arg(long, value_name = "NAME", requires = "share")]
    pub station: Option<String>,
    /// The router's certificate (PEM), pinned.
    #[arg(long, value_name = "FILE", requires_all = ["share", "share_cert", "share_key"])]
    pub share_ca: Option<std::path::PathBuf>,
    /// This station's certificate (`workstation share-identity NAME`).
    #[arg(long, value_name = "FILE", requires = "share_ca")]
    pub share_cert: Option<std::path::PathBuf>,
    /// This station's key.
    #[arg(long, value_name = "FILE", requires = "share_ca")]
    pub share_key: Option<std::path::PathBuf>,
}

impl ShareArgs {
    /// The station's configuration for scene file `scene` (`None` without --share).
    pub fn resolve(
        &self,
        scene: &std::path::Path,
        viewer: bool,
    ) -> anyhow::Result<Option<StationConfig>> {
        let Some(endpoint) = &self.share else {
            return Ok(None);
        };
        let scene_name = scene
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_owned();
        let station = match &self.station {
            Some(s) => s.clone(),
            None => std::fs::read_to_string("/etc/hostname")
                .map(|h| h.trim().to_owned())
                .ok()
                .filter(|h| wire::valid_name(h))
                .unwrap_or_else(|| "station".to_owned()),
        };
        let tls = self.share_ca.as_ref().map(|ca| StationTls {
            router_cert: ca.clone(),
            cert: self.share_cert.clone().expect("clap requires it"),
            key: self.share_key.clone().expect("clap requires it"),
        });
        Ok(Some(StationConfig {
            endpoint: endpoint.clone(),
            station,
            scene: scene_name,
            tls,
            viewer,
        }))
    }
}
