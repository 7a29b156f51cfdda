//! Kim-style force from the field snapshot (seed 000, DESIGN §5): direction from the gradient
//! blended over the 8 corners of the cell at the tool tip, magnitude from the virtual contact
//! point (VCP), spring plus damping, Coulomb friction by a sticking VCP.
//!
//! Per query at tip `x`, velocity `v`, with `n = ∇f/‖∇f‖` from [`ScalarGrid::sample`]:
//! - inside (`f < 0`): the frictionless VCP `p = x + t n` with `t` the ray distance to `f = 0`
//!   ([`super::vcp`]); normal force `N = max(0, k t − b (v·n)) n`. Friction keeps the previous
//!   VCP (projected onto the contact plane through `p`) as a stick point held by a tangential
//!   spring of stiffness `k`; it slides toward `p` only as far as needed to keep the tangential
//!   force within `μ |N|`. These are exactly the formulas of
//!   [`protocol::model::ModelRenderer`]'s plane, so the model renders this force at `x`.
//! - outside but within `approach_margin` of the surface: zero force, and the plane model of
//!   the surface below so the server renders contact onset before the next command.
//! - farther out, outside the grid, at a vanishing gradient, or for a non-finite `x`: zero
//!   force, no model, friction released.
//!
//! The query reads an immutable snapshot (`&ScalarGrid`, shared by `Arc` with the simulation):
//! it never waits and allocates nothing. The only state is the friction stick point.

use glam::DVec3;
use protocol::packet::ModelKind;

use super::vcp::{RootStatus, distance_to_zero};
use super::{ContactModel, HapticError, HapticOutput};
use crate::grid::ScalarGrid;

/// Gradients shorter than this (per metre) have no usable direction.
pub const MIN_GRADIENT: f64 = 1e-9;

/// Contact material and model settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldContactParams {
    /// Contact stiffness, N/m.
    pub stiffness: f64,
    /// Contact damping, N·s/m.
    pub damping: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Farthest the VCP is searched along the normal, m (deeper contacts use the fallback).
    pub max_search: f64,
    /// Outside the surface but closer than this, m, a plane model is still sent.
    pub approach_margin: f64,
    /// Validity radius of the models, m.
    pub validity_radius: f64,
    /// Lifetime of the models, s.
    pub lifetime_s: f64,
}

impl FieldContactParams {
    /// Check every parameter is finite and non-negative and the search distance positive.
    pub fn validate(&self) -> Result<(), HapticError> {
        let named = [
            ("stiffness", self.stiffness),
            ("damping", self.damping),
            ("friction", self.friction),
            ("max_search", self.max_search),
            ("approach_margin", self.approach_margin),
            ("validity_radius", self.validity_radius),
            ("lifetime_s", self.lifetime_s),
        ];
        for (name, value) in named {
            if !(value.is_finite() && value >= 0.0) || (name == "max_search" && value == 0.0) {
                return Err(HapticError::BadParameter { name, value });
            }
        }
        Ok(())
    }
}

/// Where the tip touches, when it does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldContact {
    /// The frictionless VCP: where the ray along the normal meets the zero set, m.
    pub surface_point: DVec3,
    /// The VCP after friction (the stick point), m.
    pub vcp: DVec3,
    /// Outward unit normal from the blended gradient at the tip.
    pub normal: DVec3,
    /// Signed depth along the normal, m (> 0 inside).
    pub depth: f64,
    /// How the depth was found.
    pub root: RootStatus,
}

/// One field query's answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldQuery {
    /// Force and local model.
    pub output: HapticOutput,
    /// The contact geometry, if the tip is inside or within the approach margin.
    pub contact: Option<FieldContact>,
}

/// The field force renderer; its only state is the friction stick point.
#[derive(Debug, Clone)]
pub struct FieldForce {
    params: FieldContactParams,
    stick: Option<DVec3>,
}

impl FieldForce {
    /// A renderer with no contact history.
    pub fn new(params: FieldContactParams) -> Result<Self, HapticError> {
        params.validate()?;
        Ok(Self {
            params,
            stick: None,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &FieldContactParams {
        &self.params
    }

    /// Forget the friction stick point.
    pub fn reset(&mut self) {
        self.stick = None;
    }

    fn release(&mut self) -> FieldQuery {
        self.stick = None;
        FieldQuery {
            output: HapticOutput::idle(self.params.lifetime_s),
            contact: None,
        }
    }

    /// The force at tip `x` moving at `v` (m/s) in the field `grid`.
    pub fn query(&mut self, grid: &ScalarGrid, x: DVec3, v: DVec3) -> FieldQuery {
        let p = self.params;
        let v = if v.is_finite() { v } else { DVec3::ZERO };
        let Some(s) = grid.sample(x) else {
            return self.release();
        };
        let g = s.gradient.length();
        if !(g > MIN_GRADIENT && g.is_finite() && s.value.is_finite())
            || s.value > p.approach_margin * g
        {
            return self.release();
        }
        let n = s.gradient / g;
        let inside = s.value < 0.0;
        let dir = if inside { n } else { -n };
        let (t, root) = if s.value == 0.0 {
            (0.0, RootStatus::Bracketed { iterations: 0 })
        } else {
            distance_to_zero(grid, x, dir, s.value, g, p.max_search)
        };
        let surface_point = x + t * dir;
        let depth = if inside { t } else { -t };
        let model = ContactModel {
            kind: ModelKind::Plane,
            point: surface_point,
            normal: n,
            stiffness: p.stiffness,
            damping: p.damping,
            friction: p.friction,
            // The server measures validity from `point`, which is `|depth|` from the cursor.
            validity_radius: p.validity_radius + t,
            lifetime_s: p.lifetime_s,
        };
        if !inside || depth <= 0.0 {
            self.stick = None;
            let contact = FieldContact {
                surface_point,
                vcp: surface_point,
                normal: n,
                depth,
                root,
            };
            let output = HapticOutput {
                force: DVec3::ZERO,
                model,
            };
            return FieldQuery {
                output,
                contact: Some(contact),
            };
        }
        let normal_mag = (p.stiffness * depth - p.damping * v.dot(n)).max(0.0);
        let stick = self.stick.unwrap_or(surface_point);
        let stick = stick - (stick - surface_point).dot(n) * n;
        let offset = stick - surface_point;
        let limit = p.friction * normal_mag;
        let (stick, tangential) = if (p.stiffness * offset).length() > limit {
            let d = offset.normalize_or_zero();
            (
                surface_point + d * (limit / p.stiffness.max(f64::MIN_POSITIVE)),
                d * limit,
            )
        } else {
            (stick, p.stiffness * offset)
        };
        let force = normal_mag * n + tangential;
        if !force.is_finite() {
            return self.release();
        }
        self.stick = Some(stick);
        let contact = FieldContact {
            surface_point,
            vcp: stick,
            normal: n,
            depth,
            root,
        };
        FieldQuery {
            output: HapticOutput { force, model },
            contact: Some(contact),
        }
    }
}
