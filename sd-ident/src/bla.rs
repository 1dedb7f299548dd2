//! The best linear approximation (BLA) of an experiment with its **total** variance: the
//! noise, and the stochastic nonlinear distortion wherever the excitation lets it be measured
//! (Pintelon & Schoukens, *System Identification*, 2nd ed., §3.4–3.5; Schoukens, Pintelon &
//! Rolain, *Mastering System Identification in 100 Exercises*, 2012, ch. 4).
//!
//! A periodic excitation of one phase realisation gives, at an excited line k,
//! `Ĝ(k) = G_BLA(k) + G_S(k) + N_G(k)`: the stochastic nonlinear contribution `G_S` repeats
//! from period to period, so the spread over periods (the noise variance `σ²_N` of
//! [`crate::frf_periodic`]) does not contain it. A linear model, or the same experiment with
//! another phase realisation, can only be expected to agree within `σ²_N + σ²_S`. This module
//! measures `σ²_S` where the data allow it:
//!
//! - **detection lines** ([`Distortion::DetectionLines`]): an odd (or odd-odd, random-odd)
//!   multisine leaves odd lines unexcited. Odd-degree nonlinearities put power there as on the
//!   excited lines; per excited line `σ²_S(k) = mean_j(|Ȳ_j|² − σ²_Ȳj)/|Ū_k|²` over the
//!   [`crate::NL_NEIGHBOURS`] nearest odd detection lines (`FrfEstimate::nl_variance`). It counts
//!   only where those lines' level is significant: their ratio to the noise above the
//!   `1 − α` quantile of `Gamma(K, 1)/K` ([`DISTORTION_ALPHA`] = 1 %), since the clamped level of
//!   a linear system would otherwise add about a third of the noise everywhere;
//! - **realisations** ([`Distortion::Realizations`], the *robust method*): R ≥ 2 experiments
//!   with the same lines and level and other phases give `Ĝ_BLA = mean_r Ĝ_r`, its total
//!   variance `Σ_r |Ĝ_r − Ĝ_BLA|²/(R(R − 1))` and its noise variance `mean_r σ²_N,r / R`; the
//!   distortion is their difference (clamped at 0);
//! - **roughness** ([`Distortion::Roughness`]): a full multisine (every line excited, no odd
//!   line left out) of one random-phase realisation and two steady periods or more: the
//!   residual of a local rational model over neighbouring excited lines holds noise and
//!   distortion, the periods' spread the noise alone ([`crate::roughness`]: Pintelon,
//!   Louarroudi & Lataire, I2MTC 2012); gated at [`DISTORTION_ALPHA`] by the F law of the
//!   ratio of the two estimates ([`crate::roughness::roughness_gate`]);
//! - **carried** ([`Distortion::Carried`]): an experiment that cannot measure it itself (one
//!   steady period, too few lines for either method), or whose measure is the roughness (a
//!   direct measure is preferred: the roughness assumes random phases — a Schroeder
//!   multisine's are not — and a locally rational BLA); a sibling experiment on the same channel, in the same band
//!   and at the same rms (within [`CARRY_RMS_TOLERANCE`]) that did measure it supplies the
//!   distortion's *output* power per line `P_S(f) = σ²_S·|Ū|²`, interpolated in frequency and
//!   divided by this experiment's `|Ū_k|²`. At one rms and band the distortion's output power
//!   spectrum is, to first order, a property of the system and the input's power, not of its
//!   phases or of which lines carry it (op. cit. §3.5: the BLA and the distortion of Gaussian-like
//!   excitations depend on the power spectrum only);
//! - **in the LPM's residual** ([`Distortion::InLpmResidual`]): on non-periodic data the
//!   distortion is not periodic either, so the local polynomial method's residual variance
//!   already holds noise and distortion together (they cannot be told apart);
//! - otherwise [`Distortion::NotMeasurable`], with the reason: the variance is then the noise
//!   alone and every statement that rests on it must say so.

