//! Boolean operations on point-set solids (DESIGN §4, Table 1 in our sign: `f < 0` inside).
//!
//! With `f₁, f₂` the two fields and `P₁, P₂` their points:
//! - union keeps `{p∈P₁ | f₂(p) > 0} ∪ {p∈P₂ | f₁(p) > 0}`;
//! - intersection keeps `{p∈P₁ | f₂(p) ≤ 0} ∪ {p∈P₂ | f₁(p) ≤ 0}`;
//! - difference `S₁ − S₂` keeps `{p∈P₁ | f₂(p) > 0} ∪ {p∈P₂ | f₁(p) ≤ 0}`, normals of the
//!   latter flipped.
//!
//! `fᵢ` here is the trusted value ([`GlobalField::trusted_value`]): where the other field is
//! not trusted and its sign disagrees with its nearest oriented point, the point's side wins,
//! so a spurious blob of one operand cannot swallow or spare the other's points.
//!
//! Sharp edges: the kept points thin out towards the intersection curve, where a refit would
//! round the crease. For every kept point within `edge_band` of the other surface, its nearest
//! point on the curve `{f₁ = 0, f₂ = 0}` is found by Gauss–Newton on both constraints; extra
//! samples are placed on each sheet at fractions of `edge_band` from the curve, projected onto
//! their sheet, and kept only when they lie on the result's boundary. Tangential curves (touching
//! solids) have no well-defined crease and get no extra samples.
//!
//! Contract: deterministic, finite output (non-finite inputs are rejected); the result is a
//! point set with unit normals (colours carried over when both inputs have them), ready for
//! [`crate::reconstruct::reconstruct`] with `NormalPolicy::Keep`.

use glam::DVec3;

use crate::field::GlobalField;
use crate::pointset::PointSet;

/// Which Boolean.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CsgOp {
    /// `S₁ ∪ S₂`.
    Union,
    /// `S₁ ∩ S₂`.
    Intersection,
    /// `S₁ − S₂`.
    Difference,
}

/// One operand: its points, unit outward normals, optional colours and its field.
#[derive(Debug, Clone, Copy)]
pub struct Solid<'a> {
    /// Positions.
    pub positions: &'a [DVec3],
    /// Unit outward normals.
    pub normals: &'a [DVec3],
    /// Colours, if any.
    pub colors: Option<&'a [[u8; 3]]>,
    /// The fitted field.
    pub field: &'a GlobalField,
}

/// Settings of [`csg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CsgOptions {
    /// Distance from the other surface within which a point seeds edge samples (m);
    /// `None`: half the first field's length scale.
    pub edge_band: Option<f64>,
    /// Extra samples per sheet per seed (at `((k + 0.05)/n)·edge_band`, `k = 0..n`); 0 disables
    /// edge sampling.
    pub edge_samples: usize,
}

impl Default for CsgOptions {
    fn default() -> Self {
        Self {
            edge_band: None,
            edge_samples: 2,
        }
    }
}

/// Why a Boolean could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsgError {
    /// Positions and normals (or colours) differ in length.
    #[error("operand {operand}: {what} has {got} entries for {expected} points")]
    Length {
        /// 1 or 2.
        operand: u8,
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// Number of points.
        expected: usize,
    },
    /// A position or normal is not finite.
    #[error("operand {operand}: point {index} is not finite")]
    NonFinite {
        /// 1 or 2.
        operand: u8,
        /// Index of the point.
        index: usize,
    },
    /// The edge band is not positive and finite.
    #[error("edge band {0} must be positive and finite")]
    EdgeBand(f64),
}

/// What [`csg`] produced besides the points.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CsgReport {
    /// Points kept from operand 1.
    pub kept_1: usize,
    /// Points kept from operand 2.
    pub kept_2: usize,
    /// Extra samples added near the intersection curve.
    pub edge_samples: usize,
}

/// Whether a point of operand `from` (1 or 2) with other-field value `f_other` is kept.
pub fn keeps(op: CsgOp, from: u8, f_other: f64) -> bool {
    match (op, from) {
        (CsgOp::Union, _) | (CsgOp::Difference, 1) => f_other > 0.0,
        (CsgOp::Intersection, _) | (CsgOp::Difference, _) => f_other <= 0.0,
    }
}

