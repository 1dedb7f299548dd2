//! nonlinear-distortion detection with random-odd multisines, the LPM on
//! non-periodic data (unbiased, calibrated variance), and reading a 10⁶-row CSV.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::{DMatrix, DVector};
use sd_ident::{
    design, frf_periodic, lpm, read_columns, Lines, LpmOptions, MultisineSpec, PeriodicOptions,
    Phases,
};
use sd_model::{c2d, Discretization, StateSpace};
use sd_tests::gen::Rng;

fn resonance(ts: f64) -> StateSpace {
    let w: f64 = 2.0 * std::f64::consts::PI * 50.0;
    let ct = StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -0.2 * w]),
        DMatrix::from_row_slice(2, 1, &[0.0, w * w]),
        DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        DMatrix::zeros(1, 1),
        sd_model::SampleTime::Continuous,
    )
    .unwrap();
    c2d(&ct, ts, Discretization::Zoh).unwrap()
}

/// y = P(u) + c·y_lin³ (a static cubic on the output) + white noise.
fn run(p: &StateSpace, u: &[f64], cubic: f64, noise: f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let mut x = DVector::<f64>::zeros(p.n());
    u.iter()
        .map(|&uk| {
            let yl = (p.c() * &x)[0];
            x = p.a() * &x + p.b() * uk;
            yl + cubic * yl * yl * yl + noise * rng.normal()
        })
        .collect()
}

#[test]
fn random_odd_multisine_detects_odd_distortion() {
    let fs = 1000.0;
    let p = resonance(1.0 / fs);
    let ms = design(&MultisineSpec {
        fs,
        period: 2000,
        f_min: 1.0,
        f_max: 200.0,
        lines: Lines::RandomOdd { group: 3, seed: 4 },
        phases: Phases::Random { seed: 5 },
        rms: 1.0,
        fold_rate_hz: None,
    })
    .unwrap();
    let u = ms.repeat(11);
    let opt = PeriodicOptions::new(2000, 1);
    for (cubic, expect_distortion) in [(0.0, false), (0.3, true)] {
        let y = run(&p, &u, cubic, 1e-3, 8);
        let d = frf_periodic(fs, None, &u, &y, &opt)
            .unwrap()
            .distortion
            .unwrap();
        println!(
            "cubic {cubic}: odd/noise {:.1} ({} lines), even/noise {:.1} ({} lines)",
            d.odd_ratio, d.odd_lines, d.even_ratio, d.even_lines
        );
        if expect_distortion {
            assert!(d.odd_ratio > 10.0 && d.even_ratio < 3.0);
        } else {
            assert!(d.odd_ratio < 2.0 && d.even_ratio < 2.0);
        }
    }
}

#[test]
fn lpm_on_non_periodic_data_is_unbiased_with_calibrated_variance() {
    let fs = 1000.0;
    let p = resonance(1.0 / fs);
    let mut rng = Rng::new(3);
    let n = 8192;
    let u: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
    let y = run(&p, &u, 0.0, 0.02, 9);
    let est = lpm(
        fs,
        &DMatrix::from_column_slice(n, 1, &u),
        &DMatrix::from_column_slice(n, 1, &y),
        &LpmOptions::default(),
    )
    .unwrap();
    let truth = p.freqresp(est.frd.freq_hz()).unwrap();
    let var = est.frd.variance().unwrap();
    let mut z: Vec<f64> = (0..est.frd.len())
        .map(|i| {
            (est.frd.response()[i][(0, 0)] - truth.response()[i][(0, 0)]).norm_sqr()
                / var[i][(0, 0)]
        })
        .collect();
    z.sort_by(f64::total_cmp);
    let med = z[z.len() / 2];
    println!(
        "LPM on {n} non-periodic samples: median |Ĝ−G|²/var = {med:.3} over {} lines",
        z.len()
    );
    assert!((0.5..=2.0).contains(&med));
}

#[test]
fn reads_a_million_row_csv() {
    let rows = 1_000_000;
    let mut text = String::with_capacity(rows * 40);
    text.push_str("\"t\",\"u\", \"y\",extra,\n");
    for i in 0..rows {
        text.push_str(&format!(
            "{i},{},{},,\n",
            (i as f64 * 0.001).sin(),
            i as f64 * 1e-9
        ));
    }
    let t0 = std::time::Instant::now();
    let cols = read_columns(text.as_bytes(), "big.csv", &["u", "y"]).unwrap();
    println!(
        "1e6 rows, 2 of 5 columns: {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    assert_eq!(cols[0].len(), rows);
    assert_eq!(cols[1][rows - 1], (rows - 1) as f64 * 1e-9);
}
