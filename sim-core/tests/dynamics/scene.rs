//! Scenes model only what they need: static objects change neither the work nor the memory of
//! the sculpted region, and are never touched. (Timings are in `workstation bench-sim`.)

use glam::DVec3;
use sim_core::sampling::Shape;
use sim_core::scene::{RegionParams, Scene};
use sim_core::tools::{Profile, Rope};

use crate::common::fitted_object;

fn run(statics: usize) -> Scene {
    let sphere = fitted_object(Shape::Sphere { radius: 0.3 }, 3000, 5);
    let mut scene = Scene::new();
    let id = scene.add(sphere.clone());
    for _ in 0..statics {
        scene.add(sphere.clone());
    }
    let params = RegionParams::new(0.02, 0.06);
    scene
        .open_region(
            id,
            DVec3::new(-0.2, -0.2, 0.1),
            DVec3::new(0.2, 0.2, 0.4),
            params,
        )
        .unwrap();
    let rope = Rope {
        path: vec![DVec3::new(0.0, 0.0, 0.3)],
        radius: 0.1,
        strength: 0.5,
        profile: Profile::Gaussian,
        sheet: None,
    };
    for _ in 0..100 {
        scene.step(1e-3, std::slice::from_ref(&rope)).unwrap();
    }
    scene
}

#[test]
fn static_objects_cost_nothing_and_stay_untouched() {
    let one = run(0);
    let many = run(10);
    let (r1, r2) = (one.region().unwrap(), many.region().unwrap());
    assert_eq!(r1.memory_bytes(), r2.memory_bytes());
    assert_eq!(r1.model().active_len(), r2.model().active_len());
    assert_eq!(r1.points_inside(), r2.points_inside());
    // Same work, same result, bit for bit (parallel follow is per-point independent).
    assert_eq!(one.objects()[0].positions, many.objects()[0].positions);
    assert_eq!(one.objects()[0].normals, many.objects()[0].normals);
    for o in &many.objects()[1..] {
        assert_eq!(o.positions, one_original());
    }
    // The region holds far fewer points than the object.
    assert!(r1.points_inside().len() < one.objects()[0].positions.len() / 3);
}

fn one_original() -> Vec<DVec3> {
    fitted_object(Shape::Sphere { radius: 0.3 }, 3000, 5).positions
}
