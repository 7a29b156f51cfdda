//! `workstation latency` as a user runs it: an in-process server over loopback on both
//! transports, every output written and self-consistent, the session kept for the whole run
//! with memory flat (the shortened soak; the hour-long one is documented in docs/BENCHMARKS.md),
//! and a forged-packet flood rejected without ending the session. Timing ratios are reported,
//! not asserted (machines differ); what must hold on any machine is asserted.

use std::path::Path;
use std::process::Command;

use e2e_tests::binary;
use serde_json::Value;

fn latency(out: &Path, extra: &[&str]) -> Value {
    let o = Command::new(binary("workstation"))
        .arg("latency")
        .arg("--out")
        .arg(out)
        .args(extra)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run workstation latency");
    assert!(
        o.status.success(),
        "latency {extra:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(out.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report.json is JSON")
}

fn f(v: &Value, path: &str) -> f64 {
    path.split('.')
        .fold(v, |v, k| &v[k])
        .as_f64()
        .unwrap_or_else(|| panic!("{path} missing in {v}"))
}

fn check_report(r: &Value, dir: &Path, seconds: f64) {
    let t = r["transport"].as_str().unwrap().to_string();
    // Commands are measured when a cursor acknowledges them; after a scheduling stall a burst
    // of commands is acknowledged once, so how many depends on the machine's load. That the
    // measurement runs at all is what holds anywhere.
    assert!(f(r, "samples") > 100.0, "{t}: {} samples", r["samples"]);
    for key in ["rtt_us", "network_rtt_us", "baseline_udp_rtt_us"] {
        let (p50, p99, p999, max) = (
            f(r, &format!("{key}.p50")),
            f(r, &format!("{key}.p99")),
            f(r, &format!("{key}.p999")),
            f(r, &format!("{key}.max")),
        );
        assert!(
            0.0 < p50 && p50 <= p99 && p99 <= p999 && p999 <= max,
            "{t} {key}: {p50} {p99} {p999} {max}"
        );
    }
    // Every cursor counted once by the age of the command its tick applied.
    let a = &r["applied_age_ticks"];
    let sum: f64 = ["next_tick", "two_ticks", "three_or_more", "no_command"]
        .iter()
        .map(|k| a[k].as_f64().unwrap())
        .sum();
    assert!((sum - 1.0).abs() < 1e-9, "{t}: applied_age_ticks {a}");
    assert!(
        f(r, "applied_age_ticks.ticks") > 0.5 * 1000.0 * seconds,
        "{t}: {a}"
    );
    eprintln!("{t}: applied_age_ticks {a}");
    // Per command (samples.csv), what holds whatever the load: the two one-way estimates add
    // up to the exchange's network round trip (the clock offset cancels); neither is below
    // zero by more than its stated bound (loopback's true one-way delay is ≥ 0); and the
    // cursor → force round trip contains the workstation's turnaround.
    let bound = f(r, "one_way_us.server_to_workstation.bound");
    assert!(bound > 0.0, "{t}: a bound is stated");
    let csv = std::fs::read_to_string(dir.join("samples.csv")).unwrap();
    let mut rows = 0;
    for line in csv.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let [_, rtt, network, turnaround, down, up, bound] = v[..] else {
            panic!("{t}: samples.csv row {line:?}")
        };
        assert!(
            (down + up - network).abs() < 0.01,
            "{t}: one-ways vs round trip: {line}"
        );
        assert!(
            down >= -bound - 0.01 && up >= -bound - 0.01,
            "{t}: one way below -bound: {line}"
        );
        assert!(
            rtt >= turnaround - 0.01,
            "{t}: round trip shorter than the turnaround: {line}"
        );
        rows += 1;
    }
    assert!(rows > 100, "{t}: samples.csv has {rows} rows");
    assert!(f(r, "ratio_p50") > 0.0 && r["goal"]["ratio_limit"].is_number());
    // Loopback loses, reorders and duplicates (next to) nothing. QUIC's datagram send buffer
    // holds a few packets by design (stale samples are dropped, not queued), so a stall of
    // the sending task of a few milliseconds drops some: up to 1.6 % on a loaded 2-core
    // machine. Over a percent or two there is a bug, not a stall.
    let lossy = if t == "quic" { 0.05 } else { 0.01 };
    for d in ["server_to_workstation", "workstation_to_server"] {
        assert!(f(r, &format!("loss.{d}")) < lossy, "{t}: {}", r["loss"]);
    }
    assert!(r["reordered"]["server_to_workstation"].is_u64());
    assert!(r["duplicates"]["workstation_to_server"].is_u64());
    assert_eq!(r["sessions"], 1, "{t}: the session was never lost");
    for file in [
        "samples.csv",
        "baseline.csv",
        "rtt.hgrm",
        "summary.md",
        "rtt_histogram.png",
        "rtt_over_time.png",
    ] {
        let len = std::fs::metadata(dir.join(file))
            .unwrap_or_else(|e| panic!("{t}: {file}: {e}"))
            .len();
        assert!(len > 100, "{t}: {file} is {len} bytes");
    }
}

