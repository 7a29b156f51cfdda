//! The latency report: its JSON shape (`rtt_us`, `one_way_us`, `loss`, `reordered`,
//! `baseline_udp_rtt_us` at the top), the CSV of samples, the HDR percentile file, the plots
//! and the Markdown summary.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use protocol::{ClockEstimate, ClockSample};
use serde::Serialize;

use super::baseline::PingPong;
use super::{LatencyArgs, Measured};
use crate::live::net::NetConfig;

/// The goal over loopback: our p50 within this multiple of the bare ping-pong's, UDP.
pub const GOAL_RATIO_UDP: f64 = 1.5;
/// The same for QUIC.
pub const GOAL_RATIO_QUIC: f64 = 3.0;
/// The flood goal: loop lateness p99 under the flood at most this multiple of without.
pub const GOAL_FLOOD_LATENESS_RATIO: f64 = 1.2;

/// One acknowledged command's timings, ns.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sample {
    /// When the acknowledging cursor arrived, since the phase began.
    pub t_ns: u64,
    /// Cursor → force round trip: the command's arrival − the answered cursor's timestamp
    /// (server clock both; exact).
    pub rtt_ns: u64,
    /// Network round trip `(t3 − t0) − (t2 − t1)` (exact).
    pub network_rtt_ns: u64,
    /// The workstation's turnaround: the command's send − the answered cursor's arrival.
    pub workstation_ns: u64,
    /// Server → workstation one-way delay from the clock estimate.
    pub down_ns: i64,
    /// Workstation → server one-way delay from the clock estimate.
    pub up_ns: i64,
    /// Both one-way delays are within ± this of the truth.
    pub bound_ns: u64,
}

impl Sample {
    /// From an acknowledged command: the phase-relative arrival `t_ns`, the answered cursor's
    /// arrival (client clock) and timestamp (server clock), the exchange's four timestamps
    /// and the clock estimate (`offset = server − client`).
    pub fn new(
        t_ns: u64,
        cursor_arrived_ns: u64,
        answers_ns: u64,
        s: &ClockSample,
        est: &ClockEstimate,
    ) -> Self {
        let offset = est.offset_ns;
        let down = s.t3_ns as i64 - s.t2_ns as i64 + offset;
        let up = s.t1_ns as i64 - offset - s.t0_ns as i64;
        Self {
            t_ns,
            rtt_ns: s.t1_ns.saturating_sub(answers_ns),
            network_rtt_ns: s.rtt_ns().unwrap_or(0),
            workstation_ns: s.t0_ns.saturating_sub(cursor_arrived_ns),
            down_ns: down,
            up_ns: up,
            bound_ns: est.uncertainty_ns,
        }
    }
}

/// Percentiles of a distribution, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th.
    pub p99: f64,
    /// 99.9th.
    pub p999: f64,
    /// Largest.
    pub max: f64,
    /// Smallest.
    pub min: f64,
    /// Mean.
    pub mean: f64,
}

impl Percentiles {
    /// Percentiles of an HDR histogram of ns values (3 significant digits), in µs.
    pub fn of_hist(h: &hdrhistogram::Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self::default();
        }
        let q = |q: f64| h.value_at_quantile(q) as f64 / 1e3;
        Self {
            p50: q(0.5),
            p90: q(0.9),
            p99: q(0.99),
            p999: q(0.999),
            max: h.max() as f64 / 1e3,
            min: h.min() as f64 / 1e3,
            mean: h.mean() / 1e3,
        }
    }

    /// Exact percentiles (nearest rank) of `ns` values, in µs; zeros when empty.
    pub fn of_ns(values: impl IntoIterator<Item = i64>) -> Self {
        let mut v: Vec<i64> = values.into_iter().collect();
        if v.is_empty() {
            return Self::default();
        }
        v.sort_unstable();
        let at = |q: f64| {
            let i = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
            v[i] as f64 / 1e3
        };
        Self {
            p50: at(0.5),
            p90: at(0.9),
            p99: at(0.99),
            p999: at(0.999),
            max: v[v.len() - 1] as f64 / 1e3,
            min: v[0] as f64 / 1e3,
            mean: v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64 / 1e3,
        }
    }
}

