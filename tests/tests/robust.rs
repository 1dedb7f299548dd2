//! Robust stability against a data-derived uncertainty bound, checked on plants drawn inside it.
//!
//! The chain: closed-loop identification of the virtual stage at 5 kHz (fine-step route), a
//! deliberately low-order model (rigid body and one mode), its additive bound at 95 % per line
//! and an overbounding weight `W_f` (order 8). The perturbations `Δ_f = s·W_f·R` (`R` a random
//! stable model of H∞ norm 1 with a random delay, `0 < s ≤ 1`) lie inside `|W_f|`, hence inside
//! the bound on every measured line. The slow-rate bound is the fast weight's magnitude taken
//! through Lemma 6 (`Σ_k |H_F(f_k)/F|·|W_f(f_k)|`) on the 1 kHz lines, overbounded by `W_s`.
//! Each plant `P̂_f + Δ_f` is downsampled exactly (Lemma 6, state space) and closed with 1 kHz
//! PID controllers: a controller the analysis calls robustly stable (weight margin > 1) must
//! stay stable on all 200 plants; a controller whose margin on the lines is above 1 must stay
//! stable on the worst-phase plant at the full bound at its worst line (where random plants
//! rarely go); one it calls not robustly stable must come with a destabilising plant inside
//! the bound, whose closed loop is unstable.
//!
//! Seeds: stage noise 21, perturbations 0..200 (chosen before the figures were taken; nothing
//! here is tuned: the controllers' bandwidths were picked to give one margin on each side of 1).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_model::{SampleTime, StateSpace};
use sd_testbed::{NonIdealities, Truth};
use sd_tests::gen::Rng;
use sd_tests::stage::{closed_loop_frf, rigid_body_and_one_mode};
use sd_uncertainty::{downsample, from_data, overbound, robust_stability, Bound, Form};

/// A bound whose additive values are `|W(f)|` on `freq` (nominal `p`).
fn bound_of_weight(w: &StateSpace, p: &StateSpace, freq: &[f64], ts: f64) -> Bound {
    let wv: Vec<f64> = w
        .freqresp(freq)
        .unwrap()
        .response()
        .iter()
        .map(|m| m[(0, 0)].norm())
        .collect();
    Bound {
        form: Form::Additive,
        confidence: 0.95,
        sigma_factor: 0.0,
        ts,
        freq_hz: freq.to_vec(),
        nominal: p
            .freqresp(freq)
            .unwrap()
            .response()
            .iter()
            .map(|m| m[(0, 0)])
            .collect(),
        residual: wv.clone(),
        sigma: vec![0.0; freq.len()],
        additive: wv,
    }
}

/// A random stable discrete model of order 1–4 (poles inside radius 0.97), H∞ norm 1, with a
/// delay of 0–4 samples.
fn random_unit(rng: &mut Rng, ts: f64) -> StateSpace {
    let time = SampleTime::discrete(ts).unwrap();
    let order = 1 + (rng.uniform() * 4.0) as usize;
    let mut den = vec![1.0];
    let mut num = vec![1.0];
    for _ in 0..order {
        let p = rng.range(-0.97, 0.97);
        let z = rng.range(-1.5, 1.5);
        den = sd_tests::designs::conv(&den, &[1.0, -p]);
        num = sd_tests::designs::conv(&num, &[1.0, -z]);
    }
    let delay = (rng.uniform() * 5.0) as usize;
    den.extend(std::iter::repeat_n(0.0, delay));
    let r = sd_model::TransferFunction::new(num, den, time)
        .unwrap()
        .to_ss()
        .unwrap();
    let h = r.hinf_norm().unwrap().value;
    let g = StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, 1.0 / h), time).unwrap();
    sd_model::series(&r, &g).unwrap()
}

/// `P = P̂(1 + s·W·R)` with `R` from [`random_unit`] and `0.05 ≤ |s| ≤ 1`: `|P − P̂| ≤ |P̂ W|`
/// at every frequency, inside the relative weight `W` (P̂ realised once: a sum `P̂ + P̂WR`
/// would carry the rigid body's integrators twice, one copy beyond the loop's reach).
fn inside_relative(rng: &mut Rng, w: &StateSpace, p: &StateSpace) -> StateSpace {
    let time = SampleTime::discrete(2e-4).unwrap();
    let unit = random_unit(rng, 2e-4);
    let s = rng.range(0.05, 1.0) * if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
    let gain = |v: f64| StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, v), time).unwrap();
    let rel = sd_model::series(&sd_model::series(&unit, w).unwrap(), &gain(s)).unwrap();
    sd_model::series(&sd_model::parallel(&gain(1.0), &rel).unwrap(), p).unwrap()
}

