//! Evaluating a field: the blend of the local fields covering a point, split into the two sides
//! of a thin solid or gap where the fields face apart, and the nearest point's signed distance
//! where none covers it.

use glam::DVec3;

use super::supports::Supports;
use super::{GlobalField, SupportList, weight};
use crate::bspline::{eval3, eval3_value};
use crate::local_fit::LocalFrame;
use crate::spatial::SupportGrid;

impl GlobalField {
    /// `f(x)`.
    #[inline]
    pub fn value(&self, x: DVec3) -> f64 {
        self.value_and_gradient(x).0
    }

    /// `f(x)` and `∇f(x)`. Allocation-free; finite for finite `x`.
    ///
    /// The covering fields are blended in two groups, split by the sign of their normal's dot
    /// product with that of the most central covering support. When the groups face opposite
    /// ways (mean normals with a dot product below `normal_agreement`: the two sides of a thin
    /// solid, or of a thin gap, closer than the supports) averaging them would erase both
    /// sheets; instead each group is blended alone and the two are combined like a CSG of
    /// half-spaces: `max` (intersection) when the groups face away from each other (a thin
    /// solid), `min` (union) when they face each other (a gap), or a C¹ mix of the two where
    /// the covering fields' votes (fixed at the fit: how each field's opposed neighbours lie)
    /// are split, as at the corner of a closing slit. There f has a crease where the sides
    /// meet, and it can step where the split switches on (the groups' mean normals crossing
    /// the threshold) and where a side too light for the votes to decide swaps solid for gap;
    /// elsewhere it is the papers' C¹ blend. A side that reaches across with a small share of
    /// the weight keeps its veto only where its own tangent planes agree (see
    /// `combine_sides`).
    pub fn value_and_gradient(&self, x: DVec3) -> (f64, DVec3) {
        self.value_and_gradient_over::<true>(x, &self.inner.grid)
    }

    /// `f(x)` with the supports taken from a list gathered once for a box (see
    /// [`GlobalField::gather_supports`]): equal, bit for bit, to [`GlobalField::value`] for
    /// every `x` in that box, without the per-query index lookups or the gradient's cost.
    /// Block-wise grid sampling uses this.
    pub fn value_near(&self, x: DVec3, supports: &SupportList) -> f64 {
        self.value_and_gradient_over::<false>(x, supports).0
    }

    /// [`GlobalField::value_and_gradient`] with the supports taken from a list gathered for a
    /// box ([`GlobalField::gather_supports`]): equal, bit for bit, for every `x` in that box.
    pub fn value_and_gradient_near(&self, x: DVec3, supports: &SupportList) -> (f64, DVec3) {
        self.value_and_gradient_over::<true>(x, supports)
    }

    /// `f` and, with `GRAD`, `∇f` (else the gradient is meaningless where the blend defines f).
    fn value_and_gradient_over<const GRAD: bool>(
        &self,
        x: DVec3,
        supports: &impl Supports,
    ) -> (f64, DVec3) {
        let [a, b] = self.blend::<GRAD>(x, supports);
        let agreement = self.inner.params.normal_agreement;
        let opposed = a.sw > 0.0
            && b.sw > 0.0
            && a.normal.dot(b.normal) < agreement * a.normal.length() * b.normal.length();
        let result = if opposed {
            Some(solid_or_gap::<GRAD>(a, b))
        } else {
            let all = Blend {
                sw: a.sw + b.sw,
                swf: a.swf + b.swf,
                gsw: a.gsw + b.gsw,
                gswf: a.gswf + b.gswf,
                ..Blend::default()
            };
            (all.sw > 1e-12).then(|| all.value())
        };
        match result {
            Some((f, g)) if f.is_finite() && g.is_finite() => (f, g),
            _ => self.nearest_signed_distance(x),
        }
    }

