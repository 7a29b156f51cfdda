//! The probe's implicit ellipsoid, its pose, and the analytic ray–ellipsoid root.

use glam::{DMat3, DQuat, DVec3};

use super::{ProbeError, tolerance};

/// Where the probe is: the device's 6-DOF transform in the scene frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbePose {
    /// Centre of the ellipsoid, m.
    pub position: DVec3,
    /// Orientation of the ellipsoid's axes, unit quaternion.
    pub orientation: DQuat,
}

impl ProbePose {
    /// A pose at `position` with the identity orientation.
    pub fn at(position: DVec3) -> Self {
        Self {
            position,
            orientation: DQuat::IDENTITY,
        }
    }
}

/// Where the normal line of a sample inside the probe leaves it first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayCrossing {
    /// Distance from the sample to the nearer crossing, m (> 0 for a sample strictly inside).
    pub depth: f64,
    /// `+1` if the nearer crossing lies along the sample normal, `−1` if against it.
    pub exit_sign: f64,
    /// The crossing point on the probe surface, m.
    pub point: DVec3,
    /// Outward unit normal of the probe at the crossing.
    pub probe_normal: DVec3,
    /// Outward unit probe normal at the sample itself (`∇f_p/‖∇f_p‖`, zero at the centre).
    pub normal_at_sample: DVec3,
}

/// An ellipsoid probe `f_p(x) = ‖S⁻¹Rᵀ(x − c)‖² − 1`: negative inside, zero on its surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    semi_axes: DVec3,
    inv_axes: DVec3,
    pose: ProbePose,
    rot: DMat3,
    rot_t: DMat3,
    /// `S⁻¹Rᵀ`: world offsets to the unit-sphere frame.
    to_local: DMat3,
}

impl Probe {
    /// A sphere of `radius` m at the origin.
    pub fn sphere(radius: f64) -> Result<Self, ProbeError> {
        Self::ellipsoid(DVec3::splat(radius))
    }

    /// An ellipsoid with `semi_axes` (m, along its local x, y, z) at the origin.
    pub fn ellipsoid(semi_axes: DVec3) -> Result<Self, ProbeError> {
        let mut p = Self {
            semi_axes: DVec3::ONE,
            inv_axes: DVec3::ONE,
            pose: ProbePose::at(DVec3::ZERO),
            rot: DMat3::IDENTITY,
            rot_t: DMat3::IDENTITY,
            to_local: DMat3::IDENTITY,
        };
        p.set_semi_axes(semi_axes)?;
        Ok(p)
    }

    /// Change size and shape at run time; on error the probe is unchanged.
    pub fn set_semi_axes(&mut self, semi_axes: DVec3) -> Result<(), ProbeError> {
        let ok = semi_axes.is_finite() && semi_axes.min_element() >= tolerance::MIN_SEMI_AXIS_M;
        if !ok {
            return Err(ProbeError::BadSemiAxes(semi_axes.to_array()));
        }
        self.semi_axes = semi_axes;
        self.inv_axes = semi_axes.recip();
        self.to_local = DMat3::from_diagonal(self.inv_axes) * self.rot_t;
        Ok(())
    }

    /// Move the probe; the orientation is renormalised. On error the probe is unchanged.
    pub fn set_pose(&mut self, pose: ProbePose) -> Result<(), ProbeError> {
        let q = pose.orientation;
        if !pose.position.is_finite() || !q.is_finite() || (q.length() - 1.0).abs() > 1e-6 {
            return Err(ProbeError::BadPose);
        }
        let q = q.normalize();
        self.pose = ProbePose {
            position: pose.position,
            orientation: q,
        };
        self.rot = DMat3::from_quat(q);
        self.rot_t = self.rot.transpose();
        self.to_local = DMat3::from_diagonal(self.inv_axes) * self.rot_t;
        Ok(())
    }

    /// The probe with a new pose (builder form of [`Probe::set_pose`]).
    pub fn posed(mut self, pose: ProbePose) -> Result<Self, ProbeError> {
        self.set_pose(pose)?;
        Ok(self)
    }

    /// Semi-axes, m.
    pub fn semi_axes(&self) -> DVec3 {
        self.semi_axes
    }

