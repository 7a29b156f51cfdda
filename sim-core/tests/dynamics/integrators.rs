//! Integrators: equilibrium, rollback, stiff systems, steps past the explicit limit, impulses,
//! and measured stability limits against the predicted ones.

use sim_core::dynamics::stability::{LimitSearch, is_stable, measure_limit, predicted_limits};
use sim_core::dynamics::{DynamicGrid, Integrator, NodeParams, StepError, Stepper};

use crate::common::{perturb, small_model, sphere_grid};

fn all_integrators() -> [Integrator; 3] {
    [
        Integrator::forward_euler(1e9),
        Integrator::SymplecticEuler,
        Integrator::backward_euler(),
    ]
}

#[test]
fn rest_field_is_an_exact_equilibrium() {
    for integ in all_integrators() {
        let mut m =
            DynamicGrid::new(&sphere_grid(0.3, 0.5, 17), 0.1, NodeParams::default()).unwrap();
        let mut st = Stepper::new(integ);
        for _ in 0..50 {
            st.step(&mut m, 1e-3).unwrap();
        }
        assert!(
            m.displacement().iter().all(|&u| u == 0.0),
            "{}",
            integ.name()
        );
        assert!(m.velocity().iter().all(|&v| v == 0.0), "{}", integ.name());
    }
}

#[test]
fn band_selects_only_nodes_near_the_surface() {
    let g = sphere_grid(0.3, 0.5, 21);
    let m = DynamicGrid::new(&g, 0.1, NodeParams::default()).unwrap();
    assert!(m.active_len() < g.values().len() / 2);
    for &gi in m.active_nodes() {
        assert!(g.values()[gi as usize].abs() <= 0.1);
    }
    assert!(DynamicGrid::new(&sphere_grid(0.3, 0.5, 5), 0.0, NodeParams::default()).is_err());
}

#[test]
fn non_finite_force_is_rolled_back_and_reported() {
    for integ in all_integrators() {
        let mut m = small_model(6, NodeParams::default());
        perturb(&mut m, 1e-3);
        let mut st = Stepper::new(integ);
        st.step(&mut m, 1e-4).unwrap();
        let (u, v, t) = (m.displacement().to_vec(), m.velocity().to_vec(), m.time());
        m.add_force(17, f64::NAN);
        let err = st.step(&mut m, 1e-4).unwrap_err();
        assert_eq!(
            err,
            StepError::NonFiniteForce { slot: 17 },
            "{}",
            integ.name()
        );
        // Bit-for-bit unchanged state and clock.
        assert_eq!(m.displacement(), &u[..]);
        assert_eq!(m.velocity(), &v[..]);
        assert_eq!(m.time(), t);
        assert!(matches!(
            st.step(&mut m, f64::NAN),
            Err(StepError::InvalidDt(_))
        ));
    }
}

#[test]
fn static_response_solves_k_u_equals_f() {
    // Backward Euler is a damped fixed-point iteration of K u = f: after enough steps the
    // residual |K u − f| must be below 1e-6 of |f| (CG tolerance 1e-8, slow modes decayed).
    let mut m = small_model(8, NodeParams::default());
    for s in 0..m.active_len() {
        m.add_force(s, if s % 3 == 0 { 1e-3 } else { -5e-4 });
    }
    let mut st = Stepper::new(Integrator::backward_euler());
    for _ in 0..400 {
        st.step(&mut m, 1e-2).unwrap();
    }
    let u = m.displacement().to_vec();
    let f = m.forces().to_vec();
    let mut residual: f64 = 0.0;
    for (s, fs) in f.iter().enumerate() {
        let ku = m.stiffness_times(&u, s);
        residual = residual.max((ku - fs).abs());
    }
    assert!(residual < 1e-6 * 1e-3, "residual {residual}");
}

#[test]
fn measured_limits_match_predictions() {
    // Gershgorin over-estimates ω_max, so the measured limit is at least the predicted one; on
    // this 8³ grid the top mode is within 10 % of the bound, so the measurement must not exceed
    // 1.25× the prediction. Backward Euler must be stable at 1000× the explicit limits.
    let m = small_model(8, NodeParams::default());
    let search = LimitSearch {
        steps: 1500,
        ..LimitSearch::default()
    };
    let (fe_pred, se_pred) = predicted_limits(&m);
    let fe = measure_limit(&m, Integrator::forward_euler(1e9), 1e-5, 1e-1, &search);
    let se = measure_limit(&m, Integrator::SymplecticEuler, 1e-5, 1e-1, &search);
    assert!(
        fe >= 0.98 * fe_pred && fe <= 1.25 * fe_pred,
        "FE {fe} vs {fe_pred}"
    );
    assert!(
        se >= 0.98 * se_pred && se <= 1.25 * se_pred,
        "SE {se} vs {se_pred}"
    );
    assert!(is_stable(
        &m,
        Integrator::backward_euler(),
        1000.0 * se,
        &search
    ));
    // Undamped forward Euler is unconditionally unstable: even at 1/20 of the damped limit
    // the top mode grows by (1 + ω²Δt²)^(n/2) ≈ e^22 over 20,000 steps.
    let undamped = small_model(
        8,
        NodeParams {
            damping: 0.0,
            ..NodeParams::default()
        },
    );
    assert!(!is_stable(
        &undamped,
        Integrator::forward_euler(1e9),
        1e-4,
        &LimitSearch {
            steps: 20_000,
            growth: 1.5,
            ..search
        }
    ));
}