    /// Accumulate the blend at `x` over the supports containing it, in two groups split by the
    /// sign of each field's normal against the most central covering field's.
    #[inline]
    fn blend<const GRAD: bool>(&self, x: DVec3, supports: &impl Supports) -> [Blend; 2] {
        let d = &*self.inner;
        let size = d.params.size;
        let c = size * size * size;
        let mut groups = [Blend::default(); 2];
        // The split is relative to the normal of the most central covering support (largest
        // weight; ties to the lower index), so it does not depend on the storage order.
        // One scan finds the supports containing x (keeping up to HITS of them) and the most
        // central one; the blend then visits the kept ones (past HITS it scans again), in the
        // scan's order either way.
        let (mut best, mut n_ref) = ((f64::INFINITY, usize::MAX), DVec3::ZERO);
        let mut hits = [(0u32, 0.0f64); HITS];
        let mut count = 0usize;
        supports.for_each_containing(x, |i, _, dist2| {
            if count < HITS {
                hits[count] = (i as u32, dist2);
            }
            count += 1;
            let key = (dist2 / (d.support[i] * d.support[i]), i);
            if key.0 < best.0 || (key.0 == best.0 && key.1 < best.1) {
                (best, n_ref) = (key, d.frames[i].axes[2]);
            }
        });
        let mut visit = |i: usize, rel: DVec3, dist2: f64| {
            let r = d.support[i];
            let fr = &d.frames[i];
            let normal = fr.axes[2];
            let acc = &mut groups[usize::from(normal.dot(n_ref) < 0.0)];
            let dist = dist2.sqrt();
            let (phi, dphi) = weight(dist / r);
            let (phi, dphi) = (phi * d.misfit[i], dphi * d.misfit[i]);
            let vote = d.votes[i];
            let votes = !vote.is_nan();
            if votes {
                acc.vw += phi;
                acc.vs += phi * vote;
            }
            acc.sw += phi;
            acc.centre += fr.center * phi;
            acc.normal += normal * phi;
            // How far x lies off the field's tangent plane, in world units and support radii.
            let off = normal.dot(rel);
            let lean = off / r;
            acc.lean += phi * lean;
            // A planar field's spline is the signed distance along its normal, with the normal
            // as its gradient: up to rounding the same value, as a support lies inside its
            // domain (radius ≤ the half edge), where the basis does not clamp.
            let planar = d.planar[i];
            let coeffs = &d.coeffs[i * c..(i + 1) * c];
            if !GRAD {
                acc.swf += phi
                    * if planar {
                        off
                    } else {
                        let [u, v, w] = fr.to_local(x);
                        eval3_value(size, coeffs, u, v, w)
                    };
                return;
            }
            let gphi = if dist > 0.0 {
                rel * (dphi / (r * dist))
            } else {
                DVec3::ZERO
            };
            let (s, gs) = if planar {
                (off, normal)
            } else {
                let [u, v, w] = fr.to_local(x);
                let (s, gq) = eval3(size, coeffs, u, v, w);
                let inv_edge = 0.5 / fr.half;
                (
                    s,
                    (fr.axes[0] * gq[0] + fr.axes[1] * gq[1] + normal * gq[2]) * inv_edge,
                )
            };
            acc.swf += phi * s;
            acc.gsw += gphi;
            acc.gswf += gphi * s + gs * phi;
            if votes {
                acc.gvw += gphi;
                acc.gvs += gphi * vote;
            }
            acc.glean += gphi * lean + normal * (phi / r);
        };
        if count <= HITS {
            for &(i, dist2) in &hits[..count] {
                let i = i as usize;
                visit(i, x - d.frames[i].center, dist2);
            }
        } else {
            supports.for_each_containing(x, visit);
        }
        groups
    }

