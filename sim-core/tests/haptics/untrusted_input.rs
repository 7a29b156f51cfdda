//! Regressions from the robustness review: finite but extreme inputs to the probe's index.

use glam::DVec3;
use sim_core::probe::{
    ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose, ProbeRenderer, SampleGrid,
    SurfaceSample,
};

#[test]
fn samples_spanning_more_than_f64_max_bin_without_hanging() {
    // Positions ±1e308 are finite, but their extent overflows to infinity: growing the cell
    // until the grid fits never ended (inf / cell stays inf, then inf / inf is NaN).
    let s = |x: f64| SurfaceSample {
        position: DVec3::new(x, 0.0, 0.0),
        normal: DVec3::Z,
        area: 1e-6,
    };
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let grid = SampleGrid::new(&[s(-1e308), s(1e308), s(0.0)], 0.01).unwrap();
        // The sample at the origin is still found, with a finite force.
        let params = ContactParams {
            surface_stiffness: 1e3,
            surface_damping: 0.0,
            method: DirectionMethod::SurfaceNormal,
            magnitude: MagnitudeMethod::SpringSum,
        };
        let mut r = ProbeRenderer::new(params, 8).unwrap();
        let probe = Probe::sphere(0.01)
            .unwrap()
            .posed(ProbePose::at(DVec3::new(0.0, 0.0, 0.005)))
            .unwrap();
        let f = r.query(&probe, &grid, DVec3::ZERO);
        let _ = tx.send((grid.len(), f.contact_count, f.force));
    });
    let got = rx
        .recv_timeout(std::time::Duration::from_secs(10))
        .expect("SampleGrid::new did not return within 10 s");
    let (len, contacts, force) = got;
    assert_eq!((len, contacts), (3, 1));
    assert!(force.is_finite() && force.z > 0.0, "{force}");
}