#[test]
fn very_stiff_light_nodes_stay_bounded() {
    // k = 1e6 N/m, m = 1e-3 kg: ω_max ≈ 1.1e5 rad/s, explicit limits ≈ 10 µs. At the haptic
    // step (1 ms, ~100× past them) backward Euler must dissipate: energy never above E₀.
    let p = NodeParams {
        mass: 1e-3,
        damping: 1.0,
        stiffness: 1e6,
        anchor: 1e6,
    };
    let mut m = small_model(8, p);
    perturb(&mut m, 1e-3);
    let e0 = m.energy();
    let mut st = Stepper::new(Integrator::backward_euler());
    for _ in 0..50 {
        let r = st.step(&mut m, 1e-3).unwrap();
        assert!(r.cg_residual <= 1e-8, "CG residual {}", r.cg_residual);
        assert!(m.energy() <= e0);
    }
    // Explicit Euler needs damping: with c = 1 (ζ ≈ 0.005) its limit 2ζ/ω is ~80 ns, beyond 12
    // halvings of 1 ms, and it must say so (`saturated`) rather than pretend.
    let mut m1 = small_model(8, p);
    perturb(&mut m1, 1e-3);
    let mut fe = Stepper::new(Integrator::ForwardEuler {
        accel_threshold: 1.0,
        max_halvings: 12,
        relax_after: 0,
    });
    assert!(fe.step(&mut m1, 1e-3).unwrap().saturated);
    // With ζ ≈ 0.45 (c = 100) the limit is ≈ 8 µs: at 1 ms (threshold 2× the initial |ü|) it
    // detects the instability through |ü|, halves to ≥ 128 sub-steps, and dissipates.
    let p = NodeParams {
        damping: 100.0,
        ..p
    };
    let mut m2 = small_model(8, p);
    perturb(&mut m2, 1e-3);
    let mut probe = vec![0.0; m2.active_len()];
    m2.acceleration_into(&mut probe);
    let a0 = probe.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    let mut fe = Stepper::new(Integrator::ForwardEuler {
        accel_threshold: 2.0 * a0,
        max_halvings: 12,
        relax_after: 0,
    });
    for _ in 0..20 {
        fe.step(&mut m2, 1e-3).unwrap();
        assert!(m2.energy() <= 10.0 * e0);
    }
    assert!(fe.level() >= 7, "level {}", fe.level());
    assert!(m2.energy() < e0);
}

#[test]
fn ten_times_past_the_explicit_limit_for_1e5_steps() {
    let p = NodeParams::default();
    let mut base = small_model(6, p);
    perturb(&mut base, 1e-3);
    let (fe_limit, se_limit) = predicted_limits(&base);
    let e0 = base.energy();
    // Forward Euler with halving: the threshold is 2× the initial largest |ü|, which bounds
    // |K u + C u̇| by 2 m |ü₀| and so the elastic energy by about 2² × E₀; kinetic energy adds to
    // that, so the bound is 10 × E₀. It must detect (halve), stay bounded, and dissipate.
    let mut probe = vec![0.0; base.active_len()];
    base.acceleration_into(&mut probe);
    let a0 = probe.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    let mut m = base.clone();
    let mut fe = Stepper::new(Integrator::ForwardEuler {
        accel_threshold: 2.0 * a0,
        max_halvings: 10,
        relax_after: 1000,
    });
    let (mut halvings, mut e_max) = (0, 0.0f64);
    for _ in 0..100_000 {
        halvings += fe.step(&mut m, 10.0 * fe_limit).unwrap().halvings;
        e_max = e_max.max(m.energy());
    }
    assert!(halvings > 0);
    assert!(e_max <= 10.0 * e0, "forward Euler energy {e_max} vs {e0}");
    assert!(m.energy() <= e0, "forward Euler did not dissipate");
    // Backward Euler at 10× the (larger) symplectic limit: energy never rises.
    let mut m = base.clone();
    let mut be = Stepper::new(Integrator::backward_euler());
    let mut prev = e0;
    for _ in 0..100_000 {
        be.step(&mut m, 10.0 * se_limit.max(fe_limit)).unwrap();
        let e = m.energy();
        assert!(e <= prev * (1.0 + 1e-9) + 1e-300);
        prev = e;
    }
    // Symplectic Euler at 10× its limit blows up and is caught, state left finite.
    let mut m = base.clone();
    let mut se = Stepper::new(Integrator::SymplecticEuler);
    let caught = (0..100_000).any(|_| se.step(&mut m, 10.0 * se_limit).is_err());
    assert!(caught && m.displacement().iter().all(|u| u.is_finite()));
}