    /// Signed distance to the nearest inlier point, signed by its normal (the fallback where
    /// no support covers `x`).
    pub fn nearest_signed_distance(&self, x: DVec3) -> (f64, DVec3) {
        let d = &*self.inner;
        // The index measures squared distances, which overflow beyond ~1e154: search from x
        // pulled in along its ray instead (as far out, the nearest point is the same).
        // (The index must not see NaN or infinity either.)
        let q = DVec3::from_array(x.to_array().map(|c| {
            if c.is_nan() {
                0.0
            } else {
                c.clamp(-f64::MAX, f64::MAX)
            }
        }));
        let far = q.abs().max_element();
        let q = if far > FAR_QUERY {
            q * (FAR_QUERY / far)
        } else {
            q
        };
        let (item, _) = d.nearest.nearest(q);
        let i = d.nearest_ids[item] as usize;
        let rel = x - d.frames[i].center;
        let n = d.normals[i];
        // Scaled length: finite even where |rel|² overflows.
        let m = rel.abs().max_element();
        let side = if m > 0.0 && m.is_finite() {
            (rel / m).dot(n)
        } else {
            rel.dot(n)
        };
        let sign = if side < 0.0 { -1.0 } else { 1.0 };
        let len = if m > 0.0 && m.is_finite() {
            m * (rel / m).length()
        } else {
            m
        };
        if len > 0.0 && len.is_finite() {
            (sign * len, rel * (sign / len))
        } else if m > 0.0 && !rel.is_nan() {
            // |rel| overflows (x near ±f64::MAX, or infinite): the largest component is a
            // finite lower bound of the distance; 0 would claim that x lies on the surface.
            let dir = (rel / m).try_normalize().map_or(n, |d| d * sign);
            (sign * m.min(f64::MAX), dir)
        } else {
            (0.0, n)
        }
    }

    /// `true` when some local support contains `x` (the blend, not the fallback, defines f).
    pub fn is_covered(&self, x: DVec3) -> bool {
        let d = &*self.inner;
        let mut hit = false;
        d.grid.for_each_containing(x, |_, _, _| hit = true);
        hit
    }
}

/// Two opposed groups (both with weight) combined as a thin solid (`max`), a thin gap
/// (`min`), or, where the covering fields' votes ([`vote`]) are split, a C¹ mix of the two.
/// The votes decide where the light side carries [`VOTE_FROM`] of the heavy side's weight and
/// the voting fields [`VOTE_WEIGHT`] of the blend's; short of that, the sides' weighted
/// centres (which side of one side's tangent plane the other's centre lies) decide, with a
/// C¹ hand-over between the two.
#[inline]
fn solid_or_gap<const GRAD: bool>(a: Blend, b: Blend) -> (f64, DVec3) {
    let hard = if (a.centre / a.sw - b.centre / b.sw).dot(a.normal) > 0.0 {
        1.0
    } else {
        -1.0
    };
    let (minor, major) = if a.sw < b.sw { (a, b) } else { (b, a) };
    let ratio = minor.sw / major.sw;
    let (w, vw) = (a.sw + b.sw, a.vw + b.vw);
    let (k, dk) = smoothstep(0.0, VOTE_FROM, ratio);
    let (q, dq) = smoothstep(0.0, VOTE_WEIGHT, vw / w);
    let vote = if vw > 0.0 { (a.vs + b.vs) / vw } else { hard };
    let m = hard + k * q * (vote - hard);
    let (t, dt) = smoothstep(-VOTE_BAND, VOTE_BAND, m);
    if t >= 1.0 {
        return combine_sides::<GRAD>(true, a, b);
    }
    if t <= 0.0 {
        return combine_sides::<GRAD>(false, a, b);
    }
    let (fs, gs) = combine_sides::<GRAD>(true, a, b);
    let (fg, gg) = combine_sides::<GRAD>(false, a, b);
    let f = fg + t * (fs - fg);
    if !GRAD {
        return (f, DVec3::ZERO);
    }
    let (gw, gvw) = (a.gsw + b.gsw, a.gvw + b.gvw);
    let gvote = if vw > 0.0 {
        (a.gvs + b.gvs - gvw * vote) / vw
    } else {
        DVec3::ZERO
    };
    let gratio = (minor.gsw * major.sw - major.gsw * minor.sw) / (major.sw * major.sw);
    let gshare = (gvw * w - gw * vw) / (w * w);
    let gm = gvote * (k * q) + (gratio * (dk * q) + gshare * (k * dq)) * (vote - hard);
    (f, gg + (gs - gg) * t + gm * (dt * (fs - fg)))
}