#[test]
fn latency_runs_over_udp_and_quic_write_a_consistent_report() {
    let _slot = e2e_tests::wall_clock_slot();
    let dir = tempfile::tempdir().unwrap();
    for transport in ["udp", "quic"] {
        let out = dir.path().join(transport);
        let r = latency(&out, &["--transport", transport, "--duration", "2"]);
        check_report(&r, &out, 2.0);
    }
}

/// The shortened soak: 8 s of session, memory flat after the first second, nothing lost.
#[test]
fn a_short_soak_keeps_the_session_and_memory_flat() {
    let _slot = e2e_tests::wall_clock_slot();
    let dir = tempfile::tempdir().unwrap();
    let r = latency(dir.path(), &["--duration", "8"]);
    check_report(&r, dir.path(), 8.0);
    let growth = f(&r, "memory.growth_kib");
    assert!(
        growth < 2048.0,
        "resident memory grew {growth} KiB in 7 s: {}",
        r["memory"]
    );
}

/// Forged packets at 50× the command rate (right session id, wrong MAC) are rejected by the
/// server, none ends the session, and the report compares the loop's lateness with and
/// without them in the same run.
#[test]
fn a_forged_packet_flood_is_rejected_and_survived() {
    let _slot = e2e_tests::wall_clock_slot();
    let dir = tempfile::tempdir().unwrap();
    let r = latency(dir.path(), &["--duration", "2", "--flood", "50"]);
    let flood = &r["flood"];
    let sent = f(flood, "forged_sent");
    assert!(
        sent > 0.5 * 50.0 * 1000.0 * 2.0,
        "forged packets sent: {flood}"
    );
    // Every forged packet that reached the server was rejected; at 50 kHz on a loaded machine
    // the kernel drops some of the rest from the socket's receive buffer before it reads them
    // (a loaded CI run: 89% reached it). A server that accepted them would reject none.
    assert!(
        f(flood, "rejected_by_server") >= 0.5 * sent,
        "the server rejected them: {flood}"
    );
    assert!(f(flood, "lateness_p99_us_without") > 0.0);
    assert!(f(flood, "lateness_p99_us_with") > 0.0);
    assert!(flood["goal_met"].is_boolean());
    assert_eq!(r["sessions"], 1);
}

#[test]
fn bad_counts_get_named_errors() {
    for (args, want) in [
        (&["--rate", "0"][..], "MAX_RATE_HZ"),
        (&["--duration", "1e9"][..], "MAX_DURATION_S"),
        (&["--payload", "100000"][..], "--payload"),
        (&["--flood", "1000"][..], "MAX_FLOOD"),
    ] {
        let o = Command::new(binary("workstation"))
            .arg("latency")
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{args:?}: {err}");
    }
}

