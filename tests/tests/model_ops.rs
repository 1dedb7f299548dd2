//! d2c with alias candidates, balanced truncation bound, norms, zeros,
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! minimal realisation, simulation.

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{c2d, d2c, d2c_with_aliases, Discretization, ModelError, SampleTime, StateSpace};

fn ct(a: &[f64], b: &[f64], c: &[f64], d: &[f64], n: usize, nu: usize, ny: usize) -> StateSpace {
    StateSpace::new(
        DMatrix::from_row_slice(n, n, a),
        DMatrix::from_row_slice(n, nu, b),
        DMatrix::from_row_slice(ny, n, c),
        DMatrix::from_row_slice(ny, nu, d),
        SampleTime::Continuous,
    )
    .unwrap()
}

#[test]
fn d2c_inverts_c2d_in_principal_strip() {
    // Stage with rigid body (Jordan block at z = 1) and modes below Nyquist at 5 kHz.
    let p = sd_model::stage::paper_stage_two_modes().unwrap();
    let pd = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
    let back = d2c(&pd).unwrap();
    let ea = (back.a() - p.a()).norm() / p.a().norm();
    let eb = (back.b() - p.b()).norm() / p.b().norm();
    println!("d2c(c2d(P)) relative error: A {ea:.2e}, B {eb:.2e}");
    assert!(ea <= 1e-9 && eb <= 1e-9);
    // random MIMO stable system
    let g = ct(
        &[-1.0, 2.0, 0.0, -3.0, -0.5, 1.0, 0.2, 0.0, -2.0],
        &[1.0, 0.0, 0.5, 1.0, 0.0, 2.0],
        &[1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        &[0.0, 0.1, 0.0, 0.0],
        3,
        2,
        2,
    );
    let back = d2c(&c2d(&g, 0.1, Discretization::Zoh).unwrap()).unwrap();
    assert!((back.a() - g.a()).norm() / g.a().norm() <= 1e-9);
    assert!((back.b() - g.b()).norm() / g.b().norm() <= 1e-9);
}

#[test]
fn d2c_refuses_negative_real_pole() {
    let g = StateSpace::new(
        DMatrix::from_element(1, 1, -0.5),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::zeros(1, 1),
        SampleTime::discrete(0.01).unwrap(),
    )
    .unwrap();
    let e = d2c(&g).unwrap_err();
    assert!(matches!(e, ModelError::NoRealLogarithm { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("negative real axis") && msg.contains("-0.5"),
        "{msg}"
    );
    let z = StateSpace::new(
        DMatrix::from_element(1, 1, 0.0),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::zeros(1, 1),
        SampleTime::discrete(0.01).unwrap(),
    )
    .unwrap();
    assert!(matches!(
        d2c(&z).unwrap_err(),
        ModelError::NoRealLogarithm { .. }
    ));
}

#[test]
fn alias_candidates_of_653hz_mode_at_1khz() {
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    let pd = c2d(&p, 1e-3, Discretization::Zoh).unwrap();
    let (_, modes) = d2c_with_aliases(&pd, 3000.0).unwrap();
    let m = modes.iter().find(|m| m.freq_hz > 1.0).unwrap();
    println!(
        "653 Hz mode at 1 kHz: principal {:.4} Hz, candidates {:?}",
        m.freq_hz, m.candidates
    );
    assert!((m.freq_hz - 347.0).abs() < 0.5);
    assert!(m.candidates.iter().any(|(f, _)| (f - 347.0).abs() < 0.5));
    let c653 = m
        .candidates
        .iter()
        .find(|(f, _)| (f - 653.0).abs() < 0.5)
        .expect("653 Hz candidate");
    assert!(
        (c653.1 - 0.01).abs() < 1e-6,
        "damping of the 653 Hz candidate {}",
        c653.1
    );
}

fn hinf_grid(err: &StateSpace, fmax: f64) -> f64 {
    let f = sd_model::grid(1e-2, fmax, 20000, true).unwrap();
    let r = err.freqresp(&f).unwrap();
    r.response()
        .iter()
        .map(|g| g.clone().singular_values().max())
        .fold(0.0, f64::max)
}

#[test]
fn balanced_truncation_bound_ct_and_dt() {
    // a stable 60-state model: the stage without rigid body plus one slow real pole pair
    let modes = sd_model::stage::stage60_modes();
    let mut p = sd_model::stage::stage_model(20.0, false, &modes).unwrap();
    let extra = sd_model::stage::stage_model(
        20.0,
        false,
        &[sd_model::stage::Mode {
            freq_hz: 20.0,
            zeta: 0.7,
            residue: 1.0,
        }],
    )
    .unwrap();
    p = sd_model::parallel(&p, &extra).unwrap();
    assert_eq!(p.n(), 60);
    for (name, sys, fmax) in [
        ("CT", p.clone(), 1e5),
        ("DT", c2d(&p, 2e-4, Discretization::Zoh).unwrap(), 2500.0),
    ] {
        let r = sys.balanced_truncation(10).unwrap();
        assert_eq!(r.model.n(), 10);
        let neg = sd_model::feedback(
            &r.model,
            &StateSpace::gain(DMatrix::zeros(1, 1), sys.time()).unwrap(),
            -1.0,
        )
        .unwrap();
        let diff = sd_model::parallel(
            &sys,
            &sd_model::series(
                &neg,
                &StateSpace::gain(DMatrix::from_element(1, 1, -1.0), sys.time()).unwrap(),
            )
            .unwrap(),
        )
        .unwrap();
        let e_grid = hinf_grid(&diff, fmax);
        let e_norm = diff.hinf_norm().unwrap().value;
        println!("{name}: ‖G − G10‖∞ = {e_norm:.4e} (grid {e_grid:.4e}), bound 2Σσ = {:.4e}, σ1 = {:.3e}", r.error_bound, r.hankel_sv[0]);
        assert!(e_norm <= r.error_bound * (1.0 + 1e-6));
        assert!(e_grid <= e_norm * (1.0 + 1e-9));
    }
}

#[test]
fn hinf_norm_accuracy() {
    // Second-order resonance: peak known in closed form, |G|max = 1/(2ζ√(1−ζ²)) for ζ < 1/√2.
    let z: f64 = 0.01;
    let w: f64 = 2.0 * std::f64::consts::PI * 653.0;
    let g = ct(
        &[0.0, 1.0, -w * w, -2.0 * z * w],
        &[0.0, w * w],
        &[1.0, 0.0],
        &[0.0],
        2,
        1,
        1,
    );
    let h = g.hinf_norm().unwrap();
    let exact = 1.0 / (2.0 * z * (1.0 - z * z).sqrt());
    let fpk = 653.0 * (1.0 - 2.0 * z * z).sqrt();
    println!(
        "H∞ {:.15} exact {exact:.15} rel {:.2e}; peak {} Hz vs {fpk}",
        h.value,
        (h.value - exact).abs() / exact,
        h.peak_hz
    );
    assert!((h.value - exact).abs() <= 1e-8 * exact);
    assert!((h.peak_hz - fpk).abs() <= 1e-3);
    // The same in discrete time at 5 kHz: compare with a dense local search
    let gd = c2d(&g, 2e-4, Discretization::Zoh).unwrap();
    let hd = gd.hinf_norm().unwrap();
    let mut best: f64 = 0.0;
    for i in 0..200001 {
        let f = hd.peak_hz - 1.0 + 2.0 * i as f64 / 200000.0;
        best = best.max(
            gd.eval_direct(C::from_polar(1.0, 2.0 * std::f64::consts::PI * f * 2e-4))
                .unwrap()[(0, 0)]
                .norm(),
        );
    }
    assert!(
        hd.value >= best * (1.0 - 1e-12) && (hd.value - best) / best <= 1e-8,
        "{} vs {best}",
        hd.value
    );
    // MIMO with feedthrough: H2 against the Gramian definition through a long impulse response
    let m = ct(
        &[-1.0, 2.0, 0.0, -3.0, -0.5, 1.0, 0.2, 0.0, -2.0],
        &[1.0, 0.0, 0.5, 1.0, 0.0, 2.0],
        &[1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        &[0.0, 0.1, 0.0, 0.0],
        3,
        2,
        2,
    );
    let md = c2d(&m, 0.01, Discretization::Zoh).unwrap();
    let h2 = md.h2_norm().unwrap();
    // Σ_k ‖g_k‖_F² with g_0 = D, g_k = C A^{k-1} B
    let mut s = md.d().norm_squared();
    let mut ak = DMatrix::<f64>::identity(3, 3);
    for _ in 0..20000 {
        s += (md.c() * &ak * md.b()).norm_squared();
        ak = &ak * md.a();
    }
    assert!((h2 - s.sqrt()).abs() <= 1e-10 * h2);
    assert!(md.hinf_norm().unwrap().value >= md.d().clone().singular_values().max());
    // rigid body: infinite
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    assert!(p.hinf_norm().unwrap().value.is_infinite());
}

#[test]
fn zeros_and_minreal() {
    // G(s) = (s + 2)(s + 3) / ((s + 1)(s + 4)(s + 5)) : zeros −2, −3
    let tf = sd_model::TransferFunction::new(
        vec![1.0, 5.0, 6.0],
        vec![1.0, 10.0, 29.0, 20.0],
        SampleTime::Continuous,
    )
    .unwrap();
    let g = tf.to_ss().unwrap();
    let mut z = g.zeros().unwrap();
    z.sort_by(|a, b| a.re.total_cmp(&b.re));
    assert_eq!(z.len(), 2);
    assert!(
        (z[0] - C::new(-3.0, 0.0)).norm() < 1e-10 && (z[1] - C::new(-2.0, 0.0)).norm() < 1e-10,
        "{z:?}"
    );
    // non-minimal: a pole-zero cancellation at −2 → minreal drops one state
    let nm = sd_model::TransferFunction::new(
        vec![1.0, 2.0],
        vec![1.0, 3.0, 2.0],
        SampleTime::Continuous,
    )
    .unwrap()
    .to_ss()
    .unwrap();
    let m = nm.minreal(None).unwrap();
    assert_eq!(m.n(), 1);
    for s in [C::new(0.0, 1.0), C::new(1.0, 3.0)] {
        assert!(
            (m.eval_direct(s).unwrap()[(0, 0)] - nm.eval_direct(s).unwrap()[(0, 0)]).norm() < 1e-12
        );
    }
    // MIMO non-square (2 outputs, 1 input) sharing a zero at −2 in both channels
    let a = DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -4.0]);
    let b = DMatrix::from_row_slice(2, 1, &[1.0, 1.0]);
    // c1/(s+1) + c2/(s+4) = ((c1+c2)s + 4c1 + c2)/(...): zero at −2 when c2 = 2·c1
    let c = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 3.0, 6.0]);
    let g2 = StateSpace::new(a, b, c, DMatrix::zeros(2, 1), SampleTime::Continuous).unwrap();
    let z2 = g2.zeros().unwrap();
    assert_eq!(z2.len(), 1);
    assert!((z2[0] - C::new(-2.0, 0.0)).norm() < 1e-9, "{z2:?}");
}

