//! The delay study on a surface that moves: the same closed loop as [`super::sim`] (fake hand,
//! the server's [`ServoCore`], a [`SimLink`] each way, the real [`ForceMapper`]), but the
//! workstation side is the live simulation itself: a [`SimCore`] stepping the sculpting
//! region's dynamic field at 1 kHz from the cursors as they arrive, publishing the field and
//! the probe's surface samples the force mapper reads, exactly as `workstation run` does on its
//! simulation and force threads (here in one deterministic loop on a virtual clock).
//!
//! Two strokes on the top of a 5 cm ball ([`Sculpt`]): a shaped probe pressed 12 mm into it
//! (the surface gives way under the probe while the plane the server renders goes stale), and
//! a rope that grabs it and pulls it 18 mm out (the anchor moves as the bump rises). Each run
//! ends with the stroke committed, so its final field is the sculpted shape; the depth error
//! compares that shape with the same method's run without delay.
//!
//! Per 1 ms tick, in this order: commands due are handed to the core (reordered ones
//! superseded); the device is read; the core ticks and its force is written; the cursor goes
//! on the uplink; cursors due at the workstation (reordered ones refused) are mapped (on the field and samples published last) and fed to the simulation
//! as input events, their commands going on the downlink; the simulation steps once, publishes
//! its field, lets the points follow every [`FOLLOW_EVERY`] steps and rebuilds the probe's
//! samples every 20 ms while probing (and at a release), as its thread does.

use std::sync::Arc;

use anyhow::Context as _;
use glam::{DVec3, Vec3};
use haptics_server::device::Device;
use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
use haptics_server::servo::{ServoCore, SessionEvent};
use protocol::{ForceCommand, LinkParams, LocalModel, SequenceTracker, SimLink};
use sim_core::grid::ScalarGrid;
use sim_core::probe::SampleGrid;

use super::sim::{Method, PERIOD_NS, server_applies, servo_params};
use crate::live::force::ForceMapper;
use crate::live::scene_file::SceneFile;
use crate::live::shared::ForceTool;
use crate::live::sim::{FOLLOW_EVERY, SimCore};

/// Probe samples are rebuilt this often while the probe sculpts, ticks (the simulation
/// thread's 20 ms).
const SAMPLES_EVERY_TICKS: u64 = 20;
/// Radius of the ball the strokes sculpt, m (centred at the scene origin; the device origin is
/// its top).
pub const BALL_RADIUS_M: f64 = 0.05;

/// Which stroke a live run makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sculpt {
    /// `probe_push`: an 8 mm probe pressed 12 mm into the ball, held, lifted.
    ProbePress,
    /// `rope`: grab the top of the ball, pull 18 mm out, hold, let go.
    RopePull,
}

impl Sculpt {
    /// Both, in the study's order.
    pub const ALL: [Sculpt; 2] = [Sculpt::ProbePress, Sculpt::RopePull];

