//! The local contact model in scene units (f64) and its one conversion to the wire (f32).
//!
//! Every haptic query here returns a [`HapticOutput`]: the force at the queried cursor and a
//! [`ContactModel`] the server renders ([`protocol::model::ModelRenderer`]) at the *current*
//! cursor until the next command. [`ContactModel::to_wire`] is the only place scene values
//! become wire values: it clamps to the protocol's limits (the server clamps further to its
//! device) and replaces a non-finite model, or a plane without a normal, by an inert one
//! (`None`), so the packet always validates.

use glam::{DVec3, Vec3};
use protocol::packet::{
    ForceCommand, LIMIT_DAMPING_N_S_M, LIMIT_FORCE_N, LIMIT_FRICTION, LIMIT_LIFETIME_US,
    LIMIT_POSITION_M, LIMIT_STIFFNESS_N_M, LIMIT_VALIDITY_RADIUS_M, LocalModel, ModelKind,
};

/// A local model of the scene near the contact, in scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactModel {
    /// Plane, anchor spring, or none (hold the force); see [`ModelKind`].
    pub kind: ModelKind,
    /// Contact point on the surface (plane) or anchor point, m.
    pub point: DVec3,
    /// Outward unit normal of the contact plane (zero unless `Plane`).
    pub normal: DVec3,
    /// Stiffness, N/m.
    pub stiffness: f64,
    /// Damping, N·s/m.
    pub damping: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Valid within this distance of `point`, m.
    pub validity_radius: f64,
    /// Valid this long after it arrives, s.
    pub lifetime_s: f64,
}

impl ContactModel {
    /// No model: the server holds the commanded force for `lifetime_s`.
    pub fn none(lifetime_s: f64) -> Self {
        Self {
            kind: ModelKind::None,
            point: DVec3::ZERO,
            normal: DVec3::ZERO,
            stiffness: 0.0,
            damping: 0.0,
            friction: 0.0,
            validity_radius: 0.0,
            lifetime_s,
        }
    }

    /// The wire form: f32, clamped to the protocol limits; non-finite models become `None`.
    pub fn to_wire(&self) -> LocalModel {
        let finite = self.point.is_finite()
            && self.normal.is_finite()
            && [
                self.stiffness,
                self.damping,
                self.friction,
                self.validity_radius,
            ]
            .iter()
            .all(|v| v.is_finite());
        let lifetime_us = if self.lifetime_s.is_finite() {
            (self.lifetime_s * 1e6).clamp(0.0, LIMIT_LIFETIME_US as f64) as u32
        } else {
            0
        };
        let normal = self.normal.try_normalize();
        let plane_without_normal = self.kind == ModelKind::Plane && normal.is_none();
        if !finite || self.kind == ModelKind::None || plane_without_normal {
            return LocalModel {
                lifetime_us,
                ..LocalModel::default()
            };
        }
        let normal = match (self.kind, normal) {
            (ModelKind::Plane, Some(n)) => n.as_vec3(),
            _ => Vec3::ZERO,
        };
        let lim = LIMIT_POSITION_M as f64;
        LocalModel {
            kind: self.kind,
            point: self
                .point
                .clamp(DVec3::splat(-lim), DVec3::splat(lim))
                .as_vec3(),
            normal,
            stiffness: (self.stiffness as f32).clamp(0.0, LIMIT_STIFFNESS_N_M),
            damping: (self.damping as f32).clamp(0.0, LIMIT_DAMPING_N_S_M),
            friction: (self.friction as f32).clamp(0.0, LIMIT_FRICTION),
            validity_radius: (self.validity_radius as f32).clamp(0.0, LIMIT_VALIDITY_RADIUS_M),
            lifetime_us,
        }
    }
}

/// A force and the model that reproduces it near the cursor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HapticOutput {
    /// Force on the user at the queried cursor, N (finite).
    pub force: DVec3,
    /// The local model the server renders until the next command.
    pub model: ContactModel,
}

impl HapticOutput {
    /// Nothing to feel: zero force, no model, held for `lifetime_s`.
    pub fn idle(lifetime_s: f64) -> Self {
        Self {
            force: DVec3::ZERO,
            model: ContactModel::none(lifetime_s),
        }
    }

    /// The wire command answering cursor sample `answers_sequence` (sent at
    /// `answers_timestamp_ns` of the server's clock). Force components are clamped to the limit.
    pub fn to_command(&self, answers_sequence: u32, answers_timestamp_ns: u64) -> ForceCommand {
        let force = if self.force.is_finite() {
            self.force
                .as_vec3()
                .clamp(Vec3::splat(-LIMIT_FORCE_N), Vec3::splat(LIMIT_FORCE_N))
        } else {
            Vec3::ZERO
        };
        ForceCommand {
            force,
            torque: None,
            answers_sequence,
            answers_timestamp_ns,
            model: self.model.to_wire(),
        }
    }
}
