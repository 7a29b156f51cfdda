//! Passivity observer and controller (Hannaford & Ryu, "Time-domain passivity control of
//! haptic interfaces", IEEE T-RA 2002) on the force the server outputs.
//!
//! **Sign convention.** `F` is the force the device applies to the stylus (what the servo
//! writes), `x` the stylus position. The observer integrates the energy flowing *into* the
//! rendered environment from the user:
//! `E_n = E_{n−1} − F_{n−1}·(x_n − x_{n−1})`,
//! which is exact for a force held constant over each period (the device's zero-order hold):
//! `F_{n−1}·(x_n − x_{n−1})` is the work the device did on the hand during that period. A
//! passive environment keeps `E ≥ 0` (a spring stores what it was given, a damper keeps it);
//! `E < 0` means the interface has put `−E` joules into the user that it never received —
//! delay, sampling or a model switching on inside the stylus.
//!
//! **Controller.** When `E_n < 0`, the next force gets an added damping `−α v` with
//! `α = min(−E_n / (T·|v|²), α_max)`: over one period at the current velocity it dissipates the
//! whole deficit, bounded by `α_max` (the server's `max_damping_n_s_per_m`: more virtual damping
//! than the device supports makes the stylus buzz). The damping it actually dissipated appears
//! in the next observation, because the observer sees the force really written (after the
//! safety stages).
//!
//! **Free space.** When the rendered force is zero (no contact, no command) nothing is stored,
//! so a positive `E` is dropped to 0 there: energy absorbed by friction or damping in one
//! contact is not banked to pay for generation in the next. A deficit is kept and paid back
//! by the same bounded damping as drag just after the contact ends (a unilateral wall that
//! returns more than it took shows the excess only as the stylus leaves it). The run-long
//! figures ([`Passivity::net_absorbed_j`], [`Passivity::min_energy_j`],
//! [`Passivity::dissipated_j`]) keep counting across contacts.
//!
//! Plain arithmetic on fixed state: no allocation, deterministic.

use glam::Vec3;

/// The observer (always running) and the controller's state; see the module doc.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Passivity {
    /// Energy into the environment since contact began, J (`< 0`: generated).
    energy_j: f64,
    /// The position and output of the previous tick, and the controller's part of it.
    last: Option<(Vec3, Vec3, Vec3)>,
    net_absorbed_j: f64,
    min_energy_j: f64,
    dissipated_j: f64,
}

impl Passivity {
    /// An observer with no history.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forget the history (a new session).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Account for the period that ended at position `x`; `in_contact` is false when the
    /// rendered force is zero (free space: a reserve is dropped, a deficit kept).
    pub fn observe(&mut self, x: Vec3, in_contact: bool) {
        if let Some((x0, f0, pc0)) = self.last {
            let dx = x - x0;
            if dx.is_finite() {
                let work = f64::from(f0.dot(dx));
                self.energy_j -= work;
                self.net_absorbed_j -= work;
                self.dissipated_j -= f64::from(pc0.dot(dx));
            }
        }
        self.min_energy_j = self.min_energy_j.min(self.energy_j);
        if !in_contact {
            self.energy_j = self.energy_j.min(0.0);
        }
    }

    /// The damping force to add this tick at velocity `v` (zero while `E ≥ 0`), bounded by
    /// `max_damping` N·s/m, for a period of `period_s`.
    pub fn control(&self, v: Vec3, period_s: f32, max_damping: f32) -> Vec3 {
        let v2 = v.length_squared();
        if self.energy_j >= 0.0 || v2 <= 0.0 || !v2.is_finite() {
            return Vec3::ZERO;
        }
        let alpha = (-self.energy_j / (f64::from(period_s) * f64::from(v2))) as f32;
        -alpha.min(max_damping.max(0.0)) * v
    }

    /// Record what was written this tick: position `x`, output force `f`, of which `pc` came
    /// from the controller.
    pub fn record(&mut self, x: Vec3, f: Vec3, pc: Vec3) {
        self.last = Some((x, f, pc));
    }

    /// Energy into the environment since the current contact began, J.
    pub fn energy_j(&self) -> f64 {
        self.energy_j
    }

    /// Net energy into the environment over the whole session, J: minus the energy the
    /// device delivered to the hand.
    pub fn net_absorbed_j(&self) -> f64 {
        self.net_absorbed_j
    }

    /// The lowest `E` observed, J (0 if never negative): the largest deficit.
    pub fn min_energy_j(&self) -> f64 {
        self.min_energy_j
    }

    /// Energy the controller's damping dissipated, J.
    pub fn dissipated_j(&self) -> f64 {
        self.dissipated_j
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spring_pressed_and_released_is_observed_passive() {
        // Continuous-time-like: press a 500 N/m spring 2 mm in 0.1 µm steps, release.
        let mut p = Passivity::new();
        let k = 500.0;
        let path = (0..=20_000)
            .chain((0..=20_000).rev())
            .map(|i| -(i as f32) * 1e-7);
        for x in path {
            let x = Vec3::Y * x;
            p.observe(x, true);
            p.record(x, Vec3::Y * (-k * x.y), Vec3::ZERO);
        }
        // Stored ½ k d² = 1 mJ at the bottom; given back on release, up to the hold error.
        assert!(p.energy_j().abs() < 1e-6, "{}", p.energy_j());
        assert!(p.min_energy_j() > -1e-6);
    }

    #[test]
    fn a_deficit_asks_for_bounded_damping_against_the_motion() {
        let mut p = Passivity::new();
        p.observe(Vec3::ZERO, true);
        p.record(Vec3::ZERO, Vec3::X, Vec3::ZERO);
        // The force pushed along +x while the stylus moved +1 mm: 1 mJ generated.
        p.observe(Vec3::X * 1e-3, true);
        assert!((p.energy_j() + 1e-3).abs() < 1e-9);
        let v = Vec3::X * 0.1;
        let f = p.control(v, 1e-3, 1e6);
        // α = 1e-3 / (1e-3 · 0.01) = 100 N·s/m.
        assert!((f + Vec3::X * 10.0).length() < 1e-3, "{f}");
        let bounded = p.control(v, 1e-3, 5.0);
        assert!((bounded + Vec3::X * 0.5).length() < 1e-6, "{bounded}");
        // Free space keeps a deficit (paid back as drag) but drops a reserve.
        p.record(Vec3::X * 1e-3, Vec3::ZERO, Vec3::ZERO);
        p.observe(Vec3::X * 1e-3, false);
        assert!((p.energy_j() + 1e-3).abs() < 1e-9);
        p.record(Vec3::X * 1e-3, -Vec3::X, Vec3::ZERO);
        p.observe(Vec3::X * 3e-3, false);
        assert_eq!(p.energy_j(), 0.0, "2 mJ absorbed, 1 mJ reserve dropped");
        assert!(p.min_energy_j() < -0.9e-3 && p.net_absorbed_j() > 0.9e-3);
    }
}