    /// The short name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Sculpt::ProbePress => "probe_press",
            Sculpt::RopePull => "rope_pull",
        }
    }

    fn tool(self) -> &'static str {
        match self {
            Sculpt::ProbePress => "probe_push",
            Sculpt::RopePull => "rope",
        }
    }

    /// The hand's script (device frame, m; the device origin is the top of the ball, +y out
    /// of it), with the button: (s, target, buttons).
    pub fn hand_script(self) -> Vec<(f32, Vec3, u16)> {
        let y = |y: f32| Vec3::new(0.0, y, 0.0);
        match self {
            // The probe (8 mm radius) starts 4 mm clear of the surface, is pressed toward
            // 12 mm below it at 10 mm/s (the centre 4 mm into the ball), held, let go there (the
            // carve is committed at the release, as a user carves), and lifted.
            Sculpt::ProbePress => vec![
                (0.0, y(0.012), 0),
                (0.2, y(0.012), 1),
                (1.8, y(-0.004), 1),
                (2.6, y(-0.004), 1),
                (2.7, y(-0.004), 0),
                (3.5, y(0.012), 0),
                (SCRIPT_S as f32, y(0.012), 0),
            ],
            // The tip rests 1 mm above the surface, grabs it, pulls 18 mm out at 15 mm/s,
            // holds, and lets go there.
            Sculpt::RopePull => vec![
                (0.0, y(0.001), 0),
                (0.2, y(0.001), 1),
                (1.4, y(0.019), 1),
                (2.6, y(0.019), 1),
                (2.7, y(0.019), 0),
                (SCRIPT_S as f32, y(0.019), 0),
            ],
        }
    }

    /// The scene: the ball, its sculpting region around the top, the tool selected, the
    /// device's origin at the top.
    pub fn scene(self) -> anyhow::Result<SceneFile> {
        SceneFile::parse(&format!(
            r#"
[device]
translation = [0.0, {r}, 0.0]
[[object]]
name = "ball"
generate = {{ shape = "sphere", size = {r}, points = 2000, seed = 2 }}
[region]
object = "ball"
min = [-0.035, 0.015, -0.035]
max = [0.035, 0.08, 0.035]
spacing = 0.0025
band = 0.008
dt = 0.001
[tools]
selected = "{tool}"
rope = {{ radius = 0.012, stiffness = 60.0, max_force = 3.0 }}
"#,
            r = BALL_RADIUS_M,
            tool = self.tool(),
        ))
        .context("the live delay study's scene")
    }
}

/// Length of both scripts, s.
pub const SCRIPT_S: f64 = 3.8;

/// One live run's conditions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveSpec {
    /// The stroke.
    pub sculpt: Sculpt,
    /// Rendering method.
    pub method: Method,
    /// The link, both directions.
    pub link: LinkParams,
    /// EWMA `α` for [`Method::Ewma`].
    pub ewma_alpha: f32,
}

/// What one live run produced.
#[derive(Debug, Clone)]
pub struct LiveTrace {
    /// Output force per tick, N (device frame).
    pub force: Vec<Vec3>,
    /// Energy the device delivered to the hand, J (`Σ F·Δx`; > 0: generated).
    pub energy_delivered_j: f64,
    /// The passivity observer's largest in-contact deficit, J (≤ 0).
    pub observer_min_j: f64,
    /// Energy the passivity controller dissipated, J.
    pub pc_dissipated_j: f64,
    /// Ticks on which the watchdog began to fade.
    pub fades: u64,
    /// The committed shape's height on the stroke's axis (x = z = 0) above the ball's top, m
    /// (< 0: a dent).
    pub height_m: f64,
    /// The committed field (the region grid after the release).
    pub field: Arc<ScalarGrid>,
    /// Simulation steps.
    pub sim_steps: u64,
    /// Strokes the simulation committed (1 when the press and release both arrived).
    pub strokes: usize,
    /// Packets lost on both links.
    pub lost: u64,
}

