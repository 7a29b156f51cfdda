//! The workstation process against a haptics server with the fake device, over loopback: the
//! scripted hand drives the tools through the real network path (UDP, pinned TLS).

use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

use e2e_tests::{ChildGuard, binary, free_port, loopback};
use glam::{DVec3, Vec3};
use haptics_server::device::fake::{FakeDevice, FakeMonitor, FakeParams, HandPath};
use haptics_server::server::{Server, ServerOptions, TransportKind};
use workstation::live::Workstation;
use workstation::live::frames::FrameMaker;
use workstation::live::net::NetConfig;
use workstation::live::phases::{drive_phases, hand_path};
use workstation::live::scene_file::SceneFile;
use workstation::live::shared::Shared;

const RADIUS: f64 = 0.05;
const STIFFNESS: f64 = 400.0;

/// A 5 cm ball, its upper half the sculpting region, and `phases`.
fn scene(region: &str, phases: &str) -> SceneFile {
    let text = format!(
        r#"
[[object]]
name = "ball"
generate = {{ shape = "sphere", size = {RADIUS}, points = 3000, seed = 2 }}

[region]
object = "ball"
{region}

[tools]
contact = {{ stiffness = {STIFFNESS}, damping = 0.0, friction = 0.0 }}
rope = {{ radius = 0.015, stiffness = 60.0, max_force = 3.0 }}
paint = {{ color = [200, 40, 30], radius = 0.005, radius_per_newton = 0.01, max_radius = 0.01 }}
probe = {{ semi_axes = [0.009, 0.009, 0.009], surface_stiffness = 2e6, sculpt_stiffness = 1000.0 }}

[render]
width = 160
height = 120
view_dir = [-0.35, -0.45, -1.0]
{phases}
"#
    );
    SceneFile::parse(&text).unwrap()
}

const TOP_HALF: &str =
    "min = [-0.05, 0.0, -0.05]\nmax = [0.05, 0.06, 0.05]\nspacing = 0.0025\nband = 0.008";

fn server_with(
    path: Vec<(f32, Vec3, u16)>,
    opts: ServerOptions,
) -> (Server, Arc<FakeMonitor>, NetConfig) {
    let device = FakeDevice::new(FakeParams {
        path: HandPath::Recorded(path.into()),
        ..FakeParams::default()
    });
    let monitor = device.monitor();
    let transport = opts.transport;
    let server = Server::start(device, opts).unwrap();
    let cfg = NetConfig {
        server: server.local_addr(),
        transport,
        cert: server.certificate(),
        identity: server.local_client(),
    };
    (server, monitor, cfg)
}

fn server(path: Vec<(f32, Vec3, u16)>) -> (Server, Arc<FakeMonitor>, NetConfig) {
    server_with(path, ServerOptions::for_tests(TransportKind::Udp).unwrap())
}

/// The hand rests above the pole, goes down `depth` below the surface and stays.
fn press_path(depth: f32) -> Vec<(f32, Vec3, u16)> {
    let r = RADIUS as f32;
    vec![
        (0.0, Vec3::new(0.0, r + 0.02, 0.0), 0),
        (0.8, Vec3::new(0.0, r + 0.02, 0.0), 0),
        (1.3, Vec3::new(0.0, r - depth, 0.0), 0),
        (1e5, Vec3::new(0.0, r - depth, 0.0), 0),
    ]
}

