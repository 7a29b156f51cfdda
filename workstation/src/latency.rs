//! `workstation latency`: what the network does to the cursor → force loop, measured against a
//! bare UDP ping-pong of the same size and rate in the same run.
//!
//! The run: (1) the baseline ([`baseline`]): a ping-pong with a reflector (a thread on the
//! server's address for loopback, `--echo ADDR` for a `workstation udp-echo` elsewhere);
//! (2) a session with the server whose force thread does nothing but answer: every cursor (at
//! most `--rate` a second) is answered at once with a zero force command echoing it. Every
//! cursor acknowledges the newest command the server applied ([`protocol::ForceAck`]), so per
//! answered command the workstation knows, with `t0` its send time, `t1` its arrival, `t2` the
//! acknowledging cursor's send time and `t3` that cursor's arrival:
//! - the cursor → force round trip, exactly: `t1 −` the answered cursor's timestamp (both
//!   server clock; what the server's own `force_rtt_ns` measures), the headline `rtt_us`;
//! - the network round trip, exactly: `(t3 − t0) − (t2 − t1)`;
//! - the one-way delays each way from the clock offset those same four timestamps give
//!   ([`protocol::ClockEstimator`], least-RTT sample of the last 64), each within the
//!   estimate's bound (half that sample's round trip plus drift).
//!
//! Loss, reordering and duplicates: the cursor stream's from the workstation's
//! [`protocol::SequenceTracker`], the command stream's from the server's `Stats`. With
//! `--flood X` (in-process server only) a further phase sends forged packets at X × the rate
//! and compares the servo loop's lateness p99 with the clean phase of the same run.
//! Without `--server` the server runs in this process on a fake device over loopback.
//! Outputs go to `--out` ([`report`]).

pub mod baseline;
pub mod plots;
pub mod report;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use haptics_client::client::{Client, ClientConfig};
use haptics_client::{HotPath, TransportKind};
use hdrhistogram::Histogram;
use protocol::control::{ClockPing, Stats};
use protocol::{ClockEstimator, ClockSample, Control, ForceCommand, SequenceTracker};

use crate::live::net::NetConfig;
use report::{Flood, Report, Sample};

/// Largest `--rate`, Hz: the servo loop streams at 1 kHz; above 10 kHz nothing is measured.
pub const MAX_RATE_HZ: u32 = 10_000;
/// Longest `--duration`, s (a day; the documented soak is one hour).
pub const MAX_DURATION_S: f64 = 86_400.0;
/// Largest `--flood` multiplier.
pub const MAX_FLOOD: f64 = 200.0;
/// The baseline runs this long at most (it only has to give stable percentiles).
pub const BASELINE_MAX_S: f64 = 10.0;

