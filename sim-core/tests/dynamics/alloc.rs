//! The stepping contract: after warm-up, integrator steps, rope forces and snapshot publication
//! allocate nothing (counted per thread by the test binary's global allocator,
//! `support/counting_alloc.rs`).

use glam::DVec3;
use sim_core::dynamics::{Integrator, NodeParams, Stepper};
use sim_core::tools::{Profile, Rope};

use crate::common::{perturb, small_model};
use crate::counting_alloc::{allocated_bytes, allocations};

#[test]
fn steps_tools_and_publishing_allocate_nothing_after_warm_up() {
    let rope = Rope {
        path: vec![DVec3::new(0.0, 0.0, 0.3)],
        radius: 0.2,
        strength: 0.1,
        profile: Profile::Gaussian,
        sheet: Some(DVec3::Z),
    };
    for integrator in [
        Integrator::forward_euler(1e3),
        Integrator::SymplecticEuler,
        Integrator::backward_euler(),
    ] {
        let mut m = small_model(10, NodeParams::default());
        perturb(&mut m, 1e-3);
        let mut st = Stepper::new(integrator);
        // Warm-up: scratch sized, snapshot pool filled (one held, one free).
        st.step(&mut m, 1e-3).unwrap();
        let held = m.publish();
        drop(m.publish());
        let before = allocations();
        for _ in 0..50 {
            m.clear_forces();
            rope.apply(&mut m).unwrap();
            st.step(&mut m, 1e-3).unwrap();
            drop(m.publish());
        }
        assert_eq!(allocations() - before, 0, "{} allocated", integrator.name());
        drop(held);
    }
}

/// A commit costs what the region holds, not the object: the same rope stroke on the same
/// sphere, committed with resampling, allocates fresh memory (on the committing thread) about
/// as much when
/// the object also holds four more such spheres far from the region. A commit that copied the
/// object's field (a second handle on it held across a point removal once did: 1.3 s at 10⁶
/// points) allocates the whole field, five times as much here.
#[test]
fn a_commit_allocates_for_the_region_not_the_object() {
    use sim_core::pointset::PointSet;
    use sim_core::sampling::Shape;
    use sim_core::scene::{Scene, SceneObject};

    use crate::resample::{open_cap, pull_bump};

    let sphere = Shape::Sphere { radius: 0.05 };
    let commit_bytes = |copies: usize| {
        let mut set = PointSet {
            positions: Vec::new(),
            normals: Some(Vec::new()),
            colors: None,
        };
        for c in 0..copies {
            let part = sphere.sample(6000, 5 + c as u64);
            let offset = DVec3::new(0.5 * c as f64, 0.0, 0.0);
            set.positions
                .extend(part.positions.iter().map(|&p| p + offset));
            set.normals.as_mut().unwrap().extend(part.normals.unwrap());
        }
        let object = SceneObject::fit("spheres", set, &sim_core::FitParams::default()).unwrap();
        let h = sim_core::resample::spacing(&object.positions[..6000]);
        let mut scene = Scene::new();
        let id = scene.add(object);
        open_cap(&mut scene, id, h, true);
        pull_bump(&mut scene);
        let before = allocated_bytes();
        scene.end_stroke().unwrap();
        let bytes = allocated_bytes() - before;
        let report = scene.region().unwrap().last_resample();
        assert!(report.inserted > 0 && report.removed > 0, "{report:?}");
        bytes
    };
    let (one, five) = (commit_bytes(1), commit_bytes(5));
    assert!(
        (five as f64) < 1.5 * one as f64,
        "a commit on one sphere of a 5-sphere object allocated {five} bytes, on the sphere alone {one}"
    );
}
