//! Core tests on a virtual clock: every tick is `tick(now, sample)` with `now` stepped by hand.

use glam::Vec3;
use protocol::control::Config;
use protocol::{ForceCommand, LocalModel, ModelKind};

use super::core::{ServoCore, ServoParams, SessionEvent};
use super::safety::Stage;
use crate::device::DeviceSample;

const MS: u64 = 1_000_000;

fn params() -> ServoParams {
    ServoParams {
        estop_button_mask: 0b10,
        ..ServoParams::omni_at_1khz()
    }
}

fn constant(force: Vec3) -> ForceCommand {
    ForceCommand {
        force,
        torque: None,
        answers_sequence: 0,
        answers_timestamp_ns: 0,
        model: LocalModel::default(),
    }
}

fn plane(k: f32) -> ForceCommand {
    ForceCommand {
        model: LocalModel {
            kind: ModelKind::Plane,
            point: Vec3::ZERO,
            normal: Vec3::Y,
            stiffness: k,
            damping: 0.0,
            friction: 0.0,
            validity_radius: 0.05,
            lifetime_us: 10_000_000,
        },
        ..constant(Vec3::ZERO)
    }
}

fn at(y: f32) -> DeviceSample {
    DeviceSample {
        position: Vec3::new(0.0, y, 0.0),
        ..DeviceSample::default()
    }
}

/// Ticks at 1 ms from `*t` to `*t + n ms`, re-sending `cmd` every tick when given.
fn run(
    core: &mut ServoCore,
    t: &mut u64,
    n: u64,
    cmd: Option<ForceCommand>,
    s: DeviceSample,
) -> Vec3 {
    let mut f = Vec3::ZERO;
    for _ in 0..n {
        *t += MS;
        if let Some(c) = cmd {
            core.on_command(*t, c);
        }
        f = core.tick(*t, &s).safety.force;
    }
    f
}

/// A core with a session up and output engaged at `force`.
fn engaged(force: Vec3) -> (ServoCore, u64) {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    run(&mut core, &mut t, 300, Some(constant(Vec3::ZERO)), at(0.0));
    assert_eq!(core.safety().stage(), Stage::Engaged);
    run(&mut core, &mut t, 100, Some(constant(force)), at(0.0));
    (core, t)
}

#[test]
fn no_force_without_a_session() {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    let f = run(&mut core, &mut t, 50, Some(constant(Vec3::X)), at(0.0));
    assert_eq!(f, Vec3::ZERO);
    assert_eq!(core.safety().stage(), Stage::Idle);
}

#[test]
fn ramp_in_is_linear_over_the_ramp_time() {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    let cmd = Some(constant(Vec3::new(0.4, 0.0, 0.0)));
    // First tick arms the ramp (force 0.4 N ≤ 0.5 N threshold) and outputs zero.
    assert_eq!(run(&mut core, &mut t, 1, cmd, at(0.0)), Vec3::ZERO);
    let ramp_start = t;
    let f = run(&mut core, &mut t, 100, cmd, at(0.0));
    let expected = 0.4 * (t - ramp_start) as f32 / 200.0 / MS as f32;
    assert!((f.x - expected).abs() < 1e-4, "{f} vs {expected}");
    let f = run(&mut core, &mut t, 100, cmd, at(0.0));
    assert!((f.x - 0.4).abs() < 1e-6, "{f}");
    assert_eq!(core.safety().stage(), Stage::Engaged);
}

#[test]
fn engages_only_once_the_command_is_small() {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    let f = run(
        &mut core,
        &mut t,
        50,
        Some(constant(Vec3::new(2.0, 0.0, 0.0))),
        at(0.0),
    );
    assert_eq!(f, Vec3::ZERO);
    assert_eq!(core.safety().stage(), Stage::Armed);
    run(
        &mut core,
        &mut t,
        1,
        Some(constant(Vec3::new(0.1, 0.0, 0.0))),
        at(0.0),
    );
    assert!(matches!(core.safety().stage(), Stage::Ramping { .. }));
}

#[test]
fn clamp_keeps_direction() {
    let want = Vec3::new(3.0, 4.0, 0.0);
    let (mut core, mut t) = engaged(want);
    let f = run(&mut core, &mut t, 10, Some(constant(want)), at(0.0));
    assert!((f.length() - 3.3).abs() < 1e-5, "{f}");
    assert!(f.normalize().abs_diff_eq(want.normalize(), 1e-6), "{f}");
}

#[test]
fn slew_rate_is_limited() {
    let (mut core, mut t) = engaged(Vec3::ZERO);
    let mut prev = core.safety().last_force();
    let cmd = Some(constant(Vec3::new(0.0, 0.0, 3.0)));
    for _ in 0..20 {
        let f = run(&mut core, &mut t, 1, cmd, at(0.0));
        // 200 N/s × 1 ms = 0.2 N per tick.
        assert!((f - prev).length() <= 0.2 + 1e-5, "{prev} -> {f}");
        prev = f;
    }
    assert!((prev.z - 3.0).abs() < 1e-5, "reaches the target: {prev}");
}

