//! The common-pole fit on the two-axis stage (`sd_model::stage::two_axis_stage60`: a rigid
//! body and 29 lightly damped modes, 300 Hz–6 kHz, each with its own input and output shapes,
//! two actuators and two sensors: rank-one residue matrices),
//! ZOH at 5 kHz, 2500 lines per entry with 1 % complex Gaussian noise (variance stored).
//! An order-60 fit in common: the modes' frequencies (0.3 %) and the residues' directions
//! (cosine ≥ 0.99) below the fast Nyquist frequency, ranks, the time (printed; measured in
//! `cargo xtask bench`, `fit_common_poles_2x2_order60`); Lemma 6 on the
//! fitted model against the true model's slow FRF (median relative error ≤ 1 %, the noise).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_ident::{fit_common_poles, FitOptions, MimoFitOptions, Weighting};
use sd_model::{c2d, Discretization, Frd, StateSpace};
use sd_tests::gen::Rng;
use std::f64::consts::PI;

/// The FRD of `sys` on `f` with relative complex Gaussian noise `rel` per entry.
fn noisy(sys: &StateSpace, f: &[f64], rel: f64, r: &mut Rng) -> Frd {
    let truth = sys.freqresp(f).unwrap();
    let (mut resp, mut var) = (Vec::new(), Vec::new());
    for g in truth.response() {
        let sd = g.map(|v| rel * v.norm());
        resp.push(DMatrix::from_fn(2, 2, |i, j| {
            g[(i, j)] + C::new(r.normal(), r.normal()) * (sd[(i, j)] / 2f64.sqrt())
        }));
        var.push(sd.map(|s| s * s));
    }
    Frd::new(f.to_vec(), resp, Some(var), truth.time()).unwrap()
}

