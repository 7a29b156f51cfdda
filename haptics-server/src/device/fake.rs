//! `fake`: a simulated stylus held by a simulated hand, closed loop with the server's force.
//!
//! The hand is a point following a scripted [`HandPath`]; it holds the stylus (mass `m`)
//! through a spring-damper (`k_h`, `b_h`). The force the server writes acts on the stylus too,
//! so a rendered wall really stops the stylus: `m·a = k_h·(p_hand − x) − b_h·v + F_device`.
//! Integration is semi-implicit Euler in sub-steps of at most 0.25 ms, driven only by the
//! `now_ns` the servo loop passes to [`Device::read`], so the same seed and the same sequence of
//! `now` values give bit-identical trajectories. A seeded tremor (xorshift, no allocation) adds
//! realism. A [`FakeMonitor`] lets tests observe the force written, lock-free.
//! [`FakeParams::axes`] simulates a device whose force axes are swapped or inverted (the
//! force acts along the mapped axes; the monitor still shows the force as written).

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use glam::{Quat, Vec3};

use super::axes::AxisMap;
use super::{Device, DeviceError, DeviceInfo, DeviceSample};

/// Where the simulated hand goes.
#[derive(Debug, Clone, PartialEq)]
pub enum HandPath {
    /// Stay at a point.
    Idle {
        /// Where, m.
        at: Vec3,
    },
    /// A horizontal circle (x–z plane around `center`).
    Circle {
        /// Centre, m.
        center: Vec3,
        /// Radius, m.
        radius: f32,
        /// Seconds per revolution.
        period_s: f32,
    },
    /// Back and forth between two points (cosine-eased).
    Line {
        /// Start, m.
        from: Vec3,
        /// End, m.
        to: Vec3,
        /// Seconds for one there-and-back.
        period_s: f32,
    },
    /// Press into a surface below `at` along −y, hold, release; repeats; button 0 while pressing.
    Press {
        /// Start point above the surface, m.
        at: Vec3,
        /// How far the hand aims below `at`, m.
        depth: f32,
        /// Seconds to go down (and up).
        approach_s: f32,
        /// Seconds held at depth.
        hold_s: f32,
    },
    /// A recorded or scripted path: `(t_s, position, buttons)`, positions linearly
    /// interpolated, buttons held from one point to the next; looped.
    Recorded(Arc<[(f32, Vec3, u16)]>),
}

