//! The B-spline patch and its mass-spring dual: basis, `M = A P Aᵀ`, sculpting, locality.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_core::bspline_surface::{
    BicubicPatch, DualMap, MassSpringMesh, MeshParams, ProbeSculptor, SurfaceError, cubic_basis,
    mass_parameter,
};
use sim_core::probe::{ContactParams, DirectionMethod, MagnitudeMethod, Probe, ProbePose};

#[test]
fn cubic_basis_sums_to_one_and_its_derivative_matches_finite_differences() {
    for n in [4, 5, 9, 30] {
        // Clamped ends: N_0'(0) = −3/(t_4 − t_1) = −3(n − 3).
        assert!((cubic_basis(n, 0.0).deriv[0] + 3.0 * (n - 3) as f64).abs() < 1e-12);
        for k in 0..=200 {
            let t = k as f64 / 200.0;
            let b = cubic_basis(n, t);
            assert!(
                (b.value.iter().sum::<f64>() - 1.0).abs() < 1e-14,
                "n={n} t={t}"
            );
            assert!(b.value.iter().all(|&v| v >= -1e-15));
            // Central difference with step 1e-6 inside a span: error O(1e-12 · N''').
            let (lo, hi) = ((t - 1e-6).max(0.0), (t + 1e-6).min(1.0));
            let (bl, bh) = (cubic_basis(n, lo), cubic_basis(n, hi));
            if lo > 0.0 && hi < 1.0 && bl.first == b.first && bh.first == b.first {
                for r in 0..4 {
                    let fd = (bh.value[r] - bl.value[r]) / (hi - lo);
                    assert!(
                        (fd - b.deriv[r]).abs() < 1e-6 * (n as f64).powi(2),
                        "n={n} t={t} r={r}"
                    );
                }
            }
        }
    }
}

fn random_net(n: usize, seed: u64) -> BicubicPatch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = BicubicPatch::flat(n, 0.05).unwrap();
    for c in p.control_mut() {
        *c += DVec3::new(
            rng.random_range(-0.003..0.003),
            rng.random_range(-0.003..0.003),
            rng.random_range(-0.01..0.01),
        );
    }
    p
}

#[test]
fn dual_map_puts_mass_points_on_the_surface_and_inverts_exactly() {
    for n in [4, 7, 30] {
        let patch = random_net(n, n as u64);
        let mut dual = DualMap::new(n).unwrap();
        let mut mesh = vec![DVec3::ZERO; n * n];
        dual.to_mesh(patch.control(), &mut mesh);
        for k in 0..n {
            for l in 0..n {
                let s = patch.point(mass_parameter(n, k), mass_parameter(n, l));
                // Two evaluation orders of the same sums: 1e-15 m.
                assert!((mesh[k * n + l] - s).length() < 1e-15, "n={n} ({k},{l})");
            }
        }
        let mut back = vec![DVec3::ZERO; n * n];
        dual.to_control(&mesh, &mut back);
        let err = back
            .iter()
            .zip(patch.control())
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        // cond(A) stays below ~10 for these n; round-off ~1e-16 × cond × n.
        assert!(err < 1e-13, "n={n}: {err}");
    }
    assert_eq!(DualMap::new(3).unwrap_err(), SurfaceError::BadSize(3));
}

fn mesh_params(total_mass: f64) -> MeshParams {
    MeshParams {
        total_mass,
        stiffness: 20.0,
        bending: 2.0,
        damping_rate: DAMPING_RATE,
        plastic_rate: 0.0,
        pin_border: true,
    }
}

fn contact() -> ContactParams {
    ContactParams {
        surface_stiffness: 5.0e6,
        surface_damping: 0.0,
        method: DirectionMethod::SurfaceNormal,
        magnitude: MagnitudeMethod::SpringSum,
    }
}

const N: usize = 31;
const DAMPING_RATE: f64 = 200.0;
const HALF: f64 = 0.05;
const RADIUS: f64 = 0.008;