/// One direction's one-way delay, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Direction {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
    /// Each value is within ± this of the truth (the clock estimate's bound, its largest over
    /// the run).
    pub bound: f64,
}

/// One-way delays each way.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct OneWay {
    /// Cursor samples.
    pub server_to_workstation: Direction,
    /// Force commands.
    pub workstation_to_server: Direction,
    /// The final clock offset (server − workstation), µs.
    pub clock_offset_us: f64,
}

/// A count per direction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PerDirection<T> {
    /// Cursor samples.
    pub server_to_workstation: T,
    /// Force commands.
    pub workstation_to_server: T,
}

/// Packet loss.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Loss {
    /// Lost fraction of the cursor stream.
    pub server_to_workstation: f64,
    /// Lost fraction of the command stream (the server's count).
    pub workstation_to_server: f64,
    /// Cursor samples lost.
    pub cursors_lost: u64,
    /// Force commands lost.
    pub commands_lost: u64,
}

/// The flood phase against the clean phase of the same run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Flood {
    /// Forged packets per command the workstation sends.
    pub multiplier: f64,
    /// Forged packets sent.
    pub forged_sent: u64,
    /// Forged packets per second.
    pub forged_rate_hz: f64,
    /// Packets the server rejected during the flood (UDP: bad MAC; QUIC drops them inside
    /// quinn, uncounted).
    pub rejected_by_server: u64,
    /// Servo loop start lateness p99 in the clean phase, µs.
    pub lateness_p99_us_without: f64,
    /// The same under the flood, µs.
    pub lateness_p99_us_with: f64,
    /// With / without.
    pub lateness_ratio: f64,
    /// Cursor → force round trip p50 in the clean phase, µs.
    pub rtt_p50_us_without: f64,
    /// The same under the flood, µs.
    pub rtt_p50_us_with: f64,
    /// `lateness_ratio ≤` [`GOAL_FLOOD_LATENESS_RATIO`].
    pub goal_met: bool,
    /// Servo ticks at the end (both phases).
    pub server_ticks: u64,
}

impl Flood {
    /// From the two phases and the server's lateness in each.
    pub fn new(
        multiplier: f64,
        flooded: &Measured,
        without: protocol::control::Percentiles,
        with: protocol::control::Percentiles,
        clean: &Measured,
        server_ticks: u64,
    ) -> Self {
        let (w, f) = (without.p99 as f64 / 1e3, with.p99 as f64 / 1e3);
        let ratio = if w > 0.0 { f / w } else { f64::INFINITY };
        Self {
            multiplier,
            forged_sent: flooded.forged_sent,
            forged_rate_hz: flooded.forged_sent as f64 / flooded.seconds,
            rejected_by_server: flooded.server.rejected.total(),
            lateness_p99_us_without: w,
            lateness_p99_us_with: f,
            lateness_ratio: ratio,
            rtt_p50_us_without: Percentiles::of_hist(&clean.hist.rtt).p50,
            rtt_p50_us_with: Percentiles::of_hist(&flooded.hist.rtt).p50,
            goal_met: ratio <= GOAL_FLOOD_LATENESS_RATIO,
            server_ticks,
        }
    }
}

/// The goal and whether it was met.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Goal {
    /// Our p50 over the ping-pong's p50 must be at most this (over loopback).
    pub ratio_limit: f64,
    /// Whether it was.
    pub met: bool,
}

/// Resident memory of this process, KiB (flat = the run leaks nothing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Memory {
    /// Before the run.
    pub start_kib: u64,
    /// One second into the measured session (buffers allocated, connection up).
    pub warm_kib: u64,
    /// At the end of the measured session.
    pub end_kib: u64,
    /// `end_kib − warm_kib`.
    pub growth_kib: i64,
}

