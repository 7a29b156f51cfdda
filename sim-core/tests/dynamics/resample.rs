//! Region resampling at commits (issue 19): after a rope pull raises a bump the points inside it
//! stay evenly spaced (no hole wider than the threshold) with normals from the field; after a
//! probe carve no point is left off the zero set. Without resampling the same strokes leave
//! holes and stray points, so the measures below do see what they are meant to.

use glam::{DQuat, DVec3};
use sim_core::dynamics::{Integrator, NodeParams};
use sim_core::knn::PointIndex;
use sim_core::probe::{Probe, ProbePose};
use sim_core::resample::{largest_empty_circle, spacing};
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, ResampleOptions, Scene};
use sim_core::tools::{GridTool, ProbeMode, ProbeSculpt, Profile, Rope};

use crate::common::fitted_object;

const R: f64 = 0.05;
const POLE: DVec3 = DVec3::new(0.0, 0.0, R);

fn scene(resample: bool) -> (Scene, f64) {
    let mut scene = Scene::new();
    let id = scene.add(fitted_object(Shape::Sphere { radius: R }, 6000, 5));
    let h = spacing(&scene.objects()[id].positions);
    open_cap(&mut scene, id, h, resample);
    (scene, h)
}

/// Open a region over the cap of the 5 cm sphere centred at the origin in object `id` (2 mm
/// grid, 20 mm band, stiff anchors, backward Euler), resampling at spacing `h` if asked.
pub(crate) fn open_cap(scene: &mut Scene, id: usize, h: f64, resample: bool) {
    let params = RegionParams {
        node: NodeParams {
            mass: 1e-3,
            damping: 0.5,
            stiffness: 1.0,
            anchor: 100.0,
        },
        integrator: Integrator::backward_euler(),
        resample: resample.then(|| ResampleOptions::new(h)),
        ..RegionParams::new(0.002, 0.02)
    };
    scene
        .open_region(
            id,
            DVec3::new(-0.045, -0.045, 0.005),
            DVec3::new(0.045, 0.045, 0.085),
            params,
        )
        .unwrap();
}

/// 300 steps of a rope pulling a 15 mm tall, 12 mm wide Gaussian bump at the pole (not yet
/// committed).
pub(crate) fn pull_bump(scene: &mut Scene) {
    let rope = Rope {
        path: vec![POLE],
        radius: 0.012,
        strength: 100.0 * 0.015,
        profile: Profile::Gaussian,
        sheet: None,
    };
    for _ in 0..300 {
        scene.step(1e-3, std::slice::from_ref(&rope)).unwrap();
    }
}

/// A 15 mm tall, 12 mm wide Gaussian bump pulled at the pole and committed.
fn pulled(resample: bool) -> (Scene, f64) {
    let (mut scene, h) = scene(resample);
    pull_bump(&mut scene);
    scene.end_stroke().unwrap();
    (scene, h)
}

/// Points of the bump: near the axis, risen by more than 1 mm.
fn bump(scene: &Scene) -> Vec<usize> {
    let o = &scene.objects()[0];
    (0..o.positions.len())
        .filter(|&i| {
            let p = o.positions[i];
            p.truncate().length() < 0.012 && p.z > 0.0 && p.length() > R + 1e-3
        })
        .collect()
}

/// Largest empty tangent circle around any of `which` (16 nearest neighbours), and the
/// largest nearest-neighbour distance.
fn gaps(scene: &Scene, which: &[usize]) -> (f64, f64) {
    let o = &scene.objects()[0];
    let index = PointIndex::new(&o.positions);
    let (mut circle, mut nn) = (0.0f64, 0.0f64);
    for &i in which {
        let p = o.positions[i];
        let near = index.nearest_k(p, 17);
        nn = nn.max(near[1].1);
        let hood: Vec<DVec3> = near[1..].iter().map(|&(j, _)| o.positions[j]).collect();
        if let Some((_, r)) = largest_empty_circle(p, o.normals[i], &hood) {
            circle = circle.max(r);
        }
    }
    (circle, nn)
}

