//! What a [`LocalModel`] means, as executable code: the force it renders at a cursor state.
//!
//! The server runs this every servo tick at the *current* cursor position; the workstation's
//! tests run the same code to check a model against the full field query. Deterministic, no
//! allocation; the only state is the friction stick point.
//!
//! - `Plane`: depth `d = (point − x)·n`. While `d > 0`, normal force `max(0, k·d − b·(v·n))·n`
//!   (it pushes out, never pulls in), plus Coulomb friction: a stick point on the plane held by
//!   a tangential spring of the same stiffness, which slides so the tangential force never
//!   exceeds `μ` × the normal force. Leaving the plane releases the stick point.
//! - `Anchor`: `k·(point − x) − b·v`, a bilateral spring (dragged material pulling back).
//! - `None`: the command's constant `force`.
//!
//! A `Plane` or `Anchor` model farther than `validity_radius` from `point`, or older than
//! `lifetime_us`, is stale and renders zero: the workstation has not described that region.

use glam::Vec3;

use crate::packet::{ForceCommand, LocalModel, ModelKind};

/// Renders [`ForceCommand`]s; keeps the friction state between ticks.
#[derive(Debug, Clone, Copy, Default)]
pub struct ModelRenderer {
    stick: Option<Vec3>,
}

impl ModelRenderer {
    /// A renderer with no contact history.
    pub const fn new() -> Self {
        Self { stick: None }
    }

    /// Forget the friction stick point (e.g. when a new model replaces the old one).
    pub fn reset(&mut self) {
        self.stick = None;
    }

    /// The force of `command` at cursor position `x` and velocity `v`, `age_us` after it
    /// arrived. Non-finite inputs give zero.
    pub fn render(&mut self, command: &ForceCommand, x: Vec3, v: Vec3, age_us: u64) -> Vec3 {
        let model = &command.model;
        let force = match model.kind {
            ModelKind::None => command.force,
            _ if !is_live(model, x, age_us) => {
                self.stick = None;
                Vec3::ZERO
            }
            ModelKind::Plane => self.plane(model, x, v),
            ModelKind::Anchor => model.stiffness * (model.point - x) - model.damping * v,
        };
        if force.is_finite() { force } else { Vec3::ZERO }
    }

    fn plane(&mut self, m: &LocalModel, x: Vec3, v: Vec3) -> Vec3 {
        let n = m.normal;
        let depth = (m.point - x).dot(n);
        if depth <= 0.0 {
            self.stick = None;
            return Vec3::ZERO;
        }
        let normal_mag = (m.stiffness * depth - m.damping * v.dot(n)).max(0.0);
        // The cursor projected onto the plane; friction acts within the plane.
        let on_plane = x + depth * n;
        let stick = self.stick.unwrap_or(on_plane);
        let stick = stick - (stick - on_plane).dot(n) * n;
        let offset = stick - on_plane;
        let limit = m.friction * normal_mag;
        let tangential = m.stiffness * offset;
        let (stick, tangential) = if tangential.length() > limit {
            // Slip: drag the stick point so the spring force sits on the friction cone.
            let dir = offset.normalize_or_zero();
            let slid = on_plane + dir * (limit / m.stiffness.max(f32::MIN_POSITIVE));
            (slid, dir * limit)
        } else {
            (stick, tangential)
        };
        self.stick = Some(stick);
        normal_mag * n + tangential
    }
}

fn is_live(model: &LocalModel, x: Vec3, age_us: u64) -> bool {
    age_us <= u64::from(model.lifetime_us) && x.distance(model.point) <= model.validity_radius
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(k: f32, b: f32, mu: f32) -> ForceCommand {
        ForceCommand {
            force: Vec3::ZERO,
            torque: None,
            answers_sequence: 0,
            answers_timestamp_ns: 0,
            model: LocalModel {
                kind: ModelKind::Plane,
                point: Vec3::ZERO,
                normal: Vec3::Z,
                stiffness: k,
                damping: b,
                friction: mu,
                validity_radius: 0.05,
                lifetime_us: 30_000,
            },
        }
    }

    #[test]
    fn plane_force_is_stiffness_times_penetration() {
        let mut r = ModelRenderer::new();
        let f = r.render(
            &plane(500.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -0.002),
            Vec3::ZERO,
            0,
        );
        assert!((f - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-6, "{f}");
    }

    #[test]
    fn plane_never_pulls() {
        let mut r = ModelRenderer::new();
        let cmd = plane(500.0, 2.0, 0.0);
        assert_eq!(
            r.render(&cmd, Vec3::new(0.0, 0.0, 0.001), Vec3::ZERO, 0),
            Vec3::ZERO
        );
        // Fast withdrawal: damping would pull, the clamp stops it.
        let f = r.render(
            &cmd,
            Vec3::new(0.0, 0.0, -0.0001),
            Vec3::new(0.0, 0.0, 10.0),
            0,
        );
        assert_eq!(f, Vec3::ZERO);
    }

    #[test]
    fn friction_sticks_then_slips_at_mu_times_normal() {
        let mut r = ModelRenderer::new();
        let cmd = plane(1000.0, 0.0, 0.5);
        let depth = 0.001;
        r.render(&cmd, Vec3::new(0.0, 0.0, -depth), Vec3::ZERO, 0);
        // Small slide: sticks, tangential force = k × offset.
        let f = r.render(&cmd, Vec3::new(0.0001, 0.0, -depth), Vec3::ZERO, 0);
        assert!((f.x + 0.1).abs() < 1e-5, "stick: {f}");
        // Large slide: slips, tangential force capped at μ·N = 0.5 N.
        let f = r.render(&cmd, Vec3::new(0.01, 0.0, -depth), Vec3::ZERO, 0);
        assert!(
            (f.x + 0.5).abs() < 1e-5 && (f.z - 1.0).abs() < 1e-5,
            "slip: {f}"
        );
    }

    #[test]
    fn anchor_is_a_bilateral_spring() {
        let mut r = ModelRenderer::new();
        let mut cmd = plane(200.0, 0.0, 0.0);
        cmd.model.kind = ModelKind::Anchor;
        let f = r.render(&cmd, Vec3::new(0.01, 0.0, 0.0), Vec3::ZERO, 0);
        assert!((f - Vec3::new(-2.0, 0.0, 0.0)).length() < 1e-6);
    }

    #[test]
    fn stale_models_render_zero() {
        let mut r = ModelRenderer::new();
        let cmd = plane(500.0, 0.0, 0.0);
        let inside = Vec3::new(0.0, 0.0, -0.002);
        assert_eq!(r.render(&cmd, inside, Vec3::ZERO, 30_001), Vec3::ZERO);
        assert_eq!(
            r.render(&cmd, Vec3::new(0.06, 0.0, -0.002), Vec3::ZERO, 0),
            Vec3::ZERO
        );
    }

    #[test]
    fn no_model_holds_the_commanded_force() {
        let mut r = ModelRenderer::new();
        let mut cmd = plane(0.0, 0.0, 0.0);
        cmd.model.kind = ModelKind::None;
        cmd.force = Vec3::new(0.3, 0.0, 0.0);
        assert_eq!(
            r.render(&cmd, Vec3::splat(5.0), Vec3::ZERO, 1_000_000),
            cmd.force
        );
    }
}
