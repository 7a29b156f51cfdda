//! What the user feels while a tool deforms material: the material's reaction (seed 004
//! §4.2.2, Newton's third law), and Hua & Qin's field force-mapping (seed 000) as an alternative.
//!
//! **Direct reaction** ([`ToolReaction`]): the force the tool applied to the material (to grid
//! node values mapped to space, or to mass points), reversed. Its local model is a bilateral
//! spring ([`protocol::ModelKind::Anchor`]) toward the point where the force would vanish, with
//! the series stiffness of tool and material `k = k_t k_m / (k_t + k_m)`: a stiffer material
//! feels stiffer, a rigid one feels like the tool spring alone, and when the tool lets go
//! (`applied = 0`) the model is dropped — release. A heavier material resists more over the
//! model's horizon τ: [`dynamic_stiffness`] adds the inertial term `m/τ²`.
//!
//! On the voxel grid the tool pushes on node *values*; [`value_forces_in_space`] turns those
//! scalar forces into the spatial force the material receives.
//!
//! **Hua–Qin mapping** ([`hua_qin_force`]): `f = −∫ s dC`, discretely `f = Σ_j s_j F_j` with
//! `s_j ∈ [0, 1]` the tool's distribution profile at node `j` and `F_j` the material's internal
//! (restoring) force there: the virtual work of a tool that drags node `j` by `s_j` of its own
//! motion. It needs no record of what the tool applied, only the material's state; at static
//! equilibrium under a profile-weighted load it equals the direct reaction weighted by `s`.

use glam::DVec3;
use protocol::packet::ModelKind;

use super::{ContactModel, HapticOutput};

/// The material's answer to a tool, as the simulation reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolReaction {
    /// Sum of the forces the tool applied to the material this step, N.
    pub applied: DVec3,
    /// Stiffness of the tool's coupling (rope spring, contact springs), N/m.
    pub tool_stiffness: f64,
    /// The material's effective stiffness at the tool (static, or [`dynamic_stiffness`]), N/m;
    /// `f64::INFINITY` for rigid.
    pub material_stiffness: f64,
    /// Damping of the rendered spring, N·s/m.
    pub damping: f64,
}

/// Series combination `k_t k_m / (k_t + k_m)`; a non-finite or non-positive part counts as
/// rigid (infinite) or absent (zero) as its sign says.
pub fn series_stiffness(tool: f64, material: f64) -> f64 {
    let clean = |k: f64| if k.is_nan() || k < 0.0 { 0.0 } else { k };
    let (t, m) = (clean(tool), clean(material));
    if t == 0.0 || m == 0.0 {
        0.0
    } else if m.is_infinite() {
        if t.is_infinite() { 0.0 } else { t }
    } else if t.is_infinite() {
        m
    } else {
        t * m / (t + m)
    }
}

/// Stiffness of a material of static stiffness `k` and effective moving mass `m` (kg) as felt
/// over a horizon `tau` s (≈ the model's lifetime): `k + m/τ²`.
pub fn dynamic_stiffness(k: f64, mass: f64, tau: f64) -> f64 {
    if tau > 0.0 && tau.is_finite() && mass >= 0.0 && mass.is_finite() {
        k + mass / (tau * tau)
    } else {
        k
    }
}

impl ToolReaction {
    /// The force on the user at `cursor` and its anchor model: `F = −applied`, anchor
    /// `cursor + F/k` so the server's `k (anchor − x) − b v` equals `F` at the cursor. The
    /// server measures validity from the anchor, so the model's radius is `validity_radius`
    /// (about the cursor) plus the stretch `|F|/k`.
    /// No force (the tool let go) or a non-finite input gives the idle output.
    pub fn output(&self, cursor: DVec3, validity_radius: f64, lifetime_s: f64) -> HapticOutput {
        let force = -self.applied;
        let k = series_stiffness(self.tool_stiffness, self.material_stiffness);
        let finite = force.is_finite() && cursor.is_finite() && k.is_finite();
        if !finite || force == DVec3::ZERO || k <= 0.0 {
            return HapticOutput::idle(lifetime_s);
        }
        let damping = if self.damping.is_finite() {
            self.damping.max(0.0)
        } else {
            0.0
        };
        HapticOutput {
            force,
            model: ContactModel {
                kind: ModelKind::Anchor,
                point: cursor + force / k,
                normal: DVec3::ZERO,
                stiffness: k,
                damping,
                friction: 0.0,
                validity_radius: validity_radius + force.length() / k,
                lifetime_s,
            },
        }
    }
}

/// Hua & Qin's mapping `f = Σ_j s_j F_j` over `(s_j, F_j)` pairs: profile weight in `[0, 1]`
/// (clamped) and the material's internal force at node `j`, N. Non-finite pairs are skipped.
pub fn hua_qin_force(nodes: impl IntoIterator<Item = (f64, DVec3)>) -> DVec3 {
    let mut f = DVec3::ZERO;
    for (s, internal) in nodes {
        if s.is_finite() && internal.is_finite() {
            f += s.clamp(0.0, 1.0) * internal;
        }
    }
    f
}

/// The spatial force equivalent of scalar forces on grid node values, N: what a tool that
/// pushes on values (the rope of seed 000) applies to the material in space.
///
/// Virtual work: moving the surface by `δx` changes a node's value by `−∇f·δx`, so a value force
/// `f_j` does the work of the spatial force `−f_j ∇f_j` (for a distance field `|∇f| = 1`, so a
/// rope pulling outward, `f_j < 0`, pulls along `+n`). Feed the sum to
/// [`ToolReaction::applied`]; non-finite pairs are skipped.
pub fn value_forces_in_space(nodes: impl IntoIterator<Item = (f64, DVec3)>) -> DVec3 {
    let mut f = DVec3::ZERO;
    for (value_force, gradient) in nodes {
        let term = -value_force * gradient;
        if term.is_finite() {
            f += term;
        }
    }
    f
}
