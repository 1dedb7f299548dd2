//! The multi-axis virtual stage (`sd_testbed::MultiAxisTruth::two_axis`: two actuators, three
//! sensors, translation and rotation rigid-body modes and three coupled flexible modes)
//! through the MIMO chain: orthogonal multisines in closed loop with a decentralised PID,
//! simulated by the fine-step route; the 3×2 FRF with its covariance; the common-pole fit
//! (modes to 0.3 %, rank-one residues along the true mode shapes); Lemma 6 of the fit against
//! the FRF measured at 1 kHz, within its noise.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_ident::{
    fit_common_poles, frf_of_experiments, FitOptions, Lines, MimoFitOptions, MultisineSpec, Phases,
    Role, Weighting,
};
use sd_testbed::{
    decentralised_pid, run_multiaxis, AxisData, AxisIdentification, AxisNonIdealities,
    MultiAxisTruth, Noise,
};

/// The orthogonal set at `rate` (one experiment per actuator, `period` samples, excited up to
/// `f_max`), with per-actuator hold delays `delay` and the sample clock's relative error
/// `clock`.
pub fn orthogonal_set(
    truth: &MultiAxisTruth,
    name: &str,
    (rate, period, f_max): (f64, usize, f64),
    (delay, clock): (&[f64], f64),
    seed: u64,
) -> Vec<AxisData> {
    let ms = sd_ident::design(&MultisineSpec {
        fs: rate,
        period,
        f_min: rate / period as f64,
        f_max,
        lines: Lines::Full,
        phases: Phases::Random { seed },
        rms: 1.0,
        fold_rate_hz: None,
    })
    .unwrap();
    let set = sd_ident::orthogonal(&ms, truth.inputs()).unwrap();
    let k = decentralised_pid(truth, 20.0, Some(0.2 * rate), 1.0 / rate).unwrap();
    set.into_iter()
        .enumerate()
        .map(|(e, excitation)| {
            run_multiaxis(
                truth,
                &AxisIdentification {
                    name: format!("{name}_{}", e + 1),
                    controller: k.clone(),
                    excitation,
                    periods: 6,
                    transient_periods: 1,
                    noise: Noise {
                        force_rms: 0.02,
                        sensor_rms: 1e-10,
                        sensor_drift: 0.0,
                        seed: seed * 10 + e as u64,
                    },
                    nonideal: AxisNonIdealities {
                        hold_delay: delay.to_vec(),
                        clock_error: clock,
                        ..AxisNonIdealities::ideal(truth.inputs(), truth.outputs())
                    },
                    role: if e == 0 {
                        Role::Model
                    } else {
                        Role::Validation
                    },
                    fine_steps: 16,
                },
            )
            .unwrap()
        })
        .collect()
}

fn frf(set: &[AxisData]) -> sd_ident::MimoFrfEstimate {
    let exps: Vec<sd_ident::Experiment> = set.iter().map(AxisData::to_experiment).collect();
    let refs: Vec<&sd_ident::Experiment> = exps.iter().collect();
    frf_of_experiments(&refs, &Default::default()).unwrap()
}

