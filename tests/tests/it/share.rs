//! Shared scenes over Zenoh (docs/SHARING.md): `workstation share-router` and `workstation run
//! --share` stations as separate processes, each station with its own haptics server and fake
//! device (in this process), on loopback.
//!
//! - Two stations sculpt in turn (rope and paint at A, probe and paint at B), B touches the bump
//!   A raised and feels it as its own (force ≈ k × depth), A is killed and restarted (as a
//!   station without a device), a viewer joins late: every station ends with the same points
//!   (to 1e-6 m) and colours, holding A's bump, B's dent and both strokes of paint.
//! - A Python subscriber (`eclipse-zenoh`, tests/python/share_telemetry.py) records each
//!   station's telemetry at ≥ 100 Hz.
//! - Under mutual TLS an unlisted peer cannot open a session, a listed one cannot propose under
//!   another's name, and a malformed proposal is refused by name and counted.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use e2e_tests::{ChildGuard, binary, free_port};
use glam::{DVec3, Vec3};
use haptics_server::device::fake::{FakeDevice, FakeMonitor, FakeParams, HandPath};
use haptics_server::server::{Server, ServerOptions, TransportKind};
use workstation::live::phases::hand_path;
use workstation::live::scene_file::SceneFile;
use workstation::share::{KeeperStatus, Keys};

const RADIUS: f64 = 0.05;
const STIFFNESS: f64 = 400.0;

/// The shared scene: a 5 cm ball, its upper half sculpted; each station adds its own phases.
fn scene_text(phases: &str) -> String {
    format!(
        r#"
[[object]]
name = "ball"
generate = {{ shape = "sphere", size = {RADIUS}, points = 3000, seed = 2 }}

[region]
object = "ball"
min = [-0.05, 0.0, -0.05]
max = [0.05, 0.07, 0.05]
spacing = 0.0025
band = 0.008

[tools]
contact = {{ stiffness = {STIFFNESS}, damping = 0.0, friction = 0.0 }}
rope = {{ radius = 0.015, stiffness = 60.0, max_force = 3.0 }}
paint = {{ color = [200, 40, 30], radius = 0.005, radius_per_newton = 0.01, max_radius = 0.01 }}
probe = {{ semi_axes = [0.009, 0.009, 0.009], surface_stiffness = 2e6, sculpt_stiffness = 1000.0 }}
{phases}
"#
    )
}

const A_PHASES: &str = r#"
[[phase]]
name = "rope"
stroke = { tool = "rope", path = [[0.0, 0.05, 0.0], [0.0, 0.062, 0.0]], seconds = 1.0 }
[[phase]]
name = "paint"
stroke = { tool = "paint", path = [[0.025, 0.025, 0.035], [0.0, 0.028, 0.040], [-0.025, 0.025, 0.035]], seconds = 1.0 }
"#;

const B_PHASES: &str = r#"
[[phase]]
name = "probe"
stroke = { tool = "probe_push", path = [[0.035, 0.035, 0.0], [0.031, 0.031, 0.0]], seconds = 1.0 }
[[phase]]
name = "paint"
stroke = { tool = "paint", path = [[-0.035, 0.025, -0.02], [-0.035, 0.03, 0.0], [-0.035, 0.025, 0.02]], seconds = 1.0 }
"#;

/// A haptics server with a fake device following `path`.
fn server(path: Vec<(f32, Vec3, u16)>, dir: &Path) -> (Server, Arc<FakeMonitor>, PathBuf) {
    let device = FakeDevice::new(FakeParams {
        path: HandPath::Recorded(path.into()),
        ..FakeParams::default()
    });
    let monitor = device.monitor();
    let opts = ServerOptions::for_tests(TransportKind::Udp).unwrap();
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    haptics_server::tls::write_pem(&opts.identity, &cert, &key).unwrap();
    let client = opts.local_client.clone().unwrap();
    haptics_server::tls::write_pem(&client, &dir.join("client.pem"), &dir.join("client.key"))
        .unwrap();
    let server = Server::start(device, opts).unwrap();
    (server, monitor, cert)
}