#[test]
fn a_pulled_bump_stays_evenly_sampled_with_normals_from_the_field() {
    let (plain, h) = pulled(false);
    let (even, _) = pulled(true);
    let (b0, b1) = (bump(&plain), bump(&even));
    assert!(b0.len() > 30, "the bump rose: {} points", b0.len());
    let (circle0, nn0) = gaps(&plain, &b0);
    let (circle1, nn1) = gaps(&even, &b1);
    // The sphere as sampled, around the same place: what "even" was before the stroke.
    let (fresh, _) = scene(false);
    let cap: Vec<usize> = (0..fresh.objects()[0].positions.len())
        .filter(|&i| fresh.objects()[0].positions[i].distance(POLE) < 0.012)
        .collect();
    let (circle_fresh, nn_fresh) = gaps(&fresh, &cap);
    eprintln!("as sampled: largest hole {circle_fresh:.2e}, NN gap {nn_fresh:.2e}");
    let report = even.region().unwrap().last_resample();
    eprintln!(
        "spacing {h:.2e}; without resampling: largest hole {circle0:.2e}, NN gap {nn0:.2e} ({} pts); with: {circle1:.2e}, {nn1:.2e} ({} pts), {report:?}",
        b0.len(),
        b1.len()
    );
    let opts = ResampleOptions::new(h);
    assert!(
        circle0 > circle_fresh,
        "the stroke must open holes for this test to mean anything: {circle0:.2e}"
    );
    assert!(
        circle1 <= 1.3 * opts.max_gap * h && circle1 < circle_fresh,
        "hole of radius {circle1:.2e} left (spacing {h:.2e})"
    );
    // The largest nearest-neighbour gap in the bump is no wider than the sampling's own.
    assert!(
        nn1 <= nn_fresh,
        "nearest-neighbour gap {nn1:.2e} (as sampled {nn_fresh:.2e})"
    );
    assert!(report.inserted > 0);
    // Normals are the field's.
    let o = &even.objects()[0];
    for &i in &b1 {
        let g = o.field.value_and_gradient(o.positions[i]).1.normalize();
        assert!(g.dot(o.normals[i]) > 1.0 - 1e-9, "point {i}");
        assert!(
            o.field.value(o.positions[i]).abs() < 0.1 * h,
            "point {i} off the surface"
        );
    }
}

fn carved(resample: bool) -> (Scene, f64) {
    let (mut scene, h) = scene(resample);
    let mut probe = Probe::ellipsoid(DVec3::splat(0.01)).unwrap();
    // Press a 1 cm ball 7 mm into the pole and hold it.
    for k in 0..400 {
        let depth = 0.007 * (k as f64 / 200.0).min(1.0);
        probe
            .set_pose(ProbePose {
                position: POLE + DVec3::Z * (0.01 - depth),
                orientation: DQuat::IDENTITY,
            })
            .unwrap();
        let tool = ProbeSculpt {
            probe,
            mode: ProbeMode::Push,
            stiffness: 2000.0,
        };
        scene.step_field(1e-3, &[&tool as &dyn GridTool]).unwrap();
        scene.follow_points().unwrap();
    }
    scene.end_stroke().unwrap();
    (scene, h)
}

#[test]
fn after_a_probe_carve_no_point_is_left_off_the_zero_set() {
    let off = |scene: &Scene, h: f64| {
        let o = &scene.objects()[0];
        o.positions
            .iter()
            .filter(|p| p.z > 0.01 && o.field.value(**p).abs() > 0.1 * h)
            .count()
    };
    let (plain, h) = carved(false);
    let (even, _) = carved(true);
    let report = even.region().unwrap().last_resample();
    eprintln!(
        "off the surface: {} without resampling, {} with; {report:?}",
        off(&plain, h),
        off(&even, h)
    );
    assert!(
        off(&plain, h) > 0,
        "the carve must strand points for this test to mean anything"
    );
    assert_eq!(off(&even, h), 0);
    // The carve is there: no point inside the probe's final ball.
    let centre = POLE + DVec3::Z * 0.003;
    let o = &even.objects()[0];
    assert!(o.positions.iter().all(|p| p.distance(centre) > 0.009));
    // The object stayed consistent: one normal and colour per point, all finite.
    assert_eq!(o.positions.len(), o.normals.len());
    assert_eq!(o.positions.len(), o.colors.len());
    assert!(o.positions.iter().all(|p| p.is_finite()));
}

#[test]
fn resampling_touches_only_the_region() {
    let (plain, _) = pulled(false);
    let (even, _) = pulled(true);
    let (a, b) = (&plain.objects()[0], &even.objects()[0]);
    let outside = |p: &DVec3| p.z < 0.0;
    let pa: Vec<&DVec3> = a.positions.iter().filter(|p| outside(p)).collect();
    let pb: Vec<&DVec3> = b.positions.iter().filter(|p| outside(p)).collect();
    let mut pa: Vec<[u64; 3]> = pa.iter().map(|p| p.to_array().map(f64::to_bits)).collect();
    let mut pb: Vec<[u64; 3]> = pb.iter().map(|p| p.to_array().map(f64::to_bits)).collect();
    pa.sort_unstable();
    pb.sort_unstable();
    assert_eq!(pa, pb, "points below the region changed");
}