impl HandPath {
    /// Parse a recorded path file: lines `t_s x y z [buttons]` (whitespace or commas), `#`
    /// comments, times strictly increasing; `buttons` (a bit mask, bit 0 = primary, default 0)
    /// holds until the next line, so a script can press and release the stylus button
    /// (`workstation demo` writes such files).
    pub fn load(path: &Path) -> Result<HandPath, DeviceError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| DeviceError::Parse {
            file: file.clone(),
            line: 0,
            reason: e.to_string(),
        })?;
        let mut points: Vec<(f32, Vec3, u16)> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |reason: String| DeviceError::Parse {
                file: file.clone(),
                line: i + 1,
                reason,
            };
            let v: Vec<f32> = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| s.parse::<f32>().map_err(|e| bad(format!("{s:?}: {e}"))))
                .collect::<Result<_, _>>()?;
            let (t, x, y, z, b) = match v[..] {
                [t, x, y, z] => (t, x, y, z, 0.0),
                [t, x, y, z, b] => (t, x, y, z, b),
                _ => {
                    return Err(bad(format!(
                        "expected 4 or 5 numbers (t x y z [buttons]), got {}",
                        v.len()
                    )));
                }
            };
            if !v.iter().all(|f| f.is_finite()) {
                return Err(bad("non-finite value".into()));
            }
            if !(b >= 0.0 && b <= f32::from(u16::MAX) && b.fract() == 0.0) {
                return Err(bad(format!("buttons {b} is not a 16-bit mask")));
            }
            if points.last().is_some_and(|&(t0, _, _)| t <= t0) {
                return Err(bad("time must increase".into()));
            }
            points.push((t, Vec3::new(x, y, z), b as u16));
        }
        if points.is_empty() {
            return Err(DeviceError::Parse {
                file,
                line: 0,
                reason: "no points".into(),
            });
        }
        Ok(HandPath::Recorded(points.into()))
    }

    /// Hand position and buttons at `t` seconds.
    pub fn at(&self, t: f64) -> (Vec3, u16) {
        use std::f64::consts::TAU;
        match self {
            HandPath::Idle { at } => (*at, 0),
            HandPath::Circle {
                center,
                radius,
                period_s,
            } => {
                let a = TAU * t / f64::from(period_s.max(1e-3));
                let off = Vec3::new(a.cos() as f32, 0.0, a.sin() as f32) * *radius;
                (*center + off, 0)
            }
            HandPath::Line { from, to, period_s } => {
                let a = TAU * t / f64::from(period_s.max(1e-3));
                let s = (0.5 - 0.5 * a.cos()) as f32;
                (from.lerp(*to, s), 0)
            }
            HandPath::Press {
                at,
                depth,
                approach_s,
                hold_s,
            } => {
                let (ap, hold) = (f64::from(approach_s.max(1e-3)), f64::from(hold_s.max(0.0)));
                let cycle = 2.0 * ap + hold + ap; // down, hold, up, rest
                let u = t.rem_euclid(cycle);
                let s = if u < ap {
                    u / ap
                } else if u < ap + hold {
                    1.0
                } else if u < 2.0 * ap + hold {
                    1.0 - (u - ap - hold) / ap
                } else {
                    0.0
                };
                let pressing = u < 2.0 * ap + hold && s > 0.0;
                (*at - Vec3::Y * (*depth * s as f32), u16::from(pressing))
            }
            HandPath::Recorded(points) => {
                let end = points.last().map_or(0.0, |p| p.0);
                let t = if end > 0.0 {
                    t.rem_euclid(f64::from(end))
                } else {
                    0.0
                } as f32;
                let i = points.partition_point(|p| p.0 <= t);
                match (i.checked_sub(1).map(|j| points[j]), points.get(i)) {
                    (Some((t0, a, buttons)), Some(&(t1, b, _))) => {
                        (a.lerp(b, (t - t0) / (t1 - t0)), buttons)
                    }
                    (Some((_, a, buttons)), None) => (a, buttons),
                    (None, Some(&(_, a, _))) => (a, 0),
                    (None, None) => (Vec3::ZERO, 0),
                }
            }
        }
    }
}

/// Parameters of the simulated hand and stylus.
#[derive(Debug, Clone, PartialEq)]
pub struct FakeParams {
    /// The hand's path.
    pub path: HandPath,
    /// Tremor seed.
    pub seed: u64,
    /// Stylus effective mass, kg.
    pub mass_kg: f32,
    /// Hand grip stiffness, N/m.
    pub hand_stiffness: f32,
    /// Hand grip damping, N·s/m.
    pub hand_damping: f32,
    /// Tremor amplitude (hand position noise), m.
    pub tremor_m: f32,
    /// What the device reports about itself.
    pub info: DeviceInfo,
    /// Where the written force really acts (a simulated wiring or driver error; identity for
    /// a correct device). Positions are reported truly.
    pub axes: AxisMap,
}

impl Default for FakeParams {
    fn default() -> Self {
        Self {
            path: HandPath::Idle { at: Vec3::ZERO },
            seed: 1,
            mass_kg: 0.05,
            hand_stiffness: 200.0,
            hand_damping: 5.0,
            tremor_m: 2e-5,
            info: DeviceInfo::phantom_class("fake stylus (simulated hand)"),
            axes: AxisMap::IDENTITY,
        }
    }
}

/// What tests can observe of a fake device from another thread.
#[derive(Debug, Default)]
pub struct FakeMonitor {
    force: [AtomicU32; 3],
    writes: AtomicU64,
    nonzero_writes: AtomicU64,
    nonfinite_writes: AtomicU64,
}