/// The stage, its low-order model at 5 kHz and the model's relative weight (order 8).
fn stage_model_weight() -> (Truth, StateSpace, sd_uncertainty::Weight) {
    let truth = Truth::default();
    let fast_frd = closed_loop_frf(&truth, 5000.0, NonIdealities::default(), 21);
    let p_fast = rigid_body_and_one_mode(&fast_frd);
    let b_fast = from_data(&p_fast, &fast_frd, Form::Additive, 0.95).unwrap();
    // a relative weight: the relative bound is flat where the model is good (a few %) and
    // large at the modes it misses; the additive one spans five decades
    let w_fast = overbound(&b_fast.with_form(Form::Multiplicative), 8).unwrap();
    (truth, p_fast, w_fast)
}

/// The intersample bound (`sd_uncertainty::robust_intersample`): its nominal density is the
/// multirate loop's (`MultirateLoop::error_spectrum_fast`, computed another way: the harmonic
/// transfer without the split of `1 − g`), and no plant inside the fast weight has a fast
/// error density above the bound at any frequency (200 plants, each density computed from the
/// perturbed plant's own multirate loop). Controller: the 1 kHz PID at 20 Hz, robustly stable
/// against the downsampled weight. Seeds as above.
#[test]
fn intersample_bound_holds_on_plants_inside_the_weight() {
    let (truth, p_fast, w_fast) = stage_model_weight();
    let k = sd_hinf::weights::pid(20.0, truth.mass, Some(1e-3), &Default::default()).unwrap();
    let h = 2e-4;
    let (pd, pn) = (2.0 * h * 0.05f64.powi(2), 2.0 * h * 3e-10f64.powi(2));
    let (phi_d, phi_n) = (move |_: f64| pd, move |_: f64| pn);
    let r = sd_uncertainty::robust_intersample(
        &p_fast,
        &k,
        5,
        (&w_fast.model, Form::Multiplicative),
        &phi_d,
        &phi_n,
        400,
    )
    .unwrap();
    let bound = r
        .bound_psd
        .clone()
        .expect("the 20 Hz PID is robustly stable");
    println!(
        "slow margin {:.3}; fast error rms nominal {:.4e} m, bound {:.4e} m; bound/nominal \
         density at most {:.2} ({:.1} Hz)",
        r.slow_margin,
        r.rms_nominal,
        r.rms_bound.unwrap(),
        r.worst_ratio.unwrap(),
        r.worst_hz.unwrap()
    );
    assert!(r.slow_margin > 1.0);
    let lp = sd_multirate::MultirateLoop::new(&p_fast, &k, 5).unwrap();
    let nominal = lp.error_spectrum_fast(&r.fast_hz, &phi_d, &phi_n).unwrap();
    for (a, b) in nominal.iter().zip(&r.nominal_psd) {
        assert!(
            (a - b).abs() <= 1e-8 * a.abs().max(b.abs()),
            "nominal {a} vs {b}"
        );
    }
    let mut rng = Rng::new(1000);
    let (mut closest, mut rms_max) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let plant = inside_relative(&mut rng, &w_fast.model, &p_fast);
        let lp = sd_multirate::MultirateLoop::new(&plant, &k, 5).unwrap();
        assert!(
            lp.spectral_radius().unwrap() < 1.0,
            "a plant inside the weight is unstable"
        );
        let psd = lp.error_spectrum_fast(&r.fast_hz, &phi_d, &phi_n).unwrap();
        for ((x, b), f) in psd.iter().zip(&bound).zip(&r.fast_hz) {
            assert!(
                *x <= b * (1.0 + 1e-9),
                "{f} Hz: density {x} above the bound {b}"
            );
            closest = closest.max(x / b);
        }
        rms_max = rms_max.max(sd_analysis::rms_of_density(&r.fast_hz, &psd));
    }
    println!(
        "200 plants inside the weight: density at most {closest:.3} of the bound; largest rms \
         {rms_max:.4e} m (bound {:.4e} m, nominal {:.4e} m)",
        r.rms_bound.unwrap(),
        r.rms_nominal
    );
    assert!(rms_max <= r.rms_bound.unwrap());
}

