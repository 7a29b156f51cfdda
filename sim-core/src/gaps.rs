//! Gap fields: extra local fields for a static surface where the points leave a gap that the
//! points' own fields would only reach from one side ([`FitParams::gap_fields`]).
//!
//! A point whose neighbours all lie to one side of it (a row of points along a rounded edge,
//! beside a face sampled only at its far-apart corners) fits a quadric that follows that side
//! and carries its curvature across the empty half of its domain. Where two such fits meet over
//! a gap, the blend sags between them (the rocker arm's faces sagged 4.6 mm, see
//! docs/BENCHMARKS.md). A gap field is centred in the gap itself, at the midpoint between such a
//! point and the nearest point across the gap, and fitted to *its* own `k` nearest points:
//! those on both sides, as a query-centred fit (APSS, MLS) would use.
//!
//! Contract: [`plan`] is deterministic (it visits the centres in the order given and keeps a
//! site only where no point and no site already kept lies within [`SITE_CLEARANCE`] of its
//! point's radius, so a site sits in a real gap and a gap gets one field per clearance). It
//! runs at build time and allocates; its inputs are validated finite (the field's build). A
//! site lies on a chord between two points, so a little off a curved surface; its field is
//! fitted in a frame there like any other.

use glam::DVec3;
use rayon::prelude::*;

use crate::knn::{KnnGraph, PointIndex};
use crate::local_fit::FitParams;

/// A site is kept only if no point and no site kept before it lies within this many of its
/// point's neighbourhood radii.
pub const SITE_CLEARANCE: f64 = 0.4;

/// How far across a gap a point looks for its far side, in its neighbourhood radii.
pub const REACH: f64 = 2.5;

/// The far side lies within acos(CONE) (45°) of the direction away from the point's
/// neighbours.
pub const CONE: f64 = 0.7;

/// The point across must face within acos(SAME_SHEET) (60°) of the point's own normal: the
/// other side of a gap in one sheet, not the far sheet of a thin part or a face across a crease.
pub const SAME_SHEET: f64 = 0.5;

/// Where a gap field goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapSite {
    /// Centre of the field's domain (in the gap).
    pub centre: DVec3,
    /// Frame normal: the normal of the point it was made from.
    pub normal: DVec3,
}