#[test]
fn simulation_zoh_matches_discretisation() {
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    let u = DMatrix::from_fn(500, 1, |k, _| ((k as f64) * 0.37).sin());
    let y1 = p.simulate_zoh(&u, 2e-4, None).unwrap().y;
    // the same by explicit recursion with the exact ZOH matrices
    let pd = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
    let mut x = nalgebra::DVector::zeros(pd.n());
    for k in 0..500 {
        let y = (pd.c() * &x)[0];
        assert!((y - y1[(k, 0)]).abs() <= 1e-15 * y.abs().max(1e-30) + 1e-300);
        x = pd.a() * &x + pd.b() * u[(k, 0)];
    }
    assert!(p.simulate(&u, None).is_err());
}

#[test]
fn freqresp_of_a_series_with_coincident_defective_poles() {
    // a fitted-style rigid body (Jordan block at z = 1, tiny gains) in series with a PID's
    // integrator: the block form fails its accuracy check, so does the Hessenberg form (an
    // orthogonal reduction moves the triple pole at z = 1 by ~(ε‖A‖)^(1/3)), and the evaluator
    // falls back to dense solves; the response must equal the product of the factors' responses
    use sd_model::connect::series;
    let ts = 1e-3;
    // the 1 kHz design model of `cargo xtask paper` (a 5 kHz fit with its rigid body fixed at
    // z = 1, downsampled by Lemma 6), saved in test_data
    let rigid = sd_model::model_from_json_str(
        &std::fs::read_to_string(sd_tests::test_data("defective_series_plant.json")).unwrap(),
    )
    .unwrap();
    let k = sd_hinf::weights::pid(65.0, 20.0, Some(ts), &Default::default()).unwrap();
    let l = series(&k, &rigid).unwrap();
    assert_eq!(
        sd_model::FreqRespEvaluator::new(&l).unwrap().path(),
        sd_model::EvalPath::Dense
    );
    for f in [0.5, 1.0, 10.0, 100.0, 400.0] {
        let g = l.freqresp(&[f]).unwrap().response()[0][(0, 0)];
        let pk = rigid.freqresp(&[f]).unwrap().response()[0][(0, 0)]
            * k.freqresp(&[f]).unwrap().response()[0][(0, 0)];
        assert!((g - pk).norm() <= 1e-8 * pk.norm(), "f {f}: {g} vs {pk}");
    }
    // at z = 1 itself the loop's response is infinite: refused, naming the frequency
    let e = l.freqresp(&[0.0, 1.0]).unwrap_err().to_string();
    assert!(e.contains("0 Hz is a pole"), "{e}");
}

