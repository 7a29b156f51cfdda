//! The dynamic volumetric model's state (DESIGN §3, papers' Eq. 6): field values on the nodes of
//! a narrow band of a regular grid over the sculpting region, each with a displacement
//! `u = d − d⁰` from its rest value, a velocity `u̇`, an external force and its own mass, damping,
//! neighbour-spring stiffness and anchor stiffness.
//!
//! Contract:
//! - Only *active* nodes (rest value within `band` of the zero set) carry state; the cost of every
//!   per-step operation is O(active nodes). Inactive nodes inside the grid are fixed at rest
//!   (Dirichlet boundary of the band); neighbours outside the grid do not exist (free boundary).
//! - Forces on node `i`: `f_i − c_i u̇_i − a_i u_i − Σ_j k_ij (u_i − u_j)` over its six axis
//!   neighbours, `k_ij = (k_i + k_j)/2` (an inactive neighbour has `u_j = 0`), so the rest field is
//!   an equilibrium and `K` (anchors + springs) is symmetric positive definite when every band
//!   component touches the fixed boundary or has an anchor.
//! - The model holds state only; steppers ([`crate::dynamics::Stepper`]) hold scratch.
//!   [`DynamicGrid::publish`] hands out immutable [`ScalarGrid`] snapshots, recycling buffers
//!   the readers have dropped (no allocation in steady state).

use std::sync::Arc;

use glam::DVec3;

use crate::dynamics::DynamicsError;
use crate::dynamics::springs::SpringTable;
use crate::grid::{GridSpec, ScalarGrid};

/// Marks a neighbour that is inside the grid but inactive (fixed at rest).
pub const FIXED: u32 = u32::MAX - 1;
/// Marks a neighbour outside the grid (no spring).
pub const ABSENT: u32 = u32::MAX;
/// `slot_of` entry of an inactive node.
const INACTIVE: u32 = u32::MAX;
/// `slot_of` of a node while [`DynamicGrid::grow_band`] adds it.
const JOINING: u32 = u32::MAX - 2;

/// Physical parameters of one node (units: value units are metres of signed distance).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NodeParams {
    /// Mass `m` (kg), > 0.
    pub mass: f64,
    /// Damping `c` (N·s/m), ≥ 0.
    pub damping: f64,
    /// Stiffness `k` of the springs to the six neighbours (N/m), ≥ 0.
    pub stiffness: f64,
    /// Stiffness `a` of the spring to the node's own rest value (N/m), ≥ 0.
    pub anchor: f64,
}

impl Default for NodeParams {
    /// Light, stiff and near critically damped for the top mode at 1 kHz (see docs/BENCHMARKS.md).
    fn default() -> Self {
        Self {
            mass: 1e-3,
            damping: 0.5,
            stiffness: 10.0,
            anchor: 100.0,
        }
    }
}

impl NodeParams {
    /// `Ok` when every parameter is finite and in range.
    pub fn validate(&self) -> Result<(), DynamicsError> {
        let ok = self.mass.is_finite()
            && self.mass > 0.0
            && self.damping.is_finite()
            && self.damping >= 0.0
            && self.stiffness.is_finite()
            && self.stiffness >= 0.0
            && self.anchor.is_finite()
            && self.anchor >= 0.0;
        if ok {
            Ok(())
        } else {
            Err(DynamicsError::Params(*self))
        }
    }
}

/// Per-slot parameter arrays (structure of arrays, indexed like the state).
#[derive(Debug, Clone, Default)]
pub(crate) struct ParamArrays {
    pub(crate) mass: Vec<f64>,
    pub(crate) damping: Vec<f64>,
    pub(crate) stiffness: Vec<f64>,
    pub(crate) anchor: Vec<f64>,
}