/// The gap sites of the lopsided points among `centres` (point indices).
///
/// A point is lopsided when its neighbours' mean offset, projected on its tangent plane, is
/// at least `params.gap_fields` × its neighbourhood radius `r`. It proposes the midpoint
/// between itself and the nearest point across the gap (within [`REACH`] `r`, in a cone of
/// half-angle acos [`CONE`] about the direction away from its neighbours). No proposal from:
/// - an outlier;
/// - a point with a neighbour facing more than 90° from it: one on a part thinner than its
///   neighbourhood or beside a sharp crease (sites there, between sheets or faces, split a
///   thin part of the benchmark's cow into two pieces);
/// - a point with nothing across (an open rim), or whose point across faces another way
///   ([`SAME_SHEET`]);
/// - a midpoint within [`SITE_CLEARANCE`] `r` of a point (no gap).
pub fn plan(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    outlier: &[bool],
    centres: &[u32],
    index: &PointIndex,
    params: &FitParams,
) -> Vec<GapSite> {
    if params.gap_fields <= 0.0 {
        return Vec::new();
    }
    // Proposals in parallel (each needs only its own neighbourhood and the point index).
    let proposed: Vec<(GapSite, f64)> = centres
        .par_iter()
        .filter_map(|&i| {
            let (p, n, r) = (
                points[i as usize],
                normals[i as usize],
                knn.radius(i as usize),
            );
            if outlier[i as usize] || r <= 0.0 {
                return None;
            }
            let hood = knn.neighbours(i as usize);
            let mut mean = DVec3::ZERO;
            for &j in hood {
                if normals[j as usize].dot(n) < 0.0 {
                    return None; // a thin part's other sheet, or a crease sharper than 90°
                }
                mean += points[j as usize] - p;
            }
            mean /= hood.len() as f64;
            let along = mean - n * mean.dot(n);
            let lean = along.length();
            if lean < params.gap_fields * r {
                return None;
            }
            let away = -along / lean;
            let (across, _) = index
                .within(p, REACH * r)
                .into_iter()
                .filter(|&(j, d)| d > 0.0 && !outlier[j] && (points[j] - p).dot(away) > CONE * d)
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            if normals[across].dot(n) < SAME_SHEET {
                return None; // across a thin part or a crease: not a gap in one sheet
            }
            let centre = (p + points[across]) * 0.5;
            let site = GapSite { centre, normal: n };
            (index.nearest(centre).1 >= SITE_CLEARANCE * r).then_some((site, r))
        })
        .collect();
    if proposed.is_empty() {
        return Vec::new();
    }
    // One site per gap: in order, drop a site with a kept one within its clearance.
    let centres: Vec<DVec3> = proposed.iter().map(|(s, _)| s.centre).collect();
    let site_index = PointIndex::new(&centres);
    let mut kept = vec![false; proposed.len()];
    for (a, (site, r)) in proposed.iter().enumerate() {
        kept[a] = !site_index
            .within(site.centre, SITE_CLEARANCE * r)
            .iter()
            .any(|&(b, _)| b < a && kept[b]);
    }
    proposed
        .into_iter()
        .zip(kept)
        .filter_map(|((site, _), keep)| keep.then_some(site))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nodes of a 24 × 24 unit grid on z = 0 that `keep` keeps, with normals +z.
    fn plane(keep: impl Fn(DVec3) -> bool) -> (Vec<DVec3>, Vec<DVec3>) {
        let points: Vec<DVec3> = (0..24)
            .flat_map(|i| (0..24).map(move |j| DVec3::new(i as f64, j as f64, 0.0)))
            .filter(|&p| keep(p))
            .collect();
        let normals = vec![DVec3::Z; points.len()];
        (points, normals)
    }

    /// The grid with a slot four spacings wide cut out of its middle.
    fn slotted_plane() -> (Vec<DVec3>, Vec<DVec3>) {
        plane(|p| (p.x - 11.5).abs() > 2.0)
    }

    fn sites(points: &[DVec3], normals: &[DVec3]) -> Vec<GapSite> {
        let index = PointIndex::new(points);
        let knn = KnnGraph::build(points, &index, 20);
        let params = FitParams {
            gap_fields: 0.12,
            ..FitParams::default()
        };
        let all: Vec<u32> = (0..points.len() as u32).collect();
        let outlier = vec![false; points.len()];
        plan(points, normals, &knn, &outlier, &all, &index, &params)
    }

    #[test]
    fn sites_fill_the_slot_and_not_the_open_rim() {
        let (points, normals) = slotted_plane();
        let found = sites(&points, &normals);
        assert!(!found.is_empty());
        for site in &found {
            // In the slot (the outer rim, with nothing across, proposes nothing)…
            assert!((site.centre.x - 11.5).abs() < 2.0, "{site:?}");
            assert!(site.centre.z.abs() < 1e-12 && site.normal == DVec3::Z);
            // …and clear of every point.
            let nearest = points
                .iter()
                .map(|p| (*p - site.centre).length())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest > 1.0, "{site:?} {nearest}");
        }
        assert_eq!(found, sites(&points, &normals), "deterministic");
    }

    #[test]
    fn a_field_built_with_the_callers_index_is_the_same_field() {
        use crate::field::{FieldError, GlobalField, NoProgress};
        let (points, normals) = slotted_plane();
        let index = PointIndex::new(&points);
        let knn = KnnGraph::build(&points, &index, 20);
        let params = FitParams {
            gap_fields: 0.12,
            centre_spacing: 0.35,
            ..FitParams::default()
        };
        let own = GlobalField::build(&points, &normals, &knn, &params, &NoProgress).unwrap();
        let given =
            GlobalField::build_indexed(&points, &normals, &knn, &index, &params, &NoProgress)
                .unwrap();
        assert!(given.gap_field_count() > 0, "the slot gets gap fields");
        assert_eq!(own.gap_field_count(), given.gap_field_count());
        for x in [(11.5, 7.0, 0.3), (11.2, 12.0, -0.2), (3.0, 3.0, 0.5)] {
            let x = DVec3::from(x);
            assert_eq!(
                own.value_and_gradient(x),
                given.value_and_gradient(x),
                "at {x}"
            );
        }
        // An index over other points is refused, not trusted.
        let other = PointIndex::new(&points[..10]);
        let refused =
            GlobalField::build_indexed(&points, &normals, &knn, &other, &params, &NoProgress);
        let refused = refused.unwrap_err();
        assert_eq!(
            refused,
            FieldError::IndexMismatch {
                points: points.len(),
                index: 10
            }
        );
        assert_eq!(
            refused.to_string(),
            format!("{} points but a k-d tree over 10", points.len())
        );
    }

    #[test]
    fn a_plane_without_gaps_gets_no_sites() {
        let (points, normals) = plane(|_| true);
        assert!(sites(&points, &normals).is_empty());
    }
}
