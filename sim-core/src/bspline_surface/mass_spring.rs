//! The `n×n` mass-spring mesh of the dual (seed 004 §4.1–4.2.1): `M Ẍ + C Ẋ + K X = f`.
//!
//! Springs join each point to its 4 neighbours (structural), 4 diagonals (shear) and the points
//! two apart (bending). Integration is semi-implicit (symplectic) Euler — velocity first, then
//! position with the new velocity — which is the seed's Euler made stable for undamped springs;
//! [`MassSpringMesh::step`] splits a haptic tick into equal substeps no longer than
//! [`MassSpringMesh::stable_dt`]: a quarter of the Gershgorin bound `2/ω_max` and of the
//! damping bound `2/damping_rate` (half was measured not to be enough, see `BOUND_FRACTION`).
//! Plasticity (`plastic_rate`) relaxes rest lengths toward the current lengths so a sculpted
//! shape stays. Scratch is allocated once; a step that would produce a non-finite state is
//! rolled back (positions, velocities, rest lengths) and reported.

use glam::DVec3;

use super::SurfaceError;
use crate::probe::SurfaceSample;

/// Material of the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshParams {
    /// Mass of the whole mesh, kg (spread evenly over the `n²` points).
    pub total_mass: f64,
    /// Stiffness of structural and shear springs, N/m.
    pub stiffness: f64,
    /// Stiffness of bending springs (two apart), N/m.
    pub bending: f64,
    /// Mass-proportional damping rate, 1/s: each point feels `−damping_rate·m·v`, so changing
    /// the mass changes the time scale (`√(m/k)`) and not the damping ratio's form.
    pub damping_rate: f64,
    /// Rate at which rest lengths follow current lengths, 1/s (0: perfectly elastic).
    pub plastic_rate: f64,
    /// Hold the border points fixed.
    pub pin_border: bool,
}

impl MeshParams {
    /// The material the reports, benches and tests measure: a 100 g mesh with 20 N/m
    /// structural/shear and 2 N/m bending springs, damped at 200/s, elastic, border pinned.
    pub const REFERENCE: MeshParams = MeshParams {
        total_mass: 0.1,
        stiffness: 20.0,
        bending: 2.0,
        damping_rate: 200.0,
        plastic_rate: 0.0,
        pin_border: true,
    };
}

/// Most substeps one [`MassSpringMesh::step`] takes; a mesh folded so far that it needs more
/// runs past its bound (a resulting non-finite state is rolled back).
pub const MAX_SUBSTEPS: usize = 1000;

/// Half of the tighter of the spring bound `2/ω` (Gershgorin: `ω² ≤ 2 max Σk / m`) and the
/// damping bound `2/damping_rate`; 1 s if neither binds.
fn stable_step(k_max: f64, mass: f64, damping_rate: f64) -> f64 {
    let omega = (2.0 * k_max / mass).sqrt();
    let spring = if omega > 0.0 {
        2.0 / omega
    } else {
        f64::INFINITY
    };
    let damper = if damping_rate > 0.0 {
        2.0 / damping_rate
    } else {
        f64::INFINITY
    };
    let dt = 0.25 * spring.min(damper);
    if dt.is_finite() { dt } else { 1.0 }
}

#[derive(Debug, Clone, Copy)]
struct Spring {
    a: u32,
    b: u32,
    rest: f64,
    k: f64,
}

/// Positions, velocities and springs of the mesh, plus its integration scratch.
#[derive(Debug, Clone)]
pub struct MassSpringMesh {
    n: usize,
    params: MeshParams,
    mass: f64,
    positions: Vec<DVec3>,
    velocities: Vec<DVec3>,
    pinned: Vec<bool>,
    springs: Vec<Spring>,
    forces: Vec<DVec3>,
    saved: Vec<(DVec3, DVec3)>,
    /// Rest lengths at the start of the step (plastic meshes), for the rollback.
    saved_rest: Vec<f64>,
    /// Longest stable substep.
    stable_dt: f64,
}

