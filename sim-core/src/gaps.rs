//! Gap fields: extra local fields for a static surface where the points leave a gap that the
//! points' own fields would only reach from one side ([`FitParams::gap_fields`]).
//!
//! A point whose neighbours all lie to one side of it (a row of points along a rounded edge,
//! beside a face sampled only at its far-apart corners) fits a quadric that follows that side
//! and carries its curvature across the empty half of its domain. Where two such fits meet over
//! a gap, the blend sags between them (the rocker arm's faces sagged 4.6 mm, see
//! docs/BENCHMARKS.md). A gap field is centred in the gap itself, at the place clearest of the
//! points on the chords from such a point to the nearest points across the gap, and fitted to
//! *its* own `k` nearest points: those on all sides, as a query-centred fit (APSS, MLS) would
//! use. (The midpoint of the chord to the nearest point across often lies near the gap's rim,
//! too near a point to be kept: beside an ear of the armadillo the fits of the rim's points
//! bulged 0.6 units over a gap two spacings wide that no site reached.)
//!
//! Contract: [`plan`] is deterministic (it visits the centres in the order given and keeps a
//! site only where no point lies within [`SITE_CLEARANCE`] of its point's radius and no site
//! already kept within as many, so a site sits in a real gap and a gap gets one field per
//! clearance). It
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

/// How many of the nearest points across the gap a lopsided point draws chords to.
pub const ACROSS_TRIED: usize = 4;

/// Where along a chord (a share of the way from the lopsided point to the point across) a
/// site may sit: the place on them clearest of every point is the site.
pub const CHORD_SHARES: [f64; 5] = [0.5, 0.4, 0.6, 0.3, 0.7];

/// A gap whose nearest chord's midpoint is not clear of the points (by [`SITE_CLEARANCE`]) still
/// gets a site where some place on the chords is clear by this many of the point's radii.
pub const WIDE_GAP: f64 = 0.5;

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
/// at least `params.gap_fields` × its neighbourhood radius `r`. The points across the gap are
/// those within [`REACH`] `r` in a cone of half-angle acos [`CONE`] about the direction away
/// from its neighbours. It proposes the place clearest of every point among [`CHORD_SHARES`] of
/// the way to each of the [`ACROSS_TRIED`] nearest of them (those facing its way,
/// [`SAME_SHEET`]). No proposal from:
/// - an outlier;
/// - a point with a neighbour facing more than 90° from it: one on a part thinner than its
///   neighbourhood or beside a sharp crease (sites there, between sheets or faces, split a
///   thin part of the benchmark's cow into two pieces);
/// - a point with nothing across (an open rim), or whose point across faces another way
///   ([`SAME_SHEET`]), or lies within 2 × [`SITE_CLEARANCE`] `r` (no gap on this side);
/// - a gap whose nearest chord's midpoint lies within [`SITE_CLEARANCE`] `r` of a point, unless
///   the proposed place is clear of every point by [`WIDE_GAP`] `r` (no gap, or a narrow one).
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
    let proposed: Vec<(GapSite, f64, f64)> = centres
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
            // A neighbour across nearer than `2 · SITE_CLEARANCE` puts the nearest chord's
            // midpoint too near both: no proposal (a gap beyond that neighbour is left to the
            // points around it). This settles most lopsided points of a randomly sampled
            // surface without a range query.
            if hood.iter().any(|&j| {
                let off = points[j as usize] - p;
                let d = off.length();
                d > 0.0 && d < 2.0 * SITE_CLEARANCE * r && off.dot(away) > CONE * d
            }) {
                return None;
            }
            let near = index.within(p, REACH * r);
            let mut across: Vec<(usize, f64)> = near
                .iter()
                .copied()
                .filter(|&(j, d)| d > 0.0 && !outlier[j] && (points[j] - p).dot(away) > CONE * d)
                .collect();
            across.sort_by(|a, b| a.1.total_cmp(&b.1));
            let &(first, _) = across.first()?;
            if normals[first].dot(n) < SAME_SHEET {
                return None; // across a thin part or a crease: not a gap in one sheet
            }
            // How far a place on a chord lies from every point, or `None` once a point lies
            // nearer than `beat`: the points within `REACH` of `p` are all a place can be
            // nearer to than `REACH · r − |place − p|`.
            let clearance = |place: DVec3, beat: f64| {
                let mut clear = REACH * r - (place - p).length();
                for &(j, _) in &near {
                    let d = (points[j] - place).length_squared();
                    if d <= beat * beat {
                        return None;
                    }
                    clear = clear.min(d.sqrt());
                }
                Some(clear)
            };
            let midpoint = (p + points[first]) * 0.5;
            let mut best = (midpoint, clearance(midpoint, 0.0)?);
            let midpoint_clear = best.1 >= SITE_CLEARANCE * r;
            for &(j, d) in across.iter().take(ACROSS_TRIED) {
                if normals[j].dot(n) < SAME_SHEET {
                    continue;
                }
                for t in CHORD_SHARES {
                    // A place is no clearer than its distance to the chord's two ends.
                    if t.min(1.0 - t) * d <= best.1 {
                        continue;
                    }
                    let place = p + (points[j] - p) * t;
                    if let Some(clear) = clearance(place, best.1) {
                        best = (place, clear);
                    }
                }
            }
            let (centre, clear) = best;
            let site = GapSite { centre, normal: n };
            (midpoint_clear || clear >= WIDE_GAP * r).then_some((site, r, clear / r))
        })
        .collect();
    if proposed.is_empty() {
        return Vec::new();
    }
    // One site per gap: the clearest first (ties in the centres' order), drop a site with a
    // kept one within its clearance.
    let proposed: Vec<(GapSite, f64)> = {
        let mut by_clearance = proposed;
        by_clearance.sort_by(|a, b| b.2.total_cmp(&a.2));
        by_clearance
            .into_iter()
            .map(|(site, r, _)| (site, r))
            .collect()
    };
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

    /// The grid with a round hole about five spacings across, off the grid's symmetry (a large
    /// triangle of a decimated scan, its corners the only samples around it).
    fn holed_plane(middle: DVec3) -> (Vec<DVec3>, Vec<DVec3>) {
        plane(|p| (p - middle).length() > 2.7)
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

    /// The chord to the nearest point across a round hole runs off its middle, and its midpoint
    /// lies near the rim; the site is the place on the chords clearest of the points, so the
    /// hole's middle gets one, and is kept first. Measured: the site nearest the middle 0.70
    /// spacings from it; 1.57 with the nearest chords' midpoints alone, 1.12 with the clearest
    /// places kept in the centres' order.
    #[test]
    fn a_round_hole_gets_a_site_near_its_middle() {
        let middle = DVec3::new(11.3, 11.6, 0.0);
        let (points, normals) = holed_plane(middle);
        let found = sites(&points, &normals);
        let nearest = found
            .iter()
            .map(|s| (s.centre - middle).length())
            .fold(f64::INFINITY, f64::min);
        eprintln!(
            "{} sites, nearest the middle {nearest:.2}: {found:?}",
            found.len()
        );
        for site in &found {
            assert!(
                (site.centre - middle).length() < 2.7,
                "{site:?} not in the hole"
            );
        }
        assert!(nearest < 0.8, "no site near the hole's middle: {found:?}");
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