/// The simulated field over a sculpting region.
#[derive(Debug, Clone)]
pub struct DynamicGrid {
    spec: GridSpec,
    band: f64,
    /// Grid index per slot.
    active: Vec<u32>,
    /// Slot per grid index, or `INACTIVE`.
    slot_of: Vec<u32>,
    /// Per slot: the six neighbours (−x, +x, −y, +y, −z, +z) as slots, `FIXED` or `ABSENT`.
    nbr: Vec<[u32; 6]>,
    /// Rest values `d⁰` on every grid node.
    rest: Vec<f64>,
    pub(crate) u: Vec<f64>,
    pub(crate) v: Vec<f64>,
    pub(crate) force: Vec<f64>,
    pub(crate) params: ParamArrays,
    /// `K` in a branch-free form, kept in step with `params`.
    pub(crate) springs: SpringTable,
    time: f64,
    pool: Vec<Arc<ScalarGrid>>,
    /// Slots with a neighbour outside the band ([`FIXED`]): the band's edge, which
    /// [`Self::grow_band`] watches.
    edge: Vec<u32>,
}

impl DynamicGrid {
    /// A model at rest on `rest`, simulating the nodes with `|d⁰| ≤ band` (use `f64::INFINITY`
    /// for all nodes), every node with `params`.
    pub fn new(rest: &ScalarGrid, band: f64, params: NodeParams) -> Result<Self, DynamicsError> {
        params.validate()?;
        if band.is_nan() || band < 0.0 {
            return Err(DynamicsError::Band(band));
        }
        let spec = *rest.spec();
        let values = rest.values();
        let mut slot_of = vec![INACTIVE; values.len()];
        let mut active = Vec::new();
        for (g, &d) in values.iter().enumerate() {
            if d.abs() <= band {
                slot_of[g] = active.len() as u32;
                active.push(g as u32);
            }
        }
        if active.is_empty() {
            return Err(DynamicsError::EmptyBand);
        }
        let nbr: Vec<[u32; 6]> = active
            .iter()
            .map(|&g| neighbours(&spec, &slot_of, g as usize))
            .collect();
        let n = active.len();
        let params = ParamArrays {
            mass: vec![params.mass; n],
            damping: vec![params.damping; n],
            stiffness: vec![params.stiffness; n],
            anchor: vec![params.anchor; n],
        };
        let springs = SpringTable::build(&nbr, &params);
        let edge = edge_slots(&nbr);
        Ok(Self {
            spec,
            band,
            active,
            slot_of,
            nbr,
            rest: values.to_vec(),
            u: vec![0.0; n],
            v: vec![0.0; n],
            force: vec![0.0; n],
            params,
            springs,
            time: 0.0,
            pool: Vec::new(),
            edge,
        })
    }

    /// The grid geometry.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The band half-width the active set was chosen with.
    pub fn band(&self) -> f64 {
        self.band
    }

    /// Number of simulated (active) nodes.
    pub fn active_len(&self) -> usize {
        self.active.len()
    }

    /// Grid index of every active slot.
    pub fn active_nodes(&self) -> &[u32] {
        &self.active
    }

    /// The active slot of grid node `g`, if simulated.
    #[inline]
    pub fn slot(&self, g: usize) -> Option<usize> {
        match self.slot_of.get(g) {
            Some(&s) if s != INACTIVE => Some(s as usize),
            _ => None,
        }
    }

