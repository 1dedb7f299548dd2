//! Frequency-weighted balanced truncation against scipy (`test_data/weighted_bt_reference.json`,
//! generated once by `tools/gen_weighted_bt_reference.py`), and controller reduction on the
//! paper stage's loopshaping loop, its result rechecked by the closed loop's eigenvalues and
//! the generalized Nyquist criterion.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_analysis::{generalized_nyquist, reduce_controller, ClosedLoop, ReductionMethod};
use sd_model::{c2d, model_from_json_str, stage::paper_stage, Discretization, StateSpace};
use sd_tests::read_json;

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

/// The weighted Hankel singular values `√λ(P₁₁Q)` against scipy's Lyapunov solves on eight
/// seeded systems with stable input weights: relative error ≤ 1e-8 of the largest.
#[test]
fn weighted_hankel_values_match_scipy() {
    let refs = read_json("weighted_bt_reference.json");
    let mut worst: f64 = 0.0;
    for (i, c) in refs["cases"].as_array().unwrap().iter().enumerate() {
        let (g, v) = (model(&c["g"]), model(&c["v"]));
        let r = g.weighted_balanced_truncation(2, Some(&v), None).unwrap();
        let want: Vec<f64> = c["weighted_hsv"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(r.hankel_sv.len(), want.len(), "case {i}");
        for (a, b) in r.hankel_sv.iter().zip(&want) {
            let e = (a - b).abs() / want[0];
            worst = worst.max(e);
            assert!(e <= 1e-8, "case {i}: {a} vs {b}");
        }
        assert_eq!(r.model.n(), 2);
    }
    println!("weighted Hankel singular values: worst error {worst:.1e} of the largest");
}

/// Without a weight the weighted truncation is balanced truncation: same Hankel values, same
/// frequency response.
#[test]
fn no_weight_is_plain_balanced_truncation() {
    let refs = read_json("weighted_bt_reference.json");
    let g = model(&refs["cases"][0]["g"]);
    let a = g.weighted_balanced_truncation(3, None, None).unwrap();
    let b = g.balanced_truncation(3).unwrap();
    for (x, y) in a.hankel_sv.iter().zip(&b.hankel_sv) {
        assert!((x - y).abs() <= 1e-10 * b.hankel_sv[0]);
    }
    for f in [1.0, 50.0, 200.0, 450.0] {
        let (ra, rb) = (
            a.model.freqresp(&[f]).unwrap().response()[0].clone(),
            b.model.freqresp(&[f]).unwrap().response()[0].clone(),
        );
        assert!((ra - &rb).norm() <= 1e-9 * rb.norm(), "{f} Hz");
    }
}

/// The paper stage at 1 kHz with the loopshaping controller of a PID-like weight: reduced with
/// the closed-loop weight to the smallest order that keeps |ΔS|, |ΔT| ≤ 0.5 dB below twice the
/// crossover, the loop is stable by its eigenvalues and by the generalized Nyquist criterion,
/// and an order too small to keep the loop is an error that `is_numerical` (exit 1).
#[test]
fn the_stage_controller_keeps_its_loop() {
    let p = c2d(&paper_stage(0.01).unwrap(), 1e-3, Discretization::Zoh).unwrap();
    let w1 = sd_hinf::weights::pid(65.0, 20.0, Some(1e-3), &Default::default()).unwrap();
    let k = sd_hinf::loopshape(&p, Some(&w1), None, &Default::default())
        .unwrap()
        .controller;
    let mut kept = None;
    let mut failed = None;
    for order in (1..k.n()).rev() {
        match reduce_controller(&p, &k, order, ReductionMethod::ClosedLoopWeighted) {
            Ok(r) => {
                println!(
                    "order {order}: |ΔS| {:.3} dB, |ΔT| {:.3} dB below {:.1} Hz; phase margin \
                     {:.1}° → {:.1}°",
                    r.max_delta_s_db,
                    r.max_delta_t_db,
                    r.band_hz,
                    r.before.phase_margin_deg,
                    r.after.phase_margin_deg
                );
                if r.max_delta_s_db <= 0.5 && r.max_delta_t_db <= 0.5 {
                    kept = Some(r);
                }
            }
            Err(e) => {
                println!("order {order}: {e}");
                if failed.is_none() && e.to_string().contains("does not stabilize") {
                    assert!(e.is_numerical());
                    failed = Some(order);
                }
            }
        }
    }
    let r = kept.expect("some order keeps the loop within 0.5 dB");
    println!(
        "full controller {} states; smallest within 0.5 dB: {}",
        k.n(),
        r.orders.1
    );
    assert!(r.orders.1 < k.n());
    let cl = ClosedLoop::new(&p, &r.controller).unwrap();
    let (radius, stable) = cl.stability().unwrap();
    assert!(stable && radius < 1.0);
    let nyq = generalized_nyquist(&cl).unwrap();
    assert!(nyq.stable && nyq.agrees, "{nyq:?}");
    assert!(failed.is_some(), "some order should lose the loop");
}

/// Coprime-factor reduction of the loop-scaled controller, the closed-loop-weighted
/// truncation and the loop-weighted fit on the paper stage's loop and on the 60-state stage's
/// loopshaping loop (issue #41 item 5): at each order the loop is stable by its eigenvalues and
/// the generalized Nyquist criterion, or the order is refused as a numerical failure; the
/// smallest order within 0.5 dB of |S| and |T| below twice the crossover (every order of the
/// paper stage's 8-state controller, a ladder of orders of the 60-state stage's 64-state one),
/// its `‖S‖∞` risen by at most 0.5 dB too (the modulus margin kept above the band as well), is
/// reported per method. The 60-state stage's controller must come to at most 8 states so
/// (the acceptance) by the fit.
#[test]
fn coprime_factor_reduction_keeps_the_loop() {
    let ladder: Vec<usize> = vec![24, 20, 18, 16, 14, 12, 10, 8, 6, 5, 4];
    for (name, plant, orders) in [
        (
            "paper stage",
            paper_stage(0.01).unwrap(),
            (1..8).rev().collect::<Vec<usize>>(),
        ),
        (
            "60-state stage",
            sd_model::stage::stage60().unwrap(),
            ladder,
        ),
    ] {
        let bw = 65.0;
        let p = c2d(&plant, 1e-3, Discretization::Zoh).unwrap();
        let w1 = sd_hinf::weights::pid(bw, 20.0, Some(1e-3), &Default::default()).unwrap();
        let k = sd_hinf::loopshape(&p, Some(&w1), None, &Default::default())
            .unwrap()
            .controller;
        let mut smallest = [None, None, None];
        for (slot, method) in [
            ReductionMethod::CoprimeFactor,
            ReductionMethod::ClosedLoopWeighted,
            ReductionMethod::LoopFit,
        ]
        .into_iter()
        .enumerate()
        {
            for &order in &orders {
                match reduce_controller(&p, &k, order, method) {
                    Ok(r) => {
                        let cl = ClosedLoop::new(&p, &r.controller).unwrap();
                        let nyq = generalized_nyquist(&cl).unwrap();
                        assert!(
                            nyq.stable && nyq.agrees,
                            "{name} {method:?} {order}: {nyq:?}"
                        );
                        let rise =
                            20.0 * (r.before.modulus_margin / r.after.modulus_margin).log10();
                        if method == ReductionMethod::LoopFit {
                            println!(
                                "{name} fit {order}: |ΔS| {:.3} dB, |ΔT| {:.3} dB; modulus \
                                 margin {:.3} → {:.3}, gain margin {:.2} → {:.2} dB, phase \
                                 margin {:.1} → {:.1}°",
                                r.max_delta_s_db,
                                r.max_delta_t_db,
                                r.before.modulus_margin,
                                r.after.modulus_margin,
                                r.before.gain_margin_db,
                                r.after.gain_margin_db,
                                r.before.phase_margin_deg,
                                r.after.phase_margin_deg
                            );
                        }
                        if r.max_delta_s_db <= 0.5 && r.max_delta_t_db <= 0.5 && rise <= 0.5 {
                            smallest[slot] = Some((order, r.max_delta_s_db, r.max_delta_t_db));
                        }
                    }
                    Err(e) => assert!(e.is_numerical(), "{name} {method:?} {order}: {e}"),
                }
            }
        }
        println!(
            "{name}: controller {} states; smallest order within 0.5 dB: coprime factors {:?}, \
             closed-loop weighted {:?}, loop-weighted fit {:?} (order, |ΔS| dB, |ΔT| dB)",
            k.n(),
            smallest[0],
            smallest[1],
            smallest[2]
        );
        assert!(
            smallest[0].is_some(),
            "{name}: coprime reduction never within 0.5 dB"
        );
        let fit = smallest[2].map_or(usize::MAX, |s| s.0);
        assert!(fit <= 8, "{name}: the fit needs {fit} states within 0.5 dB");
    }
}
