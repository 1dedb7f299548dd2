//! margins, |S| peaks and sensitivities against python-control on six
//! reference loops (`test_data/analysis_reference.json`, generated once by
//! `tools/gen_analysis_reference.py` with python-control 0.10.1 and scipy).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_analysis::ClosedLoop;
use sd_model::{model_from_json_str, StateSpace};
use sd_tests::read_json;

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(1e-300)
    }
}

/// The loop of P with the controller scaled by `gain` (a gain margin's independent check: it
/// puts a closed-loop pole on the stability boundary).
fn scaled_loop(p: &StateSpace, k: &StateSpace, gain: f64) -> ClosedLoop {
    let ks = StateSpace::new(
        k.a().clone(),
        k.b().clone(),
        k.c() * gain,
        k.d() * gain,
        k.time(),
    )
    .unwrap();
    ClosedLoop::new(p, &ks).unwrap()
}

#[test]
fn margins_and_peaks_match_python_control() {
    let refs = read_json("analysis_reference.json");
    let mut worst: f64 = 0.0;
    for case in refs["loops"].as_array().unwrap() {
        let name = case["name"].as_str().unwrap();
        let cl = ClosedLoop::new(&model(&case["plant"]), &model(&case["controller"])).unwrap();
        let m = cl.margins().unwrap();
        let (stable_radius, stable) = cl.stability().unwrap();
        let (peak, peak_hz) = cl.sensitivity_peak().unwrap();
        let g = |k: &str| case[k].as_f64().unwrap_or(f64::INFINITY);
        println!(
            "{name}: GM {:.9} (pc {:.9}) PM {:.9} (pc {:.9}) | MM {:.9} (pc sm {:.9}) | |S| peak {:.9} at {:.6} Hz (ref {:.9} at {:.6}) | stable {stable} ({stable_radius:.6})",
            m.gain_margin, g("gm"), m.phase_margin_deg, g("pm"), m.modulus_margin, g("sm"), peak, peak_hz, g("s_peak"), g("s_peak_hz")
        );
        assert_eq!(stable, case["stable"].as_bool().unwrap(), "{name}");
        let mut check = |what: &str, ours: f64, theirs: f64, tol: f64| {
            if theirs.is_finite() || ours.is_finite() {
                let e = rel(ours, theirs);
                assert!(e <= tol, "{name}: {what} {ours} vs {theirs} ({e:e})");
                worst = worst.max(e);
            }
        };
        if g("gm").is_finite() {
            check("gain margin", m.gain_margin, g("gm"), 1e-6);
        } else {
            // python-control misses a phase crossover at the Nyquist frequency (L(−1) < 0)
            println!(
                "  python-control reports no gain margin; ours is {} at {} Hz",
                m.gain_margin, m.phase_crossover_hz
            );
        }
        // where the margins are read (what `analyze` prints beside them): python-control's
        // phase and gain crossover frequencies
        let sm = cl.summary().unwrap();
        assert_eq!(
            sm.gain_margin_hz.to_bits(),
            m.phase_crossover_hz.to_bits(),
            "{name}"
        );
        assert_eq!(
            sm.phase_margin_hz.to_bits(),
            m.gain_crossover_hz.to_bits(),
            "{name}"
        );
        if g("gm").is_finite() && g("wpc_hz").is_finite() {
            check(
                "gain margin's frequency",
                sm.gain_margin_hz,
                g("wpc_hz"),
                1e-6,
            );
        }
        if g("pm").is_finite() && g("wgc_hz").is_finite() {
            check(
                "phase margin's frequency",
                sm.phase_margin_hz,
                g("wgc_hz"),
                1e-6,
            );
        }
        // independent check of every finite gain margin: K·GM puts a closed-loop pole on the
        // stability boundary
        if m.gain_margin.is_finite() && m.gain_margin > 0.0 {
            let k = model(&case["controller"]);
            let (r, _) = scaled_loop(&model(&case["plant"]), &k, m.gain_margin)
                .stability()
                .unwrap();
            let boundary = if k.time().is_continuous() { 0.0 } else { 1.0 };
            assert!(
                (r - boundary).abs() < 1e-6,
                "{name}: K·GM gives {r}, not {boundary}"
            );
        }
        if g("wpc_hz").is_finite() {
            if g("wpc_hz") == 0.0 {
                assert_eq!(m.phase_crossover_hz, 0.0);
            } else {
                check("phase crossover", m.phase_crossover_hz, g("wpc_hz"), 1e-6);
            }
        }
        check("phase margin", m.phase_margin_deg, g("pm"), 1e-6);
        check("gain crossover", m.gain_crossover_hz, g("wgc_hz"), 1e-6);
        // |S| peak: value to 1e-6; our modulus margin is its inverse
        check("|S| peak", peak, g("s_peak"), 1e-6);
        check("modulus margin", m.modulus_margin, 1.0 / g("s_peak"), 1e-6);
        // python-control's sm keeps interior minima only; where it found the global one, equal
        if g("sm").is_finite() && rel(g("sm"), 1.0 / g("s_peak")) < 1e-4 {
            check(
                "modulus margin vs python-control sm",
                m.modulus_margin,
                g("sm"),
                1e-6,
            );
        }
        // (the reference grid ends at 1 kHz for continuous loops: a peak there is at ω → ∞)
        if !(g("s_peak_hz") > 999.0 && peak_hz.is_infinite()) {
            check("|S| peak frequency", peak_hz, g("s_peak_hz"), 1e-4);
        }
        for p in case["points"].as_array().unwrap() {
            let f = p["freq_hz"].as_f64().unwrap();
            let r = cl.responses(f).unwrap();
            for (key, v) in [("S", &r.s), ("T", &r.t), ("PS", &r.ps), ("KS", &r.ks)] {
                check(key, v[(0, 0)].norm(), p[key].as_f64().unwrap(), 1e-6);
            }
        }
    }
    println!("worst relative difference: {worst:.2e}");
}