#[test]
fn watchdog_fades_from_20_ms_to_zero_at_30_ms() {
    let (mut core, mut t) = engaged(Vec3::X);
    let last_command = t;
    let mut at_ms = |core: &mut ServoCore, ms: u64| {
        let n = (last_command + ms * MS - t) / MS;
        run(core, &mut t, n, None, at(0.0))
    };
    assert!((at_ms(&mut core, 20).x - 1.0).abs() < 1e-6);
    assert!((at_ms(&mut core, 25).x - 0.5).abs() < 1e-4);
    assert_eq!(at_ms(&mut core, 30), Vec3::ZERO);
    // Zero re-arms: the next command must ramp in again, not jump.
    assert_eq!(core.safety().stage(), Stage::Armed);
    let f = run(&mut core, &mut t, 1, Some(constant(Vec3::X)), at(0.0));
    assert_eq!(f, Vec3::ZERO);
}

#[test]
fn late_ticks_during_the_fade_still_reach_zero_on_time() {
    let (mut core, mut t) = engaged(Vec3::X);
    let last_command = t;
    run(&mut core, &mut t, 22, None, at(0.0));
    // The loop stalls from 22 to 29 ms after the last command (a loaded machine): the fade
    // asks for 0.1 N there, and a step capped at two periods would leave 0.4 N.
    t = last_command + 29 * MS;
    let f = core.tick(t, &at(0.0)).safety.force;
    assert!((f.x - 0.1).abs() < 1e-4, "{f}");
    t = last_command + 30 * MS;
    assert_eq!(core.tick(t, &at(0.0)).safety.force, Vec3::ZERO);
}

#[test]
fn a_stalled_loop_cannot_jump_to_a_new_force() {
    let (mut core, mut t) = engaged(Vec3::ZERO);
    // Commands keep arriving while the loop stalls for 15 ms; the first tick after it may
    // move only what two periods grant (0.4 N), not 15 ms' worth.
    for _ in 0..15 {
        t += MS;
        core.on_command(t, constant(Vec3::new(0.0, 3.0, 0.0)));
    }
    let f = core.tick(t, &at(0.0)).safety.force;
    assert!((f.y - 0.4).abs() < 1e-5, "{f}");
}