#[test]
fn order60_common_pole_fit_of_a_two_axis_stage() {
    let pc = sd_model::stage::two_axis_stage60().unwrap();
    let shapes: Vec<(f64, [f64; 2], [f64; 2])> = sd_model::stage::two_axis_modes()
        .iter()
        .map(|m| (m.mode.freq_hz, m.output_shape, m.input_shape))
        .collect();
    let h = 2e-4;
    let pd = c2d(&pc, h, Discretization::Zoh).unwrap();
    let f: Vec<f64> = (1..=2500).map(|k| k as f64 * 0.999).collect();
    let frd = noisy(&pd, &f, 0.01, &mut Rng::new(21));
    let t0 = std::time::Instant::now();
    let r = fit_common_poles(
        &frd,
        &MimoFitOptions {
            fit: FitOptions {
                order: 60,
                rigid_body: 2,
                feedthrough: false,
                weighting: Weighting::Variance,
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let dt = t0.elapsed().as_secs_f64();
    // every true mode against the fitted mode nearest in frequency
    let mut worst_f: f64 = 0.0;
    let mut worst_dir: f64 = 1.0;
    let mut aliased = Vec::new();
    // the discrete poles' frequencies (principal branch: a mode above the fast Nyquist
    // frequency appears at its alias)
    let discrete: Vec<f64> = sd_model::stage::two_axis_modes()
        .iter()
        .map(|m| {
            let (w, z) = (2.0 * PI * m.mode.freq_hz, m.mode.zeta);
            let s = C::new(-z * w, w * (1.0 - z * z).sqrt());
            ((s * h).exp().ln() / h).norm() / (2.0 * PI)
        })
        .collect();
    let mut rank_one = (0, 0);
    for ((f_ct, out, inp), &fm) in shapes.iter().zip(&discrete) {
        let m = r
            .modes
            .iter()
            .min_by(|a, b| (a.freq_hz - fm).abs().total_cmp(&(b.freq_hz - fm).abs()))
            .unwrap();
        if *f_ct > 0.5 / h {
            // above the fast Nyquist frequency: reported, not required (an alias moves to a
            // lower frequency at the same decay rate, so its damping ratio grows, and a weak
            // high mode then hides under a stronger one)
            aliased.push(format!(
                "{f_ct:.0} Hz at {fm:.1} Hz: fitted {:.1} Hz",
                m.freq_hz
            ));
            continue;
        }
        worst_f = worst_f.max((m.freq_hz / fm - 1.0).abs());
        // rank one unless an alias falls on the same pole (within 5 %)
        let alone = discrete
            .iter()
            .filter(|&&g| (g / fm - 1.0).abs() < 0.05)
            .count()
            == 1;
        if alone {
            rank_one.0 += usize::from(m.rank == 1);
            rank_one.1 += 1;
        }
        let cos = |d: &[f64], t: &[f64; 2]| {
            let n = (t[0] * t[0] + t[1] * t[1]).sqrt();
            (d[0] * t[0].abs() + d[1] * t[1].abs()) / n
        };
        worst_dir = worst_dir
            .min(cos(&m.output_direction, out))
            .min(cos(&m.input_direction, inp));
    }
    let ranks: Vec<usize> = r.modes.iter().map(|m| m.rank).collect();
    // Lemma 6 on the fit against the true model's 1 kHz FRF
    let slow_f: Vec<f64> = (1..=499).map(|k| k as f64).collect();
    let down = |m: &StateSpace| {
        sd_multirate::downsample(m, 5)
            .unwrap()
            .freqresp(&slow_f)
            .unwrap()
    };
    let (fit_slow, true_slow) = (down(&r.model), down(&pd));
    let mut rel: Vec<f64> = fit_slow
        .response()
        .iter()
        .zip(true_slow.response())
        .flat_map(|(a, b)| {
            (0..4).map(move |e| {
                (a[(e / 2, e % 2)] - b[(e / 2, e % 2)]).norm() / b[(e / 2, e % 2)].norm()
            })
        })
        .collect();
    rel.sort_by(f64::total_cmp);
    let slow_median = rel[rel.len() / 2];
    println!(
        "two-axis stage, order 60 in common over 2x2 x 2500 lines: {dt:.2} s, cost {:.0} (about \
         {} for a consistent fit), {} states, ranks {:?}; mode frequencies worst relative error \
         {:.2e} and residue directions worst cosine {:.4} (rank one {rank_one:?}) over the modes below the fast Nyquist \
         frequency (aliased ones: {aliased:?}); Lemma 6 of the fit vs the true slow FRF: \
         median relative error {:.2e}, worst {:.2e}",
        r.cost,
        4 * 2500,
        r.model.n(),
        ranks,
        worst_f,
        worst_dir,
        slow_median,
        rel[rel.len() - 1]
    );
    assert!(worst_f <= 3e-3, "a mode's frequency off by {worst_f:e}");
    assert!(
        worst_dir >= 0.99,
        "a residue direction off: cosine {worst_dir}"
    );
    // each mode below the fast Nyquist frequency without an alias on it: rank one
    assert_eq!(rank_one.0, rank_one.1, "rank-one modes {rank_one:?}");
    assert!(slow_median <= 0.01);
    assert!(r.poles.iter().all(|p| p.norm() <= 1.0));
}

/// A 2×2 structure with three modes (60, 150 and 320 Hz, ζ = 0.03; rank-one residues) and a
/// direct term, driven at 1 kHz by white noise through a hold; 4096 samples, 1 % output noise.
/// `shift[j]` moves the *recorded* input `j` against the one that drove the plant: the record
/// holds `u_j(t − shift_j)` (a positive shift: the outputs respond before the recorded input).
fn shifted_record(shift: [usize; 2], lead: [bool; 2], seed: u64) -> sd_model::Frd {
    let modes = [
        (60.0, [1.0, 0.4], [0.9, 0.3]),
        (150.0, [0.5, -1.0], [0.2, 1.0]),
        (320.0, [0.8, 0.6], [-0.7, 0.5]),
    ];
    let n = 2 * modes.len();
    let (mut a, mut b, mut c) = (
        DMatrix::zeros(n, n),
        DMatrix::zeros(n, 2),
        DMatrix::zeros(2, n),
    );
    for (k, (f, out, inp)) in modes.iter().enumerate() {
        let w = 2.0 * PI * f;
        a[(2 * k, 2 * k + 1)] = 1.0;
        a[(2 * k + 1, 2 * k)] = -w * w;
        a[(2 * k + 1, 2 * k + 1)] = -2.0 * 0.03 * w;
        for j in 0..2 {
            b[(2 * k + 1, j)] = inp[j] * w * w;
            c[(j, 2 * k)] = out[j];
        }
    }
    let d = DMatrix::from_row_slice(2, 2, &[0.1, 0.0, 0.0, 0.1]);
    let sys = StateSpace::new(a, b, c, d, sd_model::SampleTime::Continuous).unwrap();
    let (len, pad) = (4096, 16);
    let mut r = Rng::new(seed);
    let u = DMatrix::from_fn(len + 2 * pad, 2, |_, _| r.normal());
    let y = sys.simulate_zoh(&u, 1e-3, None).unwrap().y;
    let noise = 0.01 * (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
    let rec_u = DMatrix::from_fn(len, 2, |t, j| {
        let s = shift[j];
        u[(if lead[j] { t + pad - s } else { t + pad + s }, j)]
    });
    let rec_y = DMatrix::from_fn(len, 2, |t, i| y[(t + pad, i)] + noise * r.normal());
    sd_ident::lpm(1000.0, &rec_u, &rec_y, &Default::default())
        .unwrap()
        .frd
}

/// Whole-sample input delays (`sd_ident::input_delay`) from time-domain records whose input
/// columns were shifted against the plant's inputs: a recorded input lagging the true one by
/// 3 samples (the outputs lead it: delay −3), one leading it by 2 (a delay of 2: found at order
/// 6, the modes' own; order 8 has poles to spare that absorb it, and the shift 0 is kept), and
/// causal records on five seeds (no delay found: the false alarms of the rule).
#[test]
fn input_delays_from_shifted_records() {
    let opt = MimoFitOptions {
        fit: FitOptions {
            order: 8,
            ..Default::default()
        },
        input_delay: sd_ident::InputDelay::Estimate { max: 6 },
        ..Default::default()
    };
    let lines = |f: &sd_model::Frd| 4.0 * f.len() as f64;
    let frd = shifted_record([3, 2], [true, false], 7);
    let r = fit_common_poles(&frd, &opt).unwrap();
    let plain = fit_common_poles(
        &frd,
        &MimoFitOptions {
            input_delay: sd_ident::InputDelay::None,
            ..opt.clone()
        },
    )
    .unwrap();
    println!(
        "shifted record: delays {:?} (true [-3, 2]); cost {:.2} per entry line with them, {:.1} without",
        r.input_delay,
        r.cost / lines(&frd),
        plain.cost / lines(&frd)
    );
    assert_eq!(r.input_delay, vec![-3, 0]);
    assert!(r.cost / lines(&frd) < 1.6);
    let six = MimoFitOptions {
        fit: FitOptions {
            order: 6,
            ..Default::default()
        },
        ..opt.clone()
    };
    let r6 = fit_common_poles(&frd, &six).unwrap();
    println!(
        "at order 6: delays {:?}, cost {:.2} per entry line",
        r6.input_delay,
        r6.cost / lines(&frd)
    );
    assert_eq!(r6.input_delay, vec![-3, 2]);
    assert!(r6.cost / lines(&frd) < 1.6);
    let mut found = Vec::new();
    for seed in 11..16 {
        let frd = shifted_record([0, 0], [false, false], seed);
        found.push(fit_common_poles(&frd, &opt).unwrap().input_delay);
    }
    println!("causal records, seeds 11..16: delays {found:?}");
    let held: Vec<Vec<i32>> = (30..33)
        .map(|seed| {
            let frd = shifted_record([3, 2], [true, false], seed);
            fit_common_poles(&frd, &six).unwrap().input_delay
        })
        .collect();
    println!(
        "shifted records at order 6, seeds 30..33 (after the rule was set on seed 7): {held:?}"
    );
    assert!(held.iter().all(|d| d == &vec![-3, 2]));
    assert!(found.iter().all(|d| d == &vec![0, 0]));
}
