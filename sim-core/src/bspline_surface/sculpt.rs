//! Sculpting the dual with the shaped probe (seed 004 §4.2): touch, or press to push and pull.
//!
//! Every haptic tick: the mass points are the probe's samples (seed 004 §4.2.2: no B-spline
//! evaluation at 1 kHz); with the button up the surface is touched rigidly (the probe force
//! of [`crate::probe`]); with it down each contact spring pushes its mass point out of the
//! probe along the point's normal line (`k_s a_i d_i` along the exit direction), the mesh is
//! integrated, and the user feels the sum of those forces reversed (Newton's third law). The
//! control net for display is recovered at a lower rate by [`ProbeSculptor::update_display`].
//! Each contact is a Kelvin–Voigt spring-damper (`k_s`, `b_s` per unit area) on its point.
//! Contacts are recomputed every substep, and substeps are short enough for the mesh springs
//! and the tool's spring-dampers alike, so the stiff tool stays stable. No allocation per tick.

use glam::DVec3;

use super::{BicubicPatch, DualMap, MAX_SUBSTEPS, MassSpringMesh, MeshParams, SurfaceError};
use crate::haptic::{ContactModel, HapticOutput, hua_qin_force};
use crate::probe::{ContactParams, Probe, ProbeRenderer, SurfaceSample};
use protocol::packet::ModelKind;

/// What one sculpting tick produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SculptTick {
    /// Force on the user and the local model for the server.
    pub output: HapticOutput,
    /// Sum of the forces the tool applied to the mesh during the tick (last substep), N.
    pub applied: DVec3,
    /// Mass points in contact (last substep).
    pub contacts: usize,
    /// Substeps the mesh took.
    pub substeps: usize,
    /// Hua & Qin's mapping of the same state for comparison ([`crate::haptic::hua_qin_force`]
    /// with profile `s_j = d_j / max d` over the contacts); zero with the button up.
    pub hua_qin: DVec3,
}

/// A B-spline surface with its mass-spring dual, sculpted by a probe.
#[derive(Debug, Clone)]
pub struct ProbeSculptor {
    patch: BicubicPatch,
    dual: DualMap,
    mesh: MassSpringMesh,
    renderer: ProbeRenderer,
    samples: Vec<SurfaceSample>,
    external: Vec<DVec3>,
    internal: Vec<DVec3>,
    /// Longest substep stable for the tool's spring-dampers on one point, s.
    tool_dt: f64,
    validity_radius: f64,
    lifetime_s: f64,
}

impl ProbeSculptor {
    /// Tie `patch` to a mesh of the same size at its mass parameters; `contact` is both the feel
    /// of touching and the stiffness of the tool springs. Models sent to the server are valid
    /// within `validity_radius` m for `lifetime_s` s.
    pub fn new(
        patch: BicubicPatch,
        mesh: MeshParams,
        contact: ContactParams,
        validity_radius: f64,
        lifetime_s: f64,
    ) -> Result<Self, SurfaceError> {
        let n = patch.n();
        let mut dual = DualMap::new(n)?;
        let mut points = vec![DVec3::ZERO; n * n];
        dual.to_mesh(patch.control(), &mut points);
        let mesh = MassSpringMesh::new(n, points, mesh)?;
        let tool_dt = tool_stable_dt(&mesh, &contact, n);
        let renderer = ProbeRenderer::new(contact, n * n).map_err(|_| SurfaceError::NonFinite)?;
        let placeholder = SurfaceSample {
            position: DVec3::ZERO,
            normal: DVec3::Z,
            area: 0.0,
        };
        Ok(Self {
            patch,
            dual,
            mesh,
            renderer,
            samples: vec![placeholder; n * n],
            external: vec![DVec3::ZERO; n * n],
            internal: vec![DVec3::ZERO; n * n],
            tool_dt,
            validity_radius,
            lifetime_s,
        })
    }

    /// The mass-spring mesh.
    pub fn mesh(&self) -> &MassSpringMesh {
        &self.mesh
    }

    /// The patch as of the last [`ProbeSculptor::update_display`].
    pub fn patch(&self) -> &BicubicPatch {
        &self.patch
    }

    /// The dual map (`A`, `A⁻¹`).
    pub fn dual(&mut self) -> &mut DualMap {
        &mut self.dual
    }

