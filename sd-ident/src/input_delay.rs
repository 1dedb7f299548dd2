//! Whole-sample input delays of a MIMO FRD, leads (non-causal data) included.
//!
//! **Model.** `G(z) = H(z) · diag(z^{−δ_1}, …, z^{−δ_nu})` with `H` rational and causal and
//! `δ_j` an integer number of samples. `δ_j > 0` is a transport or computation delay;
//! `δ_j < 0` means the outputs respond *before* input `j` as recorded: the channels are
//! misaligned, or the recorded input was computed by a non-causal filter (data converted from
//! closed-loop experiments to "open-loop equivalent" records are an example). No causal
//! rational model reaches the noise on such data at any order; `H = G · diag(z^{δ_j})` can.
//! The common-pole fit ([`crate::fit_common_poles`]) fits `H` and reports `δ`; the model it
//! returns maps the shifted inputs, `y(t) = H(q) [u_1(t − δ_1), …]ᵀ`.
//!
//! **Estimate** ([`InputDelay::Estimate`]). Each input's column is fitted on its own (common
//! poles over the column's ny entries, free residues, the vector-fitting step only, at order
//! `min(order, 16)`) after the shift `z^{δ}` for every `δ` in `[−max, max]`. The least cost
//! `V(δ*)` replaces `δ = 0` only when `V(δ*) < V(0)·(1 − 5·√(2/M))`, with `M = 2·K·ny` the
//! column's real equations (`√(2/M)` is the relative standard deviation of a χ²_M cost, the
//! cost of a model that reaches the noise): a causal column keeps `δ = 0` unless a shift
//! explains it better by five of those standard deviations. Of the shifts whose cost is within
//! `V(δ*)·(1 + 5·√(2/M))` the one nearest 0 is taken: a fit with poles to spare absorbs the
//! last samples of a delay at z = 0, so the costs of a lead of 3 and of 5 samples are alike,
//! and 3 is the smallest shift that explains the data. The same holds for a positive delay:
//! where the order leaves poles for it, δ = 0 explains the column and is kept. The shift
//! multiplies the column by `e^{j2πfTδ}` and leaves its variances unchanged.

use crate::error::{IdentError, Result};
use num_complex::Complex64 as C;
use sd_model::Frd;
use std::f64::consts::PI;

/// Largest order of the column fits that estimate a delay.
pub const DELAY_SCAN_ORDER: usize = 16;

/// How a MIMO fit treats whole-sample input delays.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum InputDelay {
    /// No delays (default).
    #[default]
    None,
    /// These delays in samples, one per input (negative: the outputs lead the input).
    Fixed(Vec<i32>),
    /// Estimated per input in `[−max, max]` samples (module documentation).
    Estimate {
        /// Largest |δ| tried.
        max: usize,
    },
}

impl std::str::FromStr for InputDelay {
    type Err = String;

    /// `none`, `auto` (±8 samples), `auto:N`, or a comma-separated list of integers (one per
    /// input): the command line's and Python's spelling.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let s = s.trim();
        match s {
            "none" => return Ok(InputDelay::None),
            "auto" => return Ok(InputDelay::Estimate { max: 8 }),
            _ => {}
        }
        if let Some(n) = s.strip_prefix("auto:") {
            return match n.parse::<usize>() {
                Ok(max) if (1..=256).contains(&max) => Ok(InputDelay::Estimate { max }),
                _ => Err(format!(
                    "`auto:{n}`: the largest delay to try must be a whole number of samples in 1..=256"
                )),
            };
        }
        s.split(',')
            .map(|v| v.trim().parse::<i32>())
            .collect::<std::result::Result<Vec<_>, _>>()
            .map(InputDelay::Fixed)
            .map_err(|_| {
                format!(
                    "`{s}` is not an input delay: use none, auto, auto:N or one whole number of \
                     samples per input (e.g. -5,0)"
                )
            })
    }
}

/// The estimate of one input's delay: the cost of its column at every delay tried.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DelayScan {
    /// Input (0-based).
    pub input: usize,
    /// The delay chosen, samples.
    pub delay: i32,
    /// `(δ, V(δ))` for every δ tried.
    pub cost: Vec<(i32, f64)>,
    /// The cost a shift had to go below to replace δ = 0.
    pub threshold: f64,
}

/// `G · diag(z^{δ_j})`: the FRD with input `j`'s column advanced by `δ_j` samples (variances
/// unchanged).
///
/// # Errors
/// A continuous-time FRD, or a delay list whose length is not the number of inputs.
pub fn shift_inputs(frd: &Frd, delay: &[i32]) -> Result<Frd> {
    one_per_input(delay, frd.shape().1)?;
    let d: Vec<f64> = delay.iter().map(|&d| f64::from(d)).collect();
    advance_inputs(frd, &d)
}

