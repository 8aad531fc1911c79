//! Analytic models cross-checked against each other, against hand-derived values and against
//! the paper's worked numbers (with the errata listed in `shared/README.md`).

use feeder_shared::model::{self, DUTY_OPT, DUTY_SAT_QUASI_STATIC};
use feeder_shared::{Drive, Error, Friction, Limits, Regime, Waveform, WaveformSpec};
use proptest::prelude::*;

const G: f64 = 9.80665;

fn close(actual: f64, expected: f64, rel: f64) -> bool {
    (actual - expected).abs() <= rel * expected.abs().max(1e-300)
}

fn accel_waveform(period_s: f64, duty: f64, accel_mps2: f64) -> Waveform {
    Waveform::new(
        WaveformSpec {
            period_s,
            duty,
            drive: Drive::Accel { accel_mps2 },
        },
        &Limits::NONE,
    )
    .unwrap()
}

#[test]
fn quasi_static_constants() {
    assert!(close(DUTY_OPT, 0.585_786_437_626_905, 1e-15));
    assert!(close(
        model::velocity_ratio_quasi_static(DUTY_OPT),
        0.5,
        1e-12
    ));
    assert!(close(
        model::velocity_ratio_quasi_static(DUTY_SAT_QUASI_STATIC),
        1.0,
        1e-12
    ));
    assert!(close(model::duty_for_velocity_ratio(0.5), DUTY_OPT, 1e-12));
    assert!(close(model::duty_for_velocity_ratio(1.0), 0.625, 1e-12));
    // Errata 2: the printed Eq. 8 is 0/0 at r = 1/4; the removable form gives d = 5/9 there.
    assert!(close(
        model::duty_for_velocity_ratio(0.25),
        5.0 / 9.0,
        1e-12
    ));
    assert!(close(
        model::velocity_ratio_quasi_static(5.0 / 9.0),
        0.25,
        1e-12
    ));
    // Peak of the quasi-static curve: aT/16 at d = 5/8 (Section III.A.1).
    let w = accel_waveform(1.0, 0.625, 1.0);
    assert!(close(
        model::feed_rate_quasi_static_mps(&w),
        1.0 / 16.0,
        1e-12
    ));
}

#[test]
fn paper_section_iv_a_saturation_duty() {
    // a ≈ 145.86 m/s², μ = 1: Eq. 16 gives d_sat,nqs ≈ 0.61 (printed "≅ 0.61").
    let w = Waveform::new(
        WaveformSpec::from_frequency(50.0, 0.586, Drive::Stroke { stroke_m: 0.0025 }),
        &Limits::NONE,
    )
    .unwrap();
    let friction = Friction::new(1.0, G).unwrap();
    let d_sat = model::duty_sat_non_quasi_static(w.accel_mps2, &friction);
    assert!((d_sat - 0.61).abs() < 0.005, "{d_sat}");
    let state = model::steady_state(&w, &friction);
    assert_eq!(state.regime, Regime::Sliding);
    assert!(close(
        state.feed_rate_mps,
        w.accel_mps2 * 0.02 * (2.0 * 0.586 - 1.0) / 4.0,
        1e-14
    ));
}

#[test]
fn paper_section_iv_c_viscosity() {
    // T = 0.01 s, a = 100 m/s², μ = 0.5, m = 0.1 g, g = 9.81 m/s²: K = 1.96 dyn·s/cm.
    let w = accel_waveform(0.01, 0.55, 100.0);
    let friction = Friction::new(0.5, 9.81).unwrap();
    let k = model::viscosity_ns_per_m(&w, &friction, 1e-4).unwrap();
    assert!(close(k, 1.962e-3, 1e-12));
    // Errata 8: the fit intercept −4.72 dyn with slope 1.95 implies v_eq = 2.42 cm/s, d ≈ 0.5484.
    let v_eq_mps: f64 = 4.72 / 1.95 / 100.0;
    let duty: f64 = 0.5 + 2.0 * v_eq_mps / (100.0 * 0.01);
    assert!((duty - 0.5484).abs() < 1e-4, "{duty}");
}

#[test]
fn no_slip_when_accel_does_not_exceed_mu_g() {
    let friction = Friction::new(1.0, G).unwrap();
    let w = accel_waveform(0.02, 0.6, G);
    let state = model::steady_state(&w, &friction);
    assert_eq!(
        (state.regime, state.feed_rate_mps, state.stick_fraction),
        (Regime::Stuck, 0.0, 1.0)
    );
    assert_eq!(
        model::feed_rate_under_force_mps(&w, &friction, 1e-3, 0.0),
        Err(Error::NoSlip {
            accel_mps2: G,
            friction_accel_mps2: G
        })
    );
}