fn sculptor(total_mass: f64) -> ProbeSculptor {
    ProbeSculptor::new(
        BicubicPatch::flat(N, HALF).unwrap(),
        mesh_params(total_mass),
        contact(),
        0.005,
        0.01,
    )
    .unwrap()
}

/// Press the probe from `z0` to `z1` over 50 ms with the button down, hold 100 ms.
fn press(s: &mut ProbeSculptor, z0: f64, z1: f64) -> DVec3 {
    let mut probe = Probe::sphere(RADIUS).unwrap();
    let dt = 0.001;
    let mut last = DVec3::ZERO;
    for t in 0..150 {
        let a = (t as f64 / 50.0).min(1.0);
        let z = z0 + (z1 - z0) * a;
        let v = if t < 50 {
            DVec3::new(0.0, 0.0, (z1 - z0) / 0.05)
        } else {
            DVec3::ZERO
        };
        probe
            .set_pose(ProbePose::at(DVec3::new(0.0, 0.0, z)))
            .unwrap();
        last = s.tick(&probe, v, true, dt).unwrap().output.force;
    }
    last
}

/// Full width at half maximum of the z-displacement along the row through the centre, m.
fn bulge_width(s: &ProbeSculptor) -> (f64, f64) {
    let mid = N / 2;
    let row: Vec<(f64, f64)> = (0..N)
        .map(|i| {
            let p = s.mesh().positions()[i * N + mid];
            (p.x, p.z.abs())
        })
        .collect();
    let peak = row[mid].1;
    let half = 0.5 * peak;
    let cross = |range: &mut dyn Iterator<Item = usize>| -> f64 {
        let mut prev = row[mid];
        for i in range {
            if row[i].1 < half {
                let f = (prev.1 - half) / (prev.1 - row[i].1);
                return (prev.0 + f * (row[i].0 - prev.0)).abs();
            }
            prev = row[i];
        }
        HALF
    };
    let w = cross(&mut (mid + 1..N)) + cross(&mut (0..mid).rev());
    (w, peak)
}

#[test]
fn heavier_mesh_bulges_more_locally_under_the_same_press() {
    // Seed 004 Fig. 8: the same tool, a mesh 100× heavier. The disturbance spreads at
    // h·√(k/m), so after the same 150 ms press the heavy bulge is narrower.
    let mut light = sculptor(0.01);
    let mut heavy = sculptor(1.0);
    let fl = press(&mut light, RADIUS + 0.002, RADIUS - 0.006);
    let fh = press(&mut heavy, RADIUS + 0.002, RADIUS - 0.006);
    let (wl, pl) = bulge_width(&light);
    let (wh, ph) = bulge_width(&heavy);
    eprintln!(
        "bspline locality: light width {:.2} mm peak {:.2} mm force {fl}; heavy width {:.2} mm peak {:.2} mm force {fh}",
        wl * 1e3,
        pl * 1e3,
        wh * 1e3,
        ph * 1e3
    );
    assert!(pl > 0.001 && ph > 0.001, "both pressed in: {pl} {ph}");
    assert!(wh < 0.75 * wl, "heavy {wh} vs light {wl}");
    // Pushing down: the material pushes back up (Newton's third law), and the heavier material
    // (whose points yield less in the same time) pushes back harder.
    assert!(fl.z > 0.0 && fh.z > fl.z, "{fl} {fh}");
}

#[test]
fn pulling_from_behind_raises_a_bulge_and_pulls_back_on_the_user() {
    let mut s = sculptor(0.1);
    let f = press(&mut s, -RADIUS - 0.002, -RADIUS + 0.006);
    let centre = s.mesh().positions()[(N / 2) * N + N / 2];
    assert!(centre.z > 0.001, "bulge raised: {centre}");
    assert!(f.z < 0.0, "reaction resists the pull: {f}");
}

#[test]
fn display_net_reproduces_the_sculpted_mesh() {
    let mut s = sculptor(0.1);
    press(&mut s, RADIUS + 0.002, RADIUS - 0.005);
    let mesh: Vec<DVec3> = s.mesh().positions().to_vec();
    let patch = s.update_display().clone();
    for k in 0..N {
        for l in 0..N {
            let p = patch.point(mass_parameter(N, k), mass_parameter(N, l));
            assert!((p - mesh[k * N + l]).length() < 1e-12, "({k},{l})");
        }
    }
}

