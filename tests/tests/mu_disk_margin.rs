//! Issue #40 item 5: the structured (μ) simultaneous disk margin (`sd_analysis::mu`).
//! References: MATLAB's published `diskmargin` example (multiloop disk margin 0.4890, bounds
//! 0.4890…0.4899) and, independently, the exact structured value on a dense frequency grid by
//! a direct root search for 2×2 loops: `μ(M) = 1/min{ρ : det(I − M·diag(δ₁, δ₂)) = 0,
//! |δ₁| = |δ₂| = ρ}` with `δ₂ = (1 − m₁₁δ₁)/(m₂₂ − det(M)δ₁)` scanned over `arg δ₁`.
//! `cargo test --release -p sd-tests --test mu_disk_margin -- --nocapture` prints the figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_analysis::{structured_disk_margins, ClosedLoop};
use sd_model::connect::series;
use sd_model::{FreqRespEvaluator, SampleTime, StateSpace};
use std::f64::consts::PI;

fn ct(a: &[f64], b: &[f64], c: &[f64], n: usize) -> StateSpace {
    let m = |v: &[f64]| DMatrix::from_row_slice(n, n, v);
    StateSpace::new(
        m(a),
        m(b),
        m(c),
        DMatrix::zeros(n, n),
        SampleTime::Continuous,
    )
    .unwrap()
}

fn gain(v: &[f64]) -> StateSpace {
    StateSpace::gain(DMatrix::from_row_slice(2, 2, v), SampleTime::Continuous).unwrap()
}

