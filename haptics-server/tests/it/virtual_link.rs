//! The whole exchange on a virtual clock, no sockets, no sleeping: the servo core and the fake
//! hand (closed loop) at 1 kHz, a "workstation" answering every cursor with a wall model, and
//! a [`SimLink`] each way with latency and seeded loss. Shows the point of local models: the wall
//! is rendered at the *current* position, so a 20 ms round trip does not destabilise contact.

use glam::Vec3;
use haptics_server::device::Device;
use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
use haptics_server::servo::{ServoCore, ServoParams, SessionEvent};
use protocol::{CursorSample, ForceCommand, LinkParams, LocalModel, ModelKind, SimLink};

const MS: u64 = 1_000_000;
const K_WALL: f32 = 500.0;

struct Run {
    /// (t_ns, stylus y, output force y) per tick.
    trace: Vec<(u64, f32, f32)>,
    max_force: f32,
}

/// Press into the wall y = 0 (cycle: 0.2 s down, 1 s hold, 0.2 s up, 0.2 s rest) for `ticks`
/// ms; `latency` one way; `loss` in [0, 1); commands stop during `outage` (ms range).
fn run(latency_ms: u64, loss: f64, outage: std::ops::Range<u64>, ticks: u64) -> Run {
    let mut dev = FakeDevice::new(FakeParams {
        path: HandPath::Press {
            at: Vec3::new(0.0, 0.01, 0.0),
            depth: 0.02,
            approach_s: 0.2,
            hold_s: 1.0,
        },
        tremor_m: 0.0,
        ..FakeParams::default()
    });
    let mut core = ServoCore::new(ServoParams::omni_at_1khz());
    core.on_event(0, SessionEvent::Start);
    let wall = |c: &CursorSample| ForceCommand {
        force: Vec3::Y * (K_WALL * -c.position.y).max(0.0),
        torque: None,
        answers_sequence: c.servo_tick,
        answers_timestamp_ns: 0,
        model: LocalModel {
            kind: ModelKind::Plane,
            point: Vec3::new(c.position.x, 0.0, c.position.z),
            normal: Vec3::Y,
            stiffness: K_WALL,
            damping: 0.0,
            friction: 0.0,
            validity_radius: 0.05,
            lifetime_us: 100_000,
        },
    };
    // One seeded link each way (the same loss both ways, independent streams).
    let link = |seed| LinkParams {
        loss,
        seed,
        ..LinkParams::delay(latency_ms * MS)
    };
    let mut up: SimLink<CursorSample> = SimLink::new(link(1));
    let mut down: SimLink<ForceCommand> = SimLink::new(link(2));
    let mut out = Run {
        trace: Vec::new(),
        max_force: 0.0,
    };
    for tick in 1..=ticks {
        let now = tick * MS;
        for cmd in down.deliver(now) {
            core.on_command(now, cmd);
        }
        let s = dev.read(now).unwrap();
        let o = core.tick(now, &s);
        dev.write_force(o.safety.force).unwrap();
        out.max_force = out.max_force.max(o.safety.force.length());
        out.trace.push((now, s.position.y, o.safety.force.y));
        up.send(now, o.cursor);
        // The workstation answers what reached it, unless in the outage.
        for c in up.deliver(now) {
            if !outage.contains(&tick) {
                down.send(now, wall(&c));
            }
        }
    }
    out
}

/// Mean and spread of stylus y and force y over `ms` range.
fn window(r: &Run, ms: std::ops::Range<u64>) -> (f32, f32, f32) {
    let pts: Vec<_> = r
        .trace
        .iter()
        .filter(|(t, ..)| ms.contains(&(t / MS)))
        .collect();
    let n = pts.len() as f32;
    let y = pts.iter().map(|p| p.1).sum::<f32>() / n;
    let f = pts.iter().map(|p| p.2).sum::<f32>() / n;
    let spread = pts.iter().map(|p| (p.2 - f).abs()).fold(0.0, f32::max);
    (y, f, spread)
}

#[test]
fn contact_settles_at_the_hand_wall_balance_despite_latency_and_loss() {
    // Hand aims 10 mm below the wall through a 200 N/m grip: the balance is
    // y = −10 mm · 200 / (200 + 500) = −2.857 mm, force 500 · 2.857 mm = 1.43 N.
    for (latency, loss) in [(0, 0.0), (20, 0.0), (20, 0.3)] {
        let r = run(latency, loss, 0..0, 1400);
        let (y, f, spread) = window(&r, 500..1100);
        assert!(
            (y + 0.002857).abs() < 0.0002,
            "latency {latency} loss {loss}: y {y}"
        );
        assert!(
            (f - 1.4286).abs() < 0.1,
            "latency {latency} loss {loss}: F {f}"
        );
        assert!(spread < 0.05, "steady, not oscillating: ±{spread} N");
        assert!(r.max_force <= 3.3 + 1e-5);
    }
}

#[test]
fn an_outage_fades_the_force_and_never_kicks_back_while_deep() {
    // Commands stop from 600 ms to 700 ms (one-way latency 5 ms).
    let r = run(5, 0.0, 600..700, 2600);
    let at = |ms: u64| r.trace[(ms - 1) as usize];
    assert!(at(600).2 > 1.0, "in contact before: {:?}", at(600));
    // The last command arrives ~605 ms; fade starts 20 ms later, zero by 30 ms.
    assert_eq!(at(640).2, 0.0);
    // Commands resume at ~705 ms, but the hand holds the stylus 10 mm deep, where the wall
    // would push 3.3 N: the output stays off (engage only when small) instead of kicking.
    let deep = window(&r, 800..1200);
    assert!(
        deep.0 < -0.009 && deep.1 == 0.0,
        "no kick while deep: {deep:?}"
    );
    // The hand lifts out (1.2–1.4 s), the output re-engages, and the next press
    // (hold from 1.8 s) settles at the balance again.
    let back = window(&r, 2100..2500);
    assert!(
        (back.0 + 0.002857).abs() < 0.0002,
        "contact resumed: {back:?}"
    );
    let jumps = r
        .trace
        .windows(2)
        .map(|w| (w[1].2 - w[0].2).abs())
        .fold(0.0, f32::max);
    assert!(jumps <= 0.2 + 1e-4, "slew-limited everywhere: {jumps}");
}