#[test]
fn viscous_law_is_refused_outside_its_range() {
    let friction = Friction::new(0.5, G).unwrap();
    let w = accel_waveform(0.01, 0.55, 100.0);
    let mass_kg = 1e-4;
    // |f/m| ≥ μg: the force overcomes friction.
    let strong = mass_kg * 0.5 * G;
    assert_eq!(
        model::feed_rate_under_force_mps(&w, &friction, mass_kg, strong),
        Err(Error::OutsideViscousRange { force_n: strong })
    );
    assert!(matches!(
        model::feed_rate_under_force_mps(&w, &friction, mass_kg, f64::NAN),
        Err(Error::NotFinite { .. })
    ));
    assert!(matches!(
        model::feed_rate_under_force_mps(&w, &friction, 0.0, 0.0),
        Err(Error::NotPositive { .. })
    ));
}

#[test]
fn friction_is_validated() {
    assert!(matches!(
        Friction::new(0.0, G),
        Err(Error::NotPositive { .. })
    ));
    assert!(matches!(
        Friction::new(1.0, f64::NAN),
        Err(Error::NotFinite { .. })
    ));
}

#[test]
fn inverse_for_fixed_accel_is_eq_15_solved_for_d() {
    let friction = Friction::new(1.0, G).unwrap();
    let w = model::duty_for_feed_rate(
        0.02,
        0.1,
        Drive::Accel { accel_mps2: 150.0 },
        &friction,
        &Limits::NONE,
    )
    .unwrap();
    // v = aT(2d − 1)/4 → d = 1/2 + 2v/(aT) = 0.5 + 0.2/3.
    assert!(close(w.duty, 0.5 + 0.2 / 3.0, 1e-9), "{}", w.duty);
    assert_eq!(w.accel_mps2, 150.0);
}

#[test]
fn inverse_for_fixed_stroke_reaches_the_target() {
    let friction = Friction::new(1.0, G).unwrap();
    let drive = Drive::Stroke { stroke_m: 0.0025 };
    let w = model::duty_for_feed_rate(0.02, 0.1, drive, &friction, &Limits::NONE).unwrap();
    assert_eq!(w.stroke_m, 0.0025);
    let state = model::steady_state(&w, &friction);
    assert_eq!(state.regime, Regime::Sliding);
    assert!(
        close(state.feed_rate_mps, 0.1, 1e-9),
        "{}",
        state.feed_rate_mps
    );
}