/// `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// `udp` or `quic`.
    pub transport: String,
    /// The server: its address, or the in-process one.
    pub server: String,
    /// Commands per second at most (and the ping rate).
    pub rate_hz: u32,
    /// Seconds of session measured.
    pub duration_s: f64,
    /// Bytes per baseline datagram.
    pub payload_bytes: usize,
    /// Acknowledged commands measured.
    pub samples: u64,
    /// Of which every `sample_stride`-th is in samples.csv and the plots.
    pub sample_stride: u64,
    /// Cursor → force round trip (the server's clock both ends), µs.
    pub rtt_us: Percentiles,
    /// Network round trip (without either side's turnaround), µs.
    pub network_rtt_us: Percentiles,
    /// The workstation's turnaround (cursor in → command out), µs.
    pub workstation_turnaround_us: Percentiles,
    /// RFC 3550-style jitter: mean |difference of consecutive round trips|, µs.
    pub jitter_us: f64,
    /// One-way delays with their bound.
    pub one_way_us: OneWay,
    /// Loss each way.
    pub loss: Loss,
    /// Reordered packets each way.
    pub reordered: PerDirection<u64>,
    /// Duplicated packets each way.
    pub duplicates: PerDirection<u64>,
    /// The age of the command each servo tick applied, in ticks after the cursor it answers
    /// (every cursor received; the goal on loopback: ≥ 99.9 % `next_tick` at --rate 1000).
    pub applied_age_ticks: protocol::AppliedAgeFractions,
    /// The bare UDP ping-pong of the same size and rate, same run, µs.
    pub baseline_udp_rtt_us: Percentiles,
    /// Its pings answered.
    pub baseline_samples: usize,
    /// Its lost fraction.
    pub baseline_loss: f64,
    /// Where it was reflected.
    pub baseline_peer: String,
    /// `rtt_us.p50 / baseline_udp_rtt_us.p50`.
    pub ratio_p50: f64,
    /// `rtt_us.p99 / baseline_udp_rtt_us.p99`.
    pub ratio_p99: f64,
    /// The loopback goal for this transport.
    pub goal: Goal,
    /// The server's own view of the cursor → force round trip (its `Stats`), µs.
    pub server_force_rtt_us: Percentiles,
    /// Servo loop start lateness during the session (in-process server only), µs.
    pub server_lateness_us: Option<Percentiles>,
    /// Sessions opened during the measured phase (1 = none lost).
    pub sessions: u64,
    /// This process's resident memory around the session.
    pub memory: Memory,
    /// The flood phase, when asked.
    pub flood: Option<Flood>,
}

fn from_protocol(p: protocol::control::Percentiles) -> Percentiles {
    Percentiles {
        p50: p.p50 as f64 / 1e3,
        p90: f64::NAN,
        p99: p.p99 as f64 / 1e3,
        p999: p.p999 as f64 / 1e3,
        max: p.max as f64 / 1e3,
        min: f64::NAN,
        mean: f64::NAN,
    }
}

fn direction(h: &hdrhistogram::Histogram<u64>, bound_ns: u64) -> Direction {
    let p = Percentiles::of_hist(h);
    Direction {
        p50: p.p50,
        p99: p.p99,
        max: p.max,
        bound: bound_ns as f64 / 1e3,
    }
}

fn fraction(lost: u64, received: u64) -> f64 {
    if lost + received == 0 {
        0.0
    } else {
        lost as f64 / (lost + received) as f64
    }
}