/// Arguments of `workstation latency`.
#[derive(Debug, Clone, clap::Args)]
pub struct LatencyArgs {
    /// Where and how to connect [default: a server in this process, fake device, loopback].
    #[command(flatten)]
    pub connect: crate::live::net::ConnectArgs,
    /// Force commands per second at most (the server streams cursors at its servo rate; one
    /// in every rate/servo-rate is answered), and the baseline's ping rate.
    #[arg(long, default_value_t = 1000)]
    pub rate: u32,
    /// Seconds of measured session (the baseline runs min(this, 10 s) before it).
    #[arg(long, default_value_t = 10.0)]
    pub duration: f64,
    /// Bytes per baseline datagram [default: 118, our largest packet, a sealed ForceCommand].
    #[arg(long, value_name = "B")]
    pub payload: Option<usize>,
    /// A `workstation udp-echo` on the server's machine for the baseline [default: a reflector
    /// thread here, on the server's IP when it is local, else loopback].
    #[arg(long, value_name = "ADDR")]
    pub echo: Option<SocketAddr>,
    /// Then flood the server with forged packets at this many times --rate for another
    /// --duration, and compare its loop lateness (in-process server only; 0 = no flood).
    #[arg(long, default_value_t = 0.0)]
    pub flood: f64,
    /// Where report.json, samples.csv, rtt.hgrm, the PNG plots and summary.md go.
    #[arg(long, default_value = "out/latency")]
    pub out: PathBuf,
    /// Print the report as JSON instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `workstation udp-echo`.
#[derive(Debug, Clone, clap::Args)]
pub struct UdpEchoArgs {
    /// Address to answer on.
    #[arg(long, default_value = "0.0.0.0:7701")]
    pub listen: SocketAddr,
}

/// `workstation udp-echo`: reflect datagrams until Ctrl-C (the baseline peer on a server PC).
pub fn udp_echo(args: &UdpEchoArgs) -> anyhow::Result<()> {
    let socket = std::net::UdpSocket::bind(args.listen)
        .with_context(|| format!("binding {}", args.listen))?;
    println!(
        "udp-echo: reflecting datagrams on {} (Ctrl-C to stop)",
        socket.local_addr()?
    );
    baseline::reflect(&socket, &std::sync::atomic::AtomicBool::new(false));
    Ok(())
}

fn check_args(args: &LatencyArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=MAX_RATE_HZ).contains(&args.rate),
        "--rate must be 1..={MAX_RATE_HZ} Hz (MAX_RATE_HZ), got {}",
        args.rate
    );
    anyhow::ensure!(
        args.duration.is_finite() && args.duration > 0.0 && args.duration <= MAX_DURATION_S,
        "--duration must be in (0, {MAX_DURATION_S}] s (MAX_DURATION_S), got {}",
        args.duration
    );
    if let Some(p) = args.payload {
        anyhow::ensure!(
            (baseline::MIN_PAYLOAD_BYTES..=baseline::MAX_PAYLOAD_BYTES).contains(&p),
            "--payload must be {}..={} bytes (one datagram within an Ethernet MTU), got {p}",
            baseline::MIN_PAYLOAD_BYTES,
            baseline::MAX_PAYLOAD_BYTES
        );
    }
    anyhow::ensure!(
        args.flood.is_finite() && (0.0..=MAX_FLOOD).contains(&args.flood),
        "--flood must be 0..={MAX_FLOOD} (MAX_FLOOD), got {}",
        args.flood
    );
    Ok(())
}