#[test]
fn robust_stability_holds_on_plants_inside_the_bound() {
    let (truth, p_fast, w_fast) = stage_model_weight();
    // the slow bound: |P̂_f·W_f| through Lemma 6 on the 1 kHz lines of the 0.5 Hz grid
    let slow_lines: Vec<f64> = (1..1000).map(|k| 0.5 * k as f64).collect();
    let fast_lines: Vec<f64> = (1..5000).map(|k| 0.5 * k as f64).collect();
    let pw = sd_model::series(&w_fast.model, &p_fast).unwrap();
    let from_w = bound_of_weight(&pw, &p_fast, &fast_lines, 2e-4);
    let slow = downsample(&from_w, 5, &slow_lines)
        .unwrap()
        .bound
        .with_form(Form::Multiplicative);
    let w_slow = overbound(&slow, 8).unwrap();
    println!(
        "weights: fast |W|/b median {:.2}, slow median {:.2}",
        w_fast.median_ratio, w_slow.median_ratio
    );
    let p_slow = sd_multirate::downsample(&p_fast, 5).unwrap();
    let ts = 1e-3;
    let pid =
        |bw: f64| sd_hinf::weights::pid(bw, truth.mass, Some(ts), &Default::default()).unwrap();
    let mut called_stable = 0;
    let mut called_unstable = 0;
    for bw in [10.0, 20.0, 40.0, 60.0, 62.0, 64.0, 66.0, 68.0] {
        let k = pid(bw);
        let r = robust_stability(&p_slow, &k, &slow, Some(&w_slow.model)).unwrap();
        println!(
            "PID {bw} Hz: nominal stable {}, margin on the lines {:.3} (at {:.1} Hz), with the \
             weight {:.3}, worst-case |S| {:.2} dB at {:.1} Hz, destabilising plant {:?}",
            r.nominal_stable,
            r.margin_lines,
            r.worst_line_hz,
            r.margin_weight.unwrap(),
            r.worst_sensitivity_db,
            r.worst_sensitivity_hz,
            r.destabilising.as_ref().map(|d| (
                d.freq_hz,
                d.max_ratio_to_bound,
                d.closed_loop_radius
            ))
        );
        if !r.nominal_stable {
            continue;
        }
        if r.margin_weight.unwrap() > 1.0 {
            called_stable += 1;
            let mut rng = Rng::new(0);
            let mut worst_radius = 0.0f64;
            for _ in 0..200 {
                let plant = inside_relative(&mut rng, &w_fast.model, &p_fast);
                let slow_plant = sd_multirate::downsample(&plant, 5).unwrap();
                let (radius, stable) = sd_analysis::ClosedLoop::new(&slow_plant, &k)
                    .unwrap()
                    .stability()
                    .unwrap();
                worst_radius = worst_radius.max(radius);
                assert!(
                    stable,
                    "PID {bw} Hz is called robustly stable, but a plant inside the bound \
                     gives a closed-loop radius {radius}"
                );
            }
            println!("  200 plants inside the bound: all stable, largest radius {worst_radius:.6}");
        }
        if r.margin_lines > 1.0 {
            // the worst-phase plant at the full bound, at the worst line: stable
            let (wp, ratio) = sd_uncertainty::worst_case_plant(&p_slow, &k, &slow, r.worst_line_hz)
                .unwrap()
                .expect("no worst-case plant inside the bound");
            let (radius, stable) = sd_analysis::ClosedLoop::new(&wp, &k)
                .unwrap()
                .stability()
                .unwrap();
            println!("  worst-phase plant at the full bound ({ratio:.3} of it at most): radius {radius:.6}");
            assert!(
                ratio <= 1.0 + 1e-9 && stable,
                "PID {bw} Hz: {ratio} {radius}"
            );
        }
        if r.margin_lines < 1.0 {
            called_unstable += 1;
            let d = r
                .destabilising
                .as_ref()
                .expect("no destabilising plant found");
            assert!(d.max_ratio_to_bound <= 1.0 + 1e-9, "{d:?}");
            assert!(d.closed_loop_radius > 1.0, "{d:?}");
            // the reported plant is what it says: P̂ + Δ, and unstable in the loop
            let (radius, stable) = sd_analysis::ClosedLoop::new(&d.plant, &k)
                .unwrap()
                .stability()
                .unwrap();
            assert!(!stable && (radius - d.closed_loop_radius).abs() < 1e-9);
        }
    }
    assert!(called_stable >= 1, "no controller is robustly stable");
    assert!(called_unstable >= 1, "every controller is robustly stable");
}