impl Report {
    /// Assemble the report of a run.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        args: &LatencyArgs,
        cfg: &NetConfig,
        in_process: bool,
        payload: usize,
        base: &PingPong,
        m: &Measured,
        lateness: Option<protocol::control::Percentiles>,
        flood: Option<Flood>,
        rss_start: u64,
    ) -> Self {
        let rtt = Percentiles::of_hist(&m.hist.rtt);
        let baseline = Percentiles::of_ns(base.rtt_ns.iter().map(|&r| r as i64));
        let bound = m.bound_max_ns;
        let jitter = if m.acknowledged > 1 {
            m.jitter_sum_ns / (m.acknowledged - 1) as f64 / 1e3
        } else {
            0.0
        };
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
        let limit = match cfg.transport {
            haptics_client::TransportKind::Udp => GOAL_RATIO_UDP,
            haptics_client::TransportKind::Quic => GOAL_RATIO_QUIC,
        };
        let fs = &m.server.force_sequence;
        Self {
            transport: format!("{:?}", cfg.transport).to_lowercase(),
            server: if in_process {
                format!("in-process (fake device) at {}", cfg.server)
            } else {
                cfg.server.to_string()
            },
            rate_hz: args.rate,
            duration_s: args.duration,
            payload_bytes: payload,
            samples: m.acknowledged,
            sample_stride: m.stride,
            rtt_us: rtt,
            network_rtt_us: Percentiles::of_hist(&m.hist.network),
            workstation_turnaround_us: Percentiles::of_hist(&m.hist.turnaround),
            jitter_us: jitter,
            one_way_us: OneWay {
                server_to_workstation: direction(&m.hist.down, bound),
                workstation_to_server: direction(&m.hist.up, bound),
                clock_offset_us: m.clock.map_or(0.0, |c| c.offset_ns as f64 / 1e3),
            },
            loss: Loss {
                server_to_workstation: fraction(m.cursors.lost, m.cursors.received),
                workstation_to_server: fraction(fs.lost, fs.received),
                cursors_lost: m.cursors.lost,
                commands_lost: fs.lost,
            },
            reordered: PerDirection {
                server_to_workstation: m.cursors.reordered,
                workstation_to_server: fs.reordered,
            },
            duplicates: PerDirection {
                server_to_workstation: m.cursors.duplicates,
                workstation_to_server: fs.duplicates,
            },
            applied_age_ticks: m.applied.fractions(),
            baseline_udp_rtt_us: baseline,
            baseline_samples: base.rtt_ns.len(),
            baseline_loss: fraction(base.lost, base.rtt_ns.len() as u64),
            baseline_peer: args.echo.map_or_else(
                || "reflector thread in this process".into(),
                |a| a.to_string(),
            ),
            ratio_p50: ratio(rtt.p50, baseline.p50),
            ratio_p99: ratio(rtt.p99, baseline.p99),
            goal: Goal {
                ratio_limit: limit,
                met: ratio(rtt.p50, baseline.p50) <= limit,
            },
            server_force_rtt_us: from_protocol(m.server.force_rtt_ns),
            server_lateness_us: lateness.map(from_protocol),
            sessions: m.sessions,
            memory: Memory {
                start_kib: rss_start,
                warm_kib: m.rss_kib.0,
                end_kib: m.rss_kib.1,
                growth_kib: m.rss_kib.1 as i64 - m.rss_kib.0 as i64,
            },
            flood,
        }
    }
}