/// Run the measurement and write the outputs; returns the report.
pub fn run(args: &LatencyArgs) -> anyhow::Result<Report> {
    check_args(args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let remote = args.connect.resolve()?;
    anyhow::ensure!(
        args.flood == 0.0 || remote.is_none(),
        "--flood needs the in-process server (no --server or --config): it reads the servo loop's lateness directly"
    );
    let (server, cfg) = match remote {
        Some(cfg) => (None, cfg),
        None => {
            let (server, cfg) =
                in_process_server(args.connect.transport.unwrap_or(TransportKind::Udp))?;
            (Some(server), cfg)
        }
    };
    let payload = args.payload.unwrap_or(protocol::packet::MAX_PACKET_BYTES);
    let total_s =
        args.duration.min(BASELINE_MAX_S) + args.duration * (1.0 + f64::from(args.flood > 0.0));
    let bar = progress(total_s);
    // 1. The bare ping-pong.
    let baseline_s = args.duration.min(BASELINE_MAX_S);
    let (echo_addr, reflector) = match args.echo {
        Some(a) => (a, None),
        None => {
            let ip = if cfg.server.ip().is_loopback() {
                cfg.server.ip()
            } else {
                std::net::Ipv4Addr::LOCALHOST.into()
            };
            let r = baseline::Reflector::start(SocketAddr::new(ip, 0))?;
            (r.addr(), Some(r))
        }
    };
    bar.set_message("baseline: bare UDP ping-pong");
    let base = baseline::ping_pong(
        echo_addr,
        payload,
        args.rate,
        Duration::from_secs_f64(baseline_s),
        |f| bar.set_position((f * baseline_s * 10.0) as u64),
    )
    .with_context(|| format!("baseline ping-pong with {echo_addr}"))?;
    drop(reflector);
    // 2. The session.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let done_before = (baseline_s * 10.0) as u64;
    let rss_start = rss_kib();
    if let Some(s) = &server {
        s.mark_telemetry();
    }
    bar.set_message(format!("session over {:?}", cfg.transport));
    // The session is answered as the workstation answers it: on a thread at the force
    // thread's priority (SCHED_FIFO where allowed; the live workstation's force thread, or its
    // network thread on QUIC, runs so).
    let main = std::thread::scope(|scope| {
        scope
            .spawn(|| {
                let priority = crate::live::force::raise_priority();
                tracing::debug!(priority, "latency session thread");
                runtime.block_on(measure(&cfg, args, None, |f| {
                    bar.set_position(done_before + (f * args.duration * 10.0) as u64);
                }))
            })
            .join()
            .unwrap_or_else(|_| Err(anyhow::anyhow!("the session thread panicked")))
    })?;
    let lateness_clean = server
        .as_ref()
        .map(|s| s.servo_stats().lateness_since_mark_ns);
    // 3. The flood, if asked.
    let flood = match (&server, args.flood > 0.0) {
        (Some(s), true) => {
            s.mark_telemetry();
            bar.set_message(format!("flood: forged packets at {}x", args.flood));
            let done_before = done_before + (args.duration * 10.0) as u64;
            let rate = args.flood * f64::from(args.rate);
            let flooded = runtime.block_on(measure(&cfg, args, Some(rate), |f| {
                bar.set_position(done_before + (f * args.duration * 10.0) as u64);
            }))?;
            let with = s.servo_stats().lateness_since_mark_ns;
            let without = lateness_clean.unwrap_or_default();
            Some(Flood::new(
                args.flood,
                &flooded,
                without,
                with,
                &main,
                s.servo_stats().ticks,
            ))
        }
        _ => None,
    };
    bar.finish_and_clear();
    let report = Report::build(
        args,
        &cfg,
        server.is_some(),
        payload,
        &base,
        &main,
        lateness_clean,
        flood,
        rss_start,
    );
    report::write(&args.out, &report, &main, &base)?;
    Ok(report)
}

fn progress(total_s: f64) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new((total_s * 10.0).ceil() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

/// A server in this process on a still fake stylus, loopback, real-time servo when allowed.
#[cfg(feature = "demo-server")]
fn in_process_server(
    transport: TransportKind,
) -> anyhow::Result<(haptics_server::server::Server, NetConfig)> {
    use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
    use haptics_server::server::{Server, ServerOptions};
    let device = FakeDevice::new(FakeParams {
        path: HandPath::Idle {
            at: glam::Vec3::ZERO,
        },
        ..FakeParams::default()
    });
    let mut opts = ServerOptions::for_tests(transport)?;
    opts.driver.rt.fifo_priority = Some(crate::live::force::SERVO_FIFO_PRIORITY);
    // A latency run pauses between phases: keep the session through them.
    opts.net.idle_timeout = Duration::from_secs(5);
    let server = Server::start(device, opts)?;
    let cfg = NetConfig::to_in_process(&server, transport);
    Ok((server, cfg))
}

/// Built without the `demo-server` feature there is no in-process server: this type has no
/// values, so the code that would use one cannot run.
#[cfg(not(feature = "demo-server"))]
enum NoServer {}

#[cfg(not(feature = "demo-server"))]
impl NoServer {
    fn mark_telemetry(&self) {
        match *self {}
    }

    fn servo_stats(&self) -> NoStats {
        match *self {}
    }
}

#[cfg(not(feature = "demo-server"))]
struct NoStats {
    lateness_since_mark_ns: protocol::control::Percentiles,
    ticks: u64,
}

#[cfg(not(feature = "demo-server"))]
fn in_process_server(_transport: TransportKind) -> anyhow::Result<(NoServer, NetConfig)> {
    anyhow::bail!(
        "this workstation was built without the in-process server (feature `demo-server`): give --server and --cert"
    )
}

/// One answered command awaiting its acknowledgement.
#[derive(Debug, Clone, Copy, Default)]
struct Pending {
    sequence: u32,
    /// Its send time (header timestamp), workstation clock.
    sent_ns: u64,
    /// The answered cursor's timestamp, server clock.
    answers_ns: u64,
    /// When that cursor arrived, workstation clock.
    cursor_arrived_ns: u64,
    /// The answered cursor's servo tick.
    answers_tick: u32,
    live: bool,
}

/// Commands in flight are looked up by sequence modulo this (1 s at 1 kHz).
const PENDING: usize = 1024;

/// At most this many samples are kept for the CSV and the plots (every `stride`-th; the
/// stride doubles when the buffer fills), so an hour-long soak runs in constant memory; the
/// percentiles come from HDR histograms of every sample.
pub const MAX_KEPT_SAMPLES: usize = 100_000;

/// HDR histograms (1 µs … 60 s, 3 significant digits) of every acknowledged command, ns.
#[derive(Debug)]
pub struct Histograms {
    /// Cursor → force round trip.
    pub rtt: Histogram<u64>,
    /// Network round trip.
    pub network: Histogram<u64>,
    /// Workstation turnaround.
    pub turnaround: Histogram<u64>,
    /// Server → workstation one way (clamped at 1 ns: the estimate can dip below zero).
    pub down: Histogram<u64>,
    /// Workstation → server one way (clamped likewise).
    pub up: Histogram<u64>,
}

impl Histograms {
    fn new() -> anyhow::Result<Self> {
        let h = || Histogram::new_with_bounds(1, 60_000_000_000, 3).context("histogram bounds");
        Ok(Self {
            rtt: h()?,
            network: h()?,
            turnaround: h()?,
            down: h()?,
            up: h()?,
        })
    }

    fn record(&mut self, s: &Sample) {
        let c = |v: u64| v.clamp(1, 60_000_000_000);
        let _ = self.rtt.record(c(s.rtt_ns));
        let _ = self.network.record(c(s.network_rtt_ns));
        let _ = self.turnaround.record(c(s.workstation_ns));
        let _ = self.down.record(c(s.down_ns.max(0) as u64));
        let _ = self.up.record(c(s.up_ns.max(0) as u64));
    }
}

/// What one session phase measured.
#[derive(Debug)]
pub struct Measured {
    /// Every `stride`-th acknowledged command, in order (at most [`MAX_KEPT_SAMPLES`]).
    pub samples: Vec<Sample>,
    /// The keeping stride.
    pub stride: u64,
    /// Acknowledged commands measured.
    pub acknowledged: u64,
    /// Histograms of all of them.
    pub hist: Histograms,
    /// Sum of |difference of consecutive round trips|, ns (jitter = this / (acknowledged − 1)).
    pub jitter_sum_ns: f64,
    /// The largest one-way bound seen, ns.
    pub bound_max_ns: u64,
    /// Resident memory one second in and at the end of the phase, KiB.
    pub rss_kib: (u64, u64),
    /// Cursor stream (server → workstation) sequence statistics.
    pub cursors: protocol::SequenceStats,
    /// The server's last `Stats` (command stream sequence statistics, its own RTT view).
    pub server: Stats,
    /// Commands sent.
    pub commands_sent: u64,
    /// Forged packets sent (flood phase).
    pub forged_sent: u64,
    /// The clock estimate at the end.
    pub clock: Option<protocol::ClockEstimate>,
    /// Sessions opened (1 unless the session was lost and reopened).
    pub sessions: u64,
    /// Seconds measured.
    pub seconds: f64,
    /// Every cursor received, by the age of the command its tick applied.
    pub applied: protocol::AppliedAge,
}

/// One session phase: connect, answer cursors for `--duration`, collect the server's `Stats`.
async fn measure(
    cfg: &NetConfig,
    args: &LatencyArgs,
    flood_rate: Option<f64>,
    mut tick: impl FnMut(f64),
) -> anyhow::Result<Measured> {
    let mut ccfg = ClientConfig::new(cfg.server, cfg.transport, cfg.cert.clone());
    ccfg.identity = cfg.identity.clone();
    ccfg.client_name = "workstation latency".into();
    ccfg.requested_rate_hz = args.rate;
    let client = connect_retrying(&ccfg).await?;
    let Client {
        mut control,
        mut hot,
        welcome,
    } = client;
    let first = tokio::time::timeout(Duration::from_secs(5), hot.recv_cursor())
        .await
        .context("no cursor from the server within 5 s")??;
    let flood = match flood_rate {
        Some(rate) => Some(Flooder::start(cfg.server, welcome.session_id, rate)?),
        None => None,
    };
    let clock = hot.clock();
    let duration = Duration::from_secs_f64(args.duration);
    let min_gap_ns = 1_000_000_000 / u64::from(args.rate);
    let keep = ((args.duration * f64::from(args.rate)) as usize + 16).min(MAX_KEPT_SAMPLES);
    let mut samples = Vec::with_capacity(keep);
    // Touch the buffer now, so the memory figures see its pages from the start.
    samples.resize(keep, Sample::default());
    samples.clear();
    let mut m = Measured {
        samples,
        stride: 1,
        acknowledged: 0,
        hist: Histograms::new()?,
        jitter_sum_ns: 0.0,
        bound_max_ns: 0,
        rss_kib: (0, 0),
        cursors: Default::default(),
        server: Stats::default(),
        commands_sent: 0,
        forged_sent: 0,
        clock: None,
        sessions: 1,
        seconds: args.duration,
        applied: protocol::AppliedAge::default(),
    };
    let mut phase = PhaseState {
        pending: vec![Pending::default(); PENDING],
        tracker: SequenceTracker::new(),
        estimator: ClockEstimator::new(200.0),
        next_answer_ns: 0,
        min_gap_ns,
        last_rtt: None,
        t_start_ns: clock.now_ns(),
        last_tick: 0,
    };
    phase.tracker.record(first.0.sequence);
    let start = Instant::now();
    let mut last_tick = start;
    let deadline = start + duration;
    let blocking = cfg.transport == TransportKind::Udp;
    let mut ping = tokio::time::interval(Duration::from_millis(100));
    while Instant::now() < deadline {
        if blocking {
            // UDP: this thread waits on the socket itself (no reactor hop); the control
            // channel is read after the phase (the hot path keeps the session alive).
            let wait = deadline
                .saturating_duration_since(Instant::now())
                .min(Duration::from_millis(100));
            if let Some((packet, cursor)) = hot.recv_cursor_blocking(wait)? {
                phase.on_cursor(&mut hot, &mut m, &packet, &cursor, clock.now_ns())?;
            }
        } else {
            tokio::select! {
                r = hot.recv_cursor() => {
                    let (packet, cursor) = r?;
                    phase.on_cursor(&mut hot, &mut m, &packet, &cursor, clock.now_ns())?;
                }
                msg = control.recv() => match msg? {
                    Control::Stats(s) => m.server = s,
                    Control::Bye(b) => anyhow::bail!("the server ended the session: {}", b.reason),
                    Control::Error(e) => anyhow::bail!("the server refused: {:?}: {}", e.code, e.message),
                    _ => {}
                },
                _ = ping.tick() => {
                    // Keeps the control channel's idle timer fed.
                    control.send(&Control::ClockPing(ClockPing { id: 0, t0_ns: clock.now_ns() })).await?;
                }
                _ = tokio::time::sleep_until(deadline.into()) => break,
            }
        }
        if last_tick.elapsed() >= Duration::from_millis(100) {
            last_tick = Instant::now();
            tick(start.elapsed().as_secs_f64() / duration.as_secs_f64());
            if m.rss_kib.0 == 0 && start.elapsed() >= Duration::from_secs(1) {
                m.rss_kib.0 = rss_kib();
            }
        }
    }
    m.rss_kib.1 = rss_kib();
    if m.rss_kib.0 == 0 {
        m.rss_kib.0 = m.rss_kib.1;
    }
    if let Some(f) = flood {
        m.forged_sent = f.stop();
    }
    m.cursors = phase.tracker.stats();
    m.clock = phase.estimator.estimate();
    // The server's counters for the whole phase: keep answering (so the session stays up)
    // until a Stats that counts the phase's last tick arrives (they come every second).
    let wait = tokio::time::Instant::now() + Duration::from_millis(2_500);
    while m.server.ticks <= phase.last_tick {
        tokio::select! {
            r = hot.recv_cursor() => {
                let (packet, cursor) = r?;
                answer(&mut hot, &mut phase.pending, packet.sequence, (packet.timestamp_ns, cursor.servo_tick), clock.now_ns())?;
            }
            msg = control.recv() => match msg? {
                Control::Stats(s) => m.server = s,
                Control::Bye(b) => anyhow::bail!("the server ended the session: {}", b.reason),
                _ => {}
            },
            _ = tokio::time::sleep_until(wait) => break,
        }
    }
    let _ = control.close("latency run done").await;
    Ok(m)
}

/// The bookkeeping of one phase's cursor handling.
struct PhaseState {
    pending: Vec<Pending>,
    tracker: SequenceTracker,
    estimator: ClockEstimator,
    next_answer_ns: u64,
    min_gap_ns: u64,
    last_rtt: Option<u64>,
    t_start_ns: u64,
    /// The servo tick of the newest cursor.
    last_tick: u64,
}

impl PhaseState {
    /// A cursor arrived at `t3`: time the command it acknowledges, answer it when due.
    fn on_cursor(
        &mut self,
        hot: &mut HotPath,
        m: &mut Measured,
        packet: &protocol::Packet,
        cursor: &protocol::CursorSample,
        t3: u64,
    ) -> anyhow::Result<()> {
        self.tracker.record(packet.sequence);
        self.last_tick = u64::from(cursor.servo_tick);
        let answers_tick = cursor.ack.and_then(|ack| {
            let p = &self.pending[ack.sequence as usize % PENDING];
            (p.sequence == ack.sequence && p.sent_ns > 0).then_some(p.answers_tick)
        });
        m.applied.record(cursor.servo_tick, answers_tick);
        if let Some(ack) = cursor.ack {
            let p = &mut self.pending[ack.sequence as usize % PENDING];
            if p.live && p.sequence == ack.sequence {
                p.live = false;
                let sample = ClockSample {
                    t0_ns: p.sent_ns,
                    t1_ns: ack.arrival_ns,
                    t2_ns: packet.timestamp_ns,
                    t3_ns: t3,
                };
                let _ = self.estimator.add(sample);
                if let Some(est) = self.estimator.estimate() {
                    let t = t3.saturating_sub(self.t_start_ns);
                    let s = Sample::new(t, p.cursor_arrived_ns, p.answers_ns, &sample, &est);
                    m.keep(s, &mut self.last_rtt);
                }
            }
        }
        // Answer on schedule, with half a gap of slack for the cursors' own jitter (at
        // --rate = the servo rate, every cursor is answered).
        if t3 + self.min_gap_ns / 2 >= self.next_answer_ns {
            self.next_answer_ns =
                (self.next_answer_ns + self.min_gap_ns).max(t3.saturating_sub(self.min_gap_ns / 2));
            answer(
                hot,
                &mut self.pending,
                packet.sequence,
                (packet.timestamp_ns, cursor.servo_tick),
                t3,
            )?;
            m.commands_sent += 1;
        }
        Ok(())
    }
}

impl Measured {
    /// Account one sample; keep every `stride`-th.
    fn keep(&mut self, s: Sample, last_rtt: &mut Option<u64>) {
        self.hist.record(&s);
        if let Some(prev) = last_rtt.replace(s.rtt_ns) {
            self.jitter_sum_ns += (s.rtt_ns as f64 - prev as f64).abs();
        }
        self.bound_max_ns = self.bound_max_ns.max(s.bound_ns);
        if self.acknowledged.is_multiple_of(self.stride) {
            if self.samples.len() == self.samples.capacity() {
                let mut i = 0;
                self.samples.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if self.acknowledged.is_multiple_of(self.stride) {
                self.samples.push(s);
            }
        }
        self.acknowledged += 1;
    }
}

async fn connect_retrying(cfg: &ClientConfig) -> anyhow::Result<Client> {
    // The previous phase's session may still be closing on the server: retry `Busy` briefly.
    let give_up = Instant::now() + Duration::from_secs(5);
    loop {
        match Client::connect(cfg).await {
            Ok(c) => return Ok(c),
            Err(haptics_client::ClientError::Refused {
                code: protocol::control::ErrorCode::Busy,
                ..
            }) if Instant::now() < give_up => {
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            Err(e) => {
                return Err(anyhow::Error::new(e).context(format!("connecting to {}", cfg.server)));
            }
        }
    }
}

/// Send the zero command answering cursor (`sequence`, `timestamp_ns`) and remember it.
fn answer(
    hot: &mut HotPath,
    pending: &mut [Pending],
    sequence: u32,
    (timestamp_ns, answers_tick): (u64, u32),
    arrived_ns: u64,
) -> anyhow::Result<()> {
    let cmd = ForceCommand {
        answers_sequence: sequence,
        answers_timestamp_ns: timestamp_ns,
        ..haptics_client::client::zero_command()
    };
    hot.send_force(&cmd)?;
    if let Some((seq, sent_ns)) = hot.last_sent() {
        pending[seq as usize % PENDING] = Pending {
            sequence: seq,
            sent_ns,
            answers_ns: timestamp_ns,
            cursor_arrived_ns: arrived_ns,
            answers_tick,
            live: true,
        };
    }
    Ok(())
}

/// A thread sending forged hot-path packets (right session id, wrong MAC: what an attacker
/// who sniffed the header can do) to the server at a fixed rate.
struct Flooder {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: std::thread::JoinHandle<u64>,
}

impl Flooder {
    fn start(server: SocketAddr, session: u32, rate: f64) -> std::io::Result<Self> {
        use std::sync::atomic::{AtomicBool, Ordering};
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let socket = std::net::UdpSocket::bind(SocketAddr::new(server.ip(), 0))?;
        socket.connect(server)?;
        let thread = {
            let stop = std::sync::Arc::clone(&stop);
            std::thread::Builder::new()
                .name("flood".into())
                .spawn(move || {
                    let mut packet = [0u8; protocol::packet::MAX_PACKET_BYTES];
                    let body = protocol::Body::Force(haptics_client::client::zero_command());
                    let mut out = protocol::Outbound::new(
                        session,
                        Some(protocol::SessionKey::from_bytes([0x5a; 32])),
                    );
                    let start = Instant::now();
                    let mut sent = 0u64;
                    while !stop.load(Ordering::Acquire) {
                        // Pace in 1 ms bursts: as many as the rate owes by now.
                        let owed = (start.elapsed().as_secs_f64() * rate) as u64;
                        while sent < owed {
                            let n = out.encode(sent, body, &mut packet);
                            let _ = socket.send(&packet[..n]);
                            sent += 1;
                        }
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    sent
                })?
        };
        Ok(Self { stop, thread })
    }

    fn stop(self) -> u64 {
        self.stop.store(true, std::sync::atomic::Ordering::Release);
        self.thread.join().unwrap_or(0)
    }
}

/// This process's resident set size, KiB (Linux; 0 elsewhere).
pub fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4)
}