use crate::{FrfEstimate, IdentError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::Frd;

/// False-alarm probability of the per-line distortion gate (detection lines).
pub const DISTORTION_ALPHA: f64 = 0.01;
/// Largest relative difference of two experiments' excitation rms for one to lend the other
/// its distortion level ([`Distortion::Carried`]).
pub const CARRY_RMS_TOLERANCE: f64 = 0.2;
/// Most bands a [`Bla`]'s summary is split into (each with at least 8 lines).
const MAX_BANDS: usize = 6;

/// Why the distortion of an experiment cannot be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Unmeasurable {
    /// Every line in the band is excited, there is one phase realisation, and too few lines
    /// (fewer than [`crate::ROUGHNESS_WINDOW`]) or a response that vanishes over a window
    /// leave the roughness unmeasured.
    EveryLineExcited,
    /// Too few odd non-excited lines in the band (fewer than [`crate::NL_NEIGHBOURS`]).
    TooFewDetectionLines,
    /// One steady period: no noise level to tell the detection lines' power from.
    OnePeriod,
}

impl std::fmt::Display for Unmeasurable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Unmeasurable::EveryLineExcited => {
                "every line excited, one realisation, too few lines for the roughness"
            }
            Unmeasurable::TooFewDetectionLines => "too few non-excited odd lines in the band",
            Unmeasurable::OnePeriod => "one steady period",
        })
    }
}

/// How the stochastic nonlinear distortion of a [`Bla`] was measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum Distortion {
    /// From the odd detection lines of an odd or odd-odd multisine.
    DetectionLines {
        /// Odd non-excited lines in the band.
        detection_lines: usize,
        /// Excited lines where the local level passed the gate (the distortion counted there).
        significant_lines: usize,
    },
    /// From the spread of several phase realisations at one level (the robust method).
    Realizations {
        /// Number of realisations.
        count: usize,
    },
    /// From another experiment of the same channel, band and rms.
    Carried {
        /// That experiment's name.
        from: String,
    },
    /// From the roughness of the FRF over neighbouring excited lines (every line excited, one
    /// random-phase realisation: [`crate::roughness`]).
    Roughness {
        /// Excited lines in the band.
        lines: usize,
        /// Lines where the local level passed the gate (the distortion counted there).
        significant_lines: usize,
    },
    /// Non-periodic data: noise and distortion together in the LPM's residual.
    InLpmResidual,
    /// Not measurable with this excitation.
    NotMeasurable {
        /// Why.
        reason: Unmeasurable,
    },
}

impl Distortion {
    /// Whether the variance of the [`Bla`] includes the distortion.
    pub fn measured(&self) -> bool {
        !matches!(self, Distortion::NotMeasurable { .. })
    }

    /// Whether it was measured directly — on non-excited lines or over realisations — with no
    /// assumption on the BLA's shape or on the phases (the roughness assumes both).
    pub fn direct(&self) -> bool {
        matches!(
            self,
            Distortion::DetectionLines { .. } | Distortion::Realizations { .. }
        )
    }

    /// Whether this experiment's own measure can lend its level to a sibling: direct or by
    /// roughness ([`Bla::carried_from`]).
    pub fn lends(&self) -> bool {
        self.direct() || matches!(self, Distortion::Roughness { .. })
    }

    /// Whether some sibling's level could replace this one: not measured, or by roughness.
    pub fn replaceable(&self) -> bool {
        matches!(
            self,
            Distortion::NotMeasurable { .. } | Distortion::Roughness { .. }
        )
    }

    /// Whether a sibling's distortion `source` replaces this one ([`Bla::carried_from`]):
    /// this one is not measured and the source [`lends`](Distortion::lends), or this one is a
    /// roughness and the source direct.
    pub fn replaced_by(&self, source: &Distortion) -> bool {
        match self {
            Distortion::NotMeasurable { .. } => source.lends(),
            Distortion::Roughness { .. } => source.direct(),
            _ => false,
        }
    }
}