#[test]
fn inverse_reports_what_is_reachable() {
    let friction = Friction::new(1.0, G).unwrap();
    let limits = Limits {
        max_accel_mps2: 200.0,
        ..Limits::NONE
    };
    let drive = Drive::Accel { accel_mps2: 150.0 };
    // Sliding ends at d_sat,nqs(150): the fastest sliding rate is Eq. 15 there.
    let d_sat = model::duty_sat_non_quasi_static(150.0, &friction);
    let max_mps = 150.0 * 0.02 * (2.0 * d_sat - 1.0) / 4.0;
    match model::duty_for_feed_rate(0.02, 1.0, drive, &friction, &limits) {
        Err(Error::FeedRateAboveReach {
            target_mps,
            max_mps: reach,
        }) => {
            assert_eq!(target_mps, 1.0);
            assert!(close(reach, max_mps, 1e-6), "{reach} vs {max_mps}");
        }
        other => panic!("{other:?}"),
    }
    // A stroke limit forbids low duties at fixed accel: x = a(T(1 − d)/2)² ≤ 1.2 mm at
    // a = 60 m/s² → d ≥ 0.5528, below d_sat,nqs(60) = 0.5875.
    let short = Limits {
        max_stroke_m: 0.0012,
        ..Limits::NONE
    };
    let gentle = Drive::Accel { accel_mps2: 60.0 };
    match model::duty_for_feed_rate(0.02, 0.001, gentle, &friction, &short) {
        Err(Error::FeedRateBelowReach { min_mps, .. }) => {
            let d_min = 1.0 - 2.0 * (0.0012f64 / 60.0).sqrt() / 0.02;
            assert!(
                close(min_mps, 60.0 * 0.02 * (2.0 * d_min - 1.0) / 4.0, 1e-6),
                "{min_mps}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        model::duty_for_feed_rate(0.02, -0.1, drive, &friction, &Limits::NONE),
        Err(Error::NotPositive { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn eq_8_inverts_eq_7(duty in 0.5f64..0.625) {
        let ratio = model::velocity_ratio_quasi_static(duty);
        prop_assert!((model::duty_for_velocity_ratio(ratio) - duty).abs() < 1e-9);
    }

    #[test]
    fn eq_9_is_r_times_v_max(duty in 0.5001f64..0.625, period_s in 0.005f64..0.05, accel_mps2 in 10.0f64..500.0) {
        let w = accel_waveform(period_s, duty, accel_mps2);
        let via_ratio = model::velocity_ratio_quasi_static(duty) * w.v_max_mps;
        prop_assert!(close(model::feed_rate_quasi_static_mps(&w), via_ratio, 1e-9));
        prop_assert!(close(model::feed_rate_sliding_mps(&w), via_ratio, 1e-9));
    }

    #[test]
    fn eq_16_is_where_eq_18_meets_eq_15(accel_over_mu_g in 1.05f64..200.0, period_s in 0.005f64..0.05, mu in 0.1f64..1.5) {
        let friction = Friction::new(mu, G).unwrap();
        let accel_mps2 = accel_over_mu_g * friction.accel_mps2();
        let d_sat = model::duty_sat_non_quasi_static(accel_mps2, &friction);
        prop_assume!(d_sat > 0.5001);
        let w = accel_waveform(period_s, d_sat, accel_mps2);
        prop_assert!(close(model::feed_rate_saturated_mps(&w, &friction), model::feed_rate_sliding_mps(&w), 1e-9));
        // Eq. 14 at the onset: h_b = v_max.
        let h_b = period_s / 4.0 * (accel_mps2 * (2.0 * d_sat - 1.0) + friction.accel_mps2());
        prop_assert!(close(h_b, w.v_max_mps, 1e-9));
        // Eq. 17 (corrected direction) agrees with Eq. 16 on either side of the onset.
        let ratio_bound = model::saturation_accel_ratio(d_sat);
        prop_assert!(close(ratio_bound, accel_over_mu_g, 1e-6));
        prop_assert!(d_sat < DUTY_SAT_QUASI_STATIC);
    }

    #[test]
    fn saturated_regime_is_consistent(accel_over_mu_g in 1.1f64..50.0, excess in 0.001f64..0.3, period_s in 0.005f64..0.05) {
        let friction = Friction::new(1.0, G).unwrap();
        let accel_mps2 = accel_over_mu_g * friction.accel_mps2();
        let duty = model::duty_sat_non_quasi_static(accel_mps2, &friction).max(0.5) + excess;
        prop_assume!(duty < 0.999);
        let w = accel_waveform(period_s, duty, accel_mps2);
        let state = model::steady_state(&w, &friction);
        prop_assert_eq!(state.regime, Regime::Saturated);
        prop_assert!(state.stick_s > 0.0 && state.stick_s < w.plateau_s + 1e-15);
        // The paper's weighted average with the stick time L and h_a on the rising edge equals Eq. 18.
        let meet_s = state.stick_s; // L
        let h_a = {
            let tau = (w.v_max_mps - friction.accel_mps2() * (period_s - w.t2_s)) / (accel_mps2 + friction.accel_mps2());
            accel_mps2 * tau
        };
        let weighted = (meet_s * w.v_max_mps + (period_s - meet_s) * (w.v_max_mps + h_a) / 2.0) / period_s;
        prop_assert!(close(weighted, state.feed_rate_mps, 1e-9), "{} vs {}", weighted, state.feed_rate_mps);
        // Beyond saturation the rate is below the quasi-static prediction (errata 3, 7).
        prop_assert!(state.feed_rate_mps < model::feed_rate_quasi_static_mps(&w));
    }

    #[test]
    fn d_sat_nqs_tends_to_5_8_as_mu_g_vanishes(accel_mps2 in 1e3f64..1e6) {
        let friction = Friction::new(1e-3, G).unwrap();
        prop_assert!((model::duty_sat_non_quasi_static(accel_mps2, &friction) - 0.625).abs() < 1e-5);
    }

    #[test]
    fn force_law_slope_is_one_over_k(duty in 0.52f64..0.58, force_fraction in -0.3f64..0.3) {
        let friction = Friction::new(0.5, G).unwrap();
        let mass_kg = 1e-4;
        let w = accel_waveform(0.01, duty, 100.0);
        let k = model::viscosity_ns_per_m(&w, &friction, mass_kg).unwrap();
        let force_n = force_fraction * mass_kg * friction.accel_mps2();
        let v0 = model::feed_rate_under_force_mps(&w, &friction, mass_kg, 0.0).unwrap();
        prop_assert!(close(v0, model::feed_rate_sliding_mps(&w), 1e-12));
        if let Ok(v) = model::feed_rate_under_force_mps(&w, &friction, mass_kg, force_n) {
            // Errata 4: a forward push makes the part faster, f = +K(v′ − v_eq).
            prop_assert!(close(force_n, k * (v - v0), 1e-9) || force_n.abs() < 1e-15);
        }
    }

    #[test]
    fn inverse_round_trips_through_the_forward_model(
        target_mps in 0.005f64..0.1, stroke_mm in 1.0f64..4.0, frequency_hz in 50.0f64..100.0,
    ) {
        let friction = Friction::new(0.8, G).unwrap();
        let period_s = 1.0 / frequency_hz;
        let drive = Drive::Stroke { stroke_m: stroke_mm * 1e-3 };
        match model::duty_for_feed_rate(period_s, target_mps, drive, &friction, &Limits::NONE) {
            Ok(w) => {
                let state = model::steady_state(&w, &friction);
                prop_assert_eq!(state.regime, Regime::Sliding);
                prop_assert!(close(state.feed_rate_mps, target_mps, 1e-9));
            }
            Err(Error::FeedRateAboveReach { max_mps, .. }) => prop_assert!(max_mps < target_mps),
            Err(other) => prop_assert!(false, "{other:?}"),
        }
    }
}