/// `(f, ∇f)` of the two sides `a` and `b` of a thin part, each blended alone and combined by
/// `max` for a thin solid (x is inside only where both sides say so: either side has a veto)
/// or `min` for a thin gap. A side that reaches across with a small share of the weight
/// loses its veto where only its fits' bend supports it: where x lies on the material side of
/// its own tangent planes (for a solid; the open side for a gap) while its blend says
/// otherwise. That is a fringe of the far side's supports, fitted round the
/// part's rim and reaching across an armadillo's ear or a thin shell near the end of their
/// support; kept as a veto, its extrapolated zero cut dents into the near side. Past a crease
/// the far side's planes themselves end the near side, and it keeps its veto there, as does a
/// side carrying more than [`LIGHT_SIDE_TO`] of the heavier side's weight. The hand-over is
/// gradual (C¹ in the weight ratio and the lean).
#[inline]
fn combine_sides<const GRAD: bool>(solid: bool, a: Blend, b: Blend) -> (f64, DVec3) {
    let (fa, fb) = (a.value(), b.value());
    let pick_a = if solid { fa.0 >= fb.0 } else { fa.0 <= fb.0 };
    let sides = if pick_a { fa } else { fb };
    let (minor, major, major_value) = if a.sw < b.sw { (a, b, fb) } else { (b, a, fa) };
    let ratio = minor.sw / major.sw;
    let (light, dlight) = smoothstep(LIGHT_SIDE_FROM, LIGHT_SIDE_TO, ratio);
    // The light side's lean off its planes toward where its veto would put x (outside for a
    // solid, inside for a gap): ≥ 0 where its planes agree with the veto.
    let sign = if solid { 1.0 } else { -1.0 };
    let lean = sign * minor.lean / minor.sw;
    let (planes, dplanes) = smoothstep(-PLANE_LEAN, 0.0, lean);
    // The light side's share of the combination: 1 (a veto, `sides`) unless it is light and
    // its planes disagree.
    let share = 1.0 - (1.0 - light) * (1.0 - planes);
    if share >= 1.0 {
        return sides;
    }
    let f = major_value.0 + share * (sides.0 - major_value.0);
    if !GRAD {
        return (f, DVec3::ZERO);
    }
    let gratio = (minor.gsw * major.sw - major.gsw * minor.sw) / (major.sw * major.sw);
    let glean = (minor.glean - minor.gsw * (minor.lean / minor.sw)) * (sign / minor.sw);
    let gshare = gratio * (dlight * (1.0 - planes)) + glean * ((1.0 - light) * dplanes);
    let g = major_value.1 + (sides.1 - major_value.1) * share + gshare * (sides.0 - major_value.0);
    (f, g)
}

/// The lighter side's weight, as a fraction of the heavier's, below which it can lose its
/// veto whole ...
const LIGHT_SIDE_FROM: f64 = 0.05;
/// ... and above which it keeps it whole.
const LIGHT_SIDE_TO: f64 = 0.15;
/// How far (in support radii, the weighted mean over the light side's fields) x may lie on
/// the wrong side of the light side's tangent planes before its veto is handed over whole.
const PLANE_LEAN: f64 = 0.1;

/// `(s, ds/dx)` of the C¹ smoothstep from `a` to `b`.
#[inline]
fn smoothstep(a: f64, b: f64, x: f64) -> (f64, f64) {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    (t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t) / (b - a))
}

/// Each field's vote, per slot ([`vote`]).
pub(super) fn solid_votes(
    frames: &[LocalFrame],
    support: &[f64],
    grid: &SupportGrid,
    agreement: f64,
) -> Vec<f64> {
    use rayon::prelude::*;
    (0..frames.len())
        .into_par_iter()
        .map(|i| vote(frames, support, grid, agreement, i))
        .collect()
}