impl std::fmt::Display for Distortion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Distortion::DetectionLines {
                detection_lines,
                significant_lines,
            } => write!(
                f,
                "measured at {detection_lines} detection lines (significant at \
                 {significant_lines} excited lines)"
            ),
            Distortion::Realizations { count } => {
                write!(f, "measured from the spread of {count} realisations")
            }
            Distortion::Carried { from } => {
                write!(f, "carried from `{from}` (same channel, band and rms)")
            }
            Distortion::Roughness {
                lines,
                significant_lines,
            } => write!(
                f,
                "measured from the FRF's roughness over neighbouring excited lines (every line \
                 excited, one realisation: significant at {significant_lines} of {lines} lines)"
            ),
            Distortion::InLpmResidual => f.write_str(
                "in the LPM residual (non-periodic data: noise and distortion together)",
            ),
            Distortion::NotMeasurable { reason } => {
                write!(f, "distortion not measurable: {reason}")
            }
        }
    }
}

/// Noise and distortion over one band, as standard deviations relative to `|Ĝ|` (medians over
/// the band's lines).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BandLevel {
    /// Lowest line (Hz).
    pub f_lo: f64,
    /// Highest line (Hz).
    pub f_hi: f64,
    /// Lines in the band.
    pub lines: usize,
    /// Median `σ_N/|Ĝ|`.
    pub noise_rel: f64,
    /// Median `σ_S/|Ĝ|` (`None` where the distortion is not measured separately).
    pub distortion_rel: Option<f64>,
}

/// A best linear approximation with its total variance (module documentation).
#[derive(Debug, Clone)]
pub struct Bla {
    /// The estimate; its variance is the total (noise + distortion) where both are known.
    pub frd: Frd,
    /// Noise variance per line (FRF units).
    pub noise_var: Vec<f64>,
    /// Distortion variance per line counted in the total (0 where not significant or not
    /// measured separately).
    pub distortion_var: Vec<f64>,
    /// The local distortion level per line before the significance gate (0 where none).
    pub distortion_level: Vec<f64>,
    /// `|Ū_k|²` per line (to carry the distortion's output power to another experiment).
    pub input_power: Vec<f64>,
    /// How the distortion was measured.
    pub distortion: Distortion,
}

impl Bla {
    /// The BLA of one periodic estimate: the distortion from its detection lines where it has
    /// them (module documentation), else not measurable.
    ///
    /// # Errors
    /// An estimate without variance (one period without noise bins).
    pub fn from_periodic(est: &FrfEstimate) -> Result<Bla> {
        let noise_var = siso_var(&est.frd)?;
        let input_power: Vec<f64> = est.u_mean.iter().map(|u| u.norm_sqr()).collect();
        let n = noise_var.len();
        let gated = |nl: &[(f64, f64)], gate: f64| -> (Vec<f64>, Vec<f64>, usize) {
            let level: Vec<f64> = nl.iter().map(|x| x.0).collect();
            let var: Vec<f64> = nl
                .iter()
                .map(|&(d, ratio)| if ratio > gate { d } else { 0.0 })
                .collect();
            let significant = var.iter().filter(|v| **v > 0.0).count();
            (level, var, significant)
        };
        // every line excited: the roughness over neighbouring lines
        let rough = match est.frd.siso(0, 0) {
            Ok(g) if est.periods >= 2 && detection_lines(&est.lines) == 0 => {
                crate::roughness::roughness_variance(&est.lines, &g, &noise_var)
            }
            _ => None,
        };
        let (distortion_level, distortion_var, distortion) = match (&est.nl_variance, rough) {
            (Some(nl), _) if est.periods >= 2 => {
                let (level, var, significant) = gated(nl, detection_gate());
                let detection = detection_lines(&est.lines);
                (
                    level,
                    var,
                    Distortion::DetectionLines {
                        detection_lines: detection,
                        significant_lines: significant,
                    },
                )
            }
            (_, Some(nl)) => {
                let gate = crate::roughness::roughness_gate(est.periods);
                let (level, var, significant) = gated(&nl, gate);
                (
                    level,
                    var,
                    Distortion::Roughness {
                        lines: n,
                        significant_lines: significant,
                    },
                )
            }
            _ => {
                let reason = if est.periods < 2 {
                    Unmeasurable::OnePeriod
                } else if detection_lines(&est.lines) == 0 {
                    Unmeasurable::EveryLineExcited
                } else {
                    Unmeasurable::TooFewDetectionLines
                };
                (
                    vec![0.0; n],
                    vec![0.0; n],
                    Distortion::NotMeasurable { reason },
                )
            }
        };
        let frd = with_total(&est.frd, &noise_var, &distortion_var)?;
        Ok(Bla {
            frd,
            noise_var,
            distortion_var,
            distortion_level,
            input_power,
            distortion,
        })
    }