/// A haptics server process (fake device, idle) on a free loopback port with a fresh
/// certificate in `dir`; returns its guard and address once it listens.
fn server_process(dir: &Path) -> (e2e_tests::ChildGuard, std::net::SocketAddr) {
    let made = Command::new(binary("haptics-server"))
        .args(["gen-cert", "--out"])
        .arg(dir)
        .output()
        .expect("gen-cert");
    assert!(made.status.success(), "gen-cert failed");
    let addr = e2e_tests::loopback(e2e_tests::free_port());
    let mut server = Command::new(binary("haptics-server"));
    server
        .args([
            "--device",
            "fake",
            "--fake-path",
            "idle",
            "--no-realtime",
            "--listen",
        ])
        .arg(addr.to_string())
        .arg("--cert")
        .arg(dir.join("cert.pem"))
        .arg("--key")
        .arg(dir.join("key.pem"));
    let guard = e2e_tests::ChildGuard::spawn(server);
    // The server creates the local client identity beside its certificate on start.
    let start = std::time::Instant::now();
    while !dir.join("client.key").exists() {
        assert!(start.elapsed().as_secs() < 20, "the server did not start");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    (guard, addr)
}

/// `workstation relay --listen … --to server` with the given impairments.
fn relay(to: std::net::SocketAddr, impairments: &[&str]) -> (e2e_tests::ChildGuard, String) {
    let listen = e2e_tests::loopback(e2e_tests::free_port()).to_string();
    let mut cmd = Command::new(binary("workstation"));
    cmd.args(["relay", "--listen", &listen, "--to", &to.to_string()])
        .args(impairments);
    let guard = e2e_tests::ChildGuard::spawn(cmd);
    std::thread::sleep(std::time::Duration::from_millis(300));
    (guard, listen)
}

#[test]
fn a_latency_run_through_the_relay_measures_its_delay_on_any_machine() {
    let _slot = e2e_tests::wall_clock_slot();
    const DELAY_MS: f64 = 5.0;
    let dir = tempfile::tempdir().unwrap();
    let (_server, addr) = server_process(dir.path());
    let cert = dir.path().join("cert.pem");
    // The same server without the relay first: what this machine's hot path takes by itself.
    let direct = latency(
        &dir.path().join("direct"),
        &[
            "--server",
            &addr.to_string(),
            "--cert",
            cert.to_str().unwrap(),
            "--duration",
            "2",
        ],
    );
    let direct_ms = f(&direct, "network_rtt_us.p50") / 1e3;
    let (_relay, via) = relay(addr, &["--delay", "5"]);
    let out = dir.path().join("out");
    let r = latency(
        &out,
        &[
            "--server",
            &via,
            "--cert",
            cert.to_str().unwrap(),
            "--duration",
            "3",
        ],
    );
    let rtt_ms = f(&r, "network_rtt_us.p50") / 1e3;
    // What the relay may add beyond its delay: the hot path's own round trip measured without
    // it just before (0.03 ms on an idle machine, 0.3–0.7 ms on a loaded one: the wake-ups of
    // issue 20), plus 1 ms for the relay's own two hops.
    let slack_ms = 1.0 + direct_ms;
    eprintln!(
        "relay: {DELAY_MS} ms each way: network round trip p50 {rtt_ms:.2} ms (direct {direct_ms:.2} ms, \
         slack {slack_ms:.2} ms)"
    );
    assert!(
        (2.0 * DELAY_MS..2.0 * DELAY_MS + slack_ms).contains(&rtt_ms),
        "network round trip p50 {rtt_ms} ms through a {DELAY_MS} ms-each-way relay"
    );
    for d in ["server_to_workstation", "workstation_to_server"] {
        let p50 = f(&r, &format!("one_way_us.{d}.p50")) / 1e3;
        let bound = f(&r, &format!("one_way_us.{d}.bound")) / 1e3;
        eprintln!("relay: {d} one way p50 {p50:.2} ms ± {bound:.2} ms");
        assert!(
            (p50 - DELAY_MS).abs() <= bound + slack_ms / 2.0,
            "{d}: one way p50 {p50} ms ± {bound} ms, configured {DELAY_MS} ms"
        );
    }
    // 10 ms there and back is 10 servo ticks: no tick can apply the answer to the previous
    // tick's cursor, so the age measure must see nearly every tick as late.
    let late = f(&r, "applied_age_ticks.three_or_more");
    assert!(
        late > 0.95,
        "through 10 ms of round trip {late} of ticks applied a command ≥ 3 ticks old"
    );
    assert_eq!(r["sessions"], 1);
}

#[test]
fn loss_through_the_relay_shows_in_both_directions() {
    let _slot = e2e_tests::wall_clock_slot();
    const LOSS: f64 = 0.02;
    let dir = tempfile::tempdir().unwrap();
    let (_server, addr) = server_process(dir.path());
    let (_relay, via) = relay(addr, &["--loss", "0.02", "--seed", "3"]);
    let cert = dir.path().join("cert.pem");
    let out = dir.path().join("out");
    let r = latency(
        &out,
        &[
            "--server",
            &via,
            "--cert",
            cert.to_str().unwrap(),
            "--duration",
            "4",
        ],
    );
    let n = f(&r, "samples").max(1000.0);
    // Binomial sampling error at about a thousand packets a second, 4 standard deviations.
    let tolerance = 4.0 * (LOSS * (1.0 - LOSS) / n).sqrt();
    for d in ["server_to_workstation", "workstation_to_server"] {
        let loss = f(&r, &format!("loss.{d}"));
        eprintln!("relay: {d} loss {loss:.4} (configured {LOSS}, ± {tolerance:.4})");
        assert!(
            (loss - LOSS).abs() <= tolerance,
            "{d}: measured loss {loss}, configured {LOSS} ± {tolerance}"
        );
    }
}

/// `workstation run --seconds 3` against `server` with `cert` pinned; its exit status and
/// everything it printed.
fn run_briefly(server: &str, cert: &Path, dir: &Path) -> (bool, String) {
    // The demo's scene without its scripted phases: `run` just holds the session.
    let demo = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../examples/live/demo.toml"
    ))
    .unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, &demo[..demo.find("[[phase]]").unwrap()]).unwrap();
    let o = Command::new(binary("workstation"))
        .args(["run", "--server", server, "--cert"])
        .arg(cert)
        .arg("--scene")
        .arg(&scene)
        .args(["--seconds", "3", "--out"])
        .arg(dir.join("run"))
        .output()
        .expect("run workstation run");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), text)
}