/// Field `i`'s vote: how its opposed neighbours (fields whose support contains its centre and
/// whose normal has a dot product below `agreement` with its own) lie, weighted by their
/// blending weight there: +1 for one behind it (the two bound a thin solid), −1 for one in
/// front (a thin gap), soft within [`VOTE_SOFT`] of its support radius of level. NaN for a
/// field without opposed neighbours (and for outliers). Votes are fixed when a field is
/// fitted, so the mix the blend takes from them is continuous where the sides' own centres
/// come level.
pub(super) fn vote(
    frames: &[LocalFrame],
    support: &[f64],
    grid: &SupportGrid,
    agreement: f64,
    i: usize,
) -> f64 {
    let r = support[i];
    if r.is_nan() || r <= 0.0 {
        return f64::NAN;
    }
    let (c, n) = (frames[i].center, frames[i].axes[2]);
    let (mut sw, mut ss) = (0.0, 0.0);
    grid.for_each_containing(c, |j, _, dist2| {
        if j == i || n.dot(frames[j].axes[2]) >= agreement {
            return;
        }
        let w = weight(dist2.sqrt() / support[j]).0;
        let lead = (c - frames[j].center).dot(n) / (VOTE_SOFT * r);
        sw += w;
        ss += w * lead.clamp(-1.0, 1.0);
    });
    if sw > 0.0 { ss / sw } else { f64::NAN }
}

/// A field's vote is soft while its opposed neighbour's centre lies within this share of its
/// support radius of level with its own.
const VOTE_SOFT: f64 = 0.1;
/// The voting fields' share of the blend's weight by which the votes have taken over.
const VOTE_WEIGHT: f64 = 0.1;
/// The light side's weight, as a fraction of the heavier's, by which the votes have taken
/// over from the centres' arrangement.
const VOTE_FROM: f64 = 0.01;
/// The mean vote over which the combination turns from gap (`min`) to solid (`max`).
const VOTE_BAND: f64 = 0.5;

/// Supports a blend keeps from its one scan ([`GlobalField::blend`]); past this many it
/// scans again.
const HITS: usize = 64;

/// Beyond this coordinate magnitude the nearest-point search runs from a point pulled in along
/// the query's ray (squared distances overflow past ~1e154).
const FAR_QUERY: f64 = 1e150;

/// Running sums of the blend of one group of fields at one point.
#[derive(Debug, Clone, Copy, Default)]
struct Blend {
    sw: f64,
    swf: f64,
    gsw: DVec3,
    gswf: DVec3,
    /// `Σ φᵢ cᵢ` and `Σ φᵢ nᵢ`: where the group's points are and which way they face.
    centre: DVec3,
    normal: DVec3,
    /// `Σ φᵢ nᵢ·(x − cᵢ)/rᵢ` and its gradient: how far x lies off the group's tangent
    /// planes, outward, in support radii.
    lean: f64,
    glean: DVec3,
    /// `Σ φᵢ` and `Σ φᵢ vᵢ` over the fields that vote, and their gradients.
    vw: f64,
    vs: f64,
    gvw: DVec3,
    gvs: DVec3,
}