    /// The BLA of a non-periodic estimate (LPM): its variance holds noise and distortion.
    ///
    /// # Errors
    /// An FRD without variance or not SISO.
    pub fn from_lpm(frd: &Frd) -> Result<Bla> {
        let noise_var = siso_var(frd)?;
        let n = noise_var.len();
        Ok(Bla {
            frd: frd.clone(),
            noise_var,
            distortion_var: vec![0.0; n],
            distortion_level: vec![0.0; n],
            input_power: vec![f64::NAN; n],
            distortion: Distortion::InLpmResidual,
        })
    }

    /// The robust method over R ≥ 2 realisations with the same excited lines (module
    /// documentation).
    ///
    /// # Errors
    /// Fewer than two estimates, estimates on other lines, without variance or not SISO.
    pub fn from_realizations(ests: &[&FrfEstimate]) -> Result<Bla> {
        let first = match ests {
            [first, _, ..] => first,
            _ => {
                return Err(IdentError::InvalidArgument(
                    "the robust method needs two realisations or more".into(),
                ))
            }
        };
        if let Some(e) = ests.iter().find(|e| e.lines != first.lines) {
            return Err(IdentError::Data(format!(
                "realisations must excite the same lines: {} lines against {}",
                e.lines.len(),
                first.lines.len()
            )));
        }
        let rf = ests.len() as f64;
        let n = first.lines.len();
        let g: Vec<Vec<C>> = ests
            .iter()
            .map(|e| e.frd.siso(0, 0).map_err(IdentError::from))
            .collect::<Result<_>>()?;
        let nv: Vec<Vec<f64>> = ests
            .iter()
            .map(|e| siso_var(&e.frd))
            .collect::<Result<_>>()?;
        let mut resp = Vec::with_capacity(n);
        let (mut noise_var, mut dist, mut power) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut total = vec![0.0; n];
        for k in 0..n {
            let mean = g.iter().map(|gr| gr[k]).sum::<C>() / rf;
            let spread = g.iter().map(|gr| (gr[k] - mean).norm_sqr()).sum::<f64>();
            total[k] = spread / (rf * (rf - 1.0));
            noise_var[k] = nv.iter().map(|v| v[k]).sum::<f64>() / (rf * rf);
            dist[k] = (total[k] - noise_var[k]).max(0.0);
            power[k] = ests.iter().map(|e| e.u_mean[k].norm_sqr()).sum::<f64>() / rf;
            resp.push(DMatrix::from_element(1, 1, mean));
        }
        let frd = Frd::new(first.frd.freq_hz().to_vec(), resp, None, first.frd.time())?;
        let frd = with_total(&frd, &noise_var, &dist)?;
        Ok(Bla {
            frd,
            noise_var,
            distortion_level: dist.clone(),
            distortion_var: dist,
            input_power: power,
            distortion: Distortion::Realizations { count: ests.len() },
        })
    }

    /// Output power of the distortion per line, `σ²_S·|Ū|²` (0 where none).
    pub fn distortion_output_power(&self) -> Vec<f64> {
        self.distortion_level
            .iter()
            .zip(&self.input_power)
            .map(|(d, p)| if p.is_finite() { d * p } else { 0.0 })
            .collect()
    }

