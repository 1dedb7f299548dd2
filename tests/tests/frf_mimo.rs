//! The MIMO periodic FRF (`sd_ident::frf_periodic_mimo`) of a seeded 2×2 discrete system of
//! three lightly damped modes, excited by orthogonal multisines (`sd_ident::orthogonal`) or
//! one input per experiment, with white output noise: the estimate against the true FRF,
//! normalised by the estimated variances (per entry: mean |ΔG|²/σ² ≈ 1) and by the full
//! covariance of vec(G) (mean ΔgᴴC⁻¹Δg ≈ 4·16/14 = 4.57: the inverse of a covariance estimated
//! from 16 complex bins of a 2-dimensional noise is 16/14 too large on average); too few
//! experiments is an error naming it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_ident::{
    design, frf_periodic_mimo, orthogonal, Channels, Lines, MultisineSpec, PeriodicOptions, Phases,
};
use sd_model::{SampleTime, StateSpace};
use sd_tests::gen::Rng;
use std::f64::consts::PI;

const P: usize = 1000;
const PERIODS: usize = 9;

/// The discrete state matrix of pole pairs `(f Hz, ζ)` at period `ts`, one rotation block
/// `[[Re p, −Im p], [Im p, Re p]]` each.
fn pair_blocks(modes: &[(f64, f64)], ts: f64) -> DMatrix<f64> {
    let mut a = DMatrix::zeros(2 * modes.len(), 2 * modes.len());
    for (i, &(f, z)) in modes.iter().enumerate() {
        let w: f64 = 2.0 * PI * f;
        let p = (C::new(-z * w, w * (1.0 - z * z).sqrt()) * ts).exp();
        a[(2 * i, 2 * i)] = p.re;
        a[(2 * i, 2 * i + 1)] = -p.im;
        a[(2 * i + 1, 2 * i)] = p.im;
        a[(2 * i + 1, 2 * i + 1)] = p.re;
    }
    a
}

fn plant() -> StateSpace {
    let ts = 1e-3;
    let a = pair_blocks(&[(60.0, 0.02), (150.0, 0.01), (320.0, 0.03)], ts);
    let b = DMatrix::from_row_slice(
        6,
        2,
        &[
            0.3, 0.1, 0.1, -0.2, -0.2, 0.25, 0.15, 0.1, 0.1, 0.3, 0.05, -0.1,
        ],
    );
    let c = DMatrix::from_row_slice(
        2,
        6,
        &[
            1.0, 0.2, 0.5, -0.3, 0.4, 0.1, -0.3, 0.8, 0.6, 0.2, -0.5, 0.7,
        ],
    );
    StateSpace::new(
        a,
        b,
        c,
        DMatrix::zeros(2, 2),
        SampleTime::discrete(ts).unwrap(),
    )
    .unwrap()
}

/// One experiment's inputs and outputs (one vector per channel).
type Record = (Vec<Vec<f64>>, Vec<Vec<f64>>);
/// Their views.
type Views<'a> = (Vec<&'a [f64]>, Vec<&'a [f64]>);

/// `periods` repetitions of each input's period, simulated, with output noise `sigma`.
fn run(
    sys: &StateSpace,
    inputs: &[Vec<f64>],
    sigma: f64,
    rng: &mut Rng,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = P * PERIODS;
    let u = DMatrix::from_fn(n, inputs.len(), |t, j| inputs[j][t % P]);
    let y = sys.simulate(&u, None).unwrap().y;
    let us = (0..inputs.len())
        .map(|j| u.column(j).iter().copied().collect())
        .collect();
    let ys = (0..y.ncols())
        .map(|a| {
            y.column(a)
                .iter()
                .map(|v| v + sigma * rng.normal())
                .collect()
        })
        .collect();
    (us, ys)
}

/// Normalised errors of an estimate against the truth: (per entry, full covariance).
fn normalised(set: &[Vec<Vec<f64>>], sys: &StateSpace, sigma: f64, seed: u64) -> (f64, f64, usize) {
    let mut rng = Rng::new(seed);
    let runs: Vec<Record> = set.iter().map(|e| run(sys, e, sigma, &mut rng)).collect();
    let refs: Vec<Views<'_>> = runs
        .iter()
        .map(|(u, y)| {
            (
                u.iter().map(Vec::as_slice).collect(),
                y.iter().map(Vec::as_slice).collect(),
            )
        })
        .collect();
    let ch: Vec<Channels<'_>> = refs
        .iter()
        .map(|(u, y)| Channels { r: &[], u, y })
        .collect();
    let est = frf_periodic_mimo(1000.0, &ch, &PeriodicOptions::new(P, 1)).unwrap();
    let truth = sys.freqresp(est.frd.freq_hz()).unwrap();
    let var = est.frd.variance().unwrap();
    let (mut per_entry, mut full) = (0.0, 0.0);
    for k in 0..est.frd.len() {
        let d = &est.frd.response()[k] - &truth.response()[k];
        for a in 0..2 {
            for i in 0..2 {
                per_entry += d[(a, i)].norm_sqr() / var[k][(a, i)];
            }
        }
        let v = DMatrix::from_fn(4, 1, |q, _| d[(q % 2, q / 2)]);
        let ci = est.covariance[k].clone().try_inverse().unwrap();
        full += (v.adjoint() * ci * &v)[(0, 0)].re;
    }
    let n = est.frd.len();
    (per_entry / (4 * n) as f64, full / n as f64, n)
}