impl Blend {
    /// `(f, ∇f)` of this group alone (`sw > 0`).
    fn value(&self) -> (f64, DVec3) {
        let f = self.swf / self.sw;
        (f, (self.gswf - self.gsw * f) / self.sw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A group's sums as affine functions of x (each with a constant gradient), so its
    /// `value()` and the hand-over's gradient can be checked against central differences.
    fn group(x: DVec3, sw: (f64, DVec3), swf: (f64, DVec3), lean: (f64, DVec3)) -> Blend {
        Blend {
            sw: sw.0 + sw.1.dot(x),
            swf: swf.0 + swf.1.dot(x),
            gsw: sw.1,
            gswf: swf.1,
            lean: lean.0 + lean.1.dot(x),
            glean: lean.1,
            ..Blend::default()
        }
    }

    /// Two opposed groups whose centres come level as x moves along z: `b`'s centre sits at
    /// x, `a`'s at the origin facing +z, so the centres' arrangement says solid below z = 0
    /// and gap above. `b` weighs `b_weight` (plus a little slope); a share `a_voting` of
    /// `a`'s weight and all of `b`'s vote, `votes` (a mean each).
    fn level_centres(x: DVec3, b_weight: f64, a_voting: f64, votes: [f64; 2]) -> (Blend, Blend) {
        let d = DVec3::new;
        let mut a = group(
            x,
            (1.0, d(0.1, 0.0, 0.2)),
            (0.02, d(0.0, 0.1, 1.0)),
            (0.0, DVec3::ZERO),
        );
        let mut b = group(
            x,
            (b_weight, d(0.0, -0.1, 0.1) * b_weight),
            (-0.03 * b_weight, d(0.1, 0.0, -1.0) * b_weight),
            (0.0, DVec3::ZERO),
        );
        a.normal = DVec3::Z * a.sw;
        b.normal = -DVec3::Z * b.sw;
        b.centre = x * b.sw;
        (a.vw, a.gvw) = (a_voting * a.sw, a.gsw * a_voting);
        (a.vs, a.gvs) = (a.vw * votes[0], a.gvw * votes[0]);
        (b.vw, b.gvw) = (b.sw, b.gsw);
        (b.vs, b.gvs) = (b.vw * votes[1], b.gvw * votes[1]);
        (a, b)
    }

    /// The gradient `at` returns at `x` against central differences of its value, within
    /// `tolerance` relative to `1 + |∇f|`.
    fn assert_gradient_of_value(at: impl Fn(DVec3) -> (f64, DVec3), x: DVec3, tolerance: f64) {
        let (_, g) = at(x);
        let h = 1e-6;
        let fd = DVec3::new(
            at(x + DVec3::X * h).0 - at(x - DVec3::X * h).0,
            at(x + DVec3::Y * h).0 - at(x - DVec3::Y * h).0,
            at(x + DVec3::Z * h).0 - at(x - DVec3::Z * h).0,
        ) / (2.0 * h);
        assert!(
            (g - fd).length() < tolerance * (1.0 + g.length()),
            "at {x}: analytic {g} vs finite difference {fd}"
        );
    }

    #[test]
    fn planar_fields_blend_as_their_splines_do() {
        use crate::field::NoProgress;
        use crate::knn::{KnnGraph, PointIndex};
        use crate::local_fit::FitParams;
        use std::sync::Arc;
        // A flat sheet (z = 0, normals exactly +z) with a smooth bump in its middle: the flat
        // part's fields are planes, the bump's are not.
        let bump = |x: f64, y: f64| {
            let s = 1.0 - (x * x + y * y) / 0.09;
            if s > 0.0 {
                (
                    0.05 * s * s,
                    DVec3::new(0.4 * s * x / 0.09, 0.4 * s * y / 0.09, 1.0),
                )
            } else {
                (0.0, DVec3::Z)
            }
        };
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for a in -20..=20 {
            for b in -20..=20 {
                let (x, y) = (a as f64 * 0.03, b as f64 * 0.03);
                let (z, n) = bump(x, y);
                points.push(DVec3::new(x, y, z));
                normals.push(n.normalize());
            }
        }
        let knn = KnnGraph::build(&points, &PointIndex::new(&points), 20);
        for params in [
            FitParams::default(),
            FitParams {
                centre_spacing: 0.35,
                flat_spacing: 0.5,
                ..FitParams::default()
            },
        ] {
            let field = GlobalField::build(&points, &normals, &knn, &params, &NoProgress).unwrap();
            let planar = field.inner.planar.iter().filter(|p| **p).count();
            assert!(
                planar > field.inner.planar.len() / 3 && planar < field.inner.planar.len(),
                "{planar} of {} fields planar",
                field.inner.planar.len()
            );
            let mut splines = field.clone();
            Arc::make_mut(&mut splines.inner).planar.fill(false);
            // Over the sheet, the bump and the rim, on and off the surface, and past the rim
            // (where the supports end).
            for a in -26..=26 {
                for b in -26..=26 {
                    for z in [-0.04, -0.003, 0.0, 0.01, 0.06] {
                        let x = DVec3::new(a as f64 * 0.0237, b as f64 * 0.0237, z);
                        let (f, g) = field.value_and_gradient(x);
                        let (fs, gs) = splines.value_and_gradient(x);
                        assert!(
                            (f - fs).abs() <= 1e-14 + 1e-12 * fs.abs(),
                            "{x}: {f} vs {fs}"
                        );
                        assert!((g - gs).length() <= 1e-11, "{x}: {g} vs {gs}");
                        assert!(
                            (field.value(x) - splines.value(x)).abs() <= 1e-14 + 1e-12 * fs.abs()
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn split_votes_mix_solid_and_gap_without_a_step_where_the_centres_come_level() {
        // Both sides heavy, every field voting, the votes split (a mean of about 0.17): the
        // votes decide, so f is continuous where the centres come level.
        let at = |x: DVec3, votes: [f64; 2]| {
            let (a, b) = level_centres(x, 0.5, 1.0, votes);
            solid_or_gap::<true>(a, b)
        };
        let (below, above) = (
            DVec3::new(0.01, 0.02, -1e-12),
            DVec3::new(0.01, 0.02, 1e-12),
        );
        let jump = (at(above, [0.3, -0.1]).0 - at(below, [0.3, -0.1]).0).abs();
        assert!(
            jump < 1e-9,
            "f jumps by {jump} where the centres come level"
        );
        // Without votes (NaN for every field: no opposed neighbours) the centres decide, and f
        // steps there.
        let at_unvoted = |x: DVec3| {
            let (mut a, mut b) = level_centres(x, 0.5, 1.0, [0.0; 2]);
            (a.vw, a.vs, b.vw, b.vs) = (0.0, 0.0, 0.0, 0.0);
            solid_or_gap::<true>(a, b).0
        };
        let hard = (at_unvoted(above) - at_unvoted(below)).abs();
        assert!(hard > 1e-3, "without votes: {hard}");
        // Inside the mix the gradient is that of the value.
        assert_gradient_of_value(|x| at(x, [0.3, -0.1]), DVec3::new(0.01, 0.02, 0.03), 1e-6);
        // And where a light side (0.6 % of the other's weight) and few voters (7 % of the
        // weight) hand the decision between the centres and the votes.
        assert_gradient_of_value(
            |x| {
                let (a, b) = level_centres(x, 0.006, 0.06, [-0.9, -0.9]);
                solid_or_gap::<true>(a, b)
            },
            DVec3::new(0.01, 0.02, -0.03),
            1e-6,
        );
    }

    #[test]
    fn the_light_sides_hand_over_has_the_gradient_of_its_value() {
        let d = DVec3::new;
        // A heavy near side, and a light far side (ratio ≈ 0.1) whose blend vetoes (its value
        // is the larger) while its planes lean 0.05 radii the wrong way: both smoothsteps are
        // inside their ramps.
        let sides = |x: DVec3| {
            let near = group(
                x,
                (2.0, d(0.3, -0.2, 0.1)),
                (-0.02, d(0.5, 0.1, 1.9)),
                (0.0, DVec3::ZERO),
            );
            let far = group(
                x,
                (0.2, d(-0.1, 0.05, 0.02)),
                (0.002, d(0.01, -0.02, 0.05)),
                (-0.01, d(0.02, 0.01, -0.03)),
            );
            (near, far)
        };
        let at = |x: DVec3| {
            let (near, far) = sides(x);
            combine_sides::<true>(true, near, far)
        };
        let x = d(0.01, -0.02, 0.005);
        assert_gradient_of_value(at, x, 1e-7);
        let f = at(x).0;
        // Strictly between the near side alone and the veto.
        let (near, far) = sides(x);
        let (near, far) = (near.value().0, far.value().0);
        assert!(near < f && f < far, "{near} < {f} < {far}");
    }
}