    /// Current pose.
    pub fn pose(&self) -> ProbePose {
        self.pose
    }

    /// Centre, m.
    pub fn center(&self) -> DVec3 {
        self.pose.position
    }

    #[inline]
    fn local(&self, x: DVec3) -> DVec3 {
        self.to_local * (x - self.pose.position)
    }

    /// Outward unit probe normal at the point whose unit-sphere coordinates are `q`
    /// (`∇f_p ∝ R S⁻¹ q = (S⁻¹Rᵀ)ᵀ q`); zero at the centre.
    #[inline]
    pub(crate) fn normal_from_local(&self, q: DVec3) -> DVec3 {
        (self.to_local.transpose() * q).normalize_or_zero()
    }

    /// The signed distance `t` along `n` to the nearer crossing and the sample's unit-sphere
    /// coordinates `q`, for `p` strictly inside (see [`Probe::ray_crossing`]). The force loop's
    /// lean form: no crossing point, no normals.
    #[inline]
    pub(crate) fn nearer_root(&self, p: DVec3, n: DVec3) -> Option<(f64, DVec3)> {
        let q = self.local(p);
        let c = q.length_squared() - 1.0;
        if c >= 0.0 || !c.is_finite() {
            return None;
        }
        let e = self.to_local * n;
        let a = e.length_squared();
        let b = q.dot(e);
        let disc = b * b - a * c;
        if a <= 0.0 || disc.is_nan() || disc <= 0.0 || !a.is_finite() {
            return None;
        }
        // Roots `big/a` and `c/big` (opposite signs, no cancellation); the nearer one has the
        // smaller magnitude. Both divisions are independent (they pipeline) and the choice is a
        // select, not a branch: with the centre on the sample's plane the comparison is decided
        // by rounding, and a branch mispredicts on every other sample (measured: 2× slower).
        // At an exact tie either crossing is as near; the first is taken.
        let big = -(b + disc.sqrt().copysign(b));
        let (r1, r2) = (big / a, c / big);
        let t = if r1.abs() <= r2.abs() { r1 } else { r2 };
        Some((t, q))
    }

    /// The implicit value `f_p(x)` (dimensionless; negative inside).
    #[inline]
    pub fn value(&self, x: DVec3) -> f64 {
        self.local(x).length_squared() - 1.0
    }

    /// The gradient of `f_p` at `x`, 1/m (outward).
    pub fn gradient(&self, x: DVec3) -> DVec3 {
        2.0 * (self.rot * (self.inv_axes * self.local(x)))
    }

    /// Axis-aligned bounding box `(min, max)` of the posed ellipsoid (exact).
    pub fn aabb(&self) -> (DVec3, DVec3) {
        let cols = [
            self.rot.x_axis * self.semi_axes.x,
            self.rot.y_axis * self.semi_axes.y,
            self.rot.z_axis * self.semi_axes.z,
        ];
        let half = (cols[0] * cols[0] + cols[1] * cols[1] + cols[2] * cols[2]).map(f64::sqrt);
        (self.pose.position - half, self.pose.position + half)
    }

    /// The nearer crossing of the line `p + t·n` with the probe surface, for `p` strictly inside.
    ///
    /// `n` is the sample's unit normal. `None` when `p` is on or outside the probe or an input is
    /// non-finite. The quadratic `|q + t e|² = 1` (`q`, `e` in the unit-sphere frame) has one
    /// negative and one positive root when `p` is inside; both are computed without
    /// cancellation. At a tie (the sample midway along its chord) either crossing is as near.
    #[inline]
    pub fn ray_crossing(&self, p: DVec3, n: DVec3) -> Option<RayCrossing> {
        let (t, q) = self.nearer_root(p, n)?;
        let e = self.to_local * n;
        let exit_sign = if t >= 0.0 { 1.0 } else { -1.0 };
        let probe_normal = self.normal_from_local(q + t * e);
        let normal_at_sample = self.normal_from_local(q);
        Some(RayCrossing {
            depth: t.abs(),
            exit_sign,
            point: p + t * n,
            probe_normal,
            normal_at_sample,
        })
    }
}
