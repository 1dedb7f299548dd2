//! Modes tracked over excitation levels (`sd_diagnose::tracks`) on a synthetic analogue of a
//! ground vibration test: four modes (a small 3.1 Hz mode, bending 5.2 Hz, torsion 7.3 Hz
//! dominant, 11.8 Hz), excitation levels 1, 2, 4, 8; the torsion mode softens by 2 % and its
//! damping triples over the levels (a friction joint), the bending mode softens by 0.6 %,
//! the others do not move. The FRFs are generated in continuous form `Σ r/(jω − p) + c.c.`
//! at 60 Hz sampling (the local fits use the sampled form, a different numerical form), with
//! complex Gaussian noise of 1 % of |G| per line (its variance given), 0.02 Hz lines over
//! 1.5–14 Hz.
//!
//! Required on every seed: the dominant mode is the torsion mode; kind softening; damping
//! rising. Over all seeds: the two still modes move (a false alarm, probability ≈ 2 % per
//! mode: frequency and damping each at α = 1 %) in at most 2 of the 12 cases (binomial tail
//! P(X ≥ 3) ≈ 2e-3 at 2 %), and each tracked point's frequency is within 2.58 standard errors
//! of the truth on ≥ 95 % of them. Written before it was run; seeds `6000..6006` (each about 10 s: the physical fit's
//! stabilisation over orders) (no tuning seeds: the
//! method's constants were set on the motor bench and the unit tests).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_diagnose::tracks::{track_modes, TrackLevel};
use sd_diagnose::{DampingTrend, FreqTrend};
use sd_ident::rng::SplitMix;
use sd_model::{Frd, SampleTime};
use std::f64::consts::TAU;

const LEVELS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];
const FS: f64 = 60.0;

/// (frequency Hz, damping, modal amplitude) of each mode at level `rho`.
fn modes(rho: f64) -> [(f64, f64, f64); 4] {
    let t = rho.ln() / 8f64.ln(); // 0 … 1 over the levels
    [
        (3.1, 0.03, 0.15),
        (5.2 * (1.0 - 0.006 * t), 0.012, 0.6),
        (7.3 * (1.0 - 0.02 * t), 0.008 * (1.0 + 2.0 * t), 1.0),
        (11.8, 0.015, 0.4),
    ]
}

/// The level's FRF: the modes' continuous responses at the lines, 1 % noise.
fn frf(rho: f64, rng: &mut SplitMix) -> Frd {
    let f: Vec<f64> = (75..=700).map(|k| 0.02 * k as f64).collect();
    let (mut g, mut var) = (Vec::new(), Vec::new());
    for &fk in &f {
        let s = C::new(0.0, TAU * fk);
        let mut v = C::new(0.0, 0.0);
        for (fm, z, a) in modes(rho) {
            let wn = TAU * fm;
            let p = C::new(-z * wn, wn * (1.0 - z * z).sqrt());
            let r = C::new(0.0, -a * wn);
            v += r / (s - p) + r.conj() / (s - p.conj());
        }
        let sd = 0.01 * v.norm();
        let e = C::new(rng.normal(), rng.normal()) * (sd / 2f64.sqrt());
        g.push(DMatrix::from_element(1, 1, v + e));
        var.push(DMatrix::from_element(1, 1, sd * sd));
    }
    Frd::new(f, g, Some(var), SampleTime::discrete(1.0 / FS).unwrap()).unwrap()
}

/// One seed: asserts the dominant mode, kind and damping trend; returns (false alarms of the
/// still modes, points within 2.58 σ, points).
fn one_seed(seed: u64) -> (usize, usize, usize) {
    let (mut inside, mut total, mut false_alarms) = (0, 0, 0);
    let mut rng = SplitMix::new(seed);
    let frds: Vec<Frd> = LEVELS.iter().map(|&r| frf(r, &mut rng)).collect();
    let names: Vec<String> = LEVELS.iter().map(|r| format!("level {r}")).collect();
    let levels: Vec<TrackLevel<'_>> = frds
        .iter()
        .zip(&names)
        .zip(LEVELS)
        .map(|((frd, name), level)| TrackLevel {
            name,
            level,
            frd,
            correlation: &[],
            spectra: None,
        })
        .collect();
    let tracks = track_modes(&frds[0], &levels, 0.01).unwrap().modes;
    let near = |f: f64| {
        tracks
            .iter()
            .find(|t| (t.freq_hz - f).abs() < 0.1)
            .unwrap_or_else(|| panic!("seed {seed}: no track near {f} Hz: {tracks:#?}"))
    };
    let torsion = near(7.3);
    assert!(torsion.dominant, "seed {seed}: {tracks:#?}");
    assert_eq!(torsion.frequency_trend, FreqTrend::Softening, "seed {seed}");
    assert_eq!(
        torsion.damping_trend,
        DampingTrend::Increasing,
        "seed {seed}"
    );
    for still in [3.1, 11.8] {
        let t = near(still);
        false_alarms += usize::from(t.frequency_moves || t.damping_moves);
    }
    for t in &tracks {
        let k = modes(1.0)
            .iter()
            .position(|m| (m.0 - t.freq_hz).abs() < 0.1)
            .unwrap_or_else(|| panic!("seed {seed}: a spurious track at {} Hz", t.freq_hz));
        for p in &t.points {
            let truth = modes(p.relative_level)[k].0;
            total += 1;
            inside += usize::from((p.freq_hz - truth).abs() <= 2.58 * p.freq_std);
        }
    }
    (false_alarms, inside, total)
}

#[test]
fn the_softening_torsion_mode_is_dominant_and_tracked_within_its_errors() {
    let out = sd_tests::diagcases::per_seed(6000..6006, one_seed);
    let false_alarms: usize = out.iter().map(|o| o.0).sum();
    let inside: usize = out.iter().map(|o| o.1).sum();
    let total: usize = out.iter().map(|o| o.2).sum();
    let share = inside as f64 / total as f64;
    println!("tracked points within 2.58 σ of the truth: {inside} of {total} ({share:.3})");
    println!("still modes that moved: {false_alarms} of 12");
    assert!(false_alarms <= 2, "{false_alarms} still modes moved");
    assert!(share >= 0.95, "{inside} of {total}");
}