#[test]
fn mimo_frf_with_its_covariance() {
    let sys = plant();
    let ms = design(&MultisineSpec {
        fs: 1000.0,
        period: P,
        f_min: 1.0,
        f_max: 400.0,
        lines: Lines::Full,
        phases: Phases::Random { seed: 3 },
        rms: 1.0,
        fold_rate_hz: None,
    })
    .unwrap();
    let orth = orthogonal(&ms, 2).unwrap();
    // one input per experiment: the other input at rest
    let zero = vec![0.0; P];
    let single = vec![
        vec![ms.signal.clone(), zero.clone()],
        vec![zero, ms.signal.clone()],
    ];
    for (name, set) in [("orthogonal", &orth), ("one input per experiment", &single)] {
        let (pe, fc, n) = normalised(set, &sys, 0.05, 11);
        println!("{name}: {n} lines, mean |ΔG|²/σ² {pe:.3} (1 expected), mean ΔgᴴC⁻¹Δg {fc:.3} (4·16/14 = 4.57 expected)");
        // 4·400 terms: the mean of Exp(1) variables has a standard deviation of 0.025;
        // the variances are estimated from 8 periods (ν = 14 real dof: E[1/σ̂²] is 7 % high)
        assert!((pe - 1.0).abs() < 0.2, "{name}: {pe}");
        assert!((fc / (4.0 * 16.0 / 14.0) - 1.0).abs() < 0.1, "{name}: {fc}");
    }
    // the orthogonal set's excitation matrix is √2 times unitary at every line
    let (a, b) = (&orth[0], &orth[1]);
    let dot: f64 = (0..P).map(|t| a[1][t] * b[1][t]).sum();
    assert!(
        (a[0]
            .iter()
            .zip(&b[0])
            .map(|(x, y)| (x - y).abs())
            .sum::<f64>())
            < 1e-9
    );
    assert!(
        (a[1]
            .iter()
            .zip(&b[1])
            .map(|(x, y)| (x + y).abs())
            .sum::<f64>())
            < 1e-9,
        "{dot}"
    );
}

#[test]
fn too_few_experiments_or_mismatched_channels_are_named() {
    let x = vec![0.0; 4000];
    let (u, y) = (vec![x.as_slice(), x.as_slice()], vec![x.as_slice()]);
    let one = [Channels {
        r: &[],
        u: &u,
        y: &y,
    }];
    let e = frf_periodic_mimo(1000.0, &one, &PeriodicOptions::new(1000, 0)).unwrap_err();
    assert!(
        e.to_string().contains("1 experiment(s) for 2 inputs"),
        "{e}"
    );
    let r = vec![x.as_slice()];
    let bad = [
        Channels {
            r: &r,
            u: &u,
            y: &y,
        },
        Channels {
            r: &r,
            u: &u,
            y: &y,
        },
    ];
    let e = frf_periodic_mimo(1000.0, &bad, &PeriodicOptions::new(1000, 0)).unwrap_err();
    assert!(e.to_string().contains("1 references for 2 inputs"), "{e}");
}

/// One non-periodic record with two independent noise inputs (MIMO LPM through
/// `sd_ident::lpm`): the covariance's diagonal is the per-entry variance, and the estimate's
/// error against the true FRF, whitened by it, has the size the covariance states.
#[test]
fn lpm_mimo_covariance() {
    // a well-damped 2×2 plant (ζ = 0.2, 0.3): the local polynomials' bias stays below the noise
    let ts = 1e-3;
    let a = pair_blocks(&[(80.0, 0.2), (220.0, 0.3)], ts);
    let b = DMatrix::from_row_slice(4, 2, &[0.3, 0.1, 0.1, -0.2, -0.2, 0.25, 0.15, 0.1]);
    let c = DMatrix::from_row_slice(2, 4, &[1.0, 0.2, 0.5, -0.3, -0.3, 0.8, 0.6, 0.2]);
    let sys = StateSpace::new(
        a,
        b,
        c,
        DMatrix::zeros(2, 2),
        SampleTime::discrete(ts).unwrap(),
    )
    .unwrap();
    let n = 8192;
    let mut rng = Rng::new(5);
    let u = DMatrix::from_fn(n, 2, |_, _| rng.normal());
    let y0 = sys.simulate(&u, None).unwrap().y;
    let y = y0.map(|v| v + 0.01 * rng.normal());
    let est = sd_ident::lpm(1000.0, &u, &y, &sd_ident::LpmOptions::default()).unwrap();
    let truth = sys.freqresp(est.frd.freq_hz()).unwrap();
    let var = est.frd.variance().unwrap();
    let (mut full, mut diag_err, mut k) = (0.0, 0.0f64, 0);
    // lines away from the band edges, where the window is centred
    for q in 20..est.frd.len() - 20 {
        let cov = &est.covariance[q];
        for e in 0..4 {
            let (i, j) = (e % 2, e / 2);
            diag_err = diag_err.max((cov[(e, e)].re - var[q][(i, j)]).abs() / var[q][(i, j)]);
        }
        let d = &est.frd.response()[q] - &truth.response()[q];
        let v = DMatrix::from_fn(4, 1, |e, _| d[(e % 2, e / 2)]);
        full += (v.adjoint() * cov.clone().try_inverse().unwrap() * &v)[(0, 0)].re;
        k += 1;
    }
    let mean = full / k as f64;
    println!("MIMO LPM: {k} lines, mean ΔgᴴC⁻¹Δg {mean:.3} (8 expected: 4 entries, 2× for ν = 4); diagonal vs var: {diag_err:.1e}");
    assert!(diag_err < 1e-9);
    // C_V from ν = 2n + 1 − q = 13 − 9 = 4 complex residual degrees of freedom per window:
    // the inverse of an estimated 2×2 covariance is ν/(ν − 2) = 2 times too large on average
    // (complex Wishart), so the mean is 4·2 = 8; ±15 % for 4000 overlapping lines
    assert!((mean / 8.0 - 1.0).abs() < 0.15, "{mean}");
}
