//! Frequency response estimation from periodic data, with variances and distortion levels
//! (Pintelon & Schoukens, *System Identification*, 2nd ed., §2.4 and §3.4; Pintelon et al.,
//! "Estimation of nonparametric noise and FRF models for multivariable systems", MSSP 24, 2010).
//!
//! With M steady-state periods (after `skip` transient ones) of P samples, `U_m(k)`, `Y_m(k)` the
//! DFTs of period m, and `Ū`, `Ȳ` their means over the periods:
//! - **closed loop with an external periodic reference r**: `Ĝ = (Ȳ/R)/(Ū/R) = Ȳ/Ū` on the lines
//!   that r excites (the indirect estimate: unbiased although u and y both carry the loop's
//!   noise; the direct `Y/U` on non-periodic closed-loop data is biased towards −1/K);
//! - **open loop** (no reference): the same ratio on the lines the input excites;
//! - **variance** (errors-in-variables, first order):
//!   `var Ĝ = (σ²_Ȳ + |Ĝ|²σ²_Ū − 2 Re(Ĝ* σ_ȲŪ))/|Ū|²`, with the noise (co)variances of the
//!   period means estimated from the spread of the data between the periodic lines: with the
//!   DFT of the whole steady record (L = M·P points) the mean over periods is exactly
//!   `X̄(k) = X_L(kM)/M`, and the 2(M − 1) bins `kM ± 1 … kM ± (M − 1)` between two harmonics
//!   hold noise only, so `σ²_X̄ = mean_j |X_L(kM + j)|²/M²` (and the cross term likewise). This is
//!   the spread over periods seen in the frequency domain, but immune to the leakage of
//!   low-frequency noise (a rigid body's drift) that inflates the per-period sample variance at
//!   high frequencies — that leakage telescopes in the mean and does not belong in its variance;
//! - **noise and nonlinear distortion**: at non-excited lines in the band, `|Ȳ|²` is noise plus
//!   nonlinear distortion and `σ²_Ȳ` is noise alone; their ratio (≈ 1 without distortion) is
//!   reported separately for odd and even lines (random-odd multisines).
//!
//! With a single period (M = 1) there is no spread to measure: the output noise is then taken as
//! white, its level `σ²_Y` estimated from the non-excited bins (at least 8 are needed; otherwise
//! the variance is absent), and `var Ĝ = σ²_Y/|Ū|²` (input noise neglected).

use crate::error::{IdentError, Result};
use crate::quality::{snr_warnings, trusted, DataWarning};
use crate::tol;
use num_complex::Complex64 as C;
use rustfft::FftPlanner;
use sd_model::{Frd, SampleTime};

/// Periodic estimation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodicOptions {
    /// Samples per period.
    pub period: usize,
    /// Leading periods dropped.
    pub skip_periods: usize,
    /// A line is excited when its reference (or input) amplitude exceeds this fraction of the
    /// largest one ([`tol::EXCITED_FRACTION`] by default; raise it for swept or coloured
    /// excitations that leave weakly excited lines between the intended ones).
    pub excited_fraction: f64,
}

impl PeriodicOptions {
    /// `period` samples per period, `skip` transient periods, the default excitation threshold.
    pub fn new(period: usize, skip: usize) -> Self {
        PeriodicOptions {
            period,
            skip_periods: skip,
            excited_fraction: tol::EXCITED_FRACTION,
        }
    }
}