    /// One haptic tick of `dt` s with the probe at its current pose moving at `velocity`;
    /// `pressed` is the stylus button (sculpt) state.
    pub fn tick(
        &mut self,
        probe: &Probe,
        velocity: DVec3,
        pressed: bool,
        dt: f64,
    ) -> Result<SculptTick, SurfaceError> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(SurfaceError::NonFinite);
        }
        let cursor = probe.center();
        if !pressed {
            self.mesh.samples(&mut self.samples);
            let f = self.renderer.query_slice(probe, &self.samples, velocity);
            self.external.fill(DVec3::ZERO);
            let substeps = self.mesh.step(dt, &self.external)?;
            let output = f.output(cursor, self.validity_radius, self.lifetime_s);
            return Ok(SculptTick {
                output,
                applied: DVec3::ZERO,
                contacts: f.contact_count,
                substeps,
                hua_qin: DVec3::ZERO,
            });
        }
        let velocity = if velocity.is_finite() {
            velocity
        } else {
            DVec3::ZERO
        };
        let substep_dt = self.mesh.stable_dt().min(self.tool_dt);
        let substeps = (dt / substep_dt).ceil().clamp(1.0, MAX_SUBSTEPS as f64) as usize;
        let h = dt / substeps as f64;
        let k = self.renderer.params().surface_stiffness;
        let b = self.renderer.params().surface_damping;
        let (mut applied, mut contacts, mut area) = (DVec3::ZERO, 0, 0.0);
        for _ in 0..substeps {
            self.mesh.samples(&mut self.samples);
            let f = self.renderer.query_slice(probe, &self.samples, velocity);
            self.external.fill(DVec3::ZERO);
            applied = DVec3::ZERO;
            let vel = self.mesh.velocities();
            for c in self.renderer.contacts() {
                // Kelvin–Voigt per contact: the depth grows at −(v_point − v_probe)·exit.
                let rate = -(vel[c.sample as usize] - velocity).dot(c.exit);
                let push = (c.area * (k * c.depth + b * rate)).max(0.0) * c.exit;
                self.external[c.sample as usize] = push;
                applied += push;
            }
            contacts = f.contact_count;
            area = f.contact_area;
            self.mesh.step(h, &self.external)?;
        }
        let force = -applied;
        let model = match force.try_normalize() {
            Some(normal) if area > 0.0 => {
                // The point dampers act on the velocity of the probe relative to the moving
                // mesh, which the server cannot see: the model carries them inside F (no model
                // damping), so `k·depth` reproduces F exactly at the cursor.
                let stiffness = k * area;
                let offset = force.length() / stiffness;
                ContactModel {
                    kind: ModelKind::Plane,
                    point: cursor + normal * offset,
                    normal,
                    stiffness,
                    damping: 0.0,
                    friction: 0.0,
                    validity_radius: self.validity_radius + offset,
                    lifetime_s: self.lifetime_s,
                }
            }
            _ => ContactModel::none(self.lifetime_s),
        };
        self.mesh.internal_forces(&mut self.internal);
        let contacts_now = self.renderer.contacts();
        let d_max = contacts_now.iter().fold(0.0f64, |m, c| m.max(c.depth));
        let internal = &self.internal;
        let hua_qin = hua_qin_force(
            contacts_now
                .iter()
                .map(|c| (c.depth / d_max, internal[c.sample as usize])),
        );
        Ok(SculptTick {
            output: HapticOutput { force, model },
            applied,
            contacts,
            substeps,
            hua_qin,
        })
    }

    /// Recover the control net from the mesh (`P = A⁻¹ M A⁻ᵀ`): call at the display rate.
    pub fn update_display(&mut self) -> &BicubicPatch {
        self.dual
            .to_control(self.mesh.positions(), self.patch.control_mut());
        &self.patch
    }
}

/// Longest substep stable for the tool springs on one point: half of `2/ω` and `2m/b` with the
/// point's spring `k_s a` and damper `b_s a`, `a` twice the largest rest area (room to stretch).
fn tool_stable_dt(mesh: &MassSpringMesh, contact: &ContactParams, n: usize) -> f64 {
    let placeholder = SurfaceSample {
        position: DVec3::ZERO,
        normal: DVec3::Z,
        area: 0.0,
    };
    let mut samples = vec![placeholder; n * n];
    mesh.samples(&mut samples);
    let a = 2.0 * samples.iter().fold(0.0f64, |m, s| m.max(s.area));
    let m = mesh.point_mass();
    let (k, b) = (contact.surface_stiffness * a, contact.surface_damping * a);
    let spring = if k > 0.0 {
        2.0 / (k / m).sqrt()
    } else {
        f64::INFINITY
    };
    let damper = if b > 0.0 { 2.0 * m / b } else { f64::INFINITY };
    0.5 * spring.min(damper)
}