impl MassSpringMesh {
    /// A mesh at rest at `positions` (row-major `n×n`), springs at their current lengths.
    pub fn new(n: usize, positions: Vec<DVec3>, params: MeshParams) -> Result<Self, SurfaceError> {
        if !(2..=256).contains(&n) {
            return Err(SurfaceError::BadSize(n));
        }
        if positions.len() != n * n {
            return Err(SurfaceError::WrongLength {
                expected: n * n,
                got: positions.len(),
            });
        }
        let p = &params;
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        let valid = p.total_mass.is_finite()
            && p.total_mass > 0.0
            && [p.stiffness, p.bending, p.damping_rate, p.plastic_rate]
                .into_iter()
                .all(ok)
            && positions.iter().all(|x| x.is_finite());
        if !valid {
            return Err(SurfaceError::NonFinite);
        }
        let mut springs = Vec::new();
        let mut incident = vec![0.0f64; n * n];
        let idx = |i: usize, j: usize| i * n + j;
        let offsets: [(usize, isize, f64); 6] = [
            (1, 0, p.stiffness),
            (0, 1, p.stiffness),
            (1, 1, p.stiffness),
            (1, -1, p.stiffness),
            (2, 0, p.bending),
            (0, 2, p.bending),
        ];
        for i in 0..n {
            for j in 0..n {
                for &(di, dj, k) in &offsets {
                    let (i2, j2) = (i + di, j as isize + dj);
                    if k <= 0.0 || i2 >= n || j2 < 0 || j2 as usize >= n {
                        continue;
                    }
                    let (a, b) = (idx(i, j), idx(i2, j2 as usize));
                    let rest = positions[a].distance(positions[b]);
                    springs.push(Spring {
                        a: a as u32,
                        b: b as u32,
                        rest,
                        k,
                    });
                    incident[a] += k;
                    incident[b] += k;
                }
            }
        }
        let mass = p.total_mass / (n * n) as f64;
        let stable_dt = stable_step(
            incident.iter().cloned().fold(0.0, f64::max),
            mass,
            p.damping_rate,
        );
        let pinned = (0..n * n)
            .map(|q| p.pin_border && (q / n == 0 || q / n == n - 1 || q % n == 0 || q % n == n - 1))
            .collect();
        Ok(Self {
            n,
            params,
            mass,
            velocities: vec![DVec3::ZERO; n * n],
            forces: vec![DVec3::ZERO; n * n],
            saved: vec![(DVec3::ZERO, DVec3::ZERO); n * n],
            positions,
            pinned,
            saved_rest: Vec::with_capacity(springs.len()),
            springs,
            stable_dt,
        })
    }

    /// Points per side.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Mass of one point, kg.
    pub fn point_mass(&self) -> f64 {
        self.mass
    }

    /// The material.
    pub fn params(&self) -> &MeshParams {
        &self.params
    }

    /// Positions, row-major, m.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Velocities, row-major, m/s.
    pub fn velocities(&self) -> &[DVec3] {
        &self.velocities
    }

    /// Whether point `q` is pinned.
    pub fn is_pinned(&self, q: usize) -> bool {
        self.pinned[q]
    }

    /// Longest substep the integrator takes, s.
    pub fn stable_dt(&self) -> f64 {
        self.stable_dt
    }