    /// This BLA with the distortion of `source` (named `name`) carried over where
    /// [`Distortion::replaced_by`] allows it (module documentation): the source's output-level
    /// distortion interpolated linearly in frequency, over this experiment's `|Ū|²`, at this
    /// experiment's lines inside the source's band. `self` unchanged (returned as is)
    /// otherwise.
    ///
    /// # Errors
    /// Shapes or sample times that do not match.
    pub fn carried_from(&self, source: &Bla, name: &str) -> Result<Bla> {
        if !self.distortion.replaced_by(&source.distortion) || source.frd.time() != self.frd.time()
        {
            return Ok(self.clone());
        }
        let fs = source.frd.freq_hz();
        let ps = source.distortion_output_power();
        let sig = source.significant_output_power();
        // an output power per source line, interpolated here and over this |Ū|²
        let carry = |power: &[f64]| -> Vec<f64> {
            self.frd
                .freq_hz()
                .iter()
                .zip(&self.input_power)
                .map(|(&f, &p)| {
                    interpolate(fs, power, f).map_or(0.0, |v| v / p.max(f64::MIN_POSITIVE))
                })
                .collect()
        };
        let (level, var) = (carry(&ps), carry(&sig));
        Ok(Bla {
            frd: with_total(&self.frd, &self.noise_var, &var)?,
            noise_var: self.noise_var.clone(),
            distortion_var: var,
            distortion_level: level,
            input_power: self.input_power.clone(),
            distortion: Distortion::Carried {
                from: name.to_string(),
            },
        })
    }

    /// The distortion output power where it passed the gate (0 elsewhere).
    fn significant_output_power(&self) -> Vec<f64> {
        self.distortion_var
            .iter()
            .zip(&self.input_power)
            .map(|(d, p)| if p.is_finite() { d * p } else { 0.0 })
            .collect()
    }

    /// Keeps the lines where `keep(i)` (e.g. the trusted ones).
    ///
    /// # Errors
    /// No line kept.
    pub fn select(&self, keep: impl Fn(usize) -> bool) -> Result<Bla> {
        let pick = |v: &[f64]| -> Vec<f64> {
            v.iter()
                .enumerate()
                .filter(|(i, _)| keep(*i))
                .map(|(_, x)| *x)
                .collect()
        };
        Ok(Bla {
            frd: self.frd.select(&keep)?,
            noise_var: pick(&self.noise_var),
            distortion_var: pick(&self.distortion_var),
            distortion_level: pick(&self.distortion_level),
            input_power: pick(&self.input_power),
            distortion: self.distortion.clone(),
        })
    }

    /// Noise and distortion per band: at most six bands of equal line counts (at least 8 lines
    /// each), medians of `σ/|Ĝ|`.
    pub fn bands(&self) -> Vec<BandLevel> {
        let n = self.noise_var.len();
        let nb = (n / 8).clamp(1, MAX_BANDS);
        let g = self.frd.response();
        let f = self.frd.freq_hz();
        let separate = !matches!(
            self.distortion,
            Distortion::InLpmResidual | Distortion::NotMeasurable { .. }
        );
        (0..nb)
            .filter_map(|b| {
                let (lo, hi) = (b * n / nb, (b + 1) * n / nb);
                (hi > lo).then(|| {
                    let rel = |v: &[f64]| {
                        let r: Vec<f64> = (lo..hi)
                            .map(|i| v[i].sqrt() / g[i][(0, 0)].norm().max(f64::MIN_POSITIVE))
                            .collect();
                        sd_model::median(&r)
                    };
                    BandLevel {
                        f_lo: f[lo],
                        f_hi: f[hi - 1],
                        lines: hi - lo,
                        noise_rel: rel(&self.noise_var),
                        distortion_rel: separate.then(|| rel(&self.distortion_level)),
                    }
                })
            })
            .collect()
    }
}

