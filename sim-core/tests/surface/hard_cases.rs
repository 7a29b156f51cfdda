//! Hard inputs from issue 4: degenerate neighbourhoods, too few neighbours, extreme scales,
//! noisy / flipped normals, outliers, thin shells. Each states and checks an error bound, and
//! none may produce NaN or an unbounded field.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::reconstruct::NormalPolicy;
use sim_core::sampling::{Noise, Shape};
use sim_core::{FitParams, PointSet};

use crate::common::{assert_bounded, error, fit};

const SPHERE: Shape = Shape::Sphere { radius: 1.0 };

fn grid_plane(n: usize, spacing: f64) -> Vec<DVec3> {
    let mut v = Vec::new();
    for i in 0..n {
        for j in 0..n {
            v.push(DVec3::new(i as f64 * spacing, j as f64 * spacing, 0.0));
        }
    }
    v
}

#[test]
fn coplanar_points_give_the_plane_exactly() {
    // A regular planar grid: every neighbourhood is coplanar (rank-deficient normal matrix).
    let pos = grid_plane(30, 0.01);
    let n = pos.len();
    let pts = PointSet {
        positions: pos.clone(),
        normals: Some(vec![DVec3::Z; n]),
        colors: None,
    };
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    assert_bounded(&rec.field, &pos, 0.5, 3.0);
    // Bound: the plane z = 0 is in the spline space and agrees with all data, so the zero set
    // is the plane to rounding: |z| ≤ 1e-9 × spacing after projection.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..500 {
        let x = DVec3::new(
            rng.random_range(0.05..0.25),
            rng.random_range(0.05..0.25),
            rng.random_range(-0.004..0.004),
        );
        let p = rec.field.project_to_zero_set(x);
        assert!(p.converged && p.point.z.abs() <= 1e-11, "{x} → {:?}", p);
        // The field is the signed distance to the plane there.
        assert!((rec.field.value(x) - x.z).abs() <= 1e-9 * 0.01);
    }
}

#[test]
fn coplanar_points_with_estimated_normals() {
    // PCA normals of a plane, then orientation: consistent, so the field is ±z and bounded.
    let pos = grid_plane(25, 0.02);
    let rec = fit(
        &PointSet::from_positions(pos.clone()),
        &FitParams::default(),
        NormalPolicy::Keep,
    );
    assert!(
        rec.normals.iter().all(|n| (n.z - 1.0).abs() < 1e-9),
        "top point faces +z"
    );
    assert_bounded(&rec.field, &pos, 0.5, 3.0);
}

#[test]
fn collinear_points_give_a_bounded_field() {
    // Points on a line: PCA has two zero eigenvalues; the fit must still be defined.
    let pos: Vec<DVec3> = (0..200)
        .map(|i| DVec3::new(i as f64 * 0.01, 0.0, 0.0))
        .collect();
    let rec = fit(
        &PointSet::from_positions(pos.clone()),
        &FitParams::default(),
        NormalPolicy::Keep,
    );
    assert!(
        rec.normals
            .iter()
            .all(|n| n.is_normalized() && n.x.abs() < 1e-9)
    );
    let grad = assert_bounded(&rec.field, &pos, 0.5, 3.0);
    // Bound: each input point lies on the zero set to 1e-9 of the spacing.
    for p in &pos {
        assert!(
            rec.field.value(*p).abs() <= 1e-11,
            "f({p}) = {}",
            rec.field.value(*p)
        );
    }
    assert!(grad > 0.5, "the field is not flat: max ‖∇f‖ = {grad}");
}

