//! One run of the delay study on a virtual clock: the fake hand, the server's [`ServoCore`],
//! a [`SimLink`] each way, and the workstation's real [`ForceMapper`] on a wall field.
//!
//! Per 1 ms tick, in this order: commands due are handed to the core (one that arrives after a
//! newer one is superseded, as the server's transport does); the device is read (the hand moves
//! under the force written last tick); the core ticks and its force is written; the cursor goes
//! on the uplink unless the cursor deadband holds it back; cursors due at the workstation are
//! mapped to commands (one older than a cursor already mapped is refused, as the force thread
//! does), which go on the downlink unless the force deadband holds them back. No clock, no thread, no sleep: the same inputs give the same
//! numbers, bit for bit.

use anyhow::Context as _;
use glam::{DVec3, Vec3};
use haptics_server::device::Device;
use haptics_server::device::fake::{FakeDevice, FakeParams, HandPath};
use haptics_server::servo::{SafetyParams, ServoCore, ServoParams, SessionEvent};
use protocol::{
    CursorDeadband, ForceCommand, ForceDeadband, LinkParams, LocalModel, SequenceTracker, SimLink,
};
use sim_core::grid::{GridSpec, ScalarGrid};

use crate::live::force::ForceMapper;
use crate::live::scene_file::{ContactSpec, SceneFile};
use crate::live::shared::ForceTool;

/// Servo period, ns (1 kHz).
pub const PERIOD_NS: u64 = 1_000_000;
/// The wall's stiffness as the workstation computes it, N/m.
pub const WALL_STIFFNESS: f64 = 2_000.0;
/// The wall's damping, N·s/m (the scene default).
pub const WALL_DAMPING: f64 = 0.5;
/// The wall's Coulomb friction (the scene default).
pub const WALL_FRICTION: f64 = 0.2;
/// The server's stiffness clamp (a Phantom-class device's usable stiffness), N/m.
pub const MAX_STIFFNESS: f32 = 700.0;
/// The server's force clamp, N.
pub const MAX_FORCE: f32 = 3.3;
/// The server's damping bound (also the passivity controller's), N·s/m.
pub const MAX_DAMPING: f32 = 5.0;
/// Default EWMA smoothing for method (b): `α = 0.5`, a 1.4 ms time constant at 1 kHz (0.9, a
/// 10 ms one, already oscillates against the 2 kN/m wall without any delay).
pub const EWMA_ALPHA: f32 = 0.5;

/// How the server renders between commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// (a) Commands without a model, the last force held (α = 0).
    Zoh,
    /// (b) Commands without a model, EWMA-smoothed (`E ← αE + (1−α)F`, α from the run).
    Ewma,
    /// (c) The local contact model rendered at the current cursor.
    LocalModel,
    /// (d) The local model plus the passivity observer/controller.
    LocalModelPassivity,
}

impl Method {
    /// All four, in the study's order.
    pub const ALL: [Method; 4] = [
        Method::Zoh,
        Method::Ewma,
        Method::LocalModel,
        Method::LocalModelPassivity,
    ];

    /// The short name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Zoh => "zoh",
            Method::Ewma => "ewma",
            Method::LocalModel => "local_model",
            Method::LocalModelPassivity => "local_model_passivity",
        }
    }

    /// Whether the commands carry the local model.
    pub fn sends_model(self) -> bool {
        matches!(self, Method::LocalModel | Method::LocalModelPassivity)
    }
}

/// One run's conditions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSpec {
    /// Rendering method.
    pub method: Method,
    /// The link, both directions (each its own seed derived from `link.seed`).
    pub link: LinkParams,
    /// Deadband Weber fraction on both streams (0 = off).
    pub deadband: f32,
    /// Simulated seconds.
    pub seconds: f64,
    /// EWMA `α` for [`Method::Ewma`].
    pub ewma_alpha: f32,
}