impl FakeMonitor {
    /// The last force written.
    pub fn last_force(&self) -> Vec3 {
        let f = |i: usize| f32::from_bits(self.force[i].load(Ordering::Acquire));
        Vec3::new(f(0), f(1), f(2))
    }
    /// Forces written so far.
    pub fn writes(&self) -> u64 {
        self.writes.load(Ordering::Acquire)
    }
    /// Non-zero forces written so far.
    pub fn nonzero_writes(&self) -> u64 {
        self.nonzero_writes.load(Ordering::Acquire)
    }
    /// Non-finite forces written so far (must stay 0).
    pub fn nonfinite_writes(&self) -> u64 {
        self.nonfinite_writes.load(Ordering::Acquire)
    }
}

/// The simulated device; see the module doc.
#[derive(Debug)]
pub struct FakeDevice {
    params: FakeParams,
    x: Vec3,
    v: Vec3,
    force: Vec3,
    t0_ns: Option<u64>,
    last_ns: u64,
    rng: u64,
    tremor: Vec3,
    monitor: Arc<FakeMonitor>,
}

impl FakeDevice {
    /// A stylus resting where the hand starts.
    pub fn new(params: FakeParams) -> Self {
        let (x, _) = params.path.at(0.0);
        Self {
            rng: params.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            x,
            v: Vec3::ZERO,
            force: Vec3::ZERO,
            t0_ns: None,
            last_ns: 0,
            tremor: Vec3::ZERO,
            monitor: Arc::default(),
            params,
        }
    }

    /// Shared view of what was written.
    pub fn monitor(&self) -> Arc<FakeMonitor> {
        Arc::clone(&self.monitor)
    }