/// One frequency for a discrete pole: `d2c`'s principal mode and `poles` (the natural frequency
/// `|ln z|/(2π h)`) agree, also for a heavily damped mode where the oscillation frequency
/// `f·√(1 − ζ²)` differs by 1.6 %; and the 653 Hz branch of a 1 kHz model is 653 Hz exactly.
#[test]
fn one_frequency_for_a_discrete_pole() {
    let (f0, zeta) = (100.0, 0.18);
    let w = 2.0 * std::f64::consts::PI * f0;
    let sys = StateSpace::new(
        nalgebra::DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * zeta * w]),
        nalgebra::DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
        nalgebra::DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        nalgebra::DMatrix::zeros(1, 1),
        SampleTime::Continuous,
    )
    .unwrap();
    let pd = c2d(&sys, 1e-3, Discretization::Zoh).unwrap();
    let (_, modes) = d2c_with_aliases(&pd, 3000.0).unwrap();
    let m = &modes[0];
    let (f, z) = sd_model::poles::natural_frequency(m.z, pd.ts());
    assert!((m.freq_hz - f0).abs() < 1e-9 * f0, "d2c {}", m.freq_hz);
    assert!(
        (f - f0).abs() < 1e-9 * f0 && (z - zeta).abs() < 1e-9,
        "poles {f} {z}"
    );
    assert!((m.damping - zeta).abs() < 1e-9);
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    let (_, modes) =
        d2c_with_aliases(&c2d(&p, 1e-3, Discretization::Zoh).unwrap(), 3000.0).unwrap();
    let m = modes.iter().find(|m| m.freq_hz > 1.0).unwrap();
    assert!(
        m.candidates.iter().any(|(f, _)| (f - 653.0).abs() < 1e-6),
        "{:?}",
        m.candidates
    );
}