/// Write every output into `dir`.
pub fn write(dir: &Path, report: &Report, m: &Measured, base: &PingPong) -> anyhow::Result<()> {
    let put = |name: &str, text: String| {
        let p = dir.join(name);
        std::fs::write(&p, text).with_context(|| format!("writing {}", p.display()))
    };
    put("report.json", serde_json::to_string_pretty(report)? + "\n")?;
    let mut csv = String::from(
        "t_s,rtt_us,network_rtt_us,workstation_turnaround_us,down_us,up_us,one_way_bound_us\n",
    );
    for s in &m.samples {
        let _ = writeln!(
            csv,
            "{:.6},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}",
            s.t_ns as f64 / 1e9,
            s.rtt_ns as f64 / 1e3,
            s.network_rtt_ns as f64 / 1e3,
            s.workstation_ns as f64 / 1e3,
            s.down_ns as f64 / 1e3,
            s.up_ns as f64 / 1e3,
            s.bound_ns as f64 / 1e3
        );
    }
    put("samples.csv", csv)?;
    let mut b = String::from("rtt_us\n");
    for r in &base.rtt_ns {
        let _ = writeln!(b, "{:.3}", *r as f64 / 1e3);
    }
    put("baseline.csv", b)?;
    put("rtt.hgrm", hgrm(&m.hist.rtt))?;
    put("summary.md", summary(report))?;
    crate::plot::register_font().map_err(anyhow::Error::msg)?;
    super::plots::histogram(&dir.join("rtt_histogram.png"), m, base)?;
    super::plots::over_time(&dir.join("rtt_over_time.png"), m, report)?;
    Ok(())
}

/// HdrHistogram's percentile-distribution text (`.hgrm`), values in µs.
fn hgrm(h: &hdrhistogram::Histogram<u64>) -> String {
    let mut out = format!(
        "{:>12} {:>14} {:>10} {:>14}\n\n",
        "Value", "Percentile", "TotalCount", "1/(1-Percentile)"
    );
    let mut total = 0u64;
    for v in h.iter_quantiles(5) {
        total += v.count_since_last_iteration();
        let q = v.quantile_iterated_to();
        let inv = if q < 1.0 {
            1.0 / (1.0 - q)
        } else {
            f64::INFINITY
        };
        let _ = writeln!(
            out,
            "{:>12.3} {:>14.12} {:>10} {:>14.2}",
            v.value_iterated_to() as f64 / 1e3,
            q,
            total,
            inv
        );
    }
    let _ = writeln!(
        out,
        "#[Mean    = {:>12.3}, StdDeviation   = {:>12.3}]\n#[Max     = {:>12.3}, Total count    = {:>12}]",
        h.mean() / 1e3,
        h.stdev() / 1e3,
        h.max() as f64 / 1e3,
        h.len()
    );
    out
}

fn row(name: &str, p: &Percentiles) -> String {
    format!(
        "| {name} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
        p.p50, p.p99, p.p999, p.max
    )
}

