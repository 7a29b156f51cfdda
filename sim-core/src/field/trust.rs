//! Where a field's zero set is trusted: vouched for by nearby points, with enough blending
//! weight, near the vouching points' planes and facing them.

use glam::DVec3;

use super::supports::{Items, Supports};
use super::{GlobalField, SupportList, weight};
#[cfg(doc)]
use crate::local_fit::FitParams;

impl GlobalField {
    /// Whether the field is trusted at `x`, the test every consumer of the zero set applies
    /// (meshing, projection, region grids, CSG classification). Three conditions:
    /// - some point *vouches* for `x`: it lies within `trust ×` that point's support radius
    ///   ([`FitParams::trust`]);
    /// - the blending weight there, `Σ φᵢ(x)`, is at least [`FitParams::trust_weight`];
    /// - the vouching points do not disown it: less than three quarters of their weight comes
    ///   from points with `x` more than [`FitParams::trust_plane`] (0.2) support radii off
    ///   their tangent plane.
    ///
    /// Nearer the points the blend interpolates them; farther out the local fits extrapolate,
    /// and a zero set there is not evidence of a surface. Each condition removes one kind of
    /// spurious piece, measured on the benchmark shapes (docs/BENCHMARKS.md): the distance, the
    /// sheets where fits curl past the end of their data (the bunny's ears; 0.7 keeps randomly
    /// sampled shapes whole, 0.5 left gaps in a 20k-point torus, the sheet returns at 0.9);
    /// the weight, the fringe a few rim fields reach alone (a CSG rim's fits continuing over
    /// the carved-away void: three fields, `Σ φ` = 0.17 against ≈ 5 on a surface); the planes,
    /// fins that one-sided fits beside a crease bend into the void (3 mm off the planes of
    /// every point near them). A sampled surface passes all three: it lies within half a
    /// spacing of a sample and near its neighbours' planes. Allocation-free.
    pub fn is_trusted(&self, x: DVec3) -> bool {
        self.trust_at(x).0
    }

    /// [`GlobalField::is_trusted`] with the supports taken from a list gathered for a box
    /// ([`GlobalField::gather_supports`]): the same answer for every `x` in that box.
    pub fn is_trusted_near(&self, x: DVec3, supports: &SupportList) -> bool {
        self.trust_near(x, supports).0
    }

    /// Where `x` is trusted ([`GlobalField::is_trusted_near`]), the way the points vouching
    /// for it face: their normals' mean weighted by blending weight, Σ φᵢ nᵢ / Σ φᵢ, whose
    /// length says how well they agree (1: all alike). Meshing keeps a piece
    /// of zero set only where its outward direction agrees with that: a zero set facing
    /// against its points is the back of a bump or dent one noisy point's fit makes (a point a
    /// fraction of a spacing off its neighbours' surface, as scans have), a small inverted
    /// piece a cell or so beside the surface.
    pub fn trusted_facing_near(&self, x: DVec3, supports: &SupportList) -> Option<DVec3> {
        let (trusted, facing) = self.trust_near(x, supports);
        trusted.then_some(facing)
    }

    /// Whether a zero set whose outward direction is `outward` faces the way `facing` (from
    /// [`GlobalField::trusted_facing_near`]) says its points do; always, with
    /// [`FitParams::trust_facing`] off, and where the points disagree among themselves
    /// (`|facing|` below 0.8: the sides of a part thinner than the supports,
    /// a tail or a horn, whose normals point every way and say nothing about which way the
    /// zero set there should face).
    pub fn faces_its_points(&self, outward: DVec3, facing: DVec3) -> bool {
        !self.inner.params.trust_facing
            || facing.length() < FACING_AGREEMENT
            || outward.dot(facing) > FACING_LIMIT * outward.length() * facing.length()
    }

    /// [`GlobalField::trusted_facing_near`] with the supports from the index.
    pub fn trusted_facing(&self, x: DVec3) -> Option<DVec3> {
        let (trusted, facing) = self.trust_at(x);
        trusted.then_some(facing)
    }

    /// Visit every local field whose support contains `x`, with the supports from a list
    /// gathered for a box holding `x`: its point (a gap field's centre), unit normal, blending
    /// weight at `x` and support radius.
    pub fn for_each_support_near(
        &self,
        x: DVec3,
        supports: &SupportList,
        mut visit: impl FnMut(DVec3, DVec3, f64, f64),
    ) {
        let d = &*self.inner;
        supports.for_each_containing(x, |i, _, dist2| {
            let r = d.support[i];
            visit(
                d.frames[i].center,
                d.normals[i],
                weight(dist2.sqrt() / r).0,
                r,
            );
        });
    }