#[test]
fn impulse_of_1e3_times_the_normal_force_decays() {
    // A "normal" rope force gives a displacement ~1e-3 m (f = a·u = 0.1 N); the impulse is
    // 1e3× that for one 1 ms step (inside every scheme's stability limit at the default nodes).
    // All must stay finite and return to within 1e-9 m of rest within 2 s (the slowest mode
    // decays like exp(−c t / 2m) = e^−500).
    for integ in [
        Integrator::forward_euler(1e7),
        Integrator::SymplecticEuler,
        Integrator::backward_euler(),
    ] {
        let mut m = small_model(8, NodeParams::default());
        let mut st = Stepper::new(integ);
        m.add_force(100, 0.1 * 1e3);
        st.step(&mut m, 1e-3).unwrap();
        m.clear_forces();
        for _ in 0..2000 {
            st.step(&mut m, 1e-3).unwrap();
        }
        let umax = m.displacement().iter().fold(0.0f64, |a, u| a.max(u.abs()));
        assert!(umax < 1e-9, "{}: {umax}", integ.name());
    }
}

#[test]
fn stepping_is_deterministic() {
    let run = || {
        let mut m = small_model(8, NodeParams::default());
        perturb(&mut m, 1e-3);
        let mut st = Stepper::new(Integrator::backward_euler());
        for _ in 0..20 {
            st.step(&mut m, 1e-3).unwrap();
        }
        m.displacement().to_vec()
    };
    assert_eq!(run(), run());
}

#[test]
fn snapshots_show_rest_plus_displacement_and_are_recycled() {
    let mut m = small_model(6, NodeParams::default());
    perturb(&mut m, 1e-3);
    let a = m.publish();
    let g0 = m.active_nodes()[5] as usize;
    assert_eq!(a.values()[g0], m.rest_value(g0) + m.displacement()[5]);
    let ptr = std::sync::Arc::as_ptr(&a);
    drop(a);
    let b = m.publish();
    assert_eq!(
        std::sync::Arc::as_ptr(&b),
        ptr,
        "a dropped snapshot is reused"
    );
    let c = m.publish();
    assert_ne!(
        std::sync::Arc::as_ptr(&c),
        ptr,
        "a held snapshot is not overwritten"
    );
}

#[test]
fn overdamped_light_nodes_have_the_fast_pole_limit() {
    // m = 1e-6 kg with the default damping: ζ ≈ 17 at the top mode, so forward Euler's limit is
    // set by the fast real pole, ≈ 2m/c = 4 µs, not by 2ζ/ω (which would say 2.3 ms).
    let p = NodeParams {
        mass: 1e-6,
        ..NodeParams::default()
    };
    let m = small_model(8, p);
    let (fe_pred, _) = predicted_limits(&m);
    assert!(
        (fe_pred - 2.0 * 1e-6 / 0.5).abs() < 0.05 * 4e-6,
        "{fe_pred}"
    );
    let search = LimitSearch {
        steps: 1500,
        ..LimitSearch::default()
    };
    let fe = measure_limit(&m, Integrator::forward_euler(1e9), 1e-8, 1e-2, &search);
    assert!(
        fe >= 0.98 * fe_pred && fe <= 1.25 * fe_pred,
        "FE {fe} vs {fe_pred}"
    );
}

#[test]
fn edited_node_parameters_take_effect_in_k() {
    // K u from the model's table must equal the definition, a u_s + Σ_j (k_s + k_j)/2 (u_s − u_j)
    // with fixed neighbours at 0, after editing the parameters of a ball of nodes (round-off
    // only: 1e-12 relative).
    use sim_core::dynamics::model::{ABSENT, FIXED};
    let mut m = DynamicGrid::new(&sphere_grid(0.3, 0.5, 15), 0.12, NodeParams::default()).unwrap();
    perturb(&mut m, 1e-3);
    let stiff = NodeParams {
        stiffness: 500.0,
        anchor: 7.0,
        ..NodeParams::default()
    };
    let edited = m
        .set_params_in_ball(glam::DVec3::new(0.0, 0.0, 0.3), 0.1, stiff)
        .unwrap();
    assert!(edited > 10);
    let u = m.displacement().to_vec();
    for s in 0..m.active_len() {
        let p = m.node_params(s);
        let mut want = p.anchor * u[s];
        for &j in m.neighbours_of(s) {
            match j {
                ABSENT => {}
                FIXED => want += p.stiffness * u[s],
                j => {
                    want += 0.5
                        * (p.stiffness + m.node_params(j as usize).stiffness)
                        * (u[s] - u[j as usize])
                }
            }
        }
        let got = m.stiffness_times(&u, s);
        assert!(
            (got - want).abs() <= 1e-12 * want.abs().max(1e-9),
            "slot {s}: {got} vs {want}"
        );
    }
    assert!(
        m.set_node_params(
            0,
            NodeParams {
                mass: -1.0,
                ..NodeParams::default()
            }
        )
        .is_err()
    );
}