#[test]
fn duplicated_points_and_a_fully_duplicated_cluster() {
    // Every point three times, plus 40 copies of one point: duplicates must not change the fit.
    let base = SPHERE.sample(3000, 5);
    let mut pts = base.clone();
    for _ in 0..2 {
        pts.positions.extend_from_slice(&base.positions);
        pts.normals
            .as_mut()
            .unwrap()
            .extend_from_slice(base.normals.as_ref().unwrap());
    }
    for _ in 0..40 {
        pts.positions.push(base.positions[0]);
        pts.normals
            .as_mut()
            .unwrap()
            .push(base.normals.as_ref().unwrap()[0]);
    }
    let params = FitParams {
        k: 60,
        ..FitParams::default()
    };
    let rec = fit(&pts, &params, NormalPolicy::Keep);
    assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
    // Bound: as accurate as the same 3000 points without duplicates at k = 20 (≤ 1e-4 R RMS).
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(
        e.rms_relative() <= 1e-4 && e.max_relative() <= 2e-3,
        "{e:?}"
    );
    // A point whose k neighbours are all its own duplicates still gets a planar field.
    let all_dups = PointSet {
        positions: vec![DVec3::ONE; 50],
        normals: Some(vec![DVec3::X; 50]),
        colors: None,
    };
    let rec = fit(&all_dups, &FitParams::default(), NormalPolicy::Keep);
    let f = rec.field.value(DVec3::ONE + DVec3::X * 1e-3);
    assert!(f.is_finite() && (f - 1e-3).abs() < 1e-12, "{f}");
}

#[test]
fn fewer_neighbours_than_coefficients() {
    // k = 2, 4, 6 give 6, 12, 18 rows for 27 unknowns: underdetermined without the regulariser.
    for k in [2, 4, 6] {
        let pts = SPHERE.sample(4000, 9);
        let params = FitParams {
            k,
            ..FitParams::default()
        };
        let rec = fit(&pts, &params, NormalPolicy::Keep);
        assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
        eprintln!("k = {k}");
        let e = error(&rec.field, &SPHERE, 10_000);
        // Bound: with so few neighbours the local fields are nearly planar; RMS ≤ 3e-3 R.
        assert!(e.rms_relative() <= 3e-3, "k = {k}: {e:?}");
    }
}

#[test]
fn scale_invariance_from_micrometres_to_kilometres() {
    // The same cloud at 1e-6, 1 and 1e3: relative errors must agree (the fit is scale-free).
    let unit = SPHERE.sample(5000, 21);
    let mut rel = Vec::new();
    for scale in [1e-6, 1.0, 1e3] {
        let pts = PointSet {
            positions: unit.positions.iter().map(|p| *p * scale).collect(),
            normals: unit.normals.clone(),
            colors: None,
        };
        let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
        let reference = Shape::Sphere { radius: scale };
        assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
        let e = error(&rec.field, &reference, 10_000);
        assert!(e.rms_relative() <= 1e-4, "scale {scale}: {e:?}");
        rel.push(e.rms_relative());
    }
    for r in &rel {
        assert!(
            (r / rel[1] - 1.0).abs() < 1e-3,
            "relative RMS differs across scales: {rel:?}"
        );
    }
}

#[test]
fn noisy_normals() {
    // Normals tilted by ~0.1 rad (σ): off-surface targets are wrong by ε·(1 − cos θ) and the
    // samples move tangentially. Bound: RMS ≤ 5e-4 R, max ≤ 5e-3 R.
    let pts = SPHERE.sample_noisy(
        10_000,
        4,
        Noise {
            position: 0.0,
            normal: 0.1,
        },
    );
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(
        e.rms_relative() <= 5e-4 && e.max_relative() <= 5e-3,
        "{e:?}"
    );
}

#[test]
fn noisy_positions() {
    // Positions displaced by σ = 1e-3 R along the normal: the fit averages over k neighbours.
    // Bound: RMS ≤ σ (the fit does not amplify the noise).
    let sigma = 1e-3;
    let pts = SPHERE.sample_noisy(
        10_000,
        4,
        Noise {
            position: sigma,
            normal: 0.0,
        },
    );
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(e.rms_relative() <= sigma && e.unconverged == 0, "{e:?}");
}

fn flip_some(pts: &mut PointSet, fraction: f64, seed: u64) -> Vec<bool> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normals = pts.normals.as_mut().unwrap();
    normals
        .iter_mut()
        .map(|n| {
            let flip = rng.random::<f64>() < fraction;
            if flip {
                *n = -*n;
            }
            flip
        })
        .collect()
}