/// The gate on the detection lines' local ratio: the `1 − DISTORTION_ALPHA` quantile of
/// `Gamma(K, 1)/K` = `χ²_2K/(2K)`, K = [`crate::NL_NEIGHBOURS`].
pub fn detection_gate() -> f64 {
    let nu = 2.0 * crate::NL_NEIGHBOURS as f64;
    sd_model::chi2_quantile(1.0 - DISTORTION_ALPHA, nu) / nu
}

/// Odd non-excited lines between the first and the last excited one.
fn detection_lines(lines: &[usize]) -> usize {
    match (lines.first(), lines.last()) {
        (Some(&a), Some(&b)) => (a..=b)
            .filter(|k| k % 2 == 1 && lines.binary_search(k).is_err())
            .count(),
        _ => 0,
    }
}

/// The (1, 1) variance of a SISO FRD per line.
fn siso_var(frd: &Frd) -> Result<Vec<f64>> {
    if frd.shape() != (1, 1) {
        return Err(IdentError::InvalidArgument(format!(
            "the BLA is SISO; this FRD is {}x{}",
            frd.shape().0,
            frd.shape().1
        )));
    }
    frd.variance()
        .map(|v| v.iter().map(|m| m[(0, 0)]).collect())
        .ok_or_else(|| {
            IdentError::Data(
                "the estimate has no variance (two steady periods or more, or non-excited \
                 bins, are needed)"
                    .into(),
            )
        })
}

/// `frd` with the variance `noise + distortion`.
fn with_total(frd: &Frd, noise: &[f64], dist: &[f64]) -> Result<Frd> {
    let var = noise
        .iter()
        .zip(dist)
        .map(|(n, d)| DMatrix::from_element(1, 1, n + d))
        .collect();
    Ok(Frd::new(
        frd.freq_hz().to_vec(),
        frd.response().to_vec(),
        Some(var),
        frd.time(),
    )?)
}

/// Linear interpolation of `v` over the ascending `f` at `x`; `None` outside `[f₀, f_last]`.
fn interpolate(f: &[f64], v: &[f64], x: f64) -> Option<f64> {
    let (&lo, &hi) = (f.first()?, f.last()?);
    if x < lo || x > hi {
        return None;
    }
    let i = f.partition_point(|&fi| fi < x);
    if i < f.len() && f[i] == x {
        return Some(v[i]);
    }
    let (a, b) = (i.checked_sub(1)?, i.min(f.len() - 1));
    let t = if f[b] > f[a] {
        (x - f[a]) / (f[b] - f[a])
    } else {
        0.0
    };
    Some(v[a] + t * (v[b] - v[a]))
}