/// `min |1 + L|` on a dense grid (20 000 log-spaced points up to Nyquist, or up to 10⁴ Hz and
/// the value at infinity for continuous loops), evaluated factor by factor: an independent
/// upper bound of the modulus margin.
fn grid_min_return_difference(p: &StateSpace, k: &StateSpace) -> f64 {
    let fmax = p.ts().map(|t| 0.5 / t * (1.0 - 1e-9)).unwrap_or(1e4);
    let f: Vec<f64> = (0..20_000)
        .map(|i| 1e-3 * (fmax / 1e-3f64).powf(i as f64 / 19_999.0))
        .collect();
    let (fp, fk) = (p.freqresp(&f).unwrap(), k.freqresp(&f).unwrap());
    let at_inf = if p.ts().is_none() {
        (1.0 + (p.d() * k.d())[(0, 0)]).abs()
    } else {
        f64::INFINITY
    };
    fp.response()
        .iter()
        .zip(fk.response())
        .map(|(a, b)| (num_complex::Complex64::new(1.0, 0.0) + a[(0, 0)] * b[(0, 0)]).norm())
        .fold(at_inf, f64::min)
}

/// Fifty seeded random loops (stable, integrating, unstable, static gains, lightly damped;
/// continuous and 1 ms discrete; `test_data/margins_random.json`, generated once by
/// `tools/gen_margins_random.py` with python-control 0.10.2): the closed-loop stability agrees;
/// every gain, phase and modulus margin python-control reports as a finite number agrees with
/// ours (GM relative 1e-5, PM 0.01°, MM relative 1e-4); where python-control reports none (its
/// `nan`/`inf`, or a gain margin above 10⁶ that is the rounding of a phase reaching −180° only
/// at infinite frequency) ours is checked independently: a finite gain margin puts a
/// closed-loop pole on the stability boundary (checked for every finite one), a modulus margin is the minimum of |1 + L| on a
/// dense grid.
#[test]
fn margins_on_fifty_random_loops() {
    let refs = read_json("margins_random.json");
    let loops = refs["loops"].as_array().unwrap();
    assert_eq!(loops.len(), 50);
    let (mut agree, mut close, mut independent, mut pc_misses) = (0, 0, 0, 0);
    for case in loops {
        let name = case["name"].as_str().unwrap();
        let (p, k) = (model(&case["plant"]), model(&case["controller"]));
        let cl = ClosedLoop::new(&p, &k).unwrap();
        let m = cl.margins().unwrap();
        let (_, stable) = cl.stability().unwrap();
        assert_eq!(
            stable,
            case["stable"].as_bool().unwrap(),
            "{name}: stability"
        );
        let pc = |key: &str| case[key].as_f64().filter(|v| v.is_finite());
        if m.gain_margin.is_finite() && m.gain_margin < 1e6 && p.n() + k.n() > 0 {
            // some closed-loop pole (not necessarily the outermost one) is on the boundary
            let poles = scaled_loop(&p, &k, m.gain_margin)
                .sensitivity()
                .poles()
                .unwrap();
            let off = poles
                .iter()
                .map(|z| {
                    if k.time().is_continuous() {
                        z.re.abs()
                    } else {
                        (z.norm() - 1.0).abs()
                    }
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                off < 1e-6,
                "{name}: K·GM leaves every pole {off} off the boundary"
            );
        }
        match pc("gm").filter(|g| *g < 1e6) {
            // python-control's frequency-grid fallback is accurate to about 1e-4 here; ours
            // passes the boundary check above to 1e-6
            Some(g) if rel(m.gain_margin, g) > 1e-3 => {
                // python-control's crossover must then not be one: L is off the real axis there
                let f = case["wpc_hz"].as_f64().unwrap();
                let l = p.freqresp(&[f]).unwrap().response()[0][(0, 0)]
                    * k.freqresp(&[f]).unwrap().response()[0][(0, 0)];
                assert!(
                    l.im.abs() > 1e-4 * l.norm(),
                    "{name}: GM {} vs {g} ({:?})",
                    m.gain_margin,
                    m.all_phase_crossovers
                );
                println!("{name}: python-control's phase crossover at {f} Hz is not one: L = {l}");
                pc_misses += 1;
            }
            Some(g) => {
                let e = rel(m.gain_margin, g);
                if e < 1e-5 {
                    agree += 1;
                } else {
                    close += 1;
                }
            }
            None => independent += 1,
        }
        match pc("pm") {
            Some(pm) => {
                let e = (m.phase_margin_deg - pm).abs();
                assert!(e < 0.05, "{name}: PM {} vs {pm}", m.phase_margin_deg);
                if e < 1e-3 {
                    agree += 1;
                } else {
                    close += 1;
                }
            }
            None => independent += 1,
        }
        // closed-loop −3 dB bandwidth: python-control's where it computes one (stable
        // continuous loops), else the definition itself: |T| at it is 3 dB below |T(0)|
        let bw = cl.bandwidth_hz().unwrap();
        match (pc("bandwidth_hz"), bw) {
            (Some(b), Some(ours)) => {
                assert!(rel(ours, b) < 1e-4, "{name}: bandwidth {ours} vs {b}");
                agree += 1;
            }
            (Some(b), None) => panic!("{name}: python-control's bandwidth {b}, ours none"),
            (None, Some(ours)) => {
                let r = cl.responses(ours).unwrap();
                let t0 = cl.complementary().eval_direct(if k.time().is_continuous() {
                    num_complex::Complex64::new(0.0, 0.0)
                } else {
                    num_complex::Complex64::new(1.0, 0.0)
                });
                let t0 = t0.unwrap()[(0, 0)].norm();
                let drop = 20.0 * (r.t[(0, 0)].norm() / t0).log10();
                assert!(
                    (drop + 3.0).abs() < 1e-6,
                    "{name}: |T| drop {drop} dB at {ours} Hz"
                );
                independent += 1;
            }
            (None, None) => {}
        }
        let grid = grid_min_return_difference(&p, &k);
        if m.modulus_margin == 0.0 {
            // S has a pole on the stability boundary (here an unobservable integrator in the
            // controller's realisation): no margin, and python-control reports none either
            assert!(!stable && pc("sm").is_none(), "{name}: MM 0");
            independent += 1;
            continue;
        }
        assert!(
            m.modulus_margin <= grid * (1.0 + 1e-9) && m.modulus_margin >= grid * 0.97,
            "{name}: MM {} vs grid minimum {grid}",
            m.modulus_margin
        );
        match pc("sm") {
            Some(sm) if rel(m.modulus_margin, sm) < 1e-4 => agree += 1,
            Some(sm) => {
                // python-control's frequency-grid fallback can miss the dip: its value must
                // then be above the grid minimum, which ours matches
                assert!(
                    sm > grid * (1.0 + 1e-3),
                    "{name}: MM {} vs {sm}",
                    m.modulus_margin
                );
                println!("{name}: python-control's MM {sm} misses the minimum of |1 + L| ({grid})");
                pc_misses += 1;
            }
            None => independent += 1,
        }
    }
    println!(
        "{agree} margins agree with python-control (GM 1e-5, PM 0.001°, MM 1e-4); {close} within \
         its grid fallback's accuracy (GM 1e-3, PM 0.05°); {independent} it does not report \
         checked independently; {pc_misses} where its value misses the grid minimum"
    );
}

/// A type-2 loop `L = (s + 0.1)/(s²(s + 1))`: `L(0)` is infinite, not a phase crossover at DC.
/// The phase is −180° + atan(10ω) − atan(ω) > −180° at every ω > 0, so there is no phase
/// crossover at all: the gain margin is infinite (python-control's convention), in the
/// companion realization and in a rotated one, continuous and discretised (z = 1 double pole).
#[test]
fn a_type_two_loop_has_no_phase_crossover_at_dc() {
    use nalgebra::DMatrix;
    let p = sd_model::TransferFunction::new(
        vec![1.0, 0.1],
        vec![1.0, 1.0, 0.0, 0.0],
        sd_model::SampleTime::Continuous,
    )
    .unwrap()
    .to_ss()
    .unwrap();
    let one = StateSpace::new(
        DMatrix::zeros(0, 0),
        DMatrix::zeros(0, 1),
        DMatrix::zeros(1, 0),
        DMatrix::from_element(1, 1, 1.0),
        sd_model::SampleTime::Continuous,
    )
    .unwrap();
    // a rotation of the states (not orthogonal: its conditioning ~10)
    let t = DMatrix::from_row_slice(3, 3, &[1.0, 0.5, -0.2, 0.3, 2.0, 0.1, -0.4, 0.2, 1.5]);
    let ti = t.clone().try_inverse().unwrap();
    let rotated = StateSpace::new(
        &ti * p.a() * &t,
        &ti * p.b(),
        p.c() * &t,
        p.d().clone(),
        p.time(),
    )
    .unwrap();
    for (name, sys) in [("companion", &p), ("rotated", &rotated)] {
        let m = ClosedLoop::new(sys, &one).unwrap().margins().unwrap();
        assert!(
            m.gain_margin.is_infinite() && m.all_phase_crossovers.is_empty(),
            "{name}: gain margin {} at {:?}",
            m.gain_margin,
            m.all_phase_crossovers
        );
        // the phase margin: at |L| = 1, −180° + atan(10ω) − atan(ω), positive
        let w = type_two_phase_margin_deg(m.gain_crossover_hz);
        assert!(
            (m.phase_margin_deg - w).abs() < 1e-6,
            "{name}: {} vs {w}",
            m.phase_margin_deg
        );
    }
    let pd = sd_model::c2d::c2d(&p, 0.01, sd_model::c2d::Discretization::Zoh).unwrap();
    let kd = StateSpace::new(
        DMatrix::zeros(0, 0),
        DMatrix::zeros(0, 1),
        DMatrix::zeros(1, 0),
        DMatrix::from_element(1, 1, 1.0),
        sd_model::SampleTime::Discrete { ts: 0.01 },
    )
    .unwrap();
    let m = ClosedLoop::new(&pd, &kd).unwrap().margins().unwrap();
    assert!(
        m.all_phase_crossovers.iter().all(|(f, _)| *f > 0.0),
        "discrete: a crossover at DC {:?}",
        m.all_phase_crossovers
    );
}

/// The phase margin of `(s + 0.1)/(s²(s + 1))` at its gain crossover `f` (Hz).
fn type_two_phase_margin_deg(f: f64) -> f64 {
    let w = 2.0 * std::f64::consts::PI * f;
    (10.0 * w).atan().to_degrees() - w.atan().to_degrees()
}