    /// Neighbour table of slot `s` (slots, [`FIXED`] or [`ABSENT`]).
    #[inline]
    pub fn neighbours_of(&self, s: usize) -> &[u32; 6] {
        &self.nbr[s]
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    pub(crate) fn advance_time(&mut self, dt: f64) {
        self.time += dt;
    }

    /// Displacements `u = d − d⁰` per slot.
    pub fn displacement(&self) -> &[f64] {
        &self.u
    }

    /// Velocities `u̇` per slot.
    pub fn velocity(&self) -> &[f64] {
        &self.v
    }

    /// External forces per slot (N), as accumulated since the last [`Self::clear_forces`].
    pub fn forces(&self) -> &[f64] {
        &self.force
    }

    /// Overwrite displacements and velocities (one per slot, finite), e.g. to restore a saved
    /// state or to start from a perturbation.
    pub fn set_state(&mut self, u: &[f64], v: &[f64]) -> Result<(), DynamicsError> {
        let n = self.active.len();
        if u.len() != n || v.len() != n {
            return Err(DynamicsError::StateLength { expected: n });
        }
        if u.iter().chain(v).any(|x| !x.is_finite()) {
            return Err(DynamicsError::NonFiniteState);
        }
        self.u.copy_from_slice(u);
        self.v.copy_from_slice(v);
        Ok(())
    }

    /// Add `f` to the external force on slot `s`.
    #[inline]
    pub fn add_force(&mut self, s: usize, f: f64) {
        self.force[s] += f;
    }

    /// Zero every external force (call once per step before tools apply theirs).
    pub fn clear_forces(&mut self) {
        self.force.fill(0.0);
    }

    /// World position of slot `s`'s node.
    #[inline]
    pub fn slot_position(&self, s: usize) -> DVec3 {
        let [i, j, k] = self.spec.coords(self.active[s] as usize);
        self.spec.node_position(i, j, k)
    }

    /// Rest value `d⁰` at grid node `g`.
    #[inline]
    pub fn rest_value(&self, g: usize) -> f64 {
        self.rest[g]
    }

    /// Rest values `d⁰` of every grid node (x fastest).
    pub fn rest_values(&self) -> &[f64] {
        &self.rest
    }

    /// Current value `d = d⁰ + u` at grid node `g`.
    #[inline]
    pub fn value(&self, g: usize) -> f64 {
        match self.slot(g) {
            Some(s) => self.rest[g] + self.u[s],
            None => self.rest[g],
        }
    }

    /// The box (grown by two cells) of the simulated nodes displaced by more than `eps`;
    /// `None` when none is. O(simulated nodes).
    pub fn displaced_box(&self, eps: f64) -> Option<(DVec3, DVec3)> {
        let spec = &self.spec;
        let mut b: Option<([usize; 3], [usize; 3])> = None;
        for (s, &g) in self.active.iter().enumerate() {
            if self.u[s].abs() <= eps {
                continue;
            }
            let c = spec.coords(g as usize);
            b = Some(match b {
                None => (c, c),
                Some((lo, hi)) => (
                    [lo[0].min(c[0]), lo[1].min(c[1]), lo[2].min(c[2])],
                    [hi[0].max(c[0]), hi[1].max(c[1]), hi[2].max(c[2])],
                ),
            });
        }
        let (lo, hi) = b?;
        let grow = DVec3::splat(2.0 * spec.spacing);
        Some((
            spec.node_position(lo[0], lo[1], lo[2]) - grow,
            spec.node_position(hi[0], hi[1], hi[2]) + grow,
        ))
    }

    /// The trilinear interpolant of the current values `d⁰ + u` at `x` (nodes outside the band
    /// at their rest values); `None` outside the grid.
    pub fn value_at(&self, x: DVec3) -> Option<f64> {
        let ([ci, cj, ck], t) = self.spec.locate(x)?;
        let w = |a: f64, d: usize| if d == 0 { 1.0 - a } else { a };
        let mut v = 0.0;
        for c in 0..8 {
            let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let g = self.spec.index(ci + dx, cj + dy, ck + dz);
            v += w(t.x, dx) * w(t.y, dy) * w(t.z, dz) * self.value(g);
        }
        Some(v)
    }

    /// Let the band follow the surface: every node outside the band ([`FIXED`]) next to a
    /// simulated node whose value `|d⁰ + u|` is below `margin` (the zero set is within about
    /// `margin` plus a cell of the band's edge) joins the simulation, with the mean
    /// displacement, velocity and parameters of its simulated neighbours (the displacement
    /// field extended by one cell, so no value near the surface jumps) and its rest value
    /// unchanged. Returns how many joined. Without it a stroke that reaches the band's edge is
    /// cut flat there: the nodes beyond are held at rest. O(nodes on the band's edge) to look; a growth
    /// (rare: when the surface nears the edge) rebuilds the spring table and may allocate.
    pub fn grow_band(&mut self, margin: f64) -> usize {
        let mut joining: Vec<u32> = Vec::new();
        for &s in &self.edge {
            let s = s as usize;
            let g = self.active[s] as usize;
            if (self.rest[g] + self.u[s]).abs() >= margin {
                continue;
            }
            for h in self.axis_neighbours(g) {
                if self.slot_of[h] == INACTIVE {
                    self.slot_of[h] = JOINING;
                    joining.push(h as u32);
                }
            }
        }
        if joining.is_empty() {
            return 0;
        }
        joining.sort_unstable();
        // The joining nodes' state from their already simulated neighbours.
        let state: Vec<(f64, f64, NodeParams)> = joining
            .iter()
            .map(|&h| {
                let (mut n, mut u, mut v) = (0.0, 0.0, 0.0);
                let mut p = NodeParams {
                    mass: 0.0,
                    damping: 0.0,
                    stiffness: 0.0,
                    anchor: 0.0,
                };
                for q in self.axis_neighbours(h as usize) {
                    let sq = self.slot_of[q];
                    if sq == INACTIVE || sq == JOINING {
                        continue;
                    }
                    let sq = sq as usize;
                    let np = self.node_params(sq);
                    (n, u, v) = (n + 1.0, u + self.u[sq], v + self.v[sq]);
                    p.mass += np.mass;
                    p.damping += np.damping;
                    p.stiffness += np.stiffness;
                    p.anchor += np.anchor;
                }
                let k = 1.0 / n;
                let p = NodeParams {
                    mass: p.mass * k,
                    damping: p.damping * k,
                    stiffness: p.stiffness * k,
                    anchor: p.anchor * k,
                };
                (u * k, v * k, p)
            })
            .collect();
        for (&h, (u, v, p)) in joining.iter().zip(state) {
            self.slot_of[h as usize] = self.active.len() as u32;
            self.active.push(h);
            self.u.push(u);
            self.v.push(v);
            self.force.push(0.0);
            self.params.mass.push(p.mass);
            self.params.damping.push(p.damping);
            self.params.stiffness.push(p.stiffness);
            self.params.anchor.push(p.anchor);
        }
        // The new slots' neighbour rows, and their neighbours' rows (FIXED → slot).
        self.nbr = self
            .active
            .iter()
            .map(|&g| neighbours(&self.spec, &self.slot_of, g as usize))
            .collect();
        self.springs = SpringTable::build(&self.nbr, &self.params);
        self.edge = edge_slots(&self.nbr);
        joining.len()
    }

    /// Whether the zero set reaches where the model cannot move it: a simulated node whose
    /// value differs in sign from a neighbour outside the band ([`FIXED`], held at rest), or
    /// that lies on the grid's boundary and either changed sign in this stroke (`d⁰` and
    /// `d⁰ + u`) or ended within a cell of the zero set after moving more than half one (the
    /// surface carried to or through a face of the region's box; one that crosses a face at
    /// rest is not). A stroke there is cut flat. O(simulated nodes).
    pub fn zero_set_at_edge(&self) -> bool {
        let half = 0.5 * self.spec.spacing;
        (0..self.active.len()).any(|s| {
            let g = self.active[s] as usize;
            let v = self.rest[g] + self.u[s];
            self.nbr[s]
                .iter()
                .zip(axis_neighbours(&self.spec, g))
                .any(|(&n, h)| match n {
                    FIXED => h.is_some_and(|h| (self.rest[h] > 0.0) != (v > 0.0)),
                    ABSENT => {
                        let u = self.u[s];
                        (v > 0.0) != (self.rest[g] > 0.0)
                            || (v.abs() < 2.0 * half && u.abs() > half)
                    }
                    _ => false,
                })
        })
    }

    /// The grid indices of node `g`'s axis neighbours inside the grid.
    fn axis_neighbours(&self, g: usize) -> impl Iterator<Item = usize> + use<> {
        axis_neighbours(&self.spec, g).into_iter().flatten()
    }

    /// Parameters of slot `s`.
    pub fn node_params(&self, s: usize) -> NodeParams {
        let p = &self.params;
        NodeParams {
            mass: p.mass[s],
            damping: p.damping[s],
            stiffness: p.stiffness[s],
            anchor: p.anchor[s],
        }
    }

    /// Set the parameters of slot `s`.
    pub fn set_node_params(&mut self, s: usize, np: NodeParams) -> Result<(), DynamicsError> {
        np.validate()?;
        let p = &mut self.params;
        (p.mass[s], p.damping[s], p.stiffness[s], p.anchor[s]) =
            (np.mass, np.damping, np.stiffness, np.anchor);
        // Springs are shared with the neighbours: refresh their rows too.
        self.springs.update_row(s, &self.nbr, &self.params);
        for &j in &self.nbr[s] {
            if j != ABSENT && j != FIXED {
                self.springs.update_row(j as usize, &self.nbr, &self.params);
            }
        }
        Ok(())
    }

    /// Set the parameters of every active node within `radius` of `center`; returns how many.
    pub fn set_params_in_ball(
        &mut self,
        center: DVec3,
        radius: f64,
        np: NodeParams,
    ) -> Result<usize, DynamicsError> {
        np.validate()?;
        let mut n = 0;
        for s in 0..self.active.len() {
            if self.slot_position(s).distance_squared(center) <= radius * radius {
                self.set_node_params(s, np)?;
                n += 1;
            }
        }
        Ok(n)
    }

    /// Plastic update at the end of a stroke: the current field becomes the rest field
    /// (`d⁰ ← d⁰ + u`, `u ← 0`, `u̇ ← 0`).
    pub fn commit(&mut self) {
        for (s, &g) in self.active.iter().enumerate() {
            self.rest[g as usize] += self.u[s];
        }
        self.u.fill(0.0);
        self.v.fill(0.0);
    }

    /// Heap bytes held by the model's state (snapshots in the pool included).
    pub fn memory_bytes(&self) -> usize {
        let n = self.active.len();
        let per_slot = 4 + 24 + 7 * 8 + 7 * 8 + 24;
        let per_node = 4 + 8;
        n * per_slot
            + self.slot_of.len() * per_node
            + self.pool.len() * self.rest.len() * 8
            + self.edge.capacity() * 4
    }

    /// An immutable snapshot of the current values `d⁰ + u` on the whole grid, for readers on
    /// other threads. Reuses a pooled buffer nobody else holds; allocates only when every pooled
    /// buffer is still held (at most 4 are pooled).
    pub fn publish(&mut self) -> Arc<ScalarGrid> {
        let free = self.pool.iter_mut().position(|a| Arc::get_mut(a).is_some());
        let idx = match free {
            Some(i) => i,
            None => {
                let g = ScalarGrid::from_values(self.spec, self.rest.clone())
                    .expect("rest values are finite and sized by the spec");
                if self.pool.len() >= 4 {
                    self.pool.remove(0);
                }
                self.pool.push(Arc::new(g));
                self.pool.len() - 1
            }
        };
        let grid = Arc::get_mut(&mut self.pool[idx]).expect("checked unique above");
        let vals = grid.values_mut();
        for (s, &g) in self.active.iter().enumerate() {
            vals[g as usize] = self.rest[g as usize] + self.u[s];
        }
        Arc::clone(&self.pool[idx])
    }
}

/// The slots with a neighbour outside the band.
fn edge_slots(nbr: &[[u32; 6]]) -> Vec<u32> {
    (0..nbr.len() as u32)
        .filter(|&s| nbr[s as usize].contains(&FIXED))
        .collect()
}

/// The grid indices of node `g`'s six axis neighbours (−x, +x, −y, +y, −z, +z: the order of
/// [`DynamicGrid::neighbours_of`]), `None` outside the grid.
fn axis_neighbours(spec: &GridSpec, g: usize) -> [Option<usize>; 6] {
    let [i, j, k] = spec.coords(g);
    [
        (i > 0).then(|| spec.index(i - 1, j, k)),
        (i + 1 < spec.dims[0]).then(|| spec.index(i + 1, j, k)),
        (j > 0).then(|| spec.index(i, j - 1, k)),
        (j + 1 < spec.dims[1]).then(|| spec.index(i, j + 1, k)),
        (k > 0).then(|| spec.index(i, j, k - 1)),
        (k + 1 < spec.dims[2]).then(|| spec.index(i, j, k + 1)),
    ]
}

fn neighbours(spec: &GridSpec, slot_of: &[u32], g: usize) -> [u32; 6] {
    axis_neighbours(spec, g).map(|h| match h {
        None => ABSENT,
        Some(h) if slot_of[h] == INACTIVE => FIXED,
        Some(h) => slot_of[h],
    })
}