fn wait_for(what: &str, timeout: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn a_rope_pull_and_a_painted_stroke_over_the_network_last_and_show() {
    let _slot = e2e_tests::wall_clock_slot();
    let scene = scene(
        TOP_HALF,
        r#"
[[phase]]
name = "rope"
stroke = { tool = "rope", path = [[0.0, 0.05, 0.0], [0.0, 0.062, 0.0]], seconds = 1.0 }
[[phase]]
name = "paint"
stroke = { tool = "paint", path = [[0.025, 0.025, 0.035], [0.0, 0.028, 0.040], [-0.025, 0.025, 0.035]], seconds = 1.0 }
"#,
    );
    let (_server, _monitor, cfg) = server(hand_path(&scene, 1.0));
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let phases = drive_phases(&ws, &scene, deadline, || false, |_, _| {}).unwrap();
    assert_eq!(phases.len(), 2);
    // The rope let go more than a second ago (paint stroke + rests): the bump must still be
    // there, committed, not sprung back.
    let mut core = ws.finish().unwrap();
    let ball = &core.scene().objects()[0];
    let (mut bump, mut elsewhere) = (0.0f64, 0.0f64);
    for p in &ball.positions {
        let dev = p.length() - RADIUS;
        if p.normalize().y > 0.98 {
            bump = bump.max(dev);
        } else if p.y < 0.0 {
            elsewhere = elsewhere.max(dev.abs());
        }
    }
    // The hand pulls 12 mm out: rope force 60 N/m × 12 mm = 0.72 N, static bump F/anchor ≈ 7 mm
    // at the pole (less as the stylus lags the hand).
    assert!(bump > 2.5e-3, "bump at the pole after release: {bump:e} m");
    assert!(
        elsewhere < 5e-4,
        "outside the region nothing moves: {elsewhere:e} m"
    );
    // The painted stroke: points along the middle of the path are red, the far side is not.
    let red = |c: &[u8; 3]| c[0] > 150 && c[1] < 120;
    let mid = DVec3::new(0.0, 0.028, 0.040).normalize() * RADIUS;
    let near_mid: Vec<_> = ball
        .positions
        .iter()
        .zip(&ball.colors)
        .filter(|(p, _)| p.distance(mid) < 0.003)
        .collect();
    assert!(!near_mid.is_empty());
    let painted = near_mid.iter().filter(|(_, c)| red(c)).count();
    assert!(
        painted * 10 >= near_mid.len() * 8,
        "{painted} of {} points under the stroke are painted",
        near_mid.len()
    );
    assert!(
        ball.positions
            .iter()
            .zip(&ball.colors)
            .all(|(p, c)| p.z > 0.0 || !red(c)),
        "paint only where the stroke went"
    );
    // The picture: the ball fills the centre, the corner is background, the paint shows.
    let mut maker = FrameMaker::new(&scene.render).unwrap();
    let shared = Shared::default();
    let img = maker.render(&core.render_snapshot(), &shared).unwrap();
    let (w, h) = (img.width, img.height);
    let bg = img.pixel(0, 0);
    let centre = img.pixel(w / 2, h / 2);
    let diff = |a: [u8; 4], b: [u8; 4]| (0..3).map(|i| a[i].abs_diff(b[i]) as u32).sum::<u32>();
    assert!(
        diff(centre, bg) > 100,
        "centre {centre:?} vs background {bg:?}"
    );
    let reds = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = img.pixel(x, y);
            p[0] > 120 && p[1] < 80 && p[2] < 80
        })
        .count();
    assert!(
        reds > 20,
        "the painted stroke is visible: {reds} red pixels"
    );
}