/// `G · diag(e^{jωδ_jT})`: input `j`'s column advanced by `δ_j` samples, a fraction allowed
/// (the FRD of a model that maps `u_j(t − δ_j)` becomes that of the model alone; variances
/// unchanged).
///
/// # Errors
/// A continuous-time FRD, a delay list whose length is not the number of inputs, a delay that
/// is not finite.
pub fn advance_inputs(frd: &Frd, delay: &[f64]) -> Result<Frd> {
    let ts = crate::fit::discrete_ts(frd)?;
    one_per_input(delay, frd.shape().1)?;
    if let Some(d) = delay.iter().find(|d| !d.is_finite()) {
        return Err(IdentError::InvalidArgument(format!(
            "an input delay of {d} samples: give a finite number"
        )));
    }
    let resp = frd
        .freq_hz()
        .iter()
        .zip(frd.response())
        .map(|(&f, g)| {
            let mut g = g.clone();
            for (j, &d) in delay.iter().enumerate() {
                let w = C::from_polar(1.0, 2.0 * PI * f * ts * d);
                g.column_mut(j).iter_mut().for_each(|v| *v *= w);
            }
            g
        })
        .collect();
    Ok(Frd::new(
        frd.freq_hz().to_vec(),
        resp,
        frd.variance().map(|v| v.to_vec()),
        frd.time(),
    )?)
}

/// A delay list must give one delay per input.
fn one_per_input<T>(delay: &[T], nu: usize) -> Result<()> {
    if delay.len() == nu {
        return Ok(());
    }
    Err(IdentError::InvalidArgument(format!(
        "{} input delays given for {nu} inputs: give one per input",
        delay.len()
    )))
}

/// The delays `opt` asks for, with the scans when they are estimated.
pub(crate) fn resolve(
    frd: &Frd,
    opt: &crate::MimoFitOptions,
) -> Result<(Vec<i32>, Vec<DelayScan>)> {
    let nu = frd.shape().1;
    match &opt.input_delay {
        InputDelay::None => Ok((vec![0; nu], Vec::new())),
        InputDelay::Fixed(d) => {
            one_per_input(d, nu)?;
            Ok((d.clone(), Vec::new()))
        }
        InputDelay::Estimate { max } => {
            // the scan's column fits derive their order from these settings
            crate::fit::check_options(&opt.fit)?;
            let scans = (0..nu)
                .map(|j| scan(frd, opt, j, *max))
                .collect::<Result<Vec<_>>>()?;
            Ok((scans.iter().map(|s| s.delay).collect(), scans))
        }
    }
}

/// One input's scan (module documentation).
fn scan(frd: &Frd, opt: &crate::MimoFitOptions, j: usize, max: usize) -> Result<DelayScan> {
    let col = frd.column(j)?;
    let ny = col.shape().0;
    let max = i32::try_from(max).map_err(|_| {
        IdentError::InvalidArgument(format!("input delay range {max} is too large"))
    })?;
    let sub = crate::MimoFitOptions {
        fit: crate::FitOptions {
            order: opt
                .fit
                .order
                .min(DELAY_SCAN_ORDER)
                .max(opt.fit.rigid_body + 1),
            lm_iterations: 0,
            ..opt.fit.clone()
        },
        rank: crate::ResidueRank::Full,
        input_delay: InputDelay::None,
        ..opt.clone()
    };
    let mut cost = Vec::with_capacity(2 * max as usize + 1);
    for d in -max..=max {
        let r = crate::fit_common_poles(&shift_inputs(&col, &[d])?, &sub)?;
        cost.push((d, r.full_rank_cost));
    }
    let at_zero = cost
        .iter()
        .find(|(d, _)| *d == 0)
        .map_or(f64::INFINITY, |c| c.1);
    // five relative standard deviations of a χ² cost with the column's M real equations
    let five_sd = 5.0 * (2.0 / (2 * frd.len() * ny) as f64).sqrt();
    let threshold = at_zero * (1.0 - five_sd);
    let best = cost.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    // the shift nearest 0 that explains the column as well as the best, within the band
    let band = best * (1.0 + five_sd);
    let delay = cost
        .iter()
        .filter(|(_, v)| *v <= band && *v < threshold)
        .min_by(|a, b| a.0.abs().cmp(&b.0.abs()).then(a.1.total_cmp(&b.1)))
        .map_or(0, |c| c.0);
    Ok(DelayScan {
        input: j,
        delay,
        cost,
        threshold,
    })
}