#[test]
fn flipped_normals_kept_or_reoriented() {
    let truth = SPHERE.sample(10_000, 8);
    let mut pts = truth.clone();
    let flipped = flip_some(&mut pts, 0.05, 2);
    assert!(flipped.iter().filter(|f| **f).count() > 300);
    // Kept as given: neighbours with opposing normals are ignored, so the zero set survives.
    // Bound: RMS ≤ 1e-4 R, max ≤ 2e-3 R.
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(
        e.rms_relative() <= 1e-4 && e.max_relative() <= 2e-3,
        "{e:?}"
    );
    // Reoriented: every normal must agree with the truth again, and the fit is as clean as
    // unflipped input (RMS ≤ 2e-5 R).
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Reorient);
    let wrong = rec
        .normals
        .iter()
        .zip(truth.normals.as_ref().unwrap())
        .filter(|(a, b)| a.dot(**b) < 0.0)
        .count();
    assert_eq!(wrong, 0, "normals still flipped after reorientation");
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(e.rms_relative() <= 2e-5, "{e:?}");
}

#[test]
fn outliers_are_rejected() {
    // 1% of the points scattered uniformly in [−2, 2]³ with random normals.
    let mut pts = SPHERE.sample(10_000, 13);
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let mut far = 0;
    for _ in 0..100 {
        let p = DVec3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
        );
        far += usize::from((p.length() - 1.0).abs() > 0.4);
        pts.positions.push(p);
        pts.normals
            .as_mut()
            .unwrap()
            .push(sim_core::sampling::unit_vector(&mut rng));
    }
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    // Near the surface ‖∇f‖ ≤ 3 (measured 1.03; ~10 away from it, near kept outliers).
    assert_bounded(&rec.field, &pts.positions[..10_000], 0.5, 3.0);
    // Bound: all outliers farther than 0.4 R (~10 spacings) from the surface are flagged, and no
    // more than
    // 1% of inliers are.
    assert!(
        rec.field.outlier_count() >= far && rec.field.outlier_count() <= far + 100,
        "{}",
        rec.field.outlier_count()
    );
    // Bound: RMS ≤ 1e-3 R and max ≤ 0.05 R (about 1.5 spacings): outliers within a spacing of
    // the surface pass every test for outliers and act like noise with random normals.
    let e = error(&rec.field, &SPHERE, 10_000);
    assert!(
        e.rms_relative() <= 1e-3 && e.max_relative() <= 0.05,
        "{e:?}"
    );
    // No phantom surfaces: the sign is right away from the sphere.
    for _ in 0..2000 {
        let p = DVec3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
        );
        let d = p.length() - 1.0;
        if d.abs() > 0.1 {
            assert_eq!(rec.field.value(p) > 0.0, d > 0.0, "wrong side at {p}");
        }
    }
}

#[test]
fn thin_shell_two_sheets_closer_than_the_spacing() {
    // A plate 0.004 thick sampled with ~0.02 spacing: each point's k-NN mixes both sheets.
    let plate = Shape::Plate {
        half_size: 0.5,
        thickness: 0.004,
    };
    let pts = plate.sample(6000, 17);
    // The papers' plain blend averages the sheets away (measured RMS 7.5e-3 > thickness). Where
    // covering fields face opposite ways, each side is blended alone and the sides combined by
    // max (a thin solid), which keeps both sheets.
    let rec = fit(&pts, &FitParams::default(), NormalPolicy::Keep);
    // Near the points ‖∇f‖ ≤ 3 (measured 1.24; ~7 elsewhere).
    assert_bounded(&rec.field, &pts.positions, 0.5, 3.0);
    // Bound: RMS ≤ 0.3 t over the whole plate (measured 0.13 t) and max ≤ 6 t (measured 4.2 t,
    // at the rim, whose radius t/2 is a tenth of the spacing: a sharp edge to the fit).
    let t = 0.004;
    let e = error(&rec.field, &plate, 10_000);
    assert!(e.rms <= 0.3 * t && e.max <= 6.0 * t, "{e:?}");
    // Away from the rim the sheets are exact to a few thousandths of the thickness.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..500 {
        let (x, y) = (rng.random_range(-0.4..0.4), rng.random_range(-0.4..0.4));
        let side: f64 = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let p = rec.field.project_to_zero_set(DVec3::new(
            x,
            y,
            side * rng.random_range(0.6 * t..3.0 * t),
        ));
        assert!(
            p.converged && (p.point.z.abs() - t / 2.0).abs() <= 0.01 * t,
            "{p:?}"
        );
    }
    assert!(rec.field.value(DVec3::ZERO) < 0.0 && rec.field.value(DVec3::new(0.1, 0.2, 0.0)) < 0.0);
}