/// The Boolean `op` of `a` and `b` as a point set.
pub fn csg(
    op: CsgOp,
    a: Solid<'_>,
    b: Solid<'_>,
    opts: &CsgOptions,
) -> Result<(PointSet, CsgReport), CsgError> {
    validate(&a, 1)?;
    validate(&b, 2)?;
    let band = opts.edge_band.unwrap_or(0.5 * a.field.scale());
    if !(band.is_finite() && band > 0.0) {
        return Err(CsgError::EdgeBand(band));
    }
    let with_colors = a.colors.is_some() && b.colors.is_some();
    let mut out = PointSet {
        positions: Vec::new(),
        normals: Some(Vec::new()),
        colors: with_colors.then(Vec::new),
    };
    let mut report = CsgReport::default();
    let mut seeds: Vec<(DVec3, u8, usize)> = Vec::new();
    for (from, me, other) in [(1u8, &a, &b), (2u8, &b, &a)] {
        let flip = op == CsgOp::Difference && from == 2;
        for (i, &p) in me.positions.iter().enumerate() {
            // Classified by the trusted value: a spurious blob of the other field's zero set
            // beyond its points must not swallow (or spare) these points.
            let f_other = other.field.trusted_value(p);
            if !keeps(op, from, f_other) {
                continue;
            }
            let n = if flip { -me.normals[i] } else { me.normals[i] };
            push(&mut out, p, n, me.colors.map(|c| c[i]));
            *(if from == 1 {
                &mut report.kept_1
            } else {
                &mut report.kept_2
            }) += 1;
            if f_other.abs() < band {
                seeds.push((p, from, i));
            }
        }
    }
    if opts.edge_samples == 0 {
        seeds.clear();
    }
    for (p, from, i) in seeds {
        let Some(c) = curve_point(a.field, b.field, p).filter(|c| c.distance(p) <= 2.0 * band)
        else {
            continue;
        };
        let (me, other) = if from == 1 { (&a, &b) } else { (&b, &a) };
        let (_, g_me) = me.field.value_and_gradient(c);
        let (_, g_other) = other.field.value_and_gradient(c);
        let (Some(n_me), Some(n_other)) = (g_me.try_normalize(), g_other.try_normalize()) else {
            continue;
        };
        // In my tangent plane, across the curve, towards where the other field keeps me.
        let Some(tangent) = n_me.cross(n_other).try_normalize() else {
            continue;
        };
        let mut across = tangent.cross(n_me);
        if !keeps(op, from, other.field.trusted_value(c + across * band * 0.5)) {
            across = -across;
        }
        let color = me.colors.map(|cs| cs[i]);
        for k in 0..opts.edge_samples {
            let s = band * (k as f64 + 0.05) / opts.edge_samples as f64;
            let pr = me.field.project_to_zero_set(c + across * s);
            let q = pr.point;
            if !(q.is_finite() && pr.trusted && keeps(op, from, other.field.trusted_value(q))) {
                continue;
            }
            let (_, gq) = me.field.value_and_gradient(q);
            let Some(mut n) = gq.try_normalize() else {
                continue;
            };
            if op == CsgOp::Difference && from == 2 {
                n = -n;
            }
            push(&mut out, q, n, color);
            report.edge_samples += 1;
        }
    }
    Ok((out, report))
}

/// Nearest point to `x` on `{f₁ = 0} ∩ {f₂ = 0}` by Gauss–Newton (minimal-norm steps), or
/// `None` when the surfaces are tangent there or it does not converge.
pub fn curve_point(f1: &GlobalField, f2: &GlobalField, x: DVec3) -> Option<DVec3> {
    let mut p = x;
    let tol = 1e-9 * f1.scale().max(f2.scale());
    for _ in 0..20 {
        let (v1, g1) = f1.value_and_gradient(p);
        let (v2, g2) = f2.value_and_gradient(p);
        if v1.abs() < tol && v2.abs() < tol {
            return Some(p);
        }
        // δ = −Jᵀ (J Jᵀ)⁻¹ F with J = [g1; g2].
        let (a, b, c) = (g1.dot(g1), g1.dot(g2), g2.dot(g2));
        let det = a * c - b * b;
        if det.is_nan() || det <= 1e-6 * a * c {
            return None; // (nearly) tangent surfaces: no crease
        }
        let l1 = (c * v1 - b * v2) / det;
        let l2 = (a * v2 - b * v1) / det;
        let step = g1 * l1 + g2 * l2;
        let max = 0.5 * f1.scale();
        p -= if step.length() > max {
            step * (max / step.length())
        } else {
            step
        };
    }
    None
}

fn push(out: &mut PointSet, p: DVec3, n: DVec3, color: Option<[u8; 3]>) {
    out.positions.push(p);
    if let Some(ns) = out.normals.as_mut() {
        ns.push(n);
    }
    if let (Some(cs), Some(c)) = (out.colors.as_mut(), color) {
        cs.push(c);
    }
}

fn validate(s: &Solid<'_>, operand: u8) -> Result<(), CsgError> {
    let n = s.positions.len();
    let len = |what, got| CsgError::Length {
        operand,
        what,
        got,
        expected: n,
    };
    if s.normals.len() != n {
        return Err(len("normals", s.normals.len()));
    }
    if let Some(c) = s.colors
        && c.len() != n
    {
        return Err(len("colors", c.len()));
    }
    if let Some(index) = (0..n).find(|&i| !(s.positions[i].is_finite() && s.normals[i].is_finite()))
    {
        return Err(CsgError::NonFinite { operand, index });
    }
    Ok(())
}

/// Volume enclosed by a closed, outward-oriented triangle mesh (divergence theorem: the sum of
/// signed tetrahedra against the origin). Open meshes give the volume of their cone to the origin.
pub fn mesh_volume(mesh: &crate::mesh::TriMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}