#[test]
fn two_axis_stage_through_the_mimo_chain() {
    let truth = MultiAxisTruth::two_axis();
    let t0 = std::time::Instant::now();
    let fast = frf(&orthogonal_set(
        &truth,
        "fast",
        (5000.0, 5000, 2400.0),
        (&[0.0, 0.0], 0.0),
        3,
    ));
    let slow = frf(&orthogonal_set(
        &truth,
        "slow",
        (1000.0, 1000, 499.0),
        (&[0.0, 0.0], 0.0),
        4,
    ));
    let sim = t0.elapsed().as_secs_f64();
    assert_eq!(
        (
            fast.frd.response()[0].nrows(),
            fast.frd.response()[0].ncols()
        ),
        (3, 2)
    );
    let t1 = std::time::Instant::now();
    let r = fit_common_poles(
        &fast.frd,
        &MimoFitOptions {
            fit: FitOptions {
                order: 8,
                rigid_body: 2,
                feedthrough: false,
                weighting: Weighting::Variance,
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let fit_s = t1.elapsed().as_secs_f64();
    // every flexible mode: frequency (of the discrete pole's principal branch, all below the
    // fast Nyquist frequency) and rank-one residue along the true shapes
    let mut worst_f: f64 = 0.0;
    let mut worst_cos: f64 = 1.0;
    for m in truth.modes.iter().filter(|m| m.freq_hz > 0.0) {
        let fitted = r
            .modes
            .iter()
            .min_by(|a, b| {
                (a.freq_hz - m.freq_hz)
                    .abs()
                    .total_cmp(&(b.freq_hz - m.freq_hz).abs())
            })
            .unwrap();
        worst_f = worst_f.max((fitted.freq_hz / m.freq_hz - 1.0).abs());
        assert_eq!(fitted.rank, 1, "{fitted:?}");
        let cos = |d: &[f64], t: &[f64]| {
            let n = t.iter().map(|v| v * v).sum::<f64>().sqrt();
            d.iter().zip(t).map(|(a, b)| a * b.abs()).sum::<f64>() / n
        };
        worst_cos = worst_cos
            .min(cos(&fitted.output_direction, &m.output))
            .min(cos(&fitted.input_direction, &m.input));
    }
    // Lemma 6 of the fit against the measured 1 kHz FRF, whitened by its variance: a
    // consistent model gives |e|²/σ² ≈ 1 on average (χ² with 2 degrees of freedom over 2)
    let down = sd_multirate::downsample(&r.model, 5).unwrap();
    let pred = down.freqresp(slow.frd.freq_hz()).unwrap();
    let var = slow.frd.variance().unwrap();
    let mut z2 = Vec::new();
    for ((g, p), v) in slow.frd.response().iter().zip(pred.response()).zip(var) {
        for i in 0..3 {
            for j in 0..2 {
                z2.push((g[(i, j)] - p[(i, j)]).norm_sqr() / v[(i, j)]);
            }
        }
    }
    let mean_z2 = z2.iter().sum::<f64>() / z2.len() as f64;
    println!(
        "multi-axis stage 3x2: simulation {sim:.2} s, fit {fit_s:.2} s ({} states, cost {:.0} \
         over {} lines x 6 entries); flexible modes' worst relative frequency error {worst_f:.2e}, \
         worst direction cosine {worst_cos:.4}; Lemma 6 of the fit vs the measured 1 kHz FRF: \
         mean whitened squared error {mean_z2:.2} (1 for a model within the noise)",
        r.model.n(),
        r.cost,
        fast.frd.freq_hz().len()
    );
    assert!(worst_f < 3e-3, "{worst_f}");
    assert!(worst_cos > 0.99, "{worst_cos}");
    // two independent rigid-body modes (4 states) and three pairs: the truth's own order
    assert_eq!(r.model.n(), 2 * truth.modes.len(), "{} states", r.model.n());
    // each entry fitted alone at the same order (its own poles: no physical model)
    let (mut entry_cost, mut entry_states) = (0.0, 0);
    for i in 0..3 {
        for j in 0..2 {
            let e = fast.frd.entry(i, j).unwrap();
            let opt = FitOptions {
                order: 8,
                rigid_body: 2,
                feedthrough: false,
                weighting: Weighting::Variance,
                ..Default::default()
            };
            let f = sd_ident::fit(&e, &opt).unwrap();
            entry_cost += f.cost;
            entry_states += f.model.n();
        }
    }
    println!(
        "per-entry fits (order 8 each): cost {entry_cost:.0}, {entry_states} states; common \
         poles: cost {:.0}, {} states",
        r.cost,
        r.model.n()
    );
    assert!(r.cost <= 1.05 * entry_cost && 4 * r.model.n() <= entry_states);
    assert!(mean_z2 < 2.0, "{mean_z2}");
}

/// The MIMO diagnosis on the multi-axis stage: a hold delay on actuator 2 only, at every rate
/// (5 kHz model set; 2.5 kHz and 1 kHz slower sets), is found on actuator 2 and nowhere else,
/// with a held-out gain; the same stage without it is consistent and nothing is named.
#[test]
fn mimo_diagnosis_names_the_delayed_actuator() {
    let truth = MultiAxisTruth::two_axis();
    for (delay, seed) in [([0.0, 0.3], 11u64), ([0.0, 0.0], 12)] {
        let mut exps: Vec<sd_ident::Experiment> = Vec::new();
        for (name, rate, period, f_max, s) in [
            ("fast", 5000.0, 5000, 2400.0, seed),
            ("mid", 2500.0, 2500, 1200.0, seed + 100),
            ("slow", 1000.0, 1000, 499.0, seed + 200),
        ] {
            let set = orthogonal_set(&truth, name, (rate, period, f_max), (&delay, 0.0), s);
            exps.extend(set.iter().map(AxisData::to_experiment));
        }
        let t0 = std::time::Instant::now();
        let d = sd_diagnose::diagnose_mimo(&exps, &Default::default(), &mut |_| {}).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let named: Vec<String> = d
            .channels
            .iter()
            .filter(|c| c.named)
            .map(|c| {
                format!(
                    "{:?} {} {:.4}±{:.1e}",
                    c.kind,
                    c.channel + 1,
                    c.fraction,
                    c.fraction_std
                )
            })
            .collect();
        println!(
            "delay {delay:?}: {} (order {}, {} states, fit cost {:.0} over {} entry lines), named \
             {named:?}, gain {:?}, entries {:?} ({secs:.1} s)",
            d.verdict,
            d.order,
            d.states,
            d.fit_cost,
            d.fit_lines,
            d.gain.as_ref().map(|g| (g.ratio, g.held_out)),
            d.entries
                .iter()
                .map(|e| format!(
                    "({},{}) {:.2}→{:.2}",
                    e.output + 1,
                    e.input + 1,
                    e.plain.value,
                    e.extended.value
                ))
                .collect::<Vec<_>>()
        );
        let act2 = d
            .channels
            .iter()
            .find(|c| c.kind == sd_diagnose::ChannelKind::Actuator && c.channel == 1)
            .unwrap();
        if delay[1] > 0.0 {
            assert_eq!(d.verdict, sd_diagnose::Verdict::Discrepancy);
            assert_eq!(named.len(), 1, "{named:?}");
            // the fine-step route switches on its sub-step grid: 0.3 of a period is
            // round(0.3·16)/16 = 0.3125 in the simulation
            assert!(
                act2.named && (act2.fraction - 0.3125).abs() < 0.005,
                "{act2:?}"
            );
            let g = d.gain.as_ref().unwrap();
            assert!(g.held_out && g.ratio >= 3.0, "{g:?}");
        } else {
            assert_eq!(d.verdict, sd_diagnose::Verdict::Consistent);
            assert!(named.is_empty(), "{named:?}");
        }
    }
}

/// The MIMO diagnosis with the 1 kHz set's sample clock 0.2 % slow (its experiments' true
/// period 1.002 ms; the 5 kHz model set and the 2.5 kHz set on time): the clock of that set is
/// named, nothing else, and the gain is held out (the clock fitted on the set's earlier
/// periods, the set judged on its later ones; only that set is judged, nothing named acts on
/// the others).
#[test]
fn mimo_diagnosis_names_a_slow_sets_clock() {
    let truth = MultiAxisTruth::two_axis();
    let mut exps: Vec<sd_ident::Experiment> = Vec::new();
    for (name, rate, period, f_max, clock, s) in [
        ("fast", 5000.0, 5000, 2400.0, 0.0, 31),
        ("mid", 2500.0, 2500, 1200.0, 0.0, 131),
        ("slow", 1000.0, 1000, 499.0, 0.002, 231),
    ] {
        let set = orthogonal_set(&truth, name, (rate, period, f_max), (&[0.0, 0.0], clock), s);
        exps.extend(set.iter().map(AxisData::to_experiment));
    }
    let t0 = std::time::Instant::now();
    let d = sd_diagnose::diagnose_mimo(&exps, &Default::default(), &mut |_| {}).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    let named: Vec<&sd_diagnose::ChannelFinding> = d.channels.iter().filter(|c| c.named).collect();
    println!(
        "clock 0.2 % slow on the 1 kHz set: {}, named {:?}, gain {:?} on {:?} ({secs:.1} s)",
        d.verdict,
        named
            .iter()
            .map(|c| format!(
                "{:?} {} {:+.5}±{:.1e}",
                c.kind,
                c.channel + 1,
                c.fraction,
                c.fraction_std
            ))
            .collect::<Vec<_>>(),
        d.gain.as_ref().map(|g| (g.ratio, g.held_out)),
        d.gain.as_ref().map(|g| g.measured_on.clone())
    );
    println!(
        "  entries (plain -> extended over the slower sets): {:?}",
        d.entries
            .iter()
            .map(|e| format!(
                "({},{}) {:.2}->{:.2}",
                e.output + 1,
                e.input + 1,
                e.plain.value,
                e.extended.value
            ))
            .collect::<Vec<_>>()
    );
    assert_eq!(d.verdict, sd_diagnose::Verdict::Discrepancy);
    assert_eq!(named.len(), 1, "{named:?}");
    let c = named[0];
    assert_eq!((c.kind, c.channel), (sd_diagnose::ChannelKind::Clock, 1));
    assert!((c.fraction - 0.002).abs() < 1e-4, "{c:?}");
    // the extension reaches the noise on every entry (the plain model is at about twice it:
    // a 0.2 % clock error moves the 1 kHz lines by 2 mHz per Hz), so the held-out gain is
    // about the plain model's excess
    assert!(
        d.entries.iter().all(|e| e.extended.value < 1.2),
        "{:?}",
        d.entries
    );
    let g = d.gain.as_ref().unwrap();
    assert!(g.held_out && g.ratio >= 2.0, "{g:?}");
}

/// A non-periodic closed-loop record of the multi-axis stage (independent white references on
/// both actuators, 8 s at 5 kHz, no transient removed): the MIMO LPM through the references
/// (`sd_ident::lpm_closed_loop_mimo`, what `frf_of_experiments` runs on such a record) against
/// the true 3×2 ZOH response, whitened by the estimate's covariance of vec(G): its mean is
/// near the 6 entries' (a consistent estimate with a consistent covariance).
#[test]
fn closed_loop_mimo_lpm_with_its_covariance() {
    let truth = MultiAxisTruth::two_axis();
    let (rate, n) = (5000.0, 40_000);
    let mut rng = sd_ident::rng::SplitMix::new(77);
    let excitation: Vec<Vec<f64>> = (0..2)
        .map(|_| (0..n).map(|_| rng.normal()).collect())
        .collect();
    let k = decentralised_pid(&truth, 20.0, Some(1000.0), 1.0 / rate).unwrap();
    let data = run_multiaxis(
        &truth,
        &AxisIdentification {
            name: "noise".into(),
            controller: k,
            excitation,
            periods: 1,
            transient_periods: 0,
            noise: Noise {
                force_rms: 0.02,
                sensor_rms: 1e-10,
                sensor_drift: 0.0,
                seed: 5,
            },
            nonideal: AxisNonIdealities::ideal(2, 3),
            role: Role::Model,
            fine_steps: 8,
        },
    )
    .unwrap();
    let mut e = data.to_experiment();
    e.spec.period_samples = None;
    let est = frf_of_experiments(&[&e], &Default::default()).unwrap();
    let pd = sd_model::c2d(
        &truth.linear_model().unwrap(),
        1.0 / rate,
        sd_model::Discretization::Zoh,
    )
    .unwrap();
    let f = est.frd.freq_hz();
    let g0 = pd.freqresp(f).unwrap();
    let (mut z, mut per_entry) = (Vec::new(), Vec::new());
    for (k, (g, t)) in est.frd.response().iter().zip(g0.response()).enumerate() {
        if !(5.0..=2000.0).contains(&f[k]) {
            continue;
        }
        let d = nalgebra::DVector::from_iterator(6, (g - t).iter().copied());
        let c = &est.covariance[k];
        let Some(ci) = c.clone().try_inverse() else {
            continue;
        };
        z.push((d.adjoint() * ci * &d)[(0, 0)].re);
        let v = &est.frd.variance().unwrap()[k];
        for (i, dd) in (g - t).iter().enumerate() {
            per_entry.push(dd.norm_sqr() / v.as_slice()[i]);
        }
    }
    let pe = per_entry.iter().sum::<f64>() / per_entry.len() as f64;
    z.sort_by(f64::total_cmp);
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    // the covariance is estimated with ν = ny + nu + 2 = 7 residual degrees of freedom per
    // window: eᴴĈ⁻¹e averages ny·nu·ν/(ν − ny) = 6·7/4 = 10.5 (a complex Hotelling T²)
    let expected = 6.0 * 7.0 / 4.0;
    println!(
        "closed-loop MIMO LPM, 3x2 over {} lines: whitened error mean {mean:.2} ({expected} \
         expected), median {:.2}; per-entry |ΔG|²/σ² mean {pe:.3} (7/6 expected)",
        z.len(),
        z[z.len() / 2]
    );
    assert!(z.len() > 10_000);
    assert!((mean / expected - 1.0).abs() < 0.15, "{mean}");
    assert!((pe / (7.0 / 6.0) - 1.0).abs() < 0.15, "{pe}");
}