#[test]
fn the_shaped_probe_carves_a_dent_and_pulls_material_out_from_inside() {
    let _slot = e2e_tests::wall_clock_slot();
    let scene = scene(
        TOP_HALF,
        r#"
[[phase]]
name = "push"
stroke = { tool = "probe_push", path = [[0.030, 0.040, 0.0], [0.028, 0.037, 0.0], [0.028, 0.037, -0.01]], seconds = 1.0 }
[[phase]]
name = "pull from inside"
stroke = { tool = "probe_pull", path = [[-0.02, 0.040, -0.02], [-0.0229, 0.0457, -0.0229]], seconds = 1.0 }
"#,
    );
    let (_server, _monitor, cfg) = server(hand_path(&scene, 1.0));
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    drive_phases(&ws, &scene, deadline, || false, |_, _| {}).unwrap();
    let core = ws.finish().unwrap();
    let ball = &core.scene().objects()[0];
    let near = |c: DVec3, r: f64| {
        let c = c.normalize() * RADIUS;
        ball.positions
            .iter()
            .filter(move |p| p.distance(c) < r)
            .map(|p| p.length() - RADIUS)
    };
    // Under the push path the surface went in, and stayed in after the release.
    let dent = near(DVec3::new(0.028, 0.037, -0.005), 0.006).fold(0.0, f64::min);
    assert!(dent < -1e-3, "deepest point under the push: {dent:e} m");
    // Where the probe left the material from inside (released 6 mm out, within the region's
    // 8 mm band: beyond it the material cannot follow), the material came out with it, and
    // the points, resampled at the commit, lie on the committed surface.
    let bulge = near(DVec3::new(-0.023, 0.046, -0.023), 0.008).fold(0.0, f64::max);
    assert!(bulge > 1e-3, "highest point above the pull: {bulge:e} m");
    let c = DVec3::new(-0.023, 0.046, -0.023).normalize() * RADIUS;
    let off = ball
        .positions
        .iter()
        .filter(|p| p.distance(c) < 0.01)
        .map(|&p| ball.field.value(p).abs())
        .fold(0.0, f64::max);
    assert!(off < 2.5e-4, "a point {off:e} m off the committed surface");
    // Elsewhere on the region's surface nothing moved.
    let calm = near(DVec3::new(0.0, 0.03, 0.04), 0.01).fold(0.0, |a: f64, d| a.max(d.abs()));
    assert!(calm < 5e-4, "untouched surface moved {calm:e} m");
}

#[test]
fn the_force_felt_pressing_a_sphere_is_stiffness_times_depth_over_udp() {
    let _slot = e2e_tests::wall_clock_slot();
    force_is_stiffness_times_depth(TransportKind::Udp);
}

#[test]
fn the_force_felt_pressing_a_sphere_is_stiffness_times_depth_over_quic() {
    let _slot = e2e_tests::wall_clock_slot();
    force_is_stiffness_times_depth(TransportKind::Quic);
}

/// A stall of the whole machine longer than the server's watchdog (commands silent for 30 ms;
/// the VM host here sometimes takes both cores for longer) fades the output to zero, and the
/// safety gate then waits for the hand to ease off before engaging again, which this fixed
/// hand never does. Such an attempt says nothing about the force mapping, so it is repeated
/// (3 attempts at most, each repeat printed with its cause); the comparison is the same.
fn force_is_stiffness_times_depth(transport: TransportKind) {
    const ATTEMPTS: usize = 3;
    for attempt in 1..=ATTEMPTS {
        match press_and_compare(transport) {
            Ok(()) => return,
            Err(fades) if attempt < ATTEMPTS => eprintln!(
                "attempt {attempt}: the watchdog faded the output {fades} time(s) (a stall of \
                 the machine); repeating"
            ),
            Err(fades) => panic!("the watchdog faded the output in every attempt ({fades})"),
        }
    }
}

/// How long the servo's telemetry gets to report a fade the monitor already shows.
const TELEMETRY_CATCH_UP: Duration = Duration::from_millis(200);