/// Run one live configuration.
pub fn simulate_live(spec: &LiveSpec) -> anyhow::Result<LiveTrace> {
    let scene = spec.sculpt.scene()?;
    // Every run loads the same scene: its "scene loaded and fitted" line, 150 times over,
    // would bury the progress bar.
    let mut sim = tracing::dispatcher::with_default(&tracing::Dispatch::none(), || {
        SimCore::new(&scene, ".".into())
    })?;
    let mut mapper = ForceMapper::new(&scene)?;
    let mut dev = FakeDevice::new(FakeParams {
        path: HandPath::Recorded(spec.sculpt.hand_script().into()),
        tremor_m: 0.0,
        ..FakeParams::default()
    });
    let mut core = ServoCore::new(servo_params(spec.method, spec.ewma_alpha));
    core.on_event(0, SessionEvent::Start);
    let mut up = SimLink::new(LinkParams {
        seed: protocol::sim_link::splitmix64(spec.link.seed),
        ..spec.link
    });
    let mut down: SimLink<(u32, ForceCommand)> = SimLink::new(LinkParams {
        seed: protocol::sim_link::splitmix64(spec.link.seed ^ 0xD0),
        ..spec.link
    });
    let ticks = (SCRIPT_S * 1e3).round() as u64;
    let mut force = Vec::with_capacity(ticks as usize);
    let mut energy = 0.0;
    let mut fades = 0;
    let mut last: Option<(Vec3, Vec3)> = None;
    let (mut sent, mut arrivals) = (0u32, SequenceTracker::new());
    let mut field = sim.publish_field().context("the scene has a region")?;
    let mut samples: Option<SampleGrid> = sim.samples();
    let mut tool = sim.force_tool();
    for tick in 1..=ticks {
        let now = tick * PERIOD_NS;
        for (seq, cmd) in down.deliver(now) {
            if server_applies(&mut arrivals, seq) {
                core.on_command(now, cmd);
            }
        }
        let s = dev.read(now).context("fake device")?;
        if let Some((x0, f0)) = last {
            energy += f64::from(f0.dot(s.position - x0));
        }
        let out = core.tick(now, &s);
        let f = out.safety.force;
        dev.write_force(f).context("fake device")?;
        fades += u64::from(out.safety.fade_started);
        force.push(f);
        last = Some((s.position, f));
        up.send(now, out.cursor);
        let strokes = sim.strokes().len();

        for c in up.deliver(now) {
            if !mapper.admit(&c) {
                continue;
            }
            let (output, event) = mapper.tick(&c, Some(&field), samples.as_ref(), &tool);
            sim.input(&event)?;
            let mut cmd: ForceCommand = output.to_command(c.servo_tick, 0);
            if !spec.method.sends_model() {
                cmd.model = LocalModel {
                    lifetime_us: cmd.model.lifetime_us,
                    ..LocalModel::default()
                };
            }
            sent += 1;
            down.send(now, (sent, cmd));
        }
        sim.step(1e-3)?;
        if let Some(g) = sim.publish_field() {
            field = g;
        }
        tool = sim.force_tool();
        if sim.steps().is_multiple_of(FOLLOW_EVERY) {
            sim.follow()?;
        }
        let probing = sim.engaged() && matches!(tool, ForceTool::Probe(_));
        if sim.strokes().len() > strokes || (probing && tick % SAMPLES_EVERY_TICKS == 0) {
            samples = sim.samples();
        }
    }
    let p = core.passivity();
    let (u, d) = (up.counters(), down.counters());
    Ok(LiveTrace {
        force,
        energy_delivered_j: energy,
        observer_min_j: p.min_energy_j(),
        pc_dissipated_j: p.dissipated_j(),
        fades,
        height_m: height_on_axis(&field)? - BALL_RADIUS_M,
        field,
        sim_steps: sim.steps(),
        strokes: sim.strokes().len(),
        lost: u.lost + d.lost,
    })
}

/// Where the field's zero set crosses the +y axis (x = z = 0), m: bisection between the
/// region's bottom (inside) and top (outside), to 1 µm.
fn height_on_axis(g: &ScalarGrid) -> anyhow::Result<f64> {
    let value = |y: f64| g.sample(DVec3::new(0.0, y, 0.0)).map(|s| s.value);
    let spec = g.spec();
    let (mut lo, mut hi) = (spec.origin.y + 1e-9, spec.max_corner().y - 1e-9);
    let (a, b) = (value(lo), value(hi));
    anyhow::ensure!(
        a.is_some_and(|a| a < 0.0) && b.is_some_and(|b| b > 0.0),
        "the sculpted field does not cross zero on the stroke's axis ({a:?} … {b:?})"
    );
    while hi - lo > 1e-6 {
        let m = 0.5 * (lo + hi);
        if value(m).is_some_and(|v| v < 0.0) {
            lo = m;
        } else {
            hi = m;
        }
    }
    Ok(0.5 * (lo + hi))
}

