//! Distributed springs between the probe and the samples inside it: the force query.

use glam::DVec3;

use super::{Probe, ProbeError, SampleGrid, SurfaceSample, tolerance};

/// How the direction of the probe force is found (seed 004 §3.2.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum DirectionMethod {
    /// Depth-weighted mean of the sample normals `Σ a_i d_i N_i`: never reverses when the probe
    /// passes through a sheet (a B-spline surface), but turns quickly over sharp edges; inside a
    /// two-faced thin wall the faces' normals cancel (see [`MagnitudeMethod`]).
    #[default]
    SurfaceNormal,
    /// Depth-weighted mean of the inward probe normals `−∇f_p/‖∇f_p‖` at the samples: smooth
    /// over edges and needs no surface normal for direction, but reverses when the centre
    /// crosses the surface. (Normals at the ray crossings would flip per sample where the two
    /// crossings tie, a jump at every edge: measured, rejected.)
    ProbeNormal,
}

/// How the distributed springs add up to a force magnitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum MagnitudeMethod {
    /// Seed 004 / DESIGN §4: `|F| = k_s Σ a_i d_i`, the springs' scalar sum, along the
    /// normalised direction. Where the direction sum cancels (the probe-normal method at a
    /// crossing, or any method midway through a two-faced thin wall) the force jumps between
    /// ±|F| over one step.
    #[default]
    SpringSum,
    /// `F = k_s Σ a_i d_i ν_i` with `ν_i` the direction method's per-sample unit vector: each
    /// spring pushes along its own direction. Continuous through cancellations (the force passes
    /// through zero), and weaker over edges where normals disagree.
    VectorSum,
}

/// Material of the distributed springs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Spring stiffness per unit contact area, N/m per m² (N/m³).
    pub surface_stiffness: f64,
    /// Damping per unit contact area, N·s/m per m².
    pub surface_damping: f64,
    /// Direction method.
    pub method: DirectionMethod,
    /// How the springs add up.
    pub magnitude: MagnitudeMethod,
}

impl ContactParams {
    /// Check that the stiffness and damping are finite and non-negative.
    pub fn validate(&self) -> Result<(), ProbeError> {
        for (name, value) in [
            ("surface_stiffness", self.surface_stiffness),
            ("surface_damping", self.surface_damping),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ProbeError::BadParameter { name, value });
            }
        }
        Ok(())
    }
}

/// One sample in contact with the probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Index of the sample (construction order of the grid, or slice index).
    pub sample: u32,
    /// Depth to the nearer probe crossing along the sample normal, m.
    pub depth: f64,
    /// Area of the sample, m².
    pub area: f64,
    /// The unit direction along which the sample leaves the probe soonest (`±N_i`): the probe
    /// pushes the sample this way, the sample pushes the probe the opposite way.
    pub exit: DVec3,
}

/// The result of one probe query. `force` is the force on the probe, N.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProbeForce {
    /// Force on the probe (what the user feels), N; always finite.
    pub force: DVec3,
    /// Unit force direction, or zero when nothing touches or the directions cancel.
    pub direction: DVec3,
    /// Spring part of the magnitude (`k_s Σ a_i d_i`, or `|k_s Σ a_i d_i ν_i|`), N.
    pub spring: f64,
    /// Contact area `A = Σ a_i`, m².
    pub contact_area: f64,
    /// Samples in contact.
    pub contact_count: usize,
    /// More contacts than the (non-zero) scratch holds: the force counts all,
    /// [`ProbeRenderer::contacts`] lists only the first ones.
    pub truncated: bool,
    /// Effective normal stiffness `k_s A` (how the force grows per metre of push), N/m.
    pub stiffness: f64,
    /// Effective damping `b_s A`, N·s/m.
    pub damping: f64,
}

/// Computes probe forces; holds the contact scratch (sized once) and the material.
#[derive(Debug, Clone)]
pub struct ProbeRenderer {
    params: ContactParams,
    contacts: Vec<Contact>,
    capacity: usize,
}

#[derive(Default)]
struct Sums {
    depth_area: f64,
    area: f64,
    surface_dir: DVec3,
    probe_dir: DVec3,
    count: usize,
    truncated: bool,
}

impl ProbeRenderer {
    /// A renderer that records up to `max_contacts` contacts per query (all are summed); `0`
    /// records none (force only: the fastest surface-normal query).
    pub fn new(params: ContactParams, max_contacts: usize) -> Result<Self, ProbeError> {
        params.validate()?;
        Ok(Self {
            params,
            contacts: Vec::with_capacity(max_contacts),
            capacity: max_contacts,
        })
    }