/// A flat ellipsoid a few spacings thick, like an armadillo's ear: near its rim the far side's
/// supports reach across with a small share of the weight, and their fits, bent round the rim,
/// cross zero inside the near side. Combined by `max` as a veto, that fringe cut dents into the
/// near side: before the hand-over, with `fit`'s defaults, 56 of these 80,000 probes (seeds
/// 0–3) 0.3 spacing under the surface lay outside f's zero set, and a mesh of such a part
/// (`workstation fit gen:ellipsoid:1:0.6:0.08:10000`) had a dent half a spacing deep. A far
/// side under 5–15 % of the near side's weight now loses its veto where its own tangent
/// planes put the place on the material side: none is left.
#[test]
fn a_thin_parts_far_side_does_not_dent_its_near_side() {
    let radii = DVec3::new(1.0, 0.6, 0.08);
    let shape = Shape::Ellipsoid { radii };
    let n = 10_000;
    let spacing = (shape.area() / n as f64).sqrt();
    let params = crate::common::thinned_with_gaps();
    let mut dents = Vec::new();
    for seed in 0..4 {
        let points = shape.sample(n, seed);
        let rec = fit(&points, &params, NormalPolicy::Keep);
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let mut probed = 0;
        while probed < 20_000 {
            // A point on the ellipsoid's faces where the part is at least 2 spacings thick.
            let (x, y) = (rng.random_range(-1.0..1.0), rng.random_range(-0.6..0.6));
            let rest = 1.0 - (x / radii.x).powi(2) - (y / radii.y).powi(2);
            if rest <= 0.0 || 2.0 * radii.z * rest.sqrt() < 2.0 * spacing {
                continue;
            }
            probed += 1;
            let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let p = DVec3::new(x, y, side * radii.z * rest.sqrt());
            let normal = (p / (radii * radii)).normalize();
            let under = p - normal * (0.3 * spacing);
            let f = rec.field.value(under);
            if f >= 0.0 {
                dents.push((seed, p, f));
            }
        }
    }
    assert!(
        dents.is_empty(),
        "{} dents: {:?}",
        dents.len(),
        &dents[..dents.len().min(6)]
    );
}

/// A cube sampled the way a coarse CAD mesh's vertices are: a grid of `n + 1` per side on each
/// face, and the normal of a point on an edge or a corner is the normalised sum of the faces'
/// meeting there (a mesh's vertex normals), which no face has.
fn cad_cube(n: i32) -> (PointSet, Shape) {
    let spacing = 2.0 / n as f64;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            for k in 0..=n {
                let p = DVec3::new(i as f64, j as f64, k as f64) * spacing - DVec3::ONE;
                let mut normal = DVec3::ZERO;
                for axis in 0..3 {
                    if (p[axis].abs() - 1.0).abs() < 1e-9 {
                        normal[axis] = p[axis].signum();
                    }
                }
                if normal != DVec3::ZERO {
                    positions.push(p);
                    normals.push(normal.normalize());
                }
            }
        }
    }
    let points = PointSet {
        positions,
        normals: Some(normals),
        colors: None,
    };
    let shape = Shape::RoundedBox {
        half: DVec3::ONE,
        radius: 1e-9,
    };
    (points, shape)
}

#[test]
fn averaged_edge_normals_bulge_less_when_positions_lead() {
    let (points, cube) = cad_cube(12);
    let fit_with = |normal_weight: f64| {
        let params = FitParams {
            normal_weight,
            ..FitParams::default()
        };
        let rec = fit(&points, &params, NormalPolicy::Keep);
        error(&rec.field, &cube, 20_000)
    };
    let (equal, positions_lead) = (fit_with(1.0), fit_with(0.25));
    // Measured: RMS 2.10e-3 → 1.88e-3 of the diagonal (11 % lower), max 9.8e-3 → 1.01e-2 (the
    // corners, which every smooth fit rounds). Bound: RMS at least 8 % lower, max within 10 %.
    assert!(
        positions_lead.rms_relative() <= 0.92 * equal.rms_relative(),
        "normal weight 0.25: {positions_lead:?}, 1: {equal:?}"
    );
    assert!(
        positions_lead.max_relative() <= 1.1 * equal.max_relative(),
        "normal weight 0.25: {positions_lead:?}, 1: {equal:?}"
    );
}