#[test]
fn run_says_why_it_cannot_connect_and_fails_without_a_session() {
    let _slot = e2e_tests::busy_slot();
    let dir = tempfile::tempdir().unwrap();
    let (_server, addr) = server_process(dir.path());
    // A certificate that is not the server's: the mismatch, with both fingerprints.
    let other = dir.path().join("other");
    let made = Command::new(binary("haptics-server"))
        .args(["gen-cert", "--out"])
        .arg(&other)
        .output()
        .expect("gen-cert");
    assert!(made.status.success());
    let (ok, text) = run_briefly(&addr.to_string(), &other.join("cert.pem"), dir.path());
    assert!(!ok, "exit status 0 without a session:\n{text}");
    assert!(
        text.contains("certificate mismatch") && text.matches("sha256:").count() >= 2,
        "the mismatch and both fingerprints are said:\n{text}"
    );
    assert_eq!(
        text.matches("cannot connect").count(),
        1,
        "said once, not at every retry:\n{text}"
    );
    // Nobody listening.
    let nobody = e2e_tests::loopback(e2e_tests::free_port()).to_string();
    let (ok, text) = run_briefly(&nobody, &dir.path().join("cert.pem"), dir.path());
    assert!(!ok, "exit status 0 without a session:\n{text}");
    assert!(text.contains("connection refused"), "{text}");
    // The right certificate: a session, exit 0.
    let (ok, text) = run_briefly(&addr.to_string(), &dir.path().join("cert.pem"), dir.path());
    assert!(ok, "{text}");
}
