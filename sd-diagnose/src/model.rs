//! Stage 2, the model: given (checked, ZOH-discretised if continuous) or fitted to the model
//! experiment's FRF (SK over the orders, Akaike's FPE, Levenberg–Marquardt on the chosen order;
//! rigid-body poles from the low-frequency slope).

use crate::{DiagnoseError, DiagnoseOptions, Result};
use sd_ident::{FitOptions, Weighting};
use sd_model::{Frd, SampleTime, StateSpace};

/// Rigid-body poles suggested by the low-frequency slope of |G| (−2: two, −1: one), over the
/// lowest octave pair of lines measured well (|G| above 3σ: a stiff loop leaves the lowest
/// lines in the noise).
fn rigid_body_count(frd: &Frd) -> usize {
    let f = frd.freq_hz();
    let good = |i: usize| {
        let g = frd.response()[i][(0, 0)].norm();
        let v = frd.variance().map(|v| v[i][(0, 0)]).unwrap_or(0.0);
        f[i] > 0.0 && g > 0.0 && g * g > 9.0 * v
    };
    let Some(f0) = (0..f.len()).find(|&i| good(i)).map(|i| f[i]) else {
        return 0;
    };
    let pts: Vec<(f64, f64)> = (0..f.len())
        .filter(|&i| f[i] <= 4.0 * f0 && good(i))
        .map(|i| (f[i].ln(), frd.response()[i][(0, 0)].norm().ln()))
        .collect();
    if pts.len() < 3 {
        return 0;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx.max(f64::MIN_POSITIVE);
    if slope < -1.5 {
        2
    } else if slope < -0.5 {
        1
    } else {
        0
    }
}

/// The model at the fast period: given (checked, ZOH-discretised if continuous) or fitted.
pub(crate) fn model_for(
    fast: &Frd,
    h: f64,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String)> {
    if let Some(m) = &opt.model {
        if m.nu() != 1 || m.ny() != 1 {
            return Err(DiagnoseError::Setup(format!(
                "the given model has {} inputs and {} outputs; the diagnosis needs a SISO model",
                m.nu(),
                m.ny()
            )));
        }
        let m = match m.time() {
            SampleTime::Continuous => sd_model::c2d(m, h, sd_model::Discretization::Zoh)?,
            SampleTime::Discrete { ts } if (ts - h).abs() <= 1e-9 * h => m.clone(),
            SampleTime::Discrete { ts } => {
                return Err(DiagnoseError::Setup(format!(
                    "the given model samples at {ts} s but the model experiment at {h} s: give \
                     it at the model experiment's rate, or as a continuous model"
                )))
            }
        };
        return Ok((m, "given".into()));
    }
    let rigid = rigid_body_count(fast);
    let base = FitOptions {
        rigid_body: rigid,
        feedthrough: true,
        weighting: Weighting::Variance,
        lm_iterations: 0,
        ..Default::default()
    };
    let mut best: Option<(f64, usize, StateSpace, f64)> = None;
    for order in rigid + 1..=opt.max_order.max(rigid + 1) {
        if let Some(b) = &best {
            // FPE has not improved for 4 orders: stop
            if order > b.1 + 4 {
                break;
            }
        }
        progress(&format!("fitting order {order}"));
        let opt_n = FitOptions {
            order,
            ..base.clone()
        };
        let Ok(r) = sd_ident::fit(fast, &opt_n) else {
            continue;
        };
        let fpe = sd_ident::final_prediction_error(r.cost, &opt_n, fast.len());
        if !fpe.is_finite() {
            continue;
        }
        if best.as_ref().map(|b| fpe < b.0).unwrap_or(true) {
            best = Some((fpe, order, r.model, r.cost));
        }
    }
    // the scan uses SK only; the chosen order is refined by Levenberg–Marquardt
    if let Some(b) = &mut best {
        progress(&format!("refining order {}", b.1));
        if let Ok(r) = sd_ident::fit(
            fast,
            &FitOptions {
                order: b.1,
                lm_iterations: FitOptions::default().lm_iterations,
                ..base.clone()
            },
        ) {
            if r.cost <= b.3 {
                b.2 = r.model;
            }
        }
    }
    match best {
        Some((_, order, m, _)) => Ok((
            m,
            format!(
                "fitted to the model experiment (order {order} by FPE, {rigid} rigid-body poles)"
            ),
        )),
        None => Err(DiagnoseError::Setup(
            "no model order could be fitted to the model experiment's FRF".into(),
        )),
    }
}