/// A process whose output goes to `log` (read back when a check fails).
fn spawn_logged(mut cmd: Command, log: &Path) -> ChildGuard {
    let out = File::create(log).unwrap();
    cmd.stdout(out.try_clone().unwrap())
        .stderr(out)
        .stdin(Stdio::null())
        .env("RUST_LOG", "info,zenoh=warn");
    ChildGuard(Some(cmd.spawn().expect("spawn")))
}

fn logs(paths: &[&Path]) -> String {
    paths
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap_or_default();
            let tail: Vec<_> = text.lines().rev().take(40).collect();
            let tail: Vec<_> = tail.into_iter().rev().collect();
            format!("--- {} ---\n{}", p.display(), tail.join("\n"))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `workstation run --share` for station `name`, on `scene` (with a server, or without: a
/// station without a device), for `seconds`.
fn station(
    name: &str,
    scene: &Path,
    endpoint: &str,
    server: Option<(std::net::SocketAddr, &Path)>,
    out: &Path,
    seconds: f64,
) -> ChildGuard {
    let mut cmd = Command::new(binary("workstation"));
    cmd.arg("run")
        .arg("--scene")
        .arg(scene)
        .arg("--out")
        .arg(out);
    if let Some((addr, cert)) = server {
        cmd.args(["--server", &addr.to_string(), "--cert"])
            .arg(cert);
    }
    cmd.args(["--share", endpoint, "--station", name])
        .args(["--seconds", &seconds.to_string()]);
    spawn_logged(cmd, &out.with_extension("log"))
}

/// The keeper's status of `scene`, as a recorder on the bus sees it.
struct Watcher {
    runtime: tokio::runtime::Runtime,
    status: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    last: Option<KeeperStatus>,
}

impl Watcher {
    fn new(endpoint: &str, scene: &str) -> Self {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .unwrap();
        let config = workstation::share::bus::client_config(endpoint, None).unwrap();
        let status = runtime.block_on(async {
            let session = zenoh::open(config).await.unwrap();
            let s = session
                .declare_subscriber(Keys::new(scene).keeper())
                .await
                .unwrap();
            std::mem::forget(session); // lives as long as the test's runtime
            s
        });
        Self {
            runtime,
            status,
            last: None,
        }
    }

    fn version(&mut self) -> u64 {
        while let Ok(Some(s)) = self.status.try_recv() {
            self.last = serde_json::from_slice(&s.payload().to_bytes()).ok();
        }
        let _ = &self.runtime;
        self.last.as_ref().map_or(0, |s| s.version)
    }

    fn wait_version(&mut self, at_least: u64, timeout: Duration, logs_of: &[&Path]) {
        let t0 = Instant::now();
        while self.version() < at_least {
            assert!(
                t0.elapsed() < timeout,
                "the scene did not reach version {at_least} within {timeout:?} (at {:?})\n{}",
                self.last,
                logs(logs_of)
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// Points and colours of a saved `final.ply`.
fn read_points(path: &Path) -> (Vec<DVec3>, Vec<[u8; 3]>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    let p = sim_core::io::read_ply(&bytes)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
        .points;
    (p.positions, p.colors.expect("colours saved"))
}

fn python() -> PathBuf {
    let venv = std::env::var_os("HAPTIC_SCULPT_PYENV").map_or_else(
        || {
            PathBuf::from(std::env::var_os("HOME").expect("HOME"))
                .join(".cache/haptic-sculpt/pyzenoh")
        },
        PathBuf::from,
    );
    let py = venv.join("bin/python");
    assert!(
        py.is_file(),
        "{} is missing: `.ci/setup` installs eclipse-zenoh there (or set HAPTIC_SCULPT_PYENV)",
        py.display()
    );
    py
}

#[test]
fn two_stations_sculpt_in_turn_feel_each_other_and_every_station_ends_identical() {
    let _slot = e2e_tests::wall_clock_slot();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for s in ["a", "b"] {
        std::fs::create_dir_all(d.join(s)).unwrap();
    }
    // The same scene (same file stem, `shared`): each station with its own strokes.
    let scene_a = d.join("a/shared.toml");
    let scene_b = d.join("b/shared.toml");
    let scene_v = d.join("shared.toml");
    std::fs::write(&scene_a, scene_text(A_PHASES)).unwrap();
    std::fs::write(&scene_b, scene_text(B_PHASES)).unwrap();
    std::fs::write(&scene_v, scene_text("")).unwrap();
    let parsed_a = SceneFile::parse(&scene_text(A_PHASES)).unwrap();
    let parsed_b = SceneFile::parse(&scene_text(B_PHASES)).unwrap();

    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let router_log = d.join("router.log");
    let mut cmd = Command::new(binary("workstation"));
    cmd.args(["share-router", "--listen", &endpoint]);
    let _router = spawn_logged(cmd, &router_log);

    // A's hand: its strokes after 6 s (the stations fit and join meanwhile).
    let path_a = hand_path(&parsed_a, 6.0);
    let a_done = path_a.iter().rev().nth(1).unwrap().0 as f64; // the last point holds the rest
    // B's hand rests until A is done, touches the top of A's bump 1.5 mm above the ball's
    // surface (nothing there before A's rope), then makes its own strokes.
    let touch_from = a_done + 3.0;
    let mut path_b = hand_path(&parsed_b, touch_from + 4.0);
    let t = parsed_b.device.transform();
    let dev = |p: DVec3| t.point_to_device(p).as_vec3();
    let rest = path_b[0].1;
    let touch_at = DVec3::new(0.0, RADIUS + 0.0015, 0.0);
    let touch = [
        (touch_from as f32, rest, 0),
        (touch_from as f32 + 0.8, dev(touch_at + DVec3::Y * 0.004), 0),
        (touch_from as f32 + 1.3, dev(touch_at), 0),
        (touch_from as f32 + 2.8, dev(touch_at), 0),
        (touch_from as f32 + 3.6, rest, 0),
    ];
    let at = path_b.iter().position(|p| p.0 as f64 > touch_from).unwrap();
    path_b.splice(at..at, touch);
    let b_done = path_b.iter().rev().nth(1).unwrap().0 as f64;

    let (_server_a, _monitor_a, cert_a) = server(path_a, &d.join("a"));
    let (server_b, monitor_b, cert_b) = server(path_b, &d.join("b"));
    let t0 = Instant::now();
    let (out_a, out_b) = (d.join("out-a"), d.join("out-b"));
    let run_for = b_done + 6.0;
    let mut a = station(
        "a",
        &scene_a,
        &endpoint,
        Some((_server_a.local_addr(), &cert_a)),
        &out_a,
        run_for,
    );
    let b = station(
        "b",
        &scene_b,
        &endpoint,
        Some((server_b.local_addr(), &cert_b)),
        &out_b,
        run_for,
    );
    let a_log = out_a.with_extension("log");
    let b_log = out_b.with_extension("log");
    let all_logs = [router_log.as_path(), a_log.as_path(), b_log.as_path()];

    // A recorder in Python records both stations' telemetry meanwhile.
    let telemetry = d.join("telemetry.json");
    let mut py = Command::new(python());
    py.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("python/share_telemetry.py"))
        .args([
            "--connect",
            &endpoint,
            "--scene",
            "shared",
            "--seconds",
            "8",
        ])
        .arg("--out")
        .arg(&telemetry);
    let mut recorder = spawn_logged(py, &d.join("python.log"));

    // The scene's first state (whoever joined first), A's rope and A's paint.
    let mut watch = Watcher::new(&endpoint, "shared");
    watch.wait_version(3, Duration::from_secs_f64(a_done + 30.0), &all_logs);

    // B touches the top of A's bump: the force its own device gets is the contact's, k × depth.
    let touch_deadline = t0 + Duration::from_secs_f64(touch_from + 2.7);
    let mut felt: f32 = 0.0;
    while Instant::now() < touch_deadline + Duration::from_secs(20) {
        felt = felt.max(monitor_b.last_force().length());
        if Instant::now() > touch_deadline && felt > 0.0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }

    // A is killed after its strokes were ordered, and comes back without its device.
    let mut proc = a.0.take().unwrap();
    proc.kill().unwrap();
    proc.wait().unwrap();
    let out_a2 = d.join("out-a2");
    let remaining = (run_for - t0.elapsed().as_secs_f64()).max(10.0);
    let a2 = station("a", &scene_v, &endpoint, None, &out_a2, remaining + 4.0);

    // B's probe and paint.
    watch.wait_version(5, Duration::from_secs_f64(b_done + 40.0), &all_logs);
    // A viewer joins late.
    let out_v = d.join("out-v");
    let viewer = station("viewer", &scene_v, &endpoint, None, &out_v, 8.0);

    for (mut p, out) in [(b, &out_b), (a2, &out_a2), (viewer, &out_v)] {
        let mut proc = p.0.take().unwrap();
        let status = proc.wait().unwrap();
        assert!(
            status.success(),
            "{} failed\n{}",
            out.display(),
            logs(&[&out.with_extension("log"), &router_log])
        );
    }
    let status = recorder.0.take().unwrap().wait().unwrap();
    assert!(status.success(), "{}", logs(&[&d.join("python.log")]));

    // Every station ends with the same points and colours.
    let (pb, cb) = read_points(&out_b.join("final.ply"));
    for out in [&out_a2, &out_v] {
        let (p, c) = read_points(&out.join("final.ply"));
        assert_eq!(p.len(), pb.len(), "{} vs B", out.display());
        let worst = p
            .iter()
            .zip(&pb)
            .map(|(x, y)| x.distance(*y))
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-6,
            "{}: {worst} m from B's points",
            out.display()
        );
        assert_eq!(c, cb, "{}: colours differ from B's", out.display());
    }
    // ... which hold A's bump, B's dent and both paint strokes.
    let top = pb
        .iter()
        .filter(|p| p.x.hypot(p.z) < 0.004)
        .map(|p| p.y)
        .fold(f64::MIN, f64::max);
    let dent = DVec3::new(0.035, 0.035, 0.0).normalize() * RADIUS;
    let nearest = pb.iter().map(|p| p.distance(dent)).fold(f64::MAX, f64::min);
    let red = |c: &&[u8; 3]| c[0] > 150 && c[1] < 100;
    let painted_a = pb
        .iter()
        .zip(&cb)
        .filter(|(p, c)| p.z > 0.02 && red(c))
        .count();
    let painted_b = pb
        .iter()
        .zip(&cb)
        .filter(|(p, c)| p.x < -0.02 && red(c))
        .count();
    // B felt A's bump as its own surface: k × the stylus's depth under the bump's top, where
    // the fake hand (a spring of `hand_stiffness` to the stylus) holds it: the contact and the
    // grip in series over the hand's depth.
    let depth = top - touch_at.y;
    let grip = FakeParams::default().hand_stiffness as f64;
    let expected = STIFFNESS * grip / (STIFFNESS + grip) * depth;
    println!(
        "A's bump {:.2} mm high, B's dent {:.2} mm from the untouched surface, painted points \
         A {painted_a} B {painted_b}; B felt {felt:.2} N touching A's bump {:.2} mm deep \
         (k × stylus depth = {expected:.2} N)",
        (top - RADIUS) * 1e3,
        nearest * 1e3,
        depth * 1e3
    );
    assert!(top > RADIUS + 0.0025, "A's bump: top at {top}");
    assert!(
        nearest > 0.002,
        "B's dent: a point {nearest} m from the untouched surface"
    );
    assert!(
        painted_a > 5 && painted_b > 5,
        "paint: A {painted_a}, B {painted_b}"
    );
    assert!(
        (felt as f64 - expected).abs() < 0.25 * expected + 0.05,
        "B felt {felt} N touching A's bump {:.2} mm deep: expected ≈ {expected:.2} N",
        depth * 1e3
    );

    // The stations' own books: B took A's states, A's restart took the scene, all measured.
    let summary = |out: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("share.json")).unwrap()).unwrap()
    };
    let sb = summary(&out_b);
    assert!(sb["adopted"].as_u64().unwrap() >= 2, "{sb}");
    assert!(sb["accepted"].as_u64().unwrap() >= 2, "{sb}");
    assert!(summary(&out_a2)["version"].as_u64() == sb["version"].as_u64());
    println!(
        "edit propagation to B: p50 {} ms p99 {} ms; B sent {} bytes",
        sb["propagation_ms_p50"], sb["propagation_ms_p99"], sb["bytes_out"]
    );

    // The Python recorder heard both stations at ≥ 100 Hz.
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&telemetry).unwrap()).unwrap();
    for s in ["a", "b"] {
        let rate = t["stations"][s]["rate_hz"].as_f64().unwrap_or(0.0);
        assert!(rate >= 100.0, "station {s}: telemetry at {rate} Hz\n{t}");
        assert_eq!(t["stations"][s]["malformed"].as_u64(), Some(0), "{t}");
    }
}