/// Whether two excitation rms values are alike enough to carry a distortion level
/// ([`CARRY_RMS_TOLERANCE`]).
pub fn same_level(a: f64, b: f64) -> bool {
    a > 0.0 && b > 0.0 && (a - b).abs() <= CARRY_RMS_TOLERANCE * a.max(b)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use crate::{frf_periodic, PeriodicOptions};

    /// Sum of sines at `lines` of a period of `p` samples, the phases from a seeded LCG.
    fn multisine(lines: &[usize], p: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        let phases: Vec<f64> = lines
            .iter()
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU
            })
            .collect();
        (0..p)
            .map(|t| {
                lines
                    .iter()
                    .zip(&phases)
                    .map(|(&k, ph)| (std::f64::consts::TAU * (k * t) as f64 / p as f64 + ph).cos())
                    .sum()
            })
            .collect()
    }

    /// y = h * u + a·(h * u)³ (a static cubic after an FIR), periodic: repeated periods.
    fn record(u1: &[f64], periods: usize, a: f64) -> (Vec<f64>, Vec<f64>) {
        let p = u1.len();
        let h = [0.5, 0.3, 0.15];
        let x: Vec<f64> = (0..p)
            .map(|t| {
                h.iter()
                    .enumerate()
                    .map(|(i, hi)| hi * u1[(t + p - i) % p])
                    .sum()
            })
            .collect();
        let y1: Vec<f64> = x.iter().map(|v| v + a * v * v * v).collect();
        let rep = |v: &[f64]| {
            v.iter()
                .cycle()
                .take(p * periods)
                .cloned()
                .collect::<Vec<_>>()
        };
        (rep(u1), rep(&y1))
    }

    /// Deterministic small noise (so that the noise level is finite).
    fn add_noise(y: &mut [f64], sd: f64, seed: u64) {
        let mut s = seed;
        for v in y.iter_mut() {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u1 = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u2 = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            *v += sd * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        }
    }

    #[test]
    fn full_multisine_by_roughness_odd_odd_by_detection_lines() {
        let p = 512;
        let full: Vec<usize> = (1..100).collect();
        let (u, mut y) = record(&multisine(&full, p, 1), 6, 0.05);
        add_noise(&mut y, 1e-3, 7);
        let est = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 1)).unwrap();
        let b = Bla::from_periodic(&est).unwrap();
        match &b.distortion {
            Distortion::Roughness {
                lines,
                significant_lines,
            } => assert!(
                *lines == 99 && *significant_lines > 50,
                "{:?}",
                b.distortion
            ),
            d => panic!("{d:?}"),
        }
        // one period: no noise level, nothing measurable
        let one = PeriodicOptions::new(p, 5);
        let est = frf_periodic(1000.0, None, &u, &y, &one).unwrap();
        assert_eq!(
            Bla::from_periodic(&est).map(|b| b.distortion).ok(),
            Some(Distortion::NotMeasurable {
                reason: Unmeasurable::OnePeriod
            })
        );
        let oo: Vec<usize> = (0..25).map(|i| 4 * i + 1).collect();
        let (u, mut y) = record(&multisine(&oo, p, 2), 6, 0.05);
        add_noise(&mut y, 1e-3, 8);
        let est = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 1)).unwrap();
        let b = Bla::from_periodic(&est).unwrap();
        match &b.distortion {
            Distortion::DetectionLines {
                significant_lines, ..
            } => assert!(*significant_lines > 20, "{:?}", b.distortion),
            d => panic!("{d:?}"),
        }
        // the total variance exceeds the noise by the distortion
        let v = b.frd.variance().unwrap();
        assert!(v.iter().zip(&b.noise_var).all(|(t, n)| t[(0, 0)] >= *n));
    }

    /// The robust method's BLA of a cubic system over realisations agrees with the detection
    /// lines' level within a factor that the number of realisations allows; realisations
    /// of a linear system give a distortion at the noise's level.
    #[test]
    fn realizations_measure_the_distortion_detection_lines_see() {
        let p = 512;
        // random odd: odd lines, one of each group of four left out (at random)
        let mut s = 99u64;
        let oo: Vec<usize> = (0..12)
            .flat_map(|g| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let skip = (s >> 33) as usize % 4;
                (0..4)
                    .filter(move |i| *i != skip)
                    .map(move |i| 8 * g + 2 * i + 1)
            })
            .collect();
        let ests: Vec<FrfEstimate> = (0..8)
            .map(|r| {
                let (u, mut y) = record(&multisine(&oo, p, 10 + r), 4, 0.05);
                add_noise(&mut y, 1e-4, 20 + r);
                frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 1)).unwrap()
            })
            .collect();
        let refs: Vec<&FrfEstimate> = ests.iter().collect();
        let robust = Bla::from_realizations(&refs).unwrap();
        let det = Bla::from_periodic(&ests[0]).unwrap();
        // the spread of 8 realisations' mean is var_S/8 per line: compare the band medians
        let med = |v: &[f64]| sd_model::median(v);
        let ratio = med(&robust.distortion_var) * 8.0 / med(&det.distortion_level);
        eprintln!("robust/detection {ratio}");
        assert!((0.4..2.5).contains(&ratio), "robust/detection {ratio}");
        assert!(Bla::from_realizations(&refs[..1]).is_err());
    }
}