#[test]
fn local_model_force_is_stiffness_times_penetration() {
    let (mut core, mut t) = engaged(Vec3::ZERO);
    // Re-send the plane every tick; the cursor is 2 mm below it: 500 N/m × 2 mm = 1 N along +y.
    let f = run(&mut core, &mut t, 50, Some(plane(500.0)), at(-0.002));
    assert!((f - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-5, "{f}");
    // The model is rendered at the current position without a new command: 3 mm → 1.5 N.
    let f = run(&mut core, &mut t, 10, None, at(-0.003));
    assert!((f.y - 1.5).abs() < 1e-5, "{f}");
    // Stiffness beyond the device's 700 N/m is clamped: 2 mm → 1.4 N, not 10 N.
    let f = run(&mut core, &mut t, 50, Some(plane(5_000.0)), at(-0.002));
    assert!((f.y - 1.4).abs() < 1e-5, "{f}");
}

#[test]
fn damping_is_clamped_to_the_servers_limit() {
    let (mut core, mut t) = engaged(Vec3::ZERO);
    // An anchor at the cursor with b = 500 N·s/m and the stylus moving at 0.1 m/s along x:
    // unclamped that is 50 N of pure damping; the 5 N·s/m cap leaves 0.5 N against the motion.
    let mut cmd = plane(0.0);
    cmd.model.kind = ModelKind::Anchor;
    cmd.model.damping = 500.0;
    let moving = DeviceSample {
        velocity: Vec3::new(0.1, 0.0, 0.0),
        ..at(0.0)
    };
    let f = run(&mut core, &mut t, 50, Some(cmd), moving);
    assert!((f - Vec3::new(-0.5, 0.0, 0.0)).length() < 1e-5, "{f}");
}

#[test]
fn ewma_matches_its_closed_form() {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    let alpha = 0.9f32;
    core.on_event(
        t,
        SessionEvent::Config(Config {
            smoothing_alpha: alpha,
            ..Config::DEFAULT
        }),
    );
    let f = Vec3::new(0.3, 0.0, 0.0);
    for n in 1..=50 {
        run(&mut core, &mut t, 1, Some(constant(f)), at(0.0));
        // E_n = (1 − αⁿ)·F from E_0 = 0.
        let expected = (1.0 - alpha.powi(n)) * f.x;
        assert!(
            (core.smoothed().x - expected).abs() < 1e-5,
            "n={n}: {} vs {expected}",
            core.smoothed().x
        );
    }
}

#[test]
fn non_finite_never_reaches_the_device() {
    let (mut core, mut t) = engaged(Vec3::ZERO);
    let mut anchor = plane(500.0);
    anchor.model.kind = ModelKind::Anchor;
    let nan = DeviceSample {
        position: Vec3::NAN,
        ..DeviceSample::default()
    };
    for _ in 0..10 {
        t += MS;
        core.on_command(t, anchor);
        let out = core.tick(t, &nan);
        assert!(out.safety.force.is_finite());
        assert!(out.cursor.output_force.is_finite());
    }
}

#[test]
fn emergency_stop_zeroes_at_once_and_release_ramps_in() {
    let (mut core, mut t) = engaged(Vec3::X);
    core.on_event(t, SessionEvent::EmergencyStop(true));
    let f = run(&mut core, &mut t, 1, Some(constant(Vec3::X)), at(0.0));
    assert_eq!(f, Vec3::ZERO, "no slew on an emergency stop");
    assert!(core.tick(t + MS, &at(0.0)).cursor.estop);
    core.on_event(t, SessionEvent::EmergencyStop(false));
    assert_eq!(core.safety().stage(), Stage::Armed);
    // Button 1 (mask 0b10) latches it too.
    let (mut core, mut t) = engaged(Vec3::X);
    let pressed = DeviceSample {
        buttons: 0b10,
        ..at(0.0)
    };
    assert_eq!(
        run(&mut core, &mut t, 1, Some(constant(Vec3::X)), pressed),
        Vec3::ZERO
    );
    assert_eq!(core.safety().stage(), Stage::Stopped);
}

#[test]
fn config_force_limit_lowers_but_never_raises_the_clamp() {
    let (mut core, mut t) = engaged(Vec3::X);
    core.on_event(
        t,
        SessionEvent::Config(Config {
            force_limit_n: 0.5,
            ..Config::DEFAULT
        }),
    );
    let f = run(&mut core, &mut t, 20, Some(constant(Vec3::X)), at(0.0));
    assert!((f.x - 0.5).abs() < 1e-6, "{f}");
    core.on_event(
        t,
        SessionEvent::Config(Config {
            force_limit_n: 50.0,
            ..Config::DEFAULT
        }),
    );
    let f = run(
        &mut core,
        &mut t,
        50,
        Some(constant(Vec3::X * 10.0)),
        at(0.0),
    );
    assert!((f.x - 3.3).abs() < 1e-5, "{f}");
}

#[test]
fn session_end_drops_output_and_same_inputs_give_same_outputs() {
    let go = || {
        let (mut core, mut t) = engaged(Vec3::new(0.2, 0.1, 0.0));
        let a = run(&mut core, &mut t, 7, Some(plane(400.0)), at(-0.001));
        core.on_event(t, SessionEvent::End);
        let b = run(&mut core, &mut t, 50, Some(constant(Vec3::X)), at(0.0));
        (a, b)
    };
    let (a, b) = go();
    assert_eq!(b, Vec3::ZERO);
    assert_eq!(go(), (a, b));
}

#[test]
fn a_sessions_config_does_not_outlive_it() {
    // Session A stretches the watchdog to 1 s and turns smoothing on, then ends.
    let (mut core, mut t) = engaged(Vec3::X);
    core.on_event(
        t,
        SessionEvent::Config(Config {
            smoothing_alpha: 0.5,
            watchdog_fade_start_us: 900_000,
            watchdog_zero_us: 1_000_000,
            force_limit_n: 3.3,
        }),
    );
    core.on_event(t, SessionEvent::End);
    run(&mut core, &mut t, 50, None, at(0.0));
    // Session B starts with the server's own settings: its watchdog zeroes force at 30 ms.
    core.on_event(t, SessionEvent::Start);
    assert_eq!(*core.safety().params(), params().safety);
    run(&mut core, &mut t, 300, Some(constant(Vec3::ZERO)), at(0.0));
    assert_eq!(core.safety().stage(), Stage::Engaged);
    let f = run(&mut core, &mut t, 100, Some(constant(Vec3::X)), at(0.0));
    assert!((f.x - 1.0).abs() < 1e-6, "{f}");
    assert_eq!(run(&mut core, &mut t, 30, None, at(0.0)), Vec3::ZERO);
}

#[test]
fn smoothing_does_not_hide_a_large_command_from_the_engage_gate() {
    let mut core = ServoCore::new(params());
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    core.on_event(
        t,
        SessionEvent::Config(Config {
            smoothing_alpha: 0.9,
            ..Config::DEFAULT
        }),
    );
    // The stylus is held deep in a wall: 3 N commanded. The first smoothed value is 0.3 N,
    // below the 0.5 N threshold, but the command itself is not small: stay armed.
    let f = run(
        &mut core,
        &mut t,
        50,
        Some(constant(Vec3::new(3.0, 0.0, 0.0))),
        at(0.0),
    );
    assert_eq!(f, Vec3::ZERO);
    assert_eq!(core.safety().stage(), Stage::Armed);
}

#[test]
fn config_cannot_raise_the_clamp_above_the_servers_own_limit() {
    // The operator capped output at 1 N on a 3.3 N device (Welcome advertises 1 N).
    let mut p = params();
    p.safety.max_force_n = 1.0;
    let mut core = ServoCore::new(p);
    let mut t = 0;
    core.on_event(t, SessionEvent::Start);
    run(&mut core, &mut t, 300, Some(constant(Vec3::ZERO)), at(0.0));
    assert_eq!(core.safety().stage(), Stage::Engaged);
    core.on_event(
        t,
        SessionEvent::Config(Config {
            force_limit_n: 50.0,
            ..Config::DEFAULT
        }),
    );
    let f = run(
        &mut core,
        &mut t,
        50,
        Some(constant(Vec3::X * 3.0)),
        at(0.0),
    );
    assert!((f.x - 1.0).abs() < 1e-6, "{f}");
}

#[test]
fn releasing_an_emergency_stop_that_is_not_latched_changes_nothing() {
    let (mut core, mut t) = engaged(Vec3::X);
    core.on_event(t, SessionEvent::EmergencyStop(false));
    assert_eq!(core.safety().stage(), Stage::Engaged);
    let f = run(&mut core, &mut t, 5, Some(constant(Vec3::X)), at(0.0));
    assert!((f.x - 1.0).abs() < 1e-6, "{f}");
}

/// A stiff spring wall at y = 0 computed from the cursor `delay_ms` old and held (no model,
/// the zero-order hold of a delayed force), closed with the fake hand pressing 10 mm into it
/// (200 N/m grip): one press cycle, 1.6 s. Returns (energy the device delivered to the hand, J, the
/// observer's lowest contact energy, J, the largest force, N).
fn delayed_spring(delay_ms: u64, passivity: bool) -> (f64, f64, f32) {
    use crate::device::Device;
    use crate::device::fake::{FakeDevice, FakeParams, HandPath};
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
    let mut core = ServoCore::new(ServoParams {
        passivity,
        ..params()
    });
    core.on_event(0, SessionEvent::Start);
    let mut history = std::collections::VecDeque::new();
    let (mut delivered, mut last, mut peak) = (0.0f64, None::<(Vec3, Vec3)>, 0.0f32);
    for tick in 1..=1600u64 {
        let now = tick * MS;
        let s = dev.read(now).unwrap();
        if let Some((x0, f0)) = last {
            delivered += f64::from(f0.dot(s.position - x0));
        }
        history.push_back(s.position.y);
        if history.len() > delay_ms as usize {
            let y = history.pop_front().unwrap();
            core.on_command(now, constant(Vec3::Y * (700.0 * -y).max(0.0)));
        }
        let f = core.tick(now, &s).safety.force;
        dev.write_force(f).unwrap();
        peak = peak.max(f.length());
        last = Some((s.position, f));
    }
    (delivered, core.passivity().min_energy_j(), peak)
}

#[test]
fn passivity_control_makes_a_delayed_stiff_spring_passive() {
    // A 10 ms round trip without the controller: the held spring force lags the stylus, the
    // contact rings at the 3.3 N clamp and hands the user a quarter of a joule it never
    // received.
    let (active, deficit, peak) = delayed_spring(10, false);
    assert!(active > 0.1, "generated {active} J");
    assert!(
        deficit < -0.1 && peak >= 3.3 - 1e-5,
        "{deficit} J, {peak} N"
    );
    // With it the run is passive: what the device delivered over the press cycle is ≤ 0
    // (to 20 µJ); the observer's deficit peaks at ~2 mJ as the stylus leaves the wall and
    // is paid back by the bounded drag right after. The contact no longer reaches the clamp.
    let (passive, deficit, peak) = delayed_spring(10, true);
    assert!(passive < 2e-5, "generated {passive} J");
    assert!(deficit > -3e-3, "observed {deficit} J");
    assert!(peak < 2.5, "{peak} N");
    // Its damping is bounded (5 N·s/m here): at a 30 ms round trip it no longer keeps up,
    // though it still takes most of the excess out.
    let (late, _, _) = delayed_spring(30, true);
    let (late_off, _, _) = delayed_spring(30, false);
    assert!(
        late > 1e-3 && late < late_off / 2.0,
        "{late} vs {late_off} J"
    );
}
