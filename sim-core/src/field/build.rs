//! Building a field: the gap samples that join the points (a static surface's), the points'
//! local fits (thinned to centres for a static surface), the gap fields between them, the
//! support index and the trust witnesses.

use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use super::{FieldData, FieldError, GlobalField, NO_LOCAL, Progress, Witnesses};
use crate::bspline::{MAX_SIZE, RefitOperator};
use crate::gaps::GapSite;
use crate::knn::{KnnGraph, PointIndex};
use crate::local_fit::{
    FitParams, FitScratch, LocalFrame, Neighbourhood, fit_local, fit_misfit, is_tangent_plane,
};
use crate::outliers::flag_outliers;
use crate::spatial::SupportGrid;

impl GlobalField {
    /// Fit every point's local field (on all cores) and index the supports.
    ///
    /// `normals` are unit and consistently oriented outward; `knn` lists each point's neighbours
    /// (its `k` is the neighbourhood size; `params.k` is not consulted here).
    /// With [`FitParams::gap_samples`] (a thinned field), samples placed in the gaps join the
    /// points ([`crate::gap_samples`]): the field's point indices from `points.len()` on are
    /// theirs, with a k-NN graph of the same `k` over both.
    pub fn build(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        Self::build_with_index(points, normals, knn, None, None, params, progress)
    }

    /// [`GlobalField::build`] with the caller's k-d tree over `points` (the one `knn` was built
    /// with), which the gap fields' planning queries instead of building a second.
    pub fn build_indexed(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        index: &PointIndex,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        if index.len() != points.len() {
            return Err(FieldError::IndexMismatch {
                points: points.len(),
                index: index.len(),
            });
        }
        Self::build_with_index(points, normals, knn, Some(index), None, params, progress)
    }