/// Noise and distortion levels at non-excited lines (mean power over the lines of the band).
#[derive(Debug, Clone, PartialEq)]
pub struct DistortionReport {
    /// Number of non-excited odd lines used.
    pub odd_lines: usize,
    /// Number of non-excited even lines used.
    pub even_lines: usize,
    /// Mean `|Ȳ|²` at odd non-excited lines.
    pub odd_level: f64,
    /// Mean `|Ȳ|²` at even non-excited lines.
    pub even_level: f64,
    /// Mean noise level `σ²_Y/M` at the same lines.
    pub noise_level: f64,
    /// `odd_level / noise_level` (≈ 1 without odd distortion).
    pub odd_ratio: f64,
    /// `even_level / noise_level`.
    pub even_ratio: f64,
    /// Degrees of freedom `ν = 4(M − 1)` of each line's noise estimate (from the `2(M − 1)`
    /// non-periodic bins around it).
    pub noise_dof: f64,
    /// Calibrated odd-line score: the mean over the odd non-excited lines of
    /// `−ln p_k = (ν/2)·ln(1 + 2t_k/ν)`, `t_k = |Ȳ_k|²/σ̂²_k` the line's power over its own
    /// noise estimate. Without distortion (Gaussian noise) `t_k ~ F(2, ν)`, so `p_k` is
    /// uniform and `−ln p_k ~ Exp(1)`: the score is `Gamma(L, 1)/L`, mean 1, whatever the
    /// noise spectrum (Fisher's combination of the per-line tests). `ratio` above, a ratio of
    /// means, is dominated by the noisiest lines and has no such law.
    pub odd_score: f64,
    /// The same over the even non-excited lines.
    pub even_score: f64,
}

/// An FRF estimate.
#[derive(Debug, Clone)]
pub struct FrfEstimate {
    /// Estimate with variance (when M ≥ 2) at the excited lines.
    pub frd: Frd,
    /// The excited DFT bins.
    pub lines: Vec<usize>,
    /// Periods averaged.
    pub periods: usize,
    /// Noise and distortion at the non-excited lines inside the excited band (when M ≥ 2).
    pub distortion: Option<DistortionReport>,
    /// Mean output spectrum `Ȳ` at the excited lines.
    pub y_mean: Vec<C>,
    /// Mean input spectrum `Ū` at the excited lines.
    pub u_mean: Vec<C>,
    /// Variance of the stochastic nonlinear distortion per excited line (FRF units), from
    /// the odd non-excited (detection) lines of an odd multisine: `max(0, mean(|Ȳ_j|² −
    /// σ²_Ȳj))` over the [`NL_NEIGHBOURS`] nearest detection lines, over `|Ū_k|²`, with the
    /// ratio `mean |Ȳ_j|²/mean σ²_Ȳj` (≈ Gamma(K, 1)/K for K lines without distortion: a user
    /// gates on it, since the clamp biases the level of a linear system upward). An FRF measured with one phase realisation of a multisine carries this
    /// contribution as an error that does not average out over periods (Pintelon & Schoukens,
    /// *System Identification*, 2nd ed., §3.4–3.5: the best linear approximation and its
    /// stochastic nonlinear contributions). `None` without detection lines or with one period.
    pub nl_variance: Option<Vec<(f64, f64)>>,
    /// Input signal-to-noise ratio `|Ū|²/σ²_Ū` per excited line (infinite with one period).
    /// The first-order variance holds where it is large; below [`MIN_INPUT_SNR`] the ratio
    /// estimate is biased by more than 0.1 σ (noise in the denominator) and its variance
    /// formula no longer applies — in closed loop the lowest lines, where the loop cancels the
    /// excitation, are such.
    pub input_snr: Vec<f64>,
}

impl FrfEstimate {
    /// Whether each line's input SNR reaches [`MIN_INPUT_SNR`].
    pub fn trusted_lines(&self) -> Vec<bool> {
        self.input_snr.iter().map(|s| *s >= MIN_INPUT_SNR).collect()
    }

    /// The estimate at the trusted lines only ([`trusted`]).
    ///
    /// # Errors
    /// No line is trusted.
    pub fn trusted_frd(&self) -> Result<Frd> {
        trusted(&self.frd, &self.input_snr)
    }

    /// The data-quality warnings of this estimate ([`snr_warnings`]; the excitation check
    /// needs two periods or more).
    pub fn warnings(&self, excluded: bool) -> Vec<DataWarning> {
        snr_warnings(&self.frd, &self.input_snr, self.periods >= 2, excluded)
    }
}

/// Detection lines averaged for each excited line's distortion level (real degrees of
/// freedom of that level: 2 per line).
pub const NL_NEIGHBOURS: usize = 6;