    /// The material and direction method.
    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// Change the material or direction method at run time; on error nothing changes.
    pub fn set_params(&mut self, params: ContactParams) -> Result<(), ProbeError> {
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// The contacts recorded by the last query, in summation order.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The force on `probe` moving at `velocity` (m/s, relative to the surface) from the samples
    /// of `grid` near it.
    pub fn query(&mut self, probe: &Probe, grid: &SampleGrid, velocity: DVec3) -> ProbeForce {
        let (lo, hi) = probe.aabb();
        let mut sums = Sums::default();
        self.contacts.clear();
        let radius = probe.semi_axes().max_element();
        grid.for_each_near(lo, hi, probe.center(), radius, |i, s| {
            self.touch(probe, i, s, &mut sums)
        });
        self.finish(&sums, velocity)
    }

    /// As [`ProbeRenderer::query`] over a plain slice (a deforming mesh): every sample is
    /// tested against the probe's bounding box first.
    pub fn query_slice(
        &mut self,
        probe: &Probe,
        samples: &[SurfaceSample],
        velocity: DVec3,
    ) -> ProbeForce {
        let (lo, hi) = probe.aabb();
        let mut sums = Sums::default();
        self.contacts.clear();
        for (i, s) in samples.iter().enumerate() {
            let p = s.position;
            if p.cmpge(lo).all() && p.cmple(hi).all() {
                self.touch(probe, i as u32, s, &mut sums);
            }
        }
        self.finish(&sums, velocity)
    }

    #[inline]
    fn touch(&mut self, probe: &Probe, index: u32, s: &SurfaceSample, sums: &mut Sums) {
        let Some((t, q)) = probe.nearer_root(s.position, s.normal) else {
            return;
        };
        let depth = t.abs();
        let w = s.area * depth;
        sums.depth_area += w;
        sums.area += s.area;
        sums.surface_dir += w * s.normal;
        sums.count += 1;
        if self.params.method == DirectionMethod::ProbeNormal {
            sums.probe_dir -= w * probe.normal_from_local(q);
        }
        if self.contacts.len() < self.capacity {
            // Branch-free: the sign is decided by rounding when the centre is on the plane.
            let exit = s.normal * 1f64.copysign(t);
            self.contacts.push(Contact {
                sample: index,
                depth,
                area: s.area,
                exit,
            });
        } else {
            sums.truncated |= self.capacity > 0;
        }
    }

    fn finish(&self, sums: &Sums, velocity: DVec3) -> ProbeForce {
        let p = &self.params;
        let velocity = if velocity.is_finite() {
            velocity
        } else {
            DVec3::ZERO
        };
        let dir_sum = match p.method {
            DirectionMethod::SurfaceNormal => sums.surface_dir,
            DirectionMethod::ProbeNormal => sums.probe_dir,
        };
        let spring = match p.magnitude {
            MagnitudeMethod::SpringSum => p.surface_stiffness * sums.depth_area,
            MagnitudeMethod::VectorSum => p.surface_stiffness * dir_sum.length(),
        };
        let cancelled = dir_sum.length() <= tolerance::DIRECTION_CANCEL * sums.depth_area;
        let direction = if cancelled || !dir_sum.is_finite() {
            DVec3::ZERO
        } else {
            dir_sum.normalize_or_zero()
        };
        let damping = p.surface_damping * sums.area;
        let magnitude = (spring - damping * velocity.dot(direction)).max(0.0);
        let force = magnitude * direction;
        let finite = force.is_finite() && spring.is_finite();
        ProbeForce {
            force: if finite { force } else { DVec3::ZERO },
            direction: if finite { direction } else { DVec3::ZERO },
            spring: if finite { spring } else { 0.0 },
            contact_area: sums.area,
            contact_count: sums.count,
            truncated: sums.truncated,
            stiffness: p.surface_stiffness * sums.area,
            damping,
        }
    }
}

impl ProbeForce {
    /// The local model reproducing this force at the probe centre `cursor`: a plane with normal
    /// `direction`, stiffness `k_s A` and damping `b_s A`, placed `spring / (k_s A)` beyond the
    /// cursor so the server's `k·depth − b·v_n` equals this query's magnitude exactly there.
    /// Frictionless (the distributed springs are). The server measures validity from `point`, so
    /// the model's radius is `validity_radius` (about the cursor) plus that offset. No contact
    /// gives a `None` model.
    pub fn contact_model(
        &self,
        cursor: DVec3,
        validity_radius: f64,
        lifetime_s: f64,
    ) -> crate::haptic::ContactModel {
        use crate::haptic::ContactModel;
        use protocol::packet::ModelKind;
        if self.direction == DVec3::ZERO || self.stiffness <= 0.0 || !cursor.is_finite() {
            return ContactModel::none(lifetime_s);
        }
        let offset = self.spring / self.stiffness;
        ContactModel {
            kind: ModelKind::Plane,
            point: cursor + self.direction * offset,
            normal: self.direction,
            stiffness: self.stiffness,
            damping: self.damping,
            friction: 0.0,
            validity_radius: validity_radius + offset,
            lifetime_s,
        }
    }

    /// The force and its local model (see [`ProbeForce::contact_model`]).
    pub fn output(
        &self,
        cursor: DVec3,
        validity_radius: f64,
        lifetime_s: f64,
    ) -> crate::haptic::HapticOutput {
        crate::haptic::HapticOutput {
            force: self.force,
            model: self.contact_model(cursor, validity_radius, lifetime_s),
        }
    }
}