    /// `own_radii`: where gap samples joined the points ([`GlobalField::build_with_samples`]),
    /// the given points' own trust radii; only those points vouch for the zero set.
    fn build_with_index(
        points: &[DVec3],
        normals: &[DVec3],
        knn: &KnnGraph,
        index: Option<&PointIndex>,
        own_radii: Option<&[f64]>,
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        validate(points, normals, knn, params)?;
        let n = points.len();
        let radii: Vec<f64> = (0..n).map(|i| knn.radius(i)).collect();
        let mut sorted: Vec<f64> = radii.iter().copied().filter(|r| *r > 0.0).collect();
        sorted.sort_by(f64::total_cmp);
        let typical = sorted.get(sorted.len() / 2).copied().unwrap_or(1.0);
        // Outliers and the trust radii (`radii`) come from the full neighbourhoods; the fits,
        // their domains and supports and the thinning from the ones used (`k_even`).
        let outlier = flag_outliers(
            points,
            normals,
            knn,
            params.outlier_ratio,
            params.normal_agreement,
            typical,
        );
        if params.gap_samples > 0.0 && params.centre_spacing > 0.0 {
            let samples =
                crate::gap_samples::place(points, normals, knn, &outlier, params.gap_samples);
            if !samples.is_empty() {
                return Self::build_with_samples(points, normals, knn, &samples, params, progress);
            }
        }
        let even;
        let knn = if params.centre_spacing > 0.0 && (2..knn.k()).contains(&params.k_even) {
            let mut shrunk = knn.clone();
            shrunk.shrink(|i, hood, dist| even_count(points, normals, i, hood, dist, params));
            even = shrunk;
            &even
        } else {
            knn
        };
        let small_neighbourhoods = (0..n)
            .filter(|&i| knn.neighbours(i).len() < knn.k())
            .count();
        // The points that get a local field (all of them unless thinned), in Morton order.
        let centres = thinned_centres(points, normals, knn, &outlier, params);
        let centre_points: Vec<DVec3> = centres.iter().map(|&i| points[i as usize]).collect();
        let order: Vec<u32> = crate::pointset::morton_order(&centre_points)
            .into_iter()
            .map(|c| centres[c as usize])
            .collect();
        let mut slot = vec![NO_LOCAL; n];
        for (s, &i) in order.iter().enumerate() {
            slot[i as usize] = s as u32;
        }
        let n = order.len();
        let c = params.size.pow(3);
        let mut coeffs = vec![0.0; n * c];
        // Every slot's frame is written by its fit.
        let unfitted = LocalFrame {
            center: DVec3::ZERO,
            axes: [DVec3::X, DVec3::Y, DVec3::Z],
            half: 1.0,
        };
        let mut frames = vec![unfitted; n];
        let mut misfit = vec![1.0; n];
        const BLOCK: usize = 512;
        coeffs
            .par_chunks_mut(c * BLOCK)
            .zip(frames.par_chunks_mut(BLOCK))
            .zip(misfit.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each_init(
                || (FitScratch::new(params.size), Vec::new(), Vec::new()),
                |(scratch, hp, hn), (block, ((cs, fs), qs))| {
                    for (o, ((coef, frame), q)) in cs
                        .chunks_mut(c)
                        .zip(fs.iter_mut())
                        .zip(qs.iter_mut())
                        .enumerate()
                    {
                        let i = order[block * BLOCK + o] as usize;
                        hp.clear();
                        hn.clear();
                        for &j in knn.neighbours(i) {
                            if !outlier[j as usize] || j as usize == i {
                                hp.push(points[j as usize]);
                                hn.push(normals[j as usize]);
                            }
                        }
                        let hood = Neighbourhood {
                            center: points[i],
                            normal: normals[i],
                            points: hp,
                            normals: hn,
                            fallback_radius: typical,
                        };
                        *frame = fit_local(&hood, params, scratch, coef);
                        *q = misfit_factor(&hood, params, frame, coef);
                    }
                    progress.advance(fs.len());
                },
            );
        // Gap fields follow the points' fields (a static surface's only: thinned).
        let sites = if params.gap_fields > 0.0 && params.centre_spacing > 0.0 {
            let own;
            let index = match index {
                Some(index) => index,
                None => {
                    own = PointIndex::new(points);
                    &own
                }
            };
            let sites = crate::gaps::plan(points, normals, knn, &outlier, &order, index, params);
            let first = frames.len();
            frames.resize(first + sites.len(), unfitted);
            coeffs.resize((first + sites.len()) * c, 0.0);
            misfit.resize(first + sites.len(), 1.0);
            fit_gap_fields(
                &sites,
                points,
                normals,
                &outlier,
                index,
                params,
                typical,
                &mut frames[first..],
                &mut coeffs[first * c..],
                &mut misfit[first..],
            );
            sites
        } else {
            Vec::new()
        };
        // Everything below is in slot order.
        let planar: Vec<bool> = coeffs
            .chunks_exact(c)
            .zip(&frames)
            .map(|(coeffs, frame)| is_tangent_plane(params.size, frame, coeffs))
            .collect();
        let support: Vec<f64> = frames
            .iter()
            .enumerate()
            .map(|(s, f)| {
                if order.get(s).is_some_and(|&i| outlier[i as usize]) {
                    0.0
                } else {
                    params.support * f.half
                }
            })
            .collect();
        let inliers: Vec<u32> = (0..n as u32)
            .filter(|&s| support[s as usize] > 0.0)
            .collect();
        if inliers.is_empty() {
            return Err(FieldError::AllOutliers);
        }
        let inlier_points: Vec<DVec3> =
            inliers.iter().map(|&s| frames[s as usize].center).collect();
        let centers: Vec<DVec3> = frames.iter().map(|f| f.center).collect();
        // The length scale is the points' fields' (gap fields, fitted where points are sparse,
        // have wider supports and would move it, and with it the padding of mesh grids).
        let mut sup_sorted: Vec<f64> = support[..n].iter().copied().filter(|r| *r > 0.0).collect();
        sup_sorted.sort_by(f64::total_cmp);
        let scale = sup_sorted[sup_sorted.len() / 2];
        let grid = SupportGrid::new(&centers, &support, 2.0 * scale);
        // The votes (parallel), the witnesses' grid and the nearest-point index (each serial)
        // side by side.
        let ((votes, witnesses), nearest) = rayon::join(
            || {
                rayon::join(
                    || super::blend::solid_votes(&frames, &support, &grid, params.normal_agreement),
                    || {
                        // Gap samples (past the given points' own radii) do not vouch.
                        let radii = own_radii.unwrap_or(&radii);
                        witnesses(points, normals, radii, &outlier, typical, scale, params)
                    },
                )
            },
            || PointIndex::new(&inlier_points),
        );
        let refit = RefitOperator::new(params.size, params.size)
            .map_err(|_| FieldError::Param("size must be in 3..=6"))?;
        Ok(Self {
            inner: Arc::new(FieldData {
                params: *params,
                frames,
                support,
                coeffs,
                normals: order
                    .iter()
                    .map(|&i| normals[i as usize])
                    .chain(sites.iter().map(|g| g.normal))
                    .collect(),
                nearest,
                nearest_ids: inliers,
                slot,
                orphans: Vec::new(),
                fitted: n + sites.len(),
                first_gap: n,
                grid,
                votes,
                misfit,
                planar,
                witnesses,
                refit: Arc::new(refit),
                scale,
                outliers: outlier.iter().filter(|o| **o).count(),
                small_neighbourhoods,
                gap_samples: 0,
            }),
        })
    }
}

impl GlobalField {
    /// The field of `points` and the gap `samples` among them ([`FitParams::gap_samples`]): the
    /// samples join the points (after them, so the points keep their indices), with a k-NN graph
    /// of the same `k` over both, and the field is built as for any points, except for trust:
    /// only the points vouch for the zero set, with the radii of their own graph `own_knn`, so
    /// the samples shape the fits but the field trusts where the points alone would (as
    /// witnesses, with radii the samples shrink, they opened holes in closed shapes). It
    /// reports the samples' count and the parameters as asked.
    fn build_with_samples(
        points: &[DVec3],
        normals: &[DVec3],
        own_knn: &KnnGraph,
        samples: &[crate::gap_samples::GapSample],
        params: &FitParams,
        progress: &dyn Progress,
    ) -> Result<Self, FieldError> {
        let joined: Vec<DVec3> = points
            .iter()
            .copied()
            .chain(samples.iter().map(|s| s.position))
            .collect();
        let joined_normals: Vec<DVec3> = normals
            .iter()
            .copied()
            .chain(samples.iter().map(|s| s.normal))
            .collect();
        let index = PointIndex::new(&joined);
        let knn = KnnGraph::build(&joined, &index, own_knn.k());
        let own_radii: Vec<f64> = (0..points.len()).map(|i| own_knn.radius(i)).collect();
        let without = FitParams {
            gap_samples: 0.0,
            ..*params
        };
        let mut field = Self::build_with_index(
            &joined,
            &joined_normals,
            &knn,
            Some(&index),
            Some(&own_radii),
            &without,
            progress,
        )?;
        let data = Arc::get_mut(&mut field.inner).expect("a field just built is not shared");
        data.params = *params;
        data.gap_samples = samples.len();
        Ok(field)
    }
}

/// Every inlier point with a radius in `radii` as a trust witness with its support radius
/// (outliers, and the gap samples past `radii`'s end, get 0), for a thinned field
/// ([`FitParams::centre_spacing`] > 0); `None` for a field at every point, whose own points are
/// the witnesses.
fn witnesses(
    points: &[DVec3],
    normals: &[DVec3],
    radii: &[f64],
    outlier: &[bool],
    typical: f64,
    scale: f64,
    params: &FitParams,
) -> Option<Witnesses> {
    (params.centre_spacing > 0.0).then(|| {
        let support: Vec<f64> = (0..points.len())
            .map(|i| match radii.get(i) {
                Some(&r) if !outlier[i] => {
                    params.support * if r > 0.0 { r } else { typical } * (1.0 + params.offset)
                }
                _ => 0.0,
            })
            .collect();
        Witnesses {
            grid: SupportGrid::new(points, &support, 2.0 * scale),
            normals: normals.to_vec(),
            support,
        }
    })
}

/// Least cosine between a point's normal and a neighbour's for [`even_count`] to shrink its
/// neighbourhood (90°; a neighbour facing against it, below `normal_agreement`, is the other
/// sheet of a thin part and is skipped instead).
const EVEN_BEND: f64 = 0.0;

/// How many of point `i`'s neighbours (`hood`, itself first, by distance `dist`) its fit uses
/// under [`FitParams::k_even`]: the fewest holding `k_even` that face its way (itself included;
/// the fit ignores the rest) whose mean offset along the point's tangent plane is under
/// [`FitParams::even_lean`] of their radius, else all of them.
fn even_count(
    points: &[DVec3],
    normals: &[DVec3],
    i: usize,
    hood: &[u32],
    dist: &[f64],
    params: &FitParams,
) -> usize {
    let (p, n) = (points[i], normals[i]);
    let mut sum = DVec3::ZERO;
    let mut agreeing = 0;
    for (m, &j) in hood.iter().enumerate().skip(1) {
        let facing = normals[j as usize].dot(n);
        // The other sheet of a thin part: the fit leaves it out, so it does not count.
        if facing < params.normal_agreement {
            continue;
        }
        // A bend sharper than the neighbourhood (a crease, a tube thinner than the spacing):
        // the nearest do not sample one sheet, so the fit takes all of them.
        if facing < EVEN_BEND {
            return hood.len();
        }
        let d = points[j as usize] - p;
        sum += d - n * d.dot(n);
        agreeing += 1;
        if agreeing + 1 >= params.k_even
            && sum.length() < params.even_lean * dist[m] * agreeing as f64
        {
            return m + 1;
        }
    }
    hood.len()
}

/// The points that get a local field, ascending: every point when
/// [`FitParams::centre_spacing`] is 0, else a greedy pass in index order over the k-NN graph
/// that skips a point where a centre already lies within that spacing (or
/// [`FitParams::flat_spacing`] where [`is_flat`]) × its neighbourhood radius, so every inlier
/// is a centre or lies that near one (outliers are left out: they would get no field anyway).
fn thinned_centres(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    outlier: &[bool],
    params: &FitParams,
) -> Vec<u32> {
    let n = knn.len();
    let spacing = params.centre_spacing;
    if spacing <= 0.0 {
        return (0..n as u32).collect();
    }
    let flat_spacing = params.flat_thinning();
    let mut taken = vec![false; n];
    let mut centres = Vec::new();
    for i in 0..n {
        if outlier[i] {
            continue;
        }
        let hood = knn.neighbours(i);
        let radius = knn.radius(i);
        let covered_within = |reach: f64| {
            hood.iter()
                .zip(knn.distances(i))
                .any(|(&j, &d)| taken[j as usize] && d <= reach)
        };
        // A point covered at the base spacing is covered at any wider one, so flatness (a pass
        // over the neighbourhood) is asked only of the points the base spacing would keep.
        let covered = covered_within(spacing * radius)
            || flat_spacing.is_some_and(|flat| {
                is_flat(points, normals, i, hood, radius) && covered_within(flat * radius)
            });
        if !covered {
            taken[i] = true;
            centres.push(i as u32);
        }
    }
    centres
}

/// [`is_flat`]'s tolerances: the least cosine between the point's normal and a neighbour's
/// (1.8°), the farthest a neighbour may lie off its tangent plane and how far their mean offset
/// along it may lean (both relative to the neighbourhood radius). Flat to within a scan's noise
/// does not count: with 3.6° and 2 % (and a flat spacing of 0.6), 56 of the Stanford bunny
/// scan's points, in small nearly flat patches all over it, took the wider spacing, and its RMS
/// error grew 1.4 % (2.6 % at resolution 100); with these, none does, while a CAD face or a
/// sampled plane still does.
const FLAT_COS: f64 = 0.9995;
const FLAT_OFF_PLANE: f64 = 0.005;
const FLAT_LEAN: f64 = 0.2;

/// Whether point `i` and its neighbours `hood` (within `radius`) sample a flat, surrounded
/// piece of one sheet ([`FitParams::flat_spacing`]): every neighbour faces its way within
/// [`FLAT_COS`] and lies within [`FLAT_OFF_PLANE`] of its tangent plane, and their mean offset
/// along the plane is under [`FLAT_LEAN`] (not a rim).
fn is_flat(points: &[DVec3], normals: &[DVec3], i: usize, hood: &[u32], radius: f64) -> bool {
    let (p, n) = (points[i], normals[i]);
    let mut lean = DVec3::ZERO;
    for &j in hood {
        let d = points[j as usize] - p;
        let off = d.dot(n);
        if normals[j as usize].dot(n) < FLAT_COS || off.abs() > FLAT_OFF_PLANE * radius {
            return false;
        }
        lean += d - n * off;
    }
    lean.length() <= FLAT_LEAN * radius * hood.len() as f64
}

/// Fit a local field at each gap site to the site's own `k` nearest inlier points, on all
/// cores, into `frames`, `coeffs` and `misfit` (one frame, `size³` coefficients and one
/// [`misfit_factor`] per site, in order).
#[allow(clippy::too_many_arguments)]
fn fit_gap_fields(
    sites: &[GapSite],
    points: &[DVec3],
    normals: &[DVec3],
    outlier: &[bool],
    index: &PointIndex,
    params: &FitParams,
    typical: f64,
    frames: &mut [LocalFrame],
    coeffs: &mut [f64],
    misfit: &mut [f64],
) {
    coeffs
        .par_chunks_mut(params.size.pow(3))
        .zip(frames.par_iter_mut())
        .zip(misfit.par_iter_mut())
        .zip(sites.par_iter())
        .for_each_init(
            || (FitScratch::new(params.size), Vec::new(), Vec::new()),
            |(scratch, hp, hn), (((coef, frame), q), site)| {
                hp.clear();
                hn.clear();
                for (j, _) in index.nearest_k(site.centre, params.k) {
                    if !outlier[j] {
                        hp.push(points[j]);
                        hn.push(normals[j]);
                    }
                }
                let hood = Neighbourhood {
                    center: site.centre,
                    normal: site.normal,
                    points: hp,
                    normals: hn,
                    fallback_radius: typical,
                };
                *frame = fit_local(&hood, params, scratch, coef);
                *q = misfit_factor(&hood, params, frame, coef);
            },
        );
}

/// The factor [`FitParams::misfit_width`] puts on a local field's blending weight:
/// `1 / (1 + (m / (misfit_width · half))²)`, where `m` is the fit's [`fit_misfit`] at its own
/// neighbourhood and `half` its domain's half edge; 1 without the option or for a field at
/// every point (a sculpting scene's, which is refitted).
fn misfit_factor(
    hood: &Neighbourhood<'_>,
    params: &FitParams,
    frame: &LocalFrame,
    coeffs: &[f64],
) -> f64 {
    if params.misfit_width <= 0.0 || params.centre_spacing <= 0.0 {
        return 1.0;
    }
    let e = fit_misfit(hood, params, frame, coeffs) / (params.misfit_width * frame.half);
    1.0 / (1.0 + e * e)
}

fn validate(
    points: &[DVec3],
    normals: &[DVec3],
    knn: &KnnGraph,
    p: &FitParams,
) -> Result<(), FieldError> {
    if points.is_empty() {
        return Err(FieldError::Empty);
    }
    if normals.len() != points.len() || knn.len() != points.len() {
        return Err(FieldError::Mismatch {
            points: points.len(),
            normals: normals.len(),
            graph: knn.len(),
        });
    }
    let checks = [
        (3..=MAX_SIZE).contains(&p.size),
        p.offset > 0.0 && p.offset < 1.0,
        p.weight_width > 0.0 && p.weight_width.is_finite(),
        p.normal_weight > 0.0 && p.normal_weight.is_finite(),
        p.regularization > 0.0 && p.regularization.is_finite(),
        p.support > 0.0 && p.support <= 1.0,
        p.normal_agreement.is_finite(),
        p.outlier_ratio > 1.0,
        p.trust > 0.0 && p.trust.is_finite(),
        p.trust_weight >= 0.0 && p.trust_weight.is_finite(),
        p.trust_plane > 0.0,
        (0.0..=1.0).contains(&p.centre_spacing),
        (0.0..=1.0).contains(&p.flat_spacing),
        (0.0..1.0).contains(&p.gap_fields),
        p.even_lean >= 0.0 && p.even_lean.is_finite(),
        p.misfit_width >= 0.0 && p.misfit_width.is_finite(),
        (0.0..1.0).contains(&p.gap_samples),
    ];
    const WHAT: [&str; 17] = [
        "size must be in 3..=6",
        "offset must be in (0, 1)",
        "weight_width must be positive",
        "normal_weight must be positive and finite",
        "regularization must be positive",
        "support must be in (0, 1]",
        "normal_agreement must be finite",
        "outlier_ratio must exceed 1",
        "trust must be positive and finite",
        "trust_weight must be finite and ≥ 0",
        "trust_plane must be positive (infinite: no plane test)",
        "centre_spacing must be in [0, 1]",
        "flat_spacing must be in [0, 1]",
        "gap_fields must be in [0, 1)",
        "even_lean must be finite and ≥ 0",
        "misfit_width must be finite and ≥ 0",
        "gap_samples must be in [0, 1)",
    ];
    match checks.iter().position(|ok| !ok) {
        Some(bad) => Err(FieldError::Param(WHAT[bad])),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 9 × 9 grid in the plane z = 0, spacing 1, facing +z; the point at (0, 0) is number 40.
    fn grid() -> (Vec<DVec3>, Vec<DVec3>) {
        let points: Vec<DVec3> = (-4..=4)
            .flat_map(|i| (-4..=4).map(move |j| DVec3::new(i as f64, j as f64, 0.0)))
            .collect();
        let normals = vec![DVec3::Z; points.len()];
        (points, normals)
    }

    fn count(points: &[DVec3], normals: &[DVec3], i: usize) -> usize {
        let knn = KnnGraph::build(points, &PointIndex::new(points), 20);
        let params = FitParams {
            k_even: 13,
            even_lean: 0.2,
            ..FitParams::default()
        };
        even_count(
            points,
            normals,
            i,
            knn.neighbours(i),
            knn.distances(i),
            &params,
        )
    }

    #[test]
    fn flat_faces_thin_further_only_in_a_thinned_field_and_above_its_spacing() {
        let with = |centre_spacing, flat_spacing| FitParams {
            centre_spacing,
            flat_spacing,
            ..FitParams::default()
        };
        assert_eq!(with(0.35, 0.5).flat_thinning(), Some(0.5));
        // A field at every point is not thinned at all.
        assert_eq!(with(0.0, 0.5).flat_thinning(), None);
        // Off, or not wider than the base spacing.
        assert_eq!(with(0.35, 0.0).flat_thinning(), None);
        assert_eq!(with(0.35, 0.35).flat_thinning(), None);
    }

    #[test]
    fn flat_only_where_one_plane_surrounds_the_point() {
        let (mut points, mut normals) = grid();
        // The 13 nearest: the point, then rings at 1, √2 and 2 (the radius).
        let knn = KnnGraph::build(&points, &PointIndex::new(&points), 13);
        let flat = |points: &[DVec3], normals: &[DVec3], i: usize| {
            is_flat(points, normals, i, knn.neighbours(i), knn.radius(i))
        };
        assert!(flat(&points, &normals, 40));
        // At the rim the neighbours lean inward.
        assert!(!flat(&points, &normals, 4));
        // A neighbour's normal 1.5° off is flat enough; 2.5° is a bend.
        let tilted = |deg: f64| DVec3::new(deg.to_radians().sin(), 0.0, deg.to_radians().cos());
        normals[41] = tilted(1.5);
        assert!(flat(&points, &normals, 40));
        normals[41] = tilted(2.5);
        assert!(!flat(&points, &normals, 40));
        normals[41] = DVec3::Z;
        // Off the tangent plane by 0.25 % of the radius is flat enough; 1 % is not.
        points[41].z = 0.005;
        assert!(flat(&points, &normals, 40));
        points[41].z = 0.02;
        assert!(!flat(&points, &normals, 40));
    }

    #[test]
    fn even_neighbourhoods_shrink_only_where_one_sheet_surrounds_the_point() {
        let (mut points, mut normals) = grid();
        // Inside, the 13 nearest (itself, then rings at 1, √2 and 2) surround it exactly.
        assert_eq!(count(&points, &normals, 40), 13);
        // At the rim they lean inward by more than 0.2 of their radius: all 20.
        assert_eq!(count(&points, &normals, 4), 20);
        // The other sheet of a thin part (facing against it) is skipped, not counted: the
        // list grows by the skipped points and still shrinks.
        let sheet = points.len();
        for p in grid().0 {
            points.push(p + DVec3::new(0.01, 0.01, 1.5));
            normals.push(-DVec3::Z);
        }
        let n = count(&points, &normals, 40);
        assert!(n > 13 && n < 20, "{n}");
        // A neighbour facing more than 90° away (a crease, a thin tube): all 20.
        points.truncate(sheet);
        normals.truncate(sheet);
        normals[41] = DVec3::new(1.0, 0.0, -0.2).normalize();
        assert_eq!(count(&points, &normals, 40), 20);
    }
}