/// Press, settle, compare the felt force with k × depth; `Err(fades)` when the server's
/// watchdog faded the output during the comparison.
fn press_and_compare(transport: TransportKind) -> Result<(), u64> {
    let scene = scene(TOP_HALF, "");
    let (server, monitor, cfg) = server_with(
        press_path(0.006),
        ServerOptions::for_tests(transport).unwrap(),
    );
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    // Settle in contact, then compare the device's force with k × depth at the cursor the
    // workstation received (both through the network).
    wait_for("contact", Duration::from_secs(10), || {
        monitor.last_force().length() > 0.3
    });
    // A fade from here on leaves the output at zero (the hand stays in the surface).
    let fades_before = server.servo_stats().watchdog_fades;
    std::thread::sleep(Duration::from_millis(800));
    let mut errors = Vec::new();
    for _ in 0..100 {
        let x = ws.shared.haptic.cursor();
        let f = monitor.last_force().as_dvec3();
        let depth = RADIUS - x.length();
        let expected = STIFFNESS * depth;
        assert!(
            depth > 5e-4,
            "the stylus rests in the surface (depth {depth:e} m)"
        );
        let mut fades = server.servo_stats().watchdog_fades - fades_before;
        if f == DVec3::ZERO {
            // The servo's counts reach `servo_stats` through the telemetry thread (a 10 ms
            // period, later on a loaded machine), while the monitor sees the output at once,
            // and a fade that late ticks speed up can reach zero within a period of starting:
            // give the counts time to catch up before calling a zero force unexplained.
            std::thread::sleep(TELEMETRY_CATCH_UP);
            fades = server.servo_stats().watchdog_fades - fades_before;
            if fades > 0 {
                ws.finish().unwrap();
                return Err(fades);
            }
        }
        assert!(
            f.normalize().dot(x.normalize()) > 0.95,
            "force {f:?} points out of the sphere at {x:?} (watchdog fades: {fades})"
        );
        errors.push((f.length() - expected).abs() / expected);
        std::thread::sleep(Duration::from_millis(10));
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    // Tolerance: the fitted surface and its 2.5 mm grid sit within ~0.1 mm of the sphere,
    // ≈ 5 % of a 2 mm depth; plus the cursor is one network hop older than the force.
    assert!(
        median < 0.1,
        "median relative error {median:.3} (sorted: {errors:?})"
    );
    ws.finish().unwrap();
    Ok(())
}

#[test]
fn the_force_loop_keeps_the_cursor_rate_while_the_simulation_steps_slowly() {
    let _slot = e2e_tests::wall_clock_slot();
    // A fine region over the whole ball: ~200k simulated nodes, a step of many milliseconds.
    let heavy = "min = [-0.056, -0.056, -0.056]\nmax = [0.056, 0.056, 0.056]\nspacing = 0.0012\nband = 0.006";
    let scene = scene(heavy, "");
    let (_server, _monitor, cfg) = server(press_path(0.004));
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(20)).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    ws.shared
        .force_loop
        .reset
        .store(true, std::sync::atomic::Ordering::Relaxed);
    let c0 = ws.stats().cursors;
    let t0 = Instant::now();
    std::thread::sleep(Duration::from_secs(3));
    let s = ws.stats();
    let cursor_hz = (s.cursors - c0) as f64 / t0.elapsed().as_secs_f64();
    ws.finish().unwrap();
    eprintln!(
        "heavy step: sim {:.0} Hz, step {:?} µs; force loop {:.0} Hz, period {:?} µs; cursors {cursor_hz:.0}/s",
        s.sim_hz, s.sim_step_us, s.force_loop_hz, s.force_loop_period_us
    );
    // The bar: a step longer than a force tick (1 ms), so a loop that waited for it would fall
    // below the cursor rate.
    assert!(
        s.sim_step_us.p50 > 1_000.0 && s.sim_hz < 900.0,
        "the step must be heavy for this test to mean anything: {:?} µs, {:.0} Hz",
        s.sim_step_us,
        s.sim_hz
    );
    // Driven by the cursor stream, the loop runs at the server's rate, whatever the step. The
    // server's rate is what arrived: the heavy step loads the two cores and the server's
    // servo, in this process, slows too (944 cursors/s in one CI run, 799 in another), so the
    // loop is held to that rate, and the stream must outpace the simulation at least twice
    // over, so that a loop waiting for the steps would fall visibly below it.
    assert!(
        s.force_loop_hz > 0.9 * cursor_hz && cursor_hz > 2.0 * s.sim_hz,
        "force loop {:.0} Hz against {cursor_hz:.0} cursors/s while the simulation ran {:.0} Hz",
        s.force_loop_hz,
        s.sim_hz
    );
}