    fn noise(&mut self) -> f32 {
        // xorshift64*: deterministic, allocation-free.
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        let r = self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D);
        ((r >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    fn step(&mut self, t_s: f64, dt: f32) {
        let (hand, _) = self.params.path.at(t_s);
        // Low-pass tremor: a random walk pulled back to zero.
        let kick = Vec3::new(self.noise(), self.noise(), self.noise());
        self.tremor = self.tremor * 0.99 + kick * (self.params.tremor_m * 0.14);
        let p = &self.params;
        let f =
            p.hand_stiffness * (hand + self.tremor - self.x) - p.hand_damping * self.v + self.force;
        self.v += f / p.mass_kg.max(1e-4) * dt;
        self.x += self.v * dt;
    }
}

impl Device for FakeDevice {
    fn info(&self) -> &DeviceInfo {
        &self.params.info
    }

    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError> {
        let t0 = *self.t0_ns.get_or_insert(now_ns);
        let elapsed = now_ns.saturating_sub(self.last_ns.max(t0));
        // At most 50 ms of simulated catch-up per read; sub-steps of at most 0.25 ms.
        let mut remaining = elapsed.min(50_000_000);
        let mut t = self.last_ns.max(t0);
        while remaining > 0 {
            let h = remaining.min(250_000);
            t += h;
            self.step((t - t0) as f64 * 1e-9, h as f32 * 1e-9);
            remaining -= h;
        }
        self.last_ns = now_ns.max(self.last_ns);
        let (_, buttons) = self.params.path.at(now_ns.saturating_sub(t0) as f64 * 1e-9);
        Ok(DeviceSample {
            position: self.x,
            orientation: Quat::IDENTITY,
            velocity: self.v,
            buttons,
        })
    }

    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        let m = &self.monitor;
        if !force.is_finite() {
            m.nonfinite_writes.fetch_add(1, Ordering::AcqRel);
            self.force = Vec3::ZERO;
            return Err(DeviceError::Io("non-finite force".into()));
        }
        self.force = self.params.axes.apply(force);
        for (slot, v) in m.force.iter().zip(force.to_array()) {
            slot.store(v.to_bits(), Ordering::Release);
        }
        m.writes.fetch_add(1, Ordering::AcqRel);
        if force != Vec3::ZERO {
            m.nonzero_writes.fetch_add(1, Ordering::AcqRel);
        }
        Ok(())
    }

    fn stop(&mut self) {
        let _ = self.write_force(Vec3::ZERO);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(dev: &mut FakeDevice, ms: u64, force: Vec3) -> DeviceSample {
        let mut s = DeviceSample::default();
        for i in 0..=ms {
            s = dev.read(i * 1_000_000).unwrap();
            dev.write_force(force).unwrap();
        }
        s
    }

    #[test]
    fn a_clock_stepping_back_does_not_panic() {
        let mut dev = FakeDevice::new(FakeParams::default());
        dev.read(5_000_000).unwrap();
        // A `now` before the first read (another time base, a clock stepped back).
        let s = dev.read(1_000_000).unwrap();
        assert!(s.position.is_finite());
    }

    #[test]
    fn same_seed_same_trajectory_bit_for_bit() {
        let p = FakeParams {
            path: HandPath::Circle {
                center: Vec3::ZERO,
                radius: 0.02,
                period_s: 1.0,
            },
            ..FakeParams::default()
        };
        let a = run(&mut FakeDevice::new(p.clone()), 500, Vec3::ZERO);
        let b = run(&mut FakeDevice::new(p.clone()), 500, Vec3::ZERO);
        assert_eq!(a, b);
        let c = run(
            &mut FakeDevice::new(FakeParams { seed: 2, ..p }),
            500,
            Vec3::ZERO,
        );
        assert_ne!(a.position, c.position);
    }

    #[test]
    fn device_force_acts_back_on_the_stylus() {
        // A steady 1 N push along +x displaces the stylus by F / k_hand = 5 mm at rest.
        let p = FakeParams {
            tremor_m: 0.0,
            ..FakeParams::default()
        };
        let s = run(&mut FakeDevice::new(p), 2000, Vec3::X);
        assert!((s.position.x - 0.005).abs() < 1e-4, "{}", s.position);
    }

    #[test]
    fn mapped_axes_push_the_stylus_the_wrong_way() {
        // `-x,z,y`: a commanded +x acts along -x, +y along +z.
        let p = FakeParams {
            tremor_m: 0.0,
            axes: AxisMap::parse("-x,z,y").unwrap(),
            ..FakeParams::default()
        };
        let s = run(&mut FakeDevice::new(p.clone()), 2000, Vec3::X);
        assert!((s.position.x + 0.005).abs() < 1e-4, "{}", s.position);
        let s = run(&mut FakeDevice::new(p), 2000, Vec3::Y);
        assert!((s.position.z - 0.005).abs() < 1e-4, "{}", s.position);
    }

    #[test]
    fn circle_is_followed() {
        let p = FakeParams {
            path: HandPath::Circle {
                center: Vec3::ZERO,
                radius: 0.02,
                period_s: 2.0,
            },
            tremor_m: 0.0,
            ..FakeParams::default()
        };
        let s = run(&mut FakeDevice::new(p), 1500, Vec3::ZERO);
        let r = (s.position.x.powi(2) + s.position.z.powi(2)).sqrt();
        assert!((r - 0.02).abs() < 0.002, "radius {r}");
    }

    #[test]
    fn recorded_path_file_parses_and_interpolates() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.txt");
        std::fs::write(&f, "# t x y z\n0 0 0 0\n1, 0.01, 0, 0\n").unwrap();
        let path = HandPath::load(&f).unwrap();
        let (p, _) = path.at(0.5);
        assert!((p.x - 0.005).abs() < 1e-6);
        assert_eq!(path.at(0.5).1, 0, "no button column: released");
        std::fs::write(&f, "0 0 0\n").unwrap();
        let err = HandPath::load(&f).unwrap_err().to_string();
        assert!(
            err.contains(":1:") && err.contains("expected 4 or 5"),
            "{err}"
        );
        std::fs::write(&f, "0 0 0 0 1\n1 0 0 0 0\n2 0 0 0 0\n").unwrap();
        let path = HandPath::load(&f).unwrap();
        assert_eq!(path.at(0.5).1, 1, "pressed from t = 0 until t = 1");
        assert_eq!(path.at(1.5).1, 0, "released at t = 1");
        std::fs::write(&f, "0 0 0 0 1.5\n").unwrap();
        let err = HandPath::load(&f).unwrap_err().to_string();
        assert!(err.contains("16-bit mask"), "{err}");
    }
}