/// What one run produced.
#[derive(Debug, Clone)]
pub struct Trace {
    /// Output force per tick, N (device frame).
    pub force: Vec<Vec3>,
    /// Stylus position per tick, m.
    pub position: Vec<Vec3>,
    /// Energy the device delivered to the hand over the run, J (`Σ F·Δx`; > 0: the interface
    /// generated energy).
    pub energy_delivered_j: f64,
    /// The passivity observer's run-long net energy into the environment, J.
    pub observer_net_j: f64,
    /// The observer's largest in-contact deficit, J (≤ 0).
    pub observer_min_j: f64,
    /// Energy the passivity controller dissipated, J.
    pub pc_dissipated_j: f64,
    /// Cursor packets the server sent.
    pub cursors_sent: u64,
    /// Force packets the workstation sent.
    pub commands_sent: u64,
    /// Commands the server applied (after loss; duplicates and commands superseded by a newer
    /// one are not).
    pub commands_applied: u64,
    /// Longest stretch without an applied command after the first, ms.
    pub longest_command_gap_ms: u64,
    /// Ticks on which the watchdog began to fade the force.
    pub fades: u64,
    /// Packets lost, reordered, duplicated (both links).
    pub lost: u64,
    /// Packets held back by the link.
    pub reordered: u64,
    /// Extra copies.
    pub duplicated: u64,
}

/// The hand's script (device frame, m): rest 5 mm above the wall y = 0 at x = −15 mm, press
/// toward 10 mm below it at 10 mm/s, hold, slide 30 mm along +x at 15 mm/s, hold, lift,
/// rest. The hand holds the stylus through the fake device's 200 N/m, 5 N·s/m grip.
pub fn hand_script() -> Vec<(f32, Vec3, u16)> {
    let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    vec![
        (0.0, p(-0.015, 0.005), 0),
        (0.2, p(-0.015, 0.005), 1),
        (1.7, p(-0.015, -0.010), 1),
        (2.2, p(-0.015, -0.010), 1),
        (4.2, p(0.015, -0.010), 1),
        (4.5, p(0.015, -0.010), 1),
        (5.0, p(0.015, 0.005), 0),
        (5.3, p(0.015, 0.005), 0),
    ]
}

/// Length of [`hand_script`], s.
pub const SCRIPT_S: f64 = 5.3;
/// The steady part of the held press (s): the window the stability check reads.
pub const HOLD_WINDOW_S: (f64, f64) = (1.9, 2.2);

/// The wall scene the workstation maps against: the field `f = y` on a 1 mm grid, the touch
/// tool at 2 kN/m.
#[derive(Debug)]
pub struct Wall {
    mapper_scene: SceneFile,
    grid: ScalarGrid,
    tool: ForceTool,
}

impl Wall {
    /// Build the scene and its field once (shared by every run).
    pub fn new() -> anyhow::Result<Self> {
        let scene = SceneFile::parse(
            r#"
[[object]]
name = "wall"
generate = { shape = "sphere", size = 0.02, points = 100, seed = 1 }
[region]
object = "wall"
min = [-0.04, -0.03, -0.02]
max = [0.04, 0.02, 0.02]
spacing = 0.001
band = 0.004
"#,
        )
        .context("the delay study's wall scene")?;
        let spec = GridSpec::covering(
            DVec3::new(-0.04, -0.03, -0.02),
            DVec3::new(0.04, 0.02, 0.02),
            0.001,
        );
        let grid = ScalarGrid::from_fn(spec, |p| p.y);
        let tool = ForceTool::Touch(ContactSpec {
            stiffness: WALL_STIFFNESS,
            damping: WALL_DAMPING,
            friction: WALL_FRICTION,
        });
        Ok(Self {
            mapper_scene: scene,
            grid,
            tool,
        })
    }
}

/// The server's settings for `method` (the device limits above, passivity for (d)).
pub fn servo_params(method: Method, ewma_alpha: f32) -> ServoParams {
    ServoParams {
        rate_hz: 1000,
        safety: SafetyParams::default(),
        smoothing_alpha: if method == Method::Ewma {
            ewma_alpha
        } else {
            0.0
        },
        device_max_force_n: MAX_FORCE,
        max_stiffness_n_per_m: MAX_STIFFNESS,
        max_damping_n_s_per_m: MAX_DAMPING,
        estop_button_mask: 0,
        passivity: method == Method::LocalModelPassivity,
    }
}