/// The exact μ of a 2×2 `m` for `diag(δ₁, δ₂)` by the direct root search (module docs).
fn mu_exact_2x2(m: &DMatrix<C>) -> f64 {
    let (m11, m22) = (m[(0, 0)], m[(1, 1)]);
    let det = m11 * m22 - m[(0, 1)] * m[(1, 0)];
    let mut best = f64::INFINITY;
    for t in 0..720 {
        let e = C::from_polar(1.0, 2.0 * PI * f64::from(t) / 720.0);
        let g = |r: f64| ((C::new(1.0, 0.0) - m11 * e * r) / (m22 - det * e * r)).norm() - r;
        // the smallest root of g on a log scan, then bisection
        let rs: Vec<f64> = (0..=600)
            .map(|i| 10f64.powf(-4.0 + 8.0 * f64::from(i) / 600.0))
            .collect();
        let Some(i) = (1..rs.len()).find(|&i| (g(rs[i - 1]) > 0.0) != (g(rs[i]) > 0.0)) else {
            continue;
        };
        let (mut lo, mut hi) = (rs[i - 1], rs[i]);
        let s0 = g(lo) > 0.0;
        for _ in 0..80 {
            let mid = (lo * hi).sqrt();
            if (g(mid) > 0.0) == s0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        best = best.min(lo);
    }
    1.0 / best
}

/// `1/max μ_exact(S − I/2)` over a dense log grid (the loop `L` under unit feedback).
fn dense_exact_margin(l: &StateSpace, (lo, hi): (f64, f64), n: usize) -> (f64, f64) {
    let ev = FreqRespEvaluator::new(l).unwrap();
    let mut worst = (0.0, 0.0);
    for i in 0..n {
        let f = lo * (hi / lo).powf(i as f64 / (n - 1) as f64);
        let s = (DMatrix::identity(2, 2) + ev.eval_hz(f))
            .try_inverse()
            .unwrap();
        let mu = mu_exact_2x2(&(s - DMatrix::identity(2, 2) * C::new(0.5, 0.0)));
        if mu > worst.0 {
            worst = (mu, f);
        }
    }
    (1.0 / worst.0, worst.1)
}

#[test]
fn published_diskmargin_example_and_the_dense_exact_value() {
    // MATLAB diskmargin doc: a = [0 10; −10 0], b = I, c = [1 8; −10 1], C = [1 −2; 0 1], L = P·C
    let p = ct(
        &[0.0, 10.0, -10.0, 0.0],
        &[1.0, 0.0, 0.0, 1.0],
        &[1.0, 8.0, -10.0, 1.0],
        2,
    );
    let l = series(&gain(&[1.0, -2.0, 0.0, 1.0]), &p).unwrap();
    let cl = ClosedLoop::new(&l, &gain(&[1.0, 0.0, 0.0, 1.0])).unwrap();
    let [input, output] = structured_disk_margins(&cl).unwrap();
    let lat = sd_analysis::mimo_margins(&cl).unwrap();
    let (exact, at) = dense_exact_margin(&l, (1e-2, 1e2), 400);
    println!(
        "diskmargin example: μ margin {:.5} (upper {:.5}) at {:.4} Hz; dense exact {exact:.5} at \
         {at:.4} Hz; unstructured {:.5}; MATLAB 0.4890 (bounds 0.4890…0.4899)",
        input.margin, input.margin_upper, input.freq_hz, lat.simultaneous_input_disk_margin
    );
    assert!((0.4885..=0.4900).contains(&input.margin), "{input:?}");
    assert_eq!(input, output); // K = I: both sides see S = (I + L)⁻¹
                               // the grid's exact value can only be at or above the true margin, and close to it
    assert!(input.margin <= exact * (1.0 + 1e-6) && exact - input.margin < 2e-3);
    assert!((input.margin_upper - input.margin).abs() < 1e-6 * input.margin);
    assert!(lat.simultaneous_input_disk_margin < 0.13); // the unstructured bound: 0.123
    let s = lat.structured_input_disk_margin.as_ref().unwrap();
    assert_eq!(s, &input);
}

#[test]
fn spinning_satellite_structured_equals_the_dense_exact_value() {
    // the spinning satellite (a = 10) under K = I: its worst perturbation is one that the
    // diagonal structure also contains, so μ gives the unstructured value, 0.0998
    let a = 10.0;
    let p = ct(
        &[0.0, a, -a, 0.0],
        &[1.0, 0.0, 0.0, 1.0],
        &[1.0, a, -a, 1.0],
        2,
    );
    let cl = ClosedLoop::new(&p, &gain(&[1.0, 0.0, 0.0, 1.0])).unwrap();
    let [input, _] = structured_disk_margins(&cl).unwrap();
    let (exact, at) = dense_exact_margin(&p, (1e-4, 1e2), 300);
    let lat = sd_analysis::mimo_margins(&cl).unwrap();
    println!(
        "satellite: μ margin {:.6} at {:.4} Hz; dense exact {exact:.6} at {at:.4} Hz; \
         unstructured {:.6}",
        input.margin, input.freq_hz, lat.simultaneous_input_disk_margin
    );
    assert!(input.margin <= exact * (1.0 + 1e-6) && exact - input.margin < 1e-4);
    assert!((input.margin - lat.simultaneous_input_disk_margin).abs() < 1e-4);
}

#[test]
fn three_channels_bounds_meet() {
    // a 3×3 coupled loop: the D-scaled bound equals μ for three scalar blocks; the phase
    // search's lower bound must meet it at the peak
    let n = 3;
    let a = DMatrix::from_row_slice(n, n, &[-0.2, 4.0, 0.0, -4.0, -0.2, 2.0, 0.0, -2.0, -3.0]);
    let b = DMatrix::identity(n, n);
    let c = DMatrix::from_row_slice(n, n, &[1.0, 3.0, 0.0, -2.0, 1.0, 1.0, 0.5, 0.0, 1.0]);
    let p = StateSpace::new(a, b, c, DMatrix::zeros(n, n), SampleTime::Continuous).unwrap();
    let kd = DMatrix::from_row_slice(n, n, &[2.0, 0.0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0, 1.0]);
    let k = StateSpace::gain(kd, SampleTime::Continuous).unwrap();
    let cl = ClosedLoop::new(&p, &k).unwrap();
    assert!(cl.stability().unwrap().1);
    let [input, output] = structured_disk_margins(&cl).unwrap();
    println!("3x3: inputs {input:?}\n     outputs {output:?}");
    for s in [&input, &output] {
        assert!(s.margin_upper >= s.margin * (1.0 - 1e-9));
        assert!(s.margin_upper - s.margin < 1e-3 * s.margin, "{s:?}");
    }
}