/// The local distortion variance of each excited line (see [`FrfEstimate::nl_variance`]):
/// `(|Ȳ_j|², σ²_Ȳj)` at the odd non-excited lines `quiet` (ascending), `u` the input at
/// `lines`; per line (variance, ratio).
fn local_distortion(
    lines: &[usize],
    u: &[C],
    quiet: &[usize],
    level: &[(f64, f64)],
) -> Vec<(f64, f64)> {
    lines
        .iter()
        .zip(u)
        .map(|(&k, uk)| {
            let pos = quiet.partition_point(|&j| j < k);
            let (mut lo, mut hi) = (pos, pos);
            while hi - lo < NL_NEIGHBOURS.min(quiet.len()) {
                let below = (lo > 0).then(|| k.abs_diff(quiet[lo - 1]));
                let above = (hi < quiet.len()).then(|| k.abs_diff(quiet[hi]));
                match (below, above) {
                    (Some(b), Some(a)) if b <= a => lo -= 1,
                    (Some(_), None) => lo -= 1,
                    (_, Some(_)) => hi += 1,
                    (None, None) => break,
                }
            }
            let n = (hi - lo).max(1) as f64;
            let y2 = level[lo..hi].iter().map(|l| l.0).sum::<f64>() / n;
            let s2 = level[lo..hi].iter().map(|l| l.1).sum::<f64>() / n;
            (
                (y2 - s2).max(0.0) / uk.norm_sqr().max(f64::MIN_POSITIVE),
                if s2 > 0.0 { y2 / s2 } else { f64::INFINITY },
            )
        })
        .collect()
}

/// [`FrfEstimate::nl_variance`] from the excited `lines`, their mean inputs `u` and
/// `level(j) = (|Ȳ_j|², σ²_Ȳj)` at a bin: `None` with fewer than [`NL_NEIGHBOURS`] odd
/// non-excited lines in the band.
fn nl_variances(
    lines: &[usize],
    u: &[C],
    level: &dyn Fn(usize) -> (f64, f64),
) -> Option<Vec<(f64, f64)>> {
    let (kmin, kmax) = (*lines.first()?, *lines.last()?);
    // `lines` ascend: the excited ones by binary search
    let quiet: Vec<usize> = (kmin..=kmax)
        .filter(|k| k % 2 == 1 && lines.binary_search(k).is_err())
        .collect();
    (quiet.len() >= NL_NEIGHBOURS).then(|| {
        let lv: Vec<(f64, f64)> = quiet.iter().map(|&j| level(j)).collect();
        local_distortion(lines, u, &quiet, &lv)
    })
}

/// The DFT of a real record by a planned FFT of its length.
/// The forward FFT plan of length `n`, from a planner kept per thread (planning a 200 000-point
/// transform costs as much as running it).
pub(crate) fn forward_plan(n: usize) -> std::sync::Arc<dyn rustfft::Fft<f64>> {
    thread_local! {
        static PLANNER: std::cell::RefCell<FftPlanner<f64>> = std::cell::RefCell::new(FftPlanner::new());
    }
    PLANNER.with(|p| p.borrow_mut().plan_fft_forward(n))
}

pub(crate) fn transform(fft: &dyn rustfft::Fft<f64>, x: &[f64]) -> Vec<C> {
    let mut buf: Vec<C> = x.iter().map(|&v| C::new(v, 0.0)).collect();
    fft.process(&mut buf);
    buf
}

/// Spectrum buffers handed back by [`recycle_spectra`], kept for the next estimate (a
/// 200 000-sample record's spectrum is 1.6 MB: allocated afresh, its pages are faulted in on
/// every call). At most [`POOL_BYTES`] are kept.
static SPECTRA: std::sync::Mutex<Vec<Vec<C>>> = std::sync::Mutex::new(Vec::new());

/// Largest total size of the kept spectrum buffers.
const POOL_BYTES: usize = 64 << 20;

/// An empty buffer with room for `cap` bins (a kept one when one is large enough).
fn spectrum_buffer(cap: usize) -> Vec<C> {
    let kept = SPECTRA.lock().ok().and_then(|mut p| {
        let i = p.iter().position(|v| v.capacity() >= cap)?;
        Some(p.swap_remove(i))
    });
    let mut v = kept.unwrap_or_else(|| Vec::with_capacity(cap));
    v.clear();
    v
}