#[test]
fn the_workstation_reconnects_when_the_server_restarts() {
    let _slot = e2e_tests::wall_clock_slot();
    let port = free_port();
    let mut opts = ServerOptions::for_tests(TransportKind::Udp).unwrap();
    opts.listen = loopback(port);
    let (first, _, cfg) = server_with(press_path(0.0), opts.clone());
    let scene = scene(TOP_HALF, "");
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    first.shutdown();
    wait_for("the session to drop", Duration::from_secs(10), || {
        !ws.connected()
    });
    let (_second, _, _) = server_with(press_path(0.0), opts);
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    let before = ws.stats().cursors;
    wait_for(
        "cursors from the new session",
        Duration::from_secs(5),
        || ws.stats().cursors > before + 200,
    );
    assert_eq!(ws.stats().sessions, 2);
    ws.finish().unwrap();
}

fn write_scene(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        format!(
            "[[object]]\nname = \"ball\"\ngenerate = {{ shape = \"sphere\", size = {RADIUS}, points = 2000, seed = 2 }}\n\
             [region]\nobject = \"ball\"\n{TOP_HALF}\n"
        ),
    )
    .unwrap();
    path
}

#[test]
fn a_killed_workstation_process_fades_to_zero_and_the_next_is_accepted() {
    let _slot = e2e_tests::wall_clock_slot();
    let dir = tempfile::tempdir().unwrap();
    let opts = ServerOptions::for_tests(TransportKind::Udp).unwrap();
    let (cert, key) = (dir.path().join("cert.pem"), dir.path().join("key.pem"));
    haptics_server::tls::write_pem(&opts.identity, &cert, &key).unwrap();
    // The authorized client identity beside the certificate, where a server writes it on
    // first start: the workstation process finds it there with no flag.
    let client = opts.local_client.clone().unwrap();
    haptics_server::tls::write_pem(
        &client,
        &dir.path().join("client.pem"),
        &dir.path().join("client.key"),
    )
    .unwrap();
    let (server, monitor, cfg) = server_with(press_path(0.006), opts);
    let scene = write_scene(dir.path());
    let mut cmd = Command::new(binary("workstation"));
    cmd.args(["run", "--server", &cfg.server.to_string(), "--cert"])
        .arg(&cert)
        .arg("--scene")
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("out"))
        .args(["--seconds", "60"]);
    let mut child = ChildGuard::spawn(cmd);
    wait_for(
        "force from the workstation process",
        Duration::from_secs(30),
        || monitor.last_force().length() > 0.3,
    );
    // Killed, no Bye: the model expires, the watchdog fades the force to zero.
    let mut proc = child.0.take().unwrap();
    proc.kill().unwrap();
    proc.wait().unwrap();
    wait_for("the force to fade to zero", Duration::from_secs(2), || {
        monitor.last_force().length() < 1e-4
    });
    // The session ends at the idle timeout; the next workstation gets one.
    let scene = SceneFile::parse(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    let ws = Workstation::start(&scene, ".".into(), cfg, None).unwrap();
    ws.wait_connected(Duration::from_secs(10)).unwrap();
    wait_for(
        "force from the next workstation",
        Duration::from_secs(10),
        || monitor.last_force().length() > 0.3,
    );
    ws.finish().unwrap();
    drop(server);
}

#[test]
fn a_bad_scene_file_names_its_field() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&scene, format!("{text}[tools.rope]\nstiffness = -5.0\n")).unwrap();
    let out = Command::new(binary("workstation"))
        .args([
            "run",
            "--server",
            "127.0.0.1:9",
            "--cert",
            "missing.pem",
            "--scene",
        ])
        .arg(&scene)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("tools.rope.stiffness") && err.contains("positive"),
        "{err}"
    );
}
