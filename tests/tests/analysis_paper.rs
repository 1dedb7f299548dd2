//! the paper's two 1 kHz controllers on the stage (docs/stage.md).
//! Controller 2 = a PID with ≈65 Hz bandwidth alone; Controller 1 = the same with a 347 Hz
//! notch (low gain at the aliased mode).
//! - C2: |S_d| peak ≥ 10 dB within 10 Hz of 347 Hz; C1: |S_d(347 Hz)| ≤ 3 dB; both stable; with
//!   ζ₁ = 0.005 C2 is unstable.
//! - Multirate standstill with C2 on the 5 kHz plant: the 1 kHz error is dominated by ≈347 Hz,
//!   the 5 kHz error by ≈653 Hz; predicted spectra = simulated within ±10 % in band medians;
//!   with C1 the fast-rate rms error is lower.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_analysis::{intersample, standstill_multirate, welch, ClosedLoop, Window};
use sd_model::connect::series;
use sd_model::{c2d, Discretization, StateSpace};
use sd_tests::gen::Rng;
use sd_tests::pid;

const TS: f64 = 1e-3;

fn controller2() -> StateSpace {
    pid(65.0, 20.0, TS)
}

fn controller1() -> StateSpace {
    let notch = sd_hinf::weights::notch(347.0, 0.02, 0.3, Some(TS)).unwrap();
    series(&controller2(), &notch).unwrap()
}

fn plant(zeta: f64, ts: f64) -> StateSpace {
    c2d(
        &sd_model::stage::paper_stage(zeta).unwrap(),
        ts,
        Discretization::Zoh,
    )
    .unwrap()
}

#[test]
fn paper_controllers_at_1khz() {
    let p = plant(0.01, TS);
    let c2 = ClosedLoop::new(&p, &controller2())
        .unwrap()
        .summary()
        .unwrap();
    let c1l = ClosedLoop::new(&p, &controller1()).unwrap();
    let c1 = c1l.summary().unwrap();
    let s347 = 20.0 * c1l.sensitivity_at(347.0).unwrap().log10();
    println!("Controller 2: {c2:?}");
    println!("Controller 1: {c1:?}; |S_d(347 Hz)| = {s347:.2} dB");
    assert!(c2.stable && c1.stable);
    assert!(c2.sensitivity_peak_db >= 10.0 && (c2.sensitivity_peak_hz - 347.0).abs() <= 10.0);
    assert!(s347 <= 3.0);
    assert!((50.0..=80.0).contains(&c1.crossover_hz) && (50.0..=80.0).contains(&c2.crossover_hz));
    // the closed-loop −3 dB bandwidth lies above the crossover for these phase margins
    assert!(c1.bandwidth_hz > c1.crossover_hz && c2.bandwidth_hz > c2.crossover_hz);
    let hazard = ClosedLoop::new(&plant(0.005, TS), &controller2()).unwrap();
    let (r, stable) = hazard.stability().unwrap();
    println!("ζ₁ = 0.005 with Controller 2: closed-loop radius {r:.6}");
    assert!(!stable);
}

/// Band medians of simulated/predicted over 100 Hz bands.
fn worst_band(f: &[f64], sim: &[f64], pred: &[f64], width: f64) -> f64 {
    let fmax = f[f.len() - 1];
    let mut worst: f64 = 0.0;
    let mut lo = 0.0;
    while lo + width <= fmax + 1e-9 {
        let mut r: Vec<f64> = (0..f.len())
            .filter(|&i| f[i] > lo.max(2.0) && f[i] < lo + width)
            .map(|i| sim[i] / pred[i])
            .collect();
        r.sort_by(f64::total_cmp);
        if !r.is_empty() {
            worst = worst.max((r[r.len() / 2] - 1.0).abs());
        }
        lo += width;
    }
    worst
}

#[test]
fn multirate_standstill() {
    let (h, factor) = (2e-4, 5usize);
    let p = plant(0.01, h);
    let (sd, sn) = (0.05, 0.3e-9);
    let n = 1usize << 20;
    let mut rng = Rng::new(17);
    let d = DMatrix::from_fn(n, 1, |_, _| sd * rng.normal());
    let v = DMatrix::from_fn(n, 1, |_, _| sn * rng.normal());
    let (phid, phin) = (2.0 * h * sd * sd, 2.0 * h * sn * sn);
    let mut rms_fast = Vec::new();
    for (name, k) in [
        ("Controller 2", controller2()),
        ("Controller 1", controller1()),
    ] {
        let s = standstill_multirate(&p, &k, factor, &d, &v).unwrap();
        let skip = 25_000;
        let ef: Vec<f64> = s.z_fast.column(0).iter().skip(skip).cloned().collect();
        let es: Vec<f64> = s
            .y_slow
            .column(0)
            .iter()
            .skip(skip / factor)
            .cloned()
            .collect();
        let wf = welch(&ef, 1.0 / h, 5000, 0.5, Window::Hann).unwrap();
        let ws = welch(&es, 1.0 / (h * factor as f64), 1000, 0.5, Window::Hann).unwrap();
        let l = sd_multirate::MultirateLoop::new(&p, &k, factor).unwrap();
        let pf = l
            .error_spectrum_fast(&wf.freq_hz, &|_| phid, &|_| phin)
            .unwrap();
        let ps = l
            .error_spectrum_slow(&ws.freq_hz, &|_| phid, &|_| phin)
            .unwrap();
        let (bf, bs) = (
            worst_band(&wf.freq_hz, &wf.psd, &pf, 100.0),
            worst_band(&ws.freq_hz, &ws.psd, &ps, 50.0),
        );
        let pred = intersample(&p, &k, factor, &|_| phid, &|_| phin, 2000).unwrap();
        println!(
            "{name}: dominant slow {:.1} Hz, fast {:.1} Hz; rms slow {:.3e} (predicted {:.3e}), fast {:.3e} (predicted {:.3e}); worst band-median error fast {:.3}, slow {:.3}; max |KS| {:.3e}",
            ws.dominant_hz(),
            wf.dominant_hz(),
            ws.rms(),
            pred.rms_slow,
            wf.rms(),
            pred.rms_fast,
            bf,
            bs,
            pred.control_sensitivity.iter().cloned().fold(0.0, f64::max)
        );
        assert!(bf <= 0.10 && bs <= 0.10);
        if name == "Controller 2" {
            assert!(
                (ws.dominant_hz() - 347.0).abs() <= 10.0,
                "slow dominant {}",
                ws.dominant_hz()
            );
            assert!(
                (wf.dominant_hz() - 653.0).abs() <= 10.0,
                "fast dominant {}",
                wf.dominant_hz()
            );
        }
        rms_fast.push(wf.rms());
    }
    assert!(
        rms_fast[1] < rms_fast[0],
        "Controller 1 fast rms {} not below Controller 2's {}",
        rms_fast[1],
        rms_fast[0]
    );
}