/// Hands spectra back for reuse (dropped when the kept ones would exceed [`POOL_BYTES`]).
pub(crate) fn recycle_spectra(vs: impl IntoIterator<Item = Vec<C>>) {
    if let Ok(mut p) = SPECTRA.lock() {
        for v in vs {
            let held: usize = p.iter().map(|x| x.capacity()).sum();
            if (held + v.capacity()) * std::mem::size_of::<C>() <= POOL_BYTES {
                p.push(v);
            }
        }
    }
}

/// An in-place FFT with a scratch buffer kept per thread (`process` allocates and zeroes one
/// on every call: for a 100 000-point transform that is a few percent of its time).
fn process_reusing_scratch(fft: &dyn rustfft::Fft<f64>, buf: &mut [C]) {
    thread_local! {
        static SCRATCH: std::cell::RefCell<Vec<C>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    SCRATCH.with(|s| {
        let mut s = s.borrow_mut();
        let need = fft.get_inplace_scratch_len();
        if s.len() < need {
            s.resize(need, C::new(0.0, 0.0));
        }
        fft.process_with_scratch(buf, &mut s[..need]);
    });
}

/// `e^{−2πik/n}` for `k = 0 … n/4` (each by its own `sin_cos`), kept per thread like the plans;
/// the other quadrant follows by symmetry.
fn quarter_twiddles(n: usize) -> std::sync::Arc<Vec<C>> {
    thread_local! {
        static TABLES: std::cell::RefCell<std::collections::HashMap<usize, std::sync::Arc<Vec<C>>>> =
            std::cell::RefCell::new(std::collections::HashMap::new());
    }
    TABLES.with(|t| {
        t.borrow_mut()
            .entry(n)
            .or_insert_with(|| {
                let w = -2.0 * std::f64::consts::PI / n as f64;
                std::sync::Arc::new(
                    (0..=n / 4)
                        .map(|k| {
                            let (s, c) = (w * k as f64).sin_cos();
                            C::new(c, s)
                        })
                        .collect(),
                )
            })
            .clone()
    })
}

/// The DFT bins `0 … n/2` of a real record of even length `n`, through one complex FFT of
/// length `n/2` (half the work of [`transform`]; the bins above `n/2` are the conjugates
/// `X_{n−k} = conj(X_k)`). With `z_t = x_{2t} + i x_{2t+1}` and `Z = FFT_{n/2}(z)`:
/// `E_k = (Z_k + conj Z_{n/2−k})/2` (the even samples' DFT), `O_k = (Z_k − conj Z_{n/2−k})/(2i)`
/// (the odd samples'), `X_k = E_k + e^{−2πik/n} O_k` (indices mod n/2). The even and odd samples
/// share one transform, so the roundoff is that of the record itself (no other record mixed
/// in). Odd `n`: the complex transform, first `n/2 + 1` bins.
pub(crate) fn transform_real(x: &[f64]) -> Vec<C> {
    let n = x.len();
    if n < 4 || n % 2 == 1 {
        let mut b = transform(forward_plan(n).as_ref(), x);
        b.truncate(n / 2 + 1);
        return b;
    }
    let h = n / 2;
    // one buffer: Z, then X in place (bins k and h − k depend on Z_k and Z_{h−k} only), then
    // X_{n/2} appended
    let mut z: Vec<C> = spectrum_buffer(h + 1);
    z.extend(x.chunks_exact(2).map(|p| C::new(p[0], p[1])));
    process_reusing_scratch(forward_plan(h).as_ref(), &mut z);
    let tw = quarter_twiddles(n);
    // e^{−2πik/n} from the quarter table: k ≤ n/4 directly, beyond as −conj of (n/2 − k)'s
    let w = |k: usize| if 4 * k <= n { tw[k] } else { -tw[h - k].conj() };
    // X_k from Z_k and conj Z_{h−k}: the even samples' DFT plus the twiddled odd samples'
    let post = |zk: C, zc: C, wk: C| (zk + zc) * 0.5 + wk * ((zk - zc) * C::new(0.0, -0.5));
    for k in 1..=h / 2 {
        let j = h - k;
        let (zk, zj) = (z[k], z[j]);
        z[k] = post(zk, zj.conj(), w(k));
        if j != k {
            z[j] = post(zj, zk.conj(), w(j));
        }
    }
    let z0 = z[0];
    z[0] = C::new(z0.re + z0.im, 0.0);
    z.push(C::new(z0.re - z0.im, 0.0));
    z
}

/// Records from this many samples have their transforms computed in parallel: below it the
/// transforms take little more than waking a pool thread costs, and one after the other is
/// faster (the 10⁴-sample row of `cargo xtask bench`'s scaling table, `frf_periodic`).
const PARALLEL_FROM: usize = 50_000;

/// The input SNR below which a line of a ratio estimate is not trusted (bias of `Ȳ/Ū` with
/// noise on `Ū` relative to its standard deviation ≈ `1/√SNR`: 0.1 at 100).
pub const MIN_INPUT_SNR: f64 = 100.0;

/// FRF of periodic data (module documentation). `r` is the external reference (closed loop),
/// or `None` when u is exogenous.
///
/// # Errors
/// Signals of different lengths, too few periods, no excited line.
pub fn frf_periodic(
    fs: f64,
    r: Option<&[f64]>,
    u: &[f64],
    y: &[f64],
    opt: &PeriodicOptions,
) -> Result<FrfEstimate> {
    let (p, m) = (opt.period, steady_periods(fs, r, u, y, opt)?);
    let start = opt.skip_periods * p;
    let len = m * p;
    // each record its own real transform (packing two real records into one complex FFT mixes
    // their roundoff, and y in metres beside u in newtons loses digits), the bins up to n/2
    // (every bin read below is under n/2), the records in parallel
    let long = |x: &[f64]| transform_real(&x[start..start + len]);
    let ((ul, yl), rl) = if len >= PARALLEL_FROM {
        rayon::join(|| rayon::join(|| long(u), || long(y)), || r.map(long))
    } else {
        ((long(u), long(y)), r.map(long))
    };
    let exc_src: &[C] = rl.as_deref().unwrap_or(&ul);
    let mf = m as f64;
    let mean_at = |x: &[C], k: usize| x[k * m] / mf;
    // noise (co)variances of the period means from the bins between harmonics
    let noise = |k: usize| -> (f64, f64, C) {
        let (mut suu, mut syy, mut syu) = (0.0, 0.0, C::new(0.0, 0.0));
        let mut cnt = 0.0;
        for j in 1..m {
            for b in [k * m + j, k * m - j] {
                let (ub, yb) = (ul[b], yl[b]);
                suu += ub.norm_sqr();
                syy += yb.norm_sqr();
                syu += yb * ub.conj();
                cnt += 1.0;
            }
        }
        let s = cnt * mf * mf;
        (suu / s, syy / s, syu / s)
    };
    let half = p / 2;
    let amp: Vec<f64> = (0..=half).map(|k| mean_at(exc_src, k).norm()).collect();
    let amax = amp[1..].iter().cloned().fold(0.0, f64::max);
    if amax == 0.0 {
        return Err(IdentError::Data(
            "the excitation is zero on every line".into(),
        ));
    }
    let lines: Vec<usize> = (1..half)
        .filter(|&k| amp[k] > opt.excited_fraction * amax)
        .collect();
    if lines.is_empty() {
        return Err(IdentError::Data("no excited line found".into()));
    }
    let mut resp = Vec::with_capacity(lines.len());
    let mut var = Vec::with_capacity(lines.len());
    let (mut ym, mut um) = (Vec::new(), Vec::new());
    let mut snr = Vec::with_capacity(lines.len());
    for &k in &lines {
        let (ub, yb) = (mean_at(&ul, k), mean_at(&yl, k));
        if ub.norm() == 0.0 {
            return Err(IdentError::Data(format!(
                "the input has no power at the excited line {k} (f = {} Hz)",
                k as f64 * fs / p as f64
            )));
        }
        let g = yb / ub;
        resp.push(nalgebra::DMatrix::from_element(1, 1, g));
        ym.push(yb);
        um.push(ub);
        if m >= 2 {
            let (suu, syy, syu) = noise(k);
            let v = (syy + g.norm_sqr() * suu - 2.0 * (g.conj() * syu).re) / ub.norm_sqr();
            var.push(nalgebra::DMatrix::from_element(1, 1, v.max(0.0)));
            snr.push(if suu > 0.0 {
                ub.norm_sqr() / suu
            } else {
                f64::INFINITY
            });
        } else {
            snr.push(f64::INFINITY);
        }
    }
    if m == 1 {
        if let Some(v) = single_period_variance(&lines, &um, &yl[..half]) {
            var = v;
        }
    }
    let has_var = !var.is_empty();
    let freq: Vec<f64> = lines.iter().map(|&k| k as f64 * fs / p as f64).collect();
    let frd = Frd::new(
        freq,
        resp,
        if has_var { Some(var) } else { None },
        SampleTime::discrete(1.0 / fs)?,
    )?;
    let distortion = (m >= 2)
        .then(|| distortion_of(&lines, mf, &|k| (mean_at(&yl, k).norm_sqr(), noise(k).1)))
        .flatten();
    let nl_variance = (m >= 2)
        .then(|| nl_variances(&lines, &um, &|j| (mean_at(&yl, j).norm_sqr(), noise(j).1)))
        .flatten();
    recycle_spectra([ul, yl].into_iter().chain(rl));
    Ok(FrfEstimate {
        frd,
        lines,
        periods: m,
        distortion,
        nl_variance,
        y_mean: ym,
        u_mean: um,
        input_snr: snr,
    })
}

/// One period: white output noise from the non-excited bins below `yl.len()` (at least 8),
/// its level over each excited line's `|U|²`.
fn single_period_variance(
    lines: &[usize],
    um: &[C],
    yl: &[C],
) -> Option<Vec<nalgebra::DMatrix<f64>>> {
    let excited: std::collections::HashSet<usize> = lines.iter().cloned().collect();
    let quiet: Vec<f64> = (1..yl.len())
        .filter(|k| !excited.contains(k))
        .map(|k| yl[k].norm_sqr())
        .collect();
    (quiet.len() >= 8).then(|| {
        let s2 = quiet.iter().sum::<f64>() / quiet.len() as f64;
        um.iter()
            .map(|u| nalgebra::DMatrix::from_element(1, 1, s2 / u.norm_sqr()))
            .collect()
    })
}

/// Checks the arguments of [`frf_periodic`]; the number of steady periods.
fn steady_periods(
    fs: f64,
    r: Option<&[f64]>,
    u: &[f64],
    y: &[f64],
    opt: &PeriodicOptions,
) -> Result<usize> {
    if !(fs.is_finite() && fs > 0.0) {
        return Err(IdentError::InvalidArgument(format!(
            "sample rate {fs} must be > 0"
        )));
    }
    let p = opt.period;
    if p < 4 {
        return Err(IdentError::InvalidArgument(format!(
            "period {p} must be ≥ 4 samples"
        )));
    }
    if u.len() != y.len() || r.map(|r| r.len() != u.len()).unwrap_or(false) {
        return Err(IdentError::Data(
            "r, u and y must have the same length".into(),
        ));
    }
    let total = u.len() / p;
    if total <= opt.skip_periods {
        return Err(IdentError::Data(format!(
            "{} samples hold {total} periods of {p}; none is left after skipping {}",
            u.len(),
            opt.skip_periods
        )));
    }
    Ok(total - opt.skip_periods)
}

/// The noise and distortion levels at the non-excited lines between the first and the last
/// excited one ([`DistortionReport`]); `line(k)` gives bin `k`'s power `|Ȳ_k|²` and its noise
/// estimate `σ̂²_k` from `M = mf` periods.
fn distortion_of(
    lines: &[usize],
    mf: f64,
    line: &dyn Fn(usize) -> (f64, f64),
) -> Option<DistortionReport> {
    let (kmin, kmax) = (*lines.first()?, *lines.last()?);
    let excited: std::collections::HashSet<usize> = lines.iter().cloned().collect();
    // per parity: lines, power, noise, score
    let nu = 4.0 * (mf - 1.0);
    let (mut odd, mut even) = ([0.0; 4], [0.0; 4]);
    for k in (kmin..=kmax).filter(|k| !excited.contains(k)) {
        let (pw, nz) = line(k);
        let score = if nz > 0.0 {
            nu / 2.0 * (2.0 * pw / (nu * nz)).ln_1p()
        } else {
            f64::INFINITY
        };
        let acc = if k % 2 == 1 { &mut odd } else { &mut even };
        acc[0] += 1.0;
        acc[1] += pw;
        acc[2] += nz;
        acc[3] += score;
    }
    let n = odd[0] + even[0];
    if n == 0.0 {
        return None;
    }
    let nl = (odd[2] + even[2]) / n;
    let mean = |a: &[f64; 4], i: usize| if a[0] > 0.0 { a[i] / a[0] } else { 0.0 };
    let ratio = |l: f64| if nl > 0.0 { l / nl } else { f64::INFINITY };
    Some(DistortionReport {
        odd_lines: odd[0] as usize,
        even_lines: even[0] as usize,
        odd_level: mean(&odd, 1),
        even_level: mean(&even, 1),
        noise_level: nl,
        odd_ratio: ratio(mean(&odd, 1)),
        even_ratio: ratio(mean(&even, 1)),
        noise_dof: nu,
        odd_score: mean(&odd, 3),
        even_score: mean(&even, 3),
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// The half-length real transform against the full complex one, bin by bin, within
    /// `10·log2(n)·ε·‖x‖₁` (the FFT's roundoff bound on a bin), on even and odd lengths
    /// (200 000 = 2⁶·5⁵ the bench's record; 6 the smallest even one that is not a fallback).
    #[test]
    fn real_transform_equals_the_complex_one() {
        let mut r = crate::rng::SplitMix::new(3);
        for n in [6usize, 7, 64, 1000, 1001, 200_000] {
            let x: Vec<f64> = (0..n).map(|_| r.normal() * 1e-6).collect();
            let full = transform(forward_plan(n).as_ref(), &x);
            let half = transform_real(&x);
            assert_eq!(half.len(), n / 2 + 1);
            let norm: f64 = x.iter().map(|v| v.abs()).sum();
            let tol = 10.0 * (n as f64).log2() * f64::EPSILON * norm;
            let worst = half
                .iter()
                .zip(&full)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            assert!(worst <= tol, "n = {n}: {worst:e} > {tol:e}");
        }
    }

    #[test]
    fn a_pure_gain_and_delay_is_recovered_exactly() {
        // y[n] = 2 u[n-1] on periodic data: G = 2 e^{-jωh}
        let p = 64;
        let u: Vec<f64> = (0..4 * p)
            .map(|n| ((n % p) as f64 * 0.7).sin() + ((n % p) as f64 * 0.23).cos())
            .collect();
        let y: Vec<f64> = (0..u.len())
            .map(|n| 2.0 * u[(n + u.len() - 1) % u.len()])
            .collect();
        let est = frf_periodic(100.0, None, &u, &y, &PeriodicOptions::new(p, 1)).unwrap();
        for (i, &k) in est.lines.iter().enumerate() {
            let want = C::from_polar(2.0, -2.0 * std::f64::consts::PI * k as f64 / p as f64);
            assert!((est.frd.response()[i][(0, 0)] - want).norm() < 1e-10);
        }
        assert!(frf_periodic(100.0, None, &u, &y[1..], &PeriodicOptions::new(p, 0)).is_err());
        assert!(frf_periodic(100.0, None, &u, &y, &PeriodicOptions::new(p, 4)).is_err());
    }

    /// A static cubic `y = u + 0.3u³` under a random-phase odd multisine (rms 1): its FRF at
    /// the excited lines scatters around the best linear approximation by the stochastic
    /// nonlinear contribution, and the detection lines' level predicts that scatter (mean of
    /// `nl_variance` within a factor 2 of the mean `|G − Ḡ|²`); a linear `y = u` with white
    /// noise gives a distortion ratio near 1 at almost every line.
    #[test]
    fn detection_lines_give_the_nonlinear_variance() {
        use crate::multisine::{design, Lines, MultisineSpec, Phases};
        let ms = design(&MultisineSpec {
            fs: 1000.0,
            period: 2000,
            f_min: 1.0,
            f_max: 300.0,
            lines: Lines::RandomOdd { group: 3, seed: 5 },
            phases: Phases::Random { seed: 9 },
            rms: 1.0,
            fold_rate_hz: None,
        })
        .unwrap();
        let p = ms.signal.len();
        let m = 4;
        let u: Vec<f64> = (0..m * p).map(|n| ms.signal[n % p]).collect();
        let mut st = 3u64;
        let mut noise = || {
            st = st
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((st >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1e-3
        };
        let y: Vec<f64> = u.iter().map(|x| x + 0.3 * x * x * x + noise()).collect();
        let est = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 0)).unwrap();
        let g: Vec<C> = est.frd.response().iter().map(|r| r[(0, 0)]).collect();
        let mean = g.iter().sum::<C>() / g.len() as f64;
        let scatter = g.iter().map(|x| (x - mean).norm_sqr()).sum::<f64>() / g.len() as f64;
        let nl = est.nl_variance.as_ref().unwrap();
        let predicted = nl.iter().map(|x| x.0).sum::<f64>() / nl.len() as f64;
        assert!(
            predicted > 0.5 * scatter && predicted < 2.0 * scatter,
            "{predicted} vs {scatter}"
        );
        let y: Vec<f64> = u.iter().map(|x| x + noise()).collect();
        let est = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 0)).unwrap();
        let nl = est.nl_variance.unwrap();
        let high = nl.iter().filter(|x| x.1 > 3.0).count();
        assert!(high * 20 < nl.len(), "{high} of {} lines", nl.len());
    }

    /// The distortion score is calibrated whatever the noise spectrum: a linear `y = u` with
    /// strongly coloured noise (AR(1) at 0.97, a 4 000× range of power over the band) over 300
    /// noise realisations gives scores of mean 1 and variance `1/L` (`Exp(1)` per line), while
    /// the ratio of means, dominated by the noisiest lines, spreads several times wider. A
    /// cubic `y = u + 0.3u³` raises the odd score far above and leaves the even one near 1.
    #[test]
    fn distortion_score_is_calibrated_under_coloured_noise() {
        use crate::multisine::{design, Lines, MultisineSpec, Phases};
        let ms = design(&MultisineSpec {
            fs: 1000.0,
            period: 1000,
            f_min: 1.0,
            f_max: 400.0,
            lines: Lines::RandomOdd { group: 3, seed: 2 },
            phases: Phases::Random { seed: 4 },
            rms: 1.0,
            fold_rate_hz: None,
        })
        .unwrap();
        let p = ms.signal.len();
        let m = 3;
        let u: Vec<f64> = (0..m * p).map(|n| ms.signal[n % p]).collect();
        let mut st = 11u64;
        let mut white = || {
            st = st
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            // sum of 4 uniforms: near-Gaussian, unit variance
            (0..4)
                .map(|_| {
                    st = st
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    (st >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                })
                .sum::<f64>()
                * 3f64.sqrt()
        };
        let reps = 300;
        let (mut scores, mut ratios, mut lines) = (Vec::new(), Vec::new(), 0);
        for _ in 0..reps {
            let mut ar = 0.0;
            let y: Vec<f64> = u
                .iter()
                .map(|x| {
                    ar = 0.97 * ar + 1e-3 * white();
                    x + ar
                })
                .collect();
            let est = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 0)).unwrap();
            let d = est.distortion.unwrap();
            scores.push(d.odd_score);
            ratios.push(d.odd_ratio / (d.noise_dof / (d.noise_dof - 2.0)));
            lines = d.odd_lines;
        }
        let stats = |x: &[f64]| {
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (x.len() - 1) as f64;
            (mean, var)
        };
        let (ms_, vs) = stats(&scores);
        let l = lines as f64;
        // the mean's standard error is 1/√(L·reps); the variance's relative one ≈ √(2/reps)
        assert!(
            (ms_ - 1.0).abs() < 4.0 / (l * reps as f64).sqrt(),
            "mean {ms_}"
        );
        assert!((vs * l - 1.0).abs() < 0.35, "variance × L = {}", vs * l);
        let (_, vr) = stats(&ratios);
        assert!(
            vr > 3.0 * vs,
            "ratio of means: variance {vr} vs the score's {vs}"
        );
        let y: Vec<f64> = u
            .iter()
            .map(|x| x + 0.3 * x * x * x + 1e-3 * white())
            .collect();
        let d = frf_periodic(1000.0, None, &u, &y, &PeriodicOptions::new(p, 0))
            .unwrap()
            .distortion
            .unwrap();
        assert!(d.odd_score > 10.0 && d.even_score < 1.5, "{d:?}");
    }
}