/// The Markdown summary (also what the command prints).
pub fn summary(r: &Report) -> String {
    let mut s = format!(
        "# Latency run: {} to {}\n\n{} s at {} Hz; baseline: bare UDP ping-pong of {} B at the same rate, same run ({}).\n\n",
        r.transport, r.server, r.duration_s, r.rate_hz, r.payload_bytes, r.baseline_peer
    );
    s += "| µs | p50 | p99 | p99.9 | max |\n|---|---:|---:|---:|---:|\n";
    s += &row("cursor → force round trip", &r.rtt_us);
    s += &row("network round trip", &r.network_rtt_us);
    s += &row("workstation turnaround", &r.workstation_turnaround_us);
    s += &row("bare UDP ping-pong", &r.baseline_udp_rtt_us);
    let _ = write!(
        s,
        "\nRatio to the ping-pong: p50 {:.2}×, p99 {:.2}× (goal p50 ≤ {}×: {}).\n\n",
        r.ratio_p50,
        r.ratio_p99,
        r.goal.ratio_limit,
        if r.goal.met { "met" } else { "NOT met" }
    );
    let a = &r.applied_age_ticks;
    let _ = write!(
        s,
        "Command each servo tick applied ({} ticks): the answer to the previous tick's cursor {:.3} %, one tick late {:.3} %, two or more {:.3} %, none yet {:.3} % (goal ≥ 99.9 % the next tick).\n\n",
        a.ticks,
        a.next_tick * 100.0,
        a.two_ticks * 100.0,
        a.three_or_more * 100.0,
        a.no_command * 100.0
    );
    let (d, u) = (
        &r.one_way_us.server_to_workstation,
        &r.one_way_us.workstation_to_server,
    );
    let _ = write!(
        s,
        "One way (± {:.1} µs, the clock estimate's bound): server → workstation p50 {:.1} µs, p99 {:.1} µs; workstation → server p50 {:.1} µs, p99 {:.1} µs.\n\n",
        d.bound, d.p50, d.p99, u.p50, u.p99
    );
    let _ = writeln!(
        s,
        "Jitter {:.1} µs. Loss: cursors {:.4} % ({}), commands {:.4} % ({}). Reordered: {} / {}; duplicates: {} / {} (cursors / commands). Samples: {}; sessions: {}; memory {} KiB one second in → {} KiB at the end.",
        r.jitter_us,
        r.loss.server_to_workstation * 100.0,
        r.loss.cursors_lost,
        r.loss.workstation_to_server * 100.0,
        r.loss.commands_lost,
        r.reordered.server_to_workstation,
        r.reordered.workstation_to_server,
        r.duplicates.server_to_workstation,
        r.duplicates.workstation_to_server,
        r.samples,
        r.sessions,
        r.memory.warm_kib,
        r.memory.end_kib
    );
    if let Some(l) = &r.server_lateness_us {
        let _ = writeln!(
            s,
            "\nServo loop start lateness during the session: p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs.",
            l.p50, l.p99, l.max
        );
    }
    if let Some(f) = &r.flood {
        let _ = writeln!(
            s,
            "\nFlood: {} forged packets ({:.0}/s, {}× the command rate; {} rejected by the server). Servo lateness p99 {:.1} µs without → {:.1} µs with ({:.2}×, goal ≤ {}×: {}); round trip p50 {:.1} → {:.1} µs.",
            f.forged_sent,
            f.forged_rate_hz,
            f.multiplier,
            f.rejected_by_server,
            f.lateness_p99_us_without,
            f.lateness_p99_us_with,
            f.lateness_ratio,
            GOAL_FLOOD_LATENESS_RATIO,
            if f.goal_met { "met" } else { "NOT met" },
            f.rtt_p50_us_without,
            f.rtt_p50_us_with
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_exact_nearest_rank() {
        let p = Percentiles::of_ns((1..=1000).map(|i| i * 1000));
        assert_eq!(
            (p.p50, p.p99, p.p999, p.max, p.min),
            (500.0, 990.0, 999.0, 1000.0, 1.0)
        );
        assert_eq!(
            Percentiles::of_ns(std::iter::empty()),
            Percentiles::default()
        );
    }

    #[test]
    fn a_sample_splits_the_round_trip_into_one_way_delays() {
        // Server clock = client clock + 1 ms. Up 30 µs, server holds 400 µs, down 50 µs.
        let off = 1_000_000i64;
        let t0 = 10_000_000u64;
        let t1 = (t0 as i64 + 30_000 + off) as u64;
        let t2 = t1 + 400_000;
        let t3 = (t2 as i64 + 50_000 - off) as u64;
        let s = ClockSample {
            t0_ns: t0,
            t1_ns: t1,
            t2_ns: t2,
            t3_ns: t3,
        };
        let est = ClockEstimate {
            offset_ns: off + 10_000, // off by 10 µs, within its bound
            rtt_ns: 80_000,
            uncertainty_ns: 40_000,
            samples: 1,
        };
        let answered = t1 - 200_000; // the cursor answered left 200 µs before the command arrived
        let x = Sample::new(5, t0 - 100_000, answered, &s, &est);
        assert_eq!(x.network_rtt_ns, 80_000);
        assert_eq!(x.rtt_ns, 200_000);
        assert_eq!(x.workstation_ns, 100_000);
        assert_eq!(
            x.down_ns + x.up_ns,
            80_000,
            "one-way delays sum to the round trip"
        );
        assert!((x.down_ns - 50_000).abs() <= 40_000 && (x.up_ns - 30_000).abs() <= 40_000);
    }
}