    /// Whether `x` is trusted, and the vouching points' mean normal weighted by their blending
    /// weights ([`GlobalField::trusted_facing_near`]), with the witnesses from the index.
    fn trust_at(&self, x: DVec3) -> (bool, DVec3) {
        let d = &*self.inner;
        match &d.witnesses {
            None => self.trust_by(x, &d.grid, &d.normals, &d.support),
            Some(w) => self.trust_by(x, &w.grid, &w.normals, &w.support),
        }
    }

    /// [`GlobalField::trust_at`] with the witnesses of a list gathered for a box.
    fn trust_near(&self, x: DVec3, list: &SupportList) -> (bool, DVec3) {
        let d = &*self.inner;
        match &d.witnesses {
            None => self.trust_by(x, list, &d.normals, &d.support),
            Some(w) => self.trust_by(x, &Items(&list.witnesses), &w.normals, &w.support),
        }
    }

    /// The trust test over `supports`, whose ids index `normals` and `support`.
    fn trust_by(
        &self,
        x: DVec3,
        supports: &impl Supports,
        normals: &[DVec3],
        support: &[f64],
    ) -> (bool, DVec3) {
        if !x.is_finite() {
            return (false, DVec3::ZERO);
        }
        let d = &*self.inner;
        let tau2 = d.params.trust * d.params.trust;
        let (mut weight_sum, mut vouching, mut off_plane) = (0.0, 0.0, 0.0);
        let mut facing = DVec3::ZERO;
        supports.for_each_containing(x, |i, rel, dist2| {
            let r2 = support[i] * support[i];
            let phi = weight((dist2 / r2).sqrt()).0;
            weight_sum += phi;
            if dist2 <= tau2 * r2 {
                // A point vouches for x; it disowns x lying far off its tangent plane.
                vouching += phi + f64::MIN_POSITIVE;
                facing += normals[i] * phi;
                if rel.dot(normals[i]).abs() > d.params.trust_plane * support[i] {
                    off_plane += phi + f64::MIN_POSITIVE;
                }
            }
        });
        let trusted = vouching > 0.0
            && weight_sum >= d.params.trust_weight
            && off_plane < OFF_PLANE_SHARE * vouching;
        (trusted, if trusted { facing / vouching } else { facing })
    }

    /// The value a sampled grid and an inside test should use: `f(x)` where it is trusted or
    /// agrees in sign with the nearest oriented point; otherwise the nearest point's signed
    /// distance ([`GlobalField::nearest_signed_distance`]). So the inside of a spurious sheet or
    /// blob beyond the trusted band is outside, while the deep interior of a solid (untrusted
    /// but on the points' inner side) keeps `f`.
    pub fn trusted_value(&self, x: DVec3) -> f64 {
        self.trusted_value_from(x, self.value(x))
    }

    /// [`GlobalField::trusted_value`] given `f = f(x)` already evaluated (e.g. by
    /// [`GlobalField::value_near`]).
    pub fn trusted_value_from(&self, x: DVec3, f: f64) -> f64 {
        if !x.is_finite() || self.is_trusted(x) {
            return f;
        }
        let (nsd, _) = self.nearest_signed_distance(x);
        if (nsd < 0.0) == (f < 0.0) { f } else { nsd }
    }
}

/// The zero set is untrusted where points holding this share of the vouching weight disown it.
const OFF_PLANE_SHARE: f64 = 0.75;

/// The least agreement (length of the vouching points' weighted mean normal) at which the
/// facing test applies ([`GlobalField::faces_its_points`]). A smooth surface's points agree
/// to better than 0.95; on a shell thinner than the supports both sides vouch and they do not.
/// Measured on a 0.02-thick ellipsoid (the test
/// `a_shell_thinner_than_the_supports_keeps_its_facing_test_quiet`): applied at any agreement
/// (as it was) the test cut it into many pieces, at 0.5 into two; at 0.8 and 0.9 it is whole,
/// while 0.95 let a piece through on the CSG crease. The Stanford bunny scan's inverted bump
/// (agreement near 1) is left out at all of them.
const FACING_AGREEMENT: f64 = 0.8;

/// Cosine of the largest angle between a meshed zero set's outward direction and the way its
/// vouching points face ([`GlobalField::faces_its_points`]).
const FACING_LIMIT: f64 = -0.5;