/// A client session of the test under `tls` (giving up after 3 s instead of retrying).
fn open_tls(
    runtime: &tokio::runtime::Runtime,
    endpoint: &str,
    tls: &workstation::share::bus::StationTls,
) -> zenoh::Result<zenoh::Session> {
    let mut config = workstation::share::bus::client_config(endpoint, Some(tls)).unwrap();
    config.insert_json5("connect/timeout_ms", "3000").unwrap();
    runtime.block_on(async { zenoh::open(config).await })
}

fn proposal(station: &str, counter: u64) -> Vec<u8> {
    use workstation::share::wire::{Kind, SharedState, StateId, encode};
    encode(&SharedState {
        kind: Kind::Proposal,
        seq: 0,
        t_unix_ns: 0,
        scene: "lab".into(),
        object: "ball".into(),
        visible: vec!["ball".into()],
        id: StateId {
            station: station.into(),
            counter,
        },
        parent: None,
        positions: vec![DVec3::new(0.0, 0.05, 0.0)],
        normals: vec![[0.0, 1.0, 0.0]],
        colors: vec![[1, 2, 3]],
    })
}

#[test]
fn under_mutual_tls_only_listed_stations_join_each_under_its_own_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ids = d.join("ids");
    let auth = d.join("authorized_stations.pem");
    for (name, listed) in [("router", false), ("a", true), ("b", true), ("x", false)] {
        let mut cmd = Command::new(binary("workstation"));
        cmd.args(["share-identity", name, "--out"]).arg(&ids);
        if name == "router" {
            // The name the stations reach it by, which they check.
            cmd.args(["--host", "localhost"]);
        }
        if listed {
            cmd.arg("--authorize-in").arg(&auth);
        }
        let out = cmd.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let port = free_port();
    let router_log = d.join("router.log");
    let mut cmd = Command::new(binary("workstation"));
    cmd.args(["share-router", "--listen", &format!("tls/127.0.0.1:{port}")])
        .arg("--tls-cert")
        .arg(ids.join("router.pem"))
        .arg("--tls-key")
        .arg(ids.join("router.key"))
        .arg("--authorized")
        .arg(&auth);
    let _router = spawn_logged(cmd, &router_log);
    let endpoint = format!("tls/localhost:{port}");
    let tls = |name: &str| workstation::share::bus::StationTls {
        router_cert: ids.join("router.pem"),
        cert: ids.join(format!("{name}.pem")),
        key: ids.join(format!("{name}.key")),
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    // The router comes up.
    let t0 = Instant::now();
    let a = loop {
        match open_tls(&runtime, &endpoint, &tls("a")) {
            Ok(s) => break s,
            Err(e) => assert!(
                t0.elapsed() < Duration::from_secs(20),
                "a listed station cannot join: {e}\n{}",
                logs(&[&router_log])
            ),
        }
    };
    // An unlisted peer's handshake fails: no session, nothing heard, nothing said.
    assert!(
        open_tls(&runtime, &endpoint, &tls("x")).is_err(),
        "an unlisted station opened a session"
    );
    // So does the Python recorder with its certificate.
    let out = Command::new(python())
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("python/share_telemetry.py"))
        .args(["--connect", &endpoint, "--scene", "lab", "--seconds", "1"])
        .args(["--open-timeout", "2", "--out"])
        .arg(d.join("x.json"))
        .arg("--ca")
        .arg(ids.join("router.pem"))
        .arg("--cert")
        .arg(ids.join("x.pem"))
        .arg("--key")
        .arg(ids.join("x.key"))
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let keys = Keys::new("lab");
    let (verdicts_a, verdicts_b, edits, status) = runtime.block_on(async {
        (
            a.declare_subscriber(keys.verdicts("a")).await.unwrap(),
            a.declare_subscriber(keys.verdicts("b")).await.unwrap(),
            a.declare_subscriber(keys.edits()).await.unwrap(),
            a.declare_subscriber(keys.keeper()).await.unwrap(),
        )
    });
    let put = |key: String, bytes: Vec<u8>| {
        runtime.block_on(async { a.put(key, bytes).await.unwrap() });
    };
    std::thread::sleep(Duration::from_millis(500));
    // a speaks for b: dropped by the router's access control, never judged.
    put(keys.propose("b"), proposal("b", 1));
    // A malformed proposal: refused by name and counted, never applied.
    put(keys.propose("a"), b"HSS1 not a state".to_vec());
    let verdict = |sub: &zenoh::pubsub::Subscriber<
        zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>,
    >| {
        runtime.block_on(async {
            tokio::time::timeout(Duration::from_secs(5), sub.recv_async())
                .await
                .ok()
                .map(|s| {
                    serde_json::from_slice::<workstation::share::VerdictMessage>(
                        &s.unwrap().payload().to_bytes(),
                    )
                    .unwrap()
                })
        })
    };
    let v = verdict(&verdicts_a).expect("a verdict on the malformed proposal");
    assert!(!v.accepted);
    assert_eq!(v.reason.as_deref(), Some("unknown kind"), "{v:?}");
    // a's own proposal is ordered: version 1, a's.
    put(keys.propose("a"), proposal("a", 1));
    let v = verdict(&verdicts_a).expect("a verdict on a's proposal");
    assert!(v.accepted && v.seq == Some(1), "{v:?}");
    let e = runtime
        .block_on(async { tokio::time::timeout(Duration::from_secs(5), edits.recv_async()).await })
        .expect("the ordered state")
        .unwrap();
    let state = workstation::share::wire::decode(&e.payload().to_bytes()).unwrap();
    assert_eq!((state.seq, state.id.station.as_str()), (1, "a"));
    // Nothing was ever judged for b, and the keeper counts the malformed one by name.
    assert!(
        verdict(&verdicts_b).is_none(),
        "a proposal under b's name was judged"
    );
    let t0 = Instant::now();
    loop {
        let s = runtime
            .block_on(async {
                tokio::time::timeout(Duration::from_secs(2), status.recv_async()).await
            })
            .expect("the keeper's status")
            .unwrap();
        let s: KeeperStatus = serde_json::from_slice(&s.payload().to_bytes()).unwrap();
        if s.version == 1 {
            assert_eq!(s.refusals.get("unknown kind"), Some(&1), "{s:?}");
            assert_eq!(s.refusals.values().sum::<u64>(), 1, "{s:?}");
            assert_eq!(s.current.as_deref(), Some("a#1"));
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(5), "{s:?}");
    }
    runtime.block_on(async { a.close().await.unwrap() });
}

#[test]
fn a_station_whose_router_is_not_there_says_so_and_still_ends_and_saves() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("shared.toml");
    std::fs::write(&scene, scene_text("")).unwrap();
    let out = dir.path().join("out");
    let log = dir.path().join("run.log");
    let mut cmd = Command::new(binary("workstation"));
    cmd.args(["run", "--scene"])
        .arg(&scene)
        .args(["--share", &format!("tcp/127.0.0.1:{}", free_port())])
        .args(["--station", "lonely", "--seconds", "3", "--out"])
        .arg(&out);
    let mut child = spawn_logged(cmd, &log);
    let t0 = Instant::now();
    let status = loop {
        if let Some(status) = child.0.as_mut().unwrap().try_wait().unwrap() {
            break status;
        }
        // Killed (by the guard) and failed if it hangs: Zenoh keeps trying to reach the router.
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "still running after {:?}\n{}",
            t0.elapsed(),
            logs(&[&log])
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{text}");
    assert!(text.contains("not joined yet"), "{text}");
    assert!(out.join("final.ply").is_file() && out.join("share.json").is_file());
}