    /// Advance `dt` seconds under constant `external` forces (N, one per point), in
    /// `ceil(dt / stable_dt)` equal substeps (at most [`MAX_SUBSTEPS`]). On a non-finite input
    /// or result nothing changes.
    pub fn step(&mut self, dt: f64, external: &[DVec3]) -> Result<usize, SurfaceError> {
        if external.len() != self.positions.len() {
            return Err(SurfaceError::WrongLength {
                expected: self.positions.len(),
                got: external.len(),
            });
        }
        let valid = dt.is_finite() && dt >= 0.0 && external.iter().all(|f| f.is_finite());
        if !valid {
            return Err(SurfaceError::NonFinite);
        }
        let substeps = (dt / self.stable_dt).ceil().clamp(1.0, MAX_SUBSTEPS as f64) as usize;
        let h = dt / substeps as f64;
        for (s, (x, v)) in self
            .saved
            .iter_mut()
            .zip(self.positions.iter().zip(&self.velocities))
        {
            *s = (*x, *v);
        }
        let plastic = self.params.plastic_rate > 0.0;
        if plastic {
            self.saved_rest.clear();
            self.saved_rest.extend(self.springs.iter().map(|s| s.rest));
        }
        for _ in 0..substeps {
            self.substep(h, external);
        }
        let finite = self
            .positions
            .iter()
            .chain(&self.velocities)
            .all(|x| x.is_finite());
        if !finite {
            for (s, (x, v)) in self
                .saved
                .iter()
                .zip(self.positions.iter_mut().zip(self.velocities.iter_mut()))
            {
                (*x, *v) = *s;
            }
            if plastic {
                for (s, rest) in self.springs.iter_mut().zip(&self.saved_rest) {
                    s.rest = *rest;
                }
            }
            return Err(SurfaceError::Diverged);
        }
        Ok(substeps)
    }

    fn substep(&mut self, h: f64, external: &[DVec3]) {
        self.forces.copy_from_slice(external);
        let relax = (self.params.plastic_rate * h).min(1.0);
        for s in &mut self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = self.positions[b] - self.positions[a];
            let len = d.length();
            if len > 0.0 {
                let f = s.k * (len - s.rest) / len * d;
                self.forces[a] += f;
                self.forces[b] -= f;
            }
            if len.is_finite() {
                s.rest += (len - s.rest) * relax;
            }
        }

        let (c, m) = (self.params.damping_rate * self.mass, self.mass);
        for q in 0..self.positions.len() {
            if self.pinned[q] {
                self.velocities[q] = DVec3::ZERO;
                continue;
            }
            let a = (self.forces[q] - c * self.velocities[q]) / m;
            self.velocities[q] += h * a;
            self.positions[q] += h * self.velocities[q];
        }
    }

    /// Kinetic plus spring energy, J (pinned points count no kinetic energy; they do not move).
    pub fn energy(&self) -> f64 {
        let kinetic: f64 = self
            .velocities
            .iter()
            .map(|v| 0.5 * self.mass * v.length_squared())
            .sum();
        let springs: f64 = self
            .springs
            .iter()
            .map(|s| {
                let stretch =
                    self.positions[s.a as usize].distance(self.positions[s.b as usize]) - s.rest;
                0.5 * s.k * stretch * stretch
            })
            .sum();
        kinetic + springs
    }

    /// The springs' force on every point (no external or damping forces), N, into `out`.
    pub fn internal_forces(&self, out: &mut [DVec3]) {
        out.fill(DVec3::ZERO);
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = self.positions[b] - self.positions[a];
            let len = d.length();
            if len > 0.0 {
                let f = s.k * (len - s.rest) / len * d;
                out[a] += f;
                out[b] -= f;
            }
        }
    }

    /// The points as probe samples: normals `t_u × t_v` from neighbour differences (oriented like
    /// the patch's `S_u × S_v`), area the point's share of the mesh (half on borders).
    pub fn samples(&self, out: &mut [SurfaceSample]) {
        let n = self.n;
        let x = &self.positions;
        for i in 0..n {
            for j in 0..n {
                let (i0, i1) = (i.saturating_sub(1), (i + 1).min(n - 1));
                let (j0, j1) = (j.saturating_sub(1), (j + 1).min(n - 1));
                let tu = (x[i1 * n + j] - x[i0 * n + j]) / (i1 - i0) as f64;
                let tv = (x[i * n + j1] - x[i * n + j0]) / (j1 - j0) as f64;
                let c = tu.cross(tv);
                let wu = if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
                let wv = if j == 0 || j == n - 1 { 0.5 } else { 1.0 };
                let normal = c.try_normalize().unwrap_or(DVec3::Z);
                out[i * n + j] = SurfaceSample {
                    position: x[i * n + j],
                    normal,
                    area: c.length() * wu * wv,
                };
            }
        }
    }
}