/// Largest difference between two committed fields where either is near its zero set (within
/// `near` m), m: how far apart the two sculpted surfaces are anywhere in the region.
pub fn shape_difference(a: &ScalarGrid, b: &ScalarGrid, near: f64) -> f64 {
    a.values()
        .iter()
        .zip(b.values())
        .filter(|(x, y)| x.abs() < near || y.abs() < near)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    //! Each run is ~1 s of compute in the `ci` profile; the numbers in comments are what the
    //! assertions measured.

    use super::*;
    use crate::delay_study::{ENERGY_TOLERANCE_J, rms_error};

    fn run(sculpt: Sculpt, method: Method, link: LinkParams) -> LiveTrace {
        simulate_live(&LiveSpec {
            sculpt,
            method,
            link,
            ewma_alpha: super::super::sim::EWMA_ALPHA,
        })
        .unwrap()
    }

    fn delay(ms: u64) -> LinkParams {
        LinkParams::delay(ms * 1_000_000)
    }

    #[test]
    fn both_strokes_sculpt_and_the_stretched_rope_is_felt_through_its_model() {
        // Without delay: the probe leaves a dent (measured −7.83 mm), the rope a bump
        // (+4.71 mm), each committed once.
        let probe = run(Sculpt::ProbePress, Method::LocalModel, delay(0));
        assert!(probe.height_m < -0.005, "{}", probe.height_m);
        let zoh = run(Sculpt::RopePull, Method::Zoh, delay(0));
        let model = run(Sculpt::RopePull, Method::LocalModel, delay(0));
        for t in [&probe, &zoh, &model] {
            assert_eq!((t.strokes, t.fades), (1, 0));
        }
        assert!(zoh.height_m > 0.003, "{}", zoh.height_m);
        // The server renders the rope's anchor model as the workstation computes the spring
        // (before the model's validity covered the stretch, it rendered zero past 4 mm).
        let peak = |t: &LiveTrace| t.force.iter().map(|f| f.length()).fold(0.0, f32::max);
        assert!(peak(&model) > 0.4, "{}", peak(&model));
        let e = rms_error(&model.force, &zoh.force);
        assert!(e < 0.005, "local model vs held force, no delay: {e} N RMS");
    }

    #[test]
    fn a_jittered_link_neither_adds_nor_loses_a_stroke() {
        // 10 ms of jitter reorders packets: a cursor the network held back must not replay an
        // old button state (which released and pressed again: two strokes, a 0.15 mm taller
        // bump) nor its command replace a newer one.
        let clean = run(Sculpt::RopePull, Method::LocalModel, delay(20));
        let jittered = run(
            Sculpt::RopePull,
            Method::LocalModel,
            LinkParams {
                jitter_ns: 10_000_000,
                ..delay(20)
            },
        );
        assert_eq!(jittered.strokes, 1);
        assert!(
            (jittered.height_m - clean.height_m).abs() < 2e-5,
            "{} vs {}",
            jittered.height_m,
            clean.height_m
        );
        assert!(shape_difference(&jittered.field, &clean.field, 0.004) < 1e-4);
    }

    #[test]
    fn at_100_ms_the_held_force_adds_energy_and_the_local_model_does_not() {
        // Pressing into the surface as it gives way, then lifting out of the committed dent:
        // the held force adds 1.08 mJ over its own run without delay, the local model takes
        // 4.1 mJ out; the sculpted depth moves by at most 0.01 mm either way.
        for m in [Method::Zoh, Method::LocalModel] {
            let base = run(Sculpt::ProbePress, m, delay(0));
            let late = run(Sculpt::ProbePress, m, delay(100));
            let added = late.energy_delivered_j - base.energy_delivered_j;
            if m == Method::Zoh {
                assert!(added > ENERGY_TOLERANCE_J, "{m:?}: {added} J");
            } else {
                assert!(added <= 0.0, "{m:?}: {added} J");
            }
            assert!((late.height_m - base.height_m).abs() < 5e-5, "{m:?}");
            assert_eq!((late.strokes, late.fades), (1, 0));
        }
    }

    #[test]
    fn same_inputs_same_numbers() {
        let link = LinkParams {
            loss: 0.2,
            jitter_ns: 5_000_000,
            ..delay(20)
        };
        let a = run(Sculpt::ProbePress, Method::LocalModelPassivity, link);
        let b = run(Sculpt::ProbePress, Method::LocalModelPassivity, link);
        assert_eq!(a.force, b.force);
        assert_eq!(a.field.values(), b.field.values());
    }
}