#[test]
fn touching_without_the_button_leaves_the_surface_and_feels_rigid() {
    let mut s = sculptor(0.1);
    let probe = Probe::sphere(RADIUS)
        .unwrap()
        .posed(ProbePose::at(DVec3::new(0.0, 0.0, RADIUS - 0.002)))
        .unwrap();
    let before: Vec<DVec3> = s.mesh().positions().to_vec();
    let t = s.tick(&probe, DVec3::ZERO, false, 0.001).unwrap();
    assert_eq!(s.mesh().positions(), &before[..]);
    assert!(t.contacts > 0 && t.output.force.z > 0.0, "{t:?}");
}

#[test]
fn non_finite_inputs_are_rejected_and_leave_the_mesh_unchanged() {
    let mut m = MassSpringMesh::new(
        4,
        BicubicPatch::flat(4, 0.01).unwrap().control().to_vec(),
        mesh_params(0.1),
    )
    .unwrap();
    let before = m.positions().to_vec();
    let mut ext = vec![DVec3::ZERO; 16];
    ext[5].z = f64::NAN;
    assert_eq!(m.step(0.001, &ext), Err(SurfaceError::NonFinite));
    assert_eq!(
        m.step(f64::INFINITY, &vec![DVec3::ZERO; 16]),
        Err(SurfaceError::NonFinite)
    );
    assert_eq!(m.positions(), &before[..]);
    let mut s = sculptor(0.1);
    let probe = Probe::sphere(RADIUS).unwrap();
    assert!(s.tick(&probe, DVec3::ZERO, true, f64::NAN).is_err());
    let t = s.tick(&probe, DVec3::splat(f64::NAN), true, 0.001).unwrap();
    assert!(t.output.force.is_finite());
}

#[test]
fn the_substep_rule_keeps_an_undamped_mesh_energy_bounded() {
    // No damping, stiff springs, a light mesh kicked hard (Δv ≈ 700 m/s on one point: the mesh
    // swings through large rotations). Symplectic Euler conserves a *modified* energy, so the
    // true energy oscillates by O(h·ω) (±20 % allowed) but must not drift: the envelope over
    // the tenth second matches the first to 2 %. At half the linear bound (the old rule) it
    // had grown 13 % by then and exploded after ~20 s.
    let n = 12;
    let params = MeshParams {
        total_mass: 0.001,
        stiffness: 200.0,
        bending: 20.0,
        damping_rate: 0.0,
        plastic_rate: 0.0,
        pin_border: true,
    };
    let flat = BicubicPatch::flat(n, 0.02).unwrap().control().to_vec();
    let mut mesh = MassSpringMesh::new(n, flat, params).unwrap();
    let mut kick = vec![DVec3::ZERO; n * n];
    kick[(n / 2) * n + n / 2] = DVec3::new(0.0, 0.0, 5.0);
    let substeps = mesh.step(0.001, &kick).unwrap();
    assert!(
        substeps > 10,
        "a light stiff mesh needs substeps: {substeps}"
    );
    let zero = vec![DVec3::ZERO; n * n];
    mesh.step(0.001, &zero).unwrap();
    let e0 = mesh.energy();
    let mut windows = Vec::new();
    for _ in 0..10 {
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for _ in 0..1000 {
            mesh.step(0.001, &zero).unwrap();
            (lo, hi) = (lo.min(mesh.energy()), hi.max(mesh.energy()));
        }
        windows.push((lo, hi));
    }
    let (first, last) = (windows[0], windows[9]);
    assert!(
        windows
            .iter()
            .all(|&(lo, hi)| lo > 0.8 * e0 && hi < 1.2 * e0),
        "{e0}: {windows:?}"
    );
    assert!(
        last.1 <= 1.02 * first.1 && last.0 >= 0.98 * first.0,
        "{first:?} → {last:?}"
    );
}