/// Whether the server applies command packet `seq`: its transport supersedes a command that
/// arrives after a newer one (`haptics_server::transport`, `accept_hot`), as the workstation's
/// [`ForceMapper::admit`] refuses a cursor older than one it mapped.
pub fn server_applies(arrivals: &mut SequenceTracker, seq: u32) -> bool {
    matches!(
        arrivals.record(seq),
        protocol::Arrival::InOrder | protocol::Arrival::Gap { .. }
    )
}

/// Run one configuration.
pub fn simulate(wall: &Wall, spec: &RunSpec) -> anyhow::Result<Trace> {
    let mut mapper = ForceMapper::new(&wall.mapper_scene)?;
    let mut dev = FakeDevice::new(FakeParams {
        path: HandPath::Recorded(hand_script().into()),
        tremor_m: 0.0,
        ..FakeParams::default()
    });
    let mut core = ServoCore::new(servo_params(spec.method, spec.ewma_alpha));
    core.on_event(0, SessionEvent::Start);
    let seed = spec.link.seed;
    let mut up = SimLink::new(LinkParams {
        seed: protocol::sim_link::splitmix64(seed),
        ..spec.link
    });
    let mut down: SimLink<(u32, ForceCommand)> = SimLink::new(LinkParams {
        seed: protocol::sim_link::splitmix64(seed ^ 0xD0),
        ..spec.link
    });
    let mut cursor_db = CursorDeadband::new(spec.deadband);
    let mut force_db = ForceDeadband::new(spec.deadband);
    let ticks = (spec.seconds * 1e3).round() as u64;
    let mut t = Trace {
        force: Vec::with_capacity(ticks as usize),
        position: Vec::with_capacity(ticks as usize),
        energy_delivered_j: 0.0,
        observer_net_j: 0.0,
        observer_min_j: 0.0,
        pc_dissipated_j: 0.0,
        cursors_sent: 0,
        commands_sent: 0,
        commands_applied: 0,
        longest_command_gap_ms: 0,
        fades: 0,
        lost: 0,
        reordered: 0,
        duplicated: 0,
    };
    let mut last: Option<(Vec3, Vec3)> = None;
    let mut last_applied: Option<u64> = None;
    let mut arrivals = SequenceTracker::new();
    for tick in 1..=ticks {
        let now = tick * PERIOD_NS;
        for (seq, cmd) in down.deliver(now) {
            if !server_applies(&mut arrivals, seq) {
                continue;
            }
            core.on_command(now, cmd);
            t.commands_applied += 1;
            if let Some(prev) = last_applied {
                t.longest_command_gap_ms = t.longest_command_gap_ms.max(tick - prev);
            }
            last_applied = Some(tick);
        }
        let s = dev.read(now).context("fake device")?;
        if let Some((x0, f0)) = last {
            t.energy_delivered_j += f64::from(f0.dot(s.position - x0));
        }
        let out = core.tick(now, &s);
        let f = out.safety.force;
        dev.write_force(f).context("fake device")?;
        t.fades += u64::from(out.safety.fade_started);
        t.force.push(f);
        t.position.push(s.position);
        last = Some((s.position, f));
        if cursor_db.should_send(now, &out.cursor) {
            up.send(now, out.cursor);
            t.cursors_sent += 1;
        }
        for c in up.deliver(now) {
            if !mapper.admit(&c) {
                continue;
            }
            let (output, _) = mapper.tick(&c, Some(&wall.grid), None, &wall.tool);
            let mut cmd: ForceCommand = output.to_command(c.servo_tick, 0);
            if !spec.method.sends_model() {
                cmd.model = LocalModel {
                    lifetime_us: cmd.model.lifetime_us,
                    ..LocalModel::default()
                };
            }
            if force_db.should_send(now, &cmd) {
                t.commands_sent += 1;
                down.send(now, (t.commands_sent as u32, cmd));
            }
        }
    }
    let p = core.passivity();
    t.observer_net_j = p.net_absorbed_j();
    t.observer_min_j = p.min_energy_j();
    t.pc_dissipated_j = p.dissipated_j();
    let (u, d) = (up.counters(), down.counters());
    t.lost = u.lost + d.lost;
    t.reordered = u.reordered + d.reordered;
    t.duplicated = u.duplicated + d.duplicated;
    Ok(t)
}
