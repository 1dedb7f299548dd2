//! The closed loop of a plant P and a controller K under negative feedback `u = −K y`.
//!
//! - **Internal stability**: the eigenvalues of the interconnection's state matrix (all four
//!   closed-loop maps share it), reported as the spectral radius (DT) or abscissa (CT).
//! - **Sensitivities** (output side): `S = (I + PK)⁻¹`, `T = PK(I + PK)⁻¹ = I − S`,
//!   `PS = P(I + KP)⁻¹ = S P` (input disturbance to output), `KS = K(I + PK)⁻¹` (the control
//!   sensitivity the paper uses as its intersample indicator). MIMO allowed. As models (for
//!   norms, simulation) and, accurately, pointwise from P(f) and K(f) ([`ClosedLoop::responses`]).
//! - **|S| peak**: `‖S‖∞` and its frequency ([`sd_model::StateSpace::hinf_norm`]).
//! - **Margins** (SISO, loop gain `L = PK`), with python-control's definitions
//!   (`stability_margins`): phase crossovers where `L` crosses the negative real axis
//!   (including ω = 0 and, in discrete time, the Nyquist frequency when `L` is real and
//!   negative there), gain margin `1/|L|` there, the one with the smallest `|log GM|` reported;
//!   gain crossovers `|L| = 1`, phase margin `(∠L mod 360°) − 180°`, the smallest `|PM|`
//!   reported; **modulus margin** `inf_ω |1 + L| = 1/‖S‖∞` from the H∞ norm (python-control's
//!   `sm` keeps only interior minima of a polynomial, and misses the global one on some
//!   discrete loops; ours is the global one, including ω → ∞).
//! - **Crossover**: the lowest gain crossover of `|L|` (the frequency up to which the loop gain
//!   exceeds one). **Bandwidth**: the closed-loop −3 dB bandwidth of `T` (python-control's and
//!   MATLAB's `bandwidth`), [`ClosedLoop::bandwidth_hz`].
//!
//! Crossings are bracketed on a log grid of [`crate::tol::GRID_POINTS`] points (plus dense
//! points around every lightly damped pole of L) and refined by bisection to machine precision.

use crate::error::{AnalysisError, Result};
use crate::tol;
use num_complex::Complex64 as C;
use sd_model::connect::{feedback, series};
use sd_model::{FreqRespEvaluator, SampleTime, StateSpace};
use std::f64::consts::PI;

/// Stability margins of a SISO loop.
#[derive(Debug, Clone, PartialEq)]
pub struct Margins {
    /// Gain margin (factor; `inf` when L never crosses the negative real axis).
    pub gain_margin: f64,
    /// Phase crossover frequency of the reported gain margin (Hz; NaN if none).
    pub phase_crossover_hz: f64,
    /// Phase margin (degrees; `inf` when |L| never crosses 1).
    pub phase_margin_deg: f64,
    /// Gain crossover frequency of the reported phase margin (Hz; NaN if none).
    pub gain_crossover_hz: f64,
    /// `inf |1 + L| = 1/‖S‖∞`.
    pub modulus_margin: f64,
    /// Where it is attained (Hz; infinite when only approached as ω → ∞).
    pub modulus_margin_hz: f64,
    /// All phase crossovers `(Hz, gain margin)`.
    pub all_phase_crossovers: Vec<(f64, f64)>,
    /// All gain crossovers `(Hz, phase margin)`.
    pub all_gain_crossovers: Vec<(f64, f64)>,
}

impl Margins {
    /// Gain margin in dB.
    pub fn gain_margin_db(&self) -> f64 {
        20.0 * self.gain_margin.log10()
    }

    /// The lowest gain crossover (Hz), if any.
    pub fn lowest_gain_crossover_hz(&self) -> Option<f64> {
        self.all_gain_crossovers
            .iter()
            .map(|g| g.0)
            .reduce(f64::min)
    }
}

/// The four closed-loop maps at one frequency.
#[derive(Debug, Clone)]
pub struct Responses {
    /// `S = (I + PK)⁻¹`.
    pub s: nalgebra::DMatrix<C>,
    /// `T = PK S`.
    pub t: nalgebra::DMatrix<C>,
    /// `PS = S P`.
    pub ps: nalgebra::DMatrix<C>,
    /// `KS = K S`.
    pub ks: nalgebra::DMatrix<C>,
}

/// The closed loop of P and K (module documentation).
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    p: StateSpace,
    k: StateSpace,
    ev_p: FreqRespEvaluator,
    ev_k: FreqRespEvaluator,
    l: StateSpace,
    cl: StateSpace,
    s: StateSpace,
    t: StateSpace,
    ps: StateSpace,
    ks: StateSpace,
}

/// The summary `sdctl analyze` prints (serde: its `--json` keys; a non-finite value is null).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Internally stable.
    pub stable: bool,
    /// Spectral radius (DT) or abscissa (CT) of the closed loop.
    pub closed_loop_radius: f64,
    /// Closed-loop −3 dB bandwidth of T (Hz; NaN if none): [`ClosedLoop::bandwidth_hz`].
    pub bandwidth_hz: f64,
    /// Lowest gain crossover of |L| (Hz; NaN if none).
    pub crossover_hz: f64,
    /// `‖S‖∞` in dB.
    pub sensitivity_peak_db: f64,
    /// Its frequency (Hz).
    pub sensitivity_peak_hz: f64,
    /// Gain margin in dB (SISO; NaN for MIMO).
    pub gain_margin_db: f64,
    /// Where the gain margin is read: the phase crossover (Hz; NaN when there is none, an
    /// infinite gain margin, and for MIMO).
    pub gain_margin_hz: f64,
    /// Phase margin in degrees (SISO; NaN for MIMO).
    pub phase_margin_deg: f64,
    /// Where the phase margin is read: the gain crossover (Hz; NaN when there is none, and for
    /// MIMO).
    pub phase_margin_hz: f64,
    /// `1/‖S‖∞`.
    pub modulus_margin: f64,
}

fn identity(n: usize, time: SampleTime) -> Result<StateSpace> {
    Ok(StateSpace::gain(nalgebra::DMatrix::identity(n, n), time)?)
}

impl ClosedLoop {
    /// Builds the loop; K must be `nu(P) × ny(P)` with the same sample time.
    ///
    /// # Errors
    /// Mixed sample times, wrong shapes, an ill-posed loop (`I + D_P D_K` singular).
    pub fn new(p: &StateSpace, k: &StateSpace) -> Result<Self> {
        if !p.time().compatible(&k.time()) {
            return Err(AnalysisError::InvalidArgument(
                "plant and controller must have the same sample time".into(),
            ));
        }
        if k.nu() != p.ny() || k.ny() != p.nu() {
            return Err(AnalysisError::InvalidArgument(format!(
                "the controller must be {}x{} (inputs = plant outputs), got {}x{}",
                p.nu(),
                p.ny(),
                k.ny(),
                k.nu()
            )));
        }
        let l = series(k, p)?;
        let cl = feedback(p, k, -1.0)?;
        let s = feedback(&identity(p.ny(), p.time())?, &l, -1.0)?;
        let t = feedback(&l, &identity(p.ny(), p.time())?, -1.0)?;
        let ps = series(p, &s)?;
        let ks = series(&s, k)?;
        Ok(ClosedLoop {
            ev_p: FreqRespEvaluator::new(p)?,
            ev_k: FreqRespEvaluator::new(k)?,
            p: p.clone(),
            k: k.clone(),
            l,
            cl,
            s,
            t,
            ps,
            ks,
        })
    }

    /// The loop gain `L = PK`.
    pub fn loop_gain(&self) -> &StateSpace {
        &self.l
    }
    /// `S = (I + PK)⁻¹`.
    pub fn sensitivity(&self) -> &StateSpace {
        &self.s
    }
    /// `T = PK(I + PK)⁻¹`.
    pub fn complementary(&self) -> &StateSpace {
        &self.t
    }
    /// `PS`.
    pub fn process_sensitivity(&self) -> &StateSpace {
        &self.ps
    }
    /// `KS`.
    pub fn control_sensitivity(&self) -> &StateSpace {
        &self.ks
    }
    /// The closed loop from the plant's and the controller's inputs to their outputs.
    pub fn closed_loop(&self) -> &StateSpace {
        &self.cl
    }
    /// The frequency-response evaluators of P and K.
    pub(crate) fn evaluators(&self) -> (&FreqRespEvaluator, &FreqRespEvaluator) {
        (&self.ev_p, &self.ev_k)
    }
    /// The plant.
    pub fn plant(&self) -> &StateSpace {
        &self.p
    }
    /// The controller.
    pub fn controller(&self) -> &StateSpace {
        &self.k
    }

    /// Spectral radius (DT) or abscissa (CT) of the closed loop, and whether it is stable.
    pub fn stability(&self) -> Result<(f64, bool)> {
        let poles = self.cl.poles()?;
        Ok(if self.cl.time().is_continuous() {
            let a = poles.iter().map(|z| z.re).fold(f64::NEG_INFINITY, f64::max);
            (a, a < 0.0)
        } else {
            let r = poles.iter().map(|z| z.norm()).fold(0.0, f64::max);
            (r, r < 1.0)
        })
    }

    /// `‖S‖∞` and its frequency (Hz).
    pub fn sensitivity_peak(&self) -> Result<(f64, f64)> {
        let h = self.s.hinf_norm()?;
        Ok((h.value, h.peak_hz))
    }

    /// S, T, PS and KS at a frequency (Hz), from P(f) and K(f) evaluated separately. Near the
    /// zeros of S (low frequencies, where |PK| is large) this keeps full relative accuracy,
    /// which evaluating a state-space realization of S itself cannot (its pole–residue sum
    /// cancels to a tiny value).
    ///
    /// # Errors
    /// `I + PK` singular at f (a closed-loop pole on the boundary).
    pub fn responses(&self, f_hz: f64) -> Result<Responses> {
        let p = self.ev_p.eval_hz(f_hz);
        let k = self.ev_k.eval_hz(f_hz);
        let ny = p.nrows();
        let s = (nalgebra::DMatrix::<C>::identity(ny, ny) + &p * &k)
            .try_inverse()
            .ok_or_else(|| {
                AnalysisError::InvalidArgument(format!("I + PK is singular at {f_hz} Hz"))
            })?;
        let t = &p * &k * &s;
        let ps = &s * &p;
        let ks = &k * &s;
        Ok(Responses { s, t, ps, ks })
    }

    /// `σ_max(S(f))` at a frequency (Hz).
    pub fn sensitivity_at(&self, f_hz: f64) -> Result<f64> {
        Ok(sigma_max(&self.responses(f_hz)?.s))
    }

    fn require_siso(&self) -> Result<()> {
        if self.p.nu() != 1 || self.p.ny() != 1 {
            return Err(AnalysisError::InvalidArgument(format!(
                "margins are defined for SISO loops; the plant is {}x{} (use the sensitivity peak)",
                self.p.ny(),
                self.p.nu()
            )));
        }
        Ok(())
    }

    /// The frequency grid (Hz) on which crossings are bracketed.
    fn grid(&self) -> Result<Vec<f64>> {
        let poles = self.l.poles()?;
        let zeros = self.l.zeros().unwrap_or_default();
        let (lo, hi, nyq) = match self.l.time() {
            SampleTime::Discrete { ts } => {
                let nyq = 0.5 / ts;
                (nyq * 1e-7, nyq, true)
            }
            SampleTime::Continuous => {
                let w: Vec<f64> = poles
                    .iter()
                    .chain(zeros.iter())
                    .map(|z| z.norm())
                    .filter(|&v| v > 0.0 && v.is_finite())
                    .collect();
                let wmin = w.iter().cloned().fold(f64::INFINITY, f64::min);
                let wmax = w.iter().cloned().fold(0.0, f64::max);
                let (lo, mut hi) = if w.is_empty() {
                    (1e-3, 1e3)
                } else {
                    (wmin / (2.0 * PI) * 1e-3, wmax / (2.0 * PI) * 1e3)
                };
                // a high gain moves the crossover above the poles: extend until |L − L(∞)| ≪ 1
                let l_inf = (self.p.d() * self.k.d())[(0, 0)];
                let mut guard = 0;
                while guard < 30
                    && ((self.ev_p.eval_hz(hi) * self.ev_k.eval_hz(hi))[(0, 0)] - l_inf).norm()
                        > 1e-3
                {
                    hi *= 10.0;
                    guard += 1;
                }
                (lo, hi, false)
            }
        };
        let mut f = sd_model::grid(lo, hi, tol::GRID_POINTS, true)?;
        // dense points around lightly damped poles
        for p in &poles {
            let (fr, zeta) = match self.l.time() {
                SampleTime::Discrete { ts } => {
                    if p.norm() == 0.0 {
                        continue;
                    }
                    let s = p.ln() / ts;
                    (
                        s.im.abs() / (2.0 * PI),
                        -s.re / s.norm().max(f64::MIN_POSITIVE),
                    )
                }
                SampleTime::Continuous => (
                    p.im.abs() / (2.0 * PI),
                    -p.re / p.norm().max(f64::MIN_POSITIVE),
                ),
            };
            if fr > lo && fr < hi && zeta < 0.2 {
                let width = (4.0 * zeta.abs().max(1e-4) * fr).max(1e-9);
                for i in 0..tol::RESONANCE_POINTS {
                    let x =
                        fr - width + 2.0 * width * i as f64 / (tol::RESONANCE_POINTS - 1) as f64;
                    if x > lo && x < hi {
                        f.push(x);
                    }
                }
            }
        }
        f.sort_by(f64::total_cmp);
        f.dedup();
        if nyq {
            if let Some(last) = f.last_mut() {
                *last = hi;
            }
        }
        Ok(f)
    }

    /// Stability margins (module documentation; SISO).
    ///
    /// # Errors
    /// A MIMO loop.
    pub fn margins(&self) -> Result<Margins> {
        self.require_siso()?;
        // L(f) = P(f)·K(f) factor by factor: the series model of L can carry defective poles
        // (a rigid body times an integrator) that make a single-model evaluation ill-conditioned
        let lval = |f: f64| (self.ev_p.eval_hz(f) * self.ev_k.eval_hz(f))[(0, 0)];
        let lat = |z: C| (self.ev_p.eval_at(z) * self.ev_k.eval_at(z))[(0, 0)];
        let f = self.grid()?;
        let vals: Vec<C> = f.iter().map(|&x| lval(x)).collect();
        let mut phase_x: Vec<(f64, f64)> = Vec::new();
        let mut gain_x: Vec<(f64, f64)> = Vec::new();
        // ω = 0 (if L is finite there: no pole of P or K at s = 0 / z = 1, where the
        // evaluation returns rounding noise of order 1/ε, not a phase crossover) and the
        // Nyquist frequency: real values of L
        let at_zero = if pole_at_dc(&self.p)? || pole_at_dc(&self.k)? {
            C::new(f64::INFINITY, 0.0)
        } else {
            match self.l.time() {
                SampleTime::Continuous => lat(C::new(0.0, 0.0)),
                SampleTime::Discrete { .. } => lat(C::new(1.0, 0.0)),
            }
        };
        if at_zero.is_finite() && at_zero.re <= 0.0 && at_zero.im.abs() <= 1e-12 * at_zero.norm() {
            phase_x.push((0.0, 1.0 / at_zero.norm()));
        }
        for i in 0..f.len() - 1 {
            let (a, b) = (vals[i], vals[i + 1]);
            if !(a.is_finite() && b.is_finite()) {
                continue;
            }
            if (a.im > 0.0) != (b.im > 0.0) && (a.re < 0.0 || b.re < 0.0) {
                let w = bisect(f[i], f[i + 1], |x| lval(x).im);
                let lw = lval(w);
                if lw.re <= 0.0 {
                    phase_x.push((w, 1.0 / lw.norm()));
                }
            }
            if (a.norm() > 1.0) != (b.norm() > 1.0) {
                let w = bisect(f[i], f[i + 1], |x| lval(x).norm() - 1.0);
                let lw = lval(w);
                let pm = (lw.arg().to_degrees()).rem_euclid(360.0) - 180.0;
                gain_x.push((w, pm));
            }
        }
        if let SampleTime::Discrete { ts } = self.l.time() {
            let nyq = 0.5 / ts;
            let ln = lat(C::new(-1.0, 0.0));
            if ln.is_finite()
                && ln.re <= 0.0
                && !phase_x.iter().any(|&(w, _)| (w - nyq).abs() < 1e-9 * nyq)
            {
                phase_x.push((nyq, 1.0 / ln.norm()));
            }
        }
        let (gm, wpc) = match phase_x
            .iter()
            .min_by(|a, b| a.1.ln().abs().total_cmp(&b.1.ln().abs()))
        {
            Some(&(w, g)) => (g, w),
            None => (f64::INFINITY, f64::NAN),
        };
        let (pm, wgc) = gain_x
            .iter()
            .cloned()
            .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(w, p)| (p, w))
            .unwrap_or((f64::INFINITY, f64::NAN));
        // modulus margin: the global infimum of |1 + L| is 1/‖S‖∞ (attained at ω → ∞ for
        // strictly proper continuous loops, which no grid reaches)
        let (peak, peak_hz) = self.sensitivity_peak()?;
        let (mm, wms) = (1.0 / peak, peak_hz);
        Ok(Margins {
            gain_margin: gm,
            phase_crossover_hz: wpc,
            phase_margin_deg: pm,
            gain_crossover_hz: wgc,
            modulus_margin: mm,
            modulus_margin_hz: wms,
            all_phase_crossovers: phase_x,
            all_gain_crossovers: gain_x,
        })
    }

    /// The lowest gain crossover of |L| (Hz), if any (SISO).
    pub fn crossover_hz(&self) -> Result<Option<f64>> {
        Ok(self.margins()?.lowest_gain_crossover_hz())
    }

    /// The closed-loop bandwidth as python-control's `bandwidth` and MATLAB's `bandwidth`
    /// define it: the lowest frequency (Hz) where `|T(f)|`, `T = L/(1 + L)`, drops 3 dB below
    /// its DC gain `|T(0)|`, i.e. to `10^(−3/20)·|T(0)|` (SISO). `None` when `|T|` never drops that far below the Nyquist
    /// frequency (or 10³ × the highest pole or zero of a continuous loop), and when the DC gain
    /// is zero or not finite (python-control: `inf` and `nan`).
    ///
    /// The DC gain is evaluated on the closed-loop model at `s = 0` / `z = 1`; the drop is
    /// bracketed on the margins' grid (log-spaced, dense around lightly damped poles) from P
    /// and K evaluated factor by factor, then bisected.
    ///
    /// # Errors
    /// A MIMO loop.
    pub fn bandwidth_hz(&self) -> Result<Option<f64>> {
        self.require_siso()?;
        let dc_point = match self.t.time() {
            SampleTime::Continuous => C::new(0.0, 0.0),
            SampleTime::Discrete { .. } => C::new(1.0, 0.0),
        };
        let dc = match self.t.eval_direct(dc_point) {
            Ok(m) => m[(0, 0)].norm(),
            Err(_) => return Ok(None),
        };
        if !(dc.is_finite() && dc > 0.0) {
            return Ok(None);
        }
        // exactly −3 dB (10^(−3/20) = 0.70795), as python-control and MATLAB; not 1/√2
        let level = dc * 10f64.powf(-3.0 / 20.0);
        let t_at = |f: f64| -> f64 {
            let l = (self.ev_p.eval_hz(f) * self.ev_k.eval_hz(f))[(0, 0)];
            (l / (1.0 + l)).norm()
        };
        let f = self.grid()?;
        let mut prev = None;
        for &x in &f {
            let v = t_at(x);
            if v.is_finite() && v < level {
                return Ok(Some(match prev {
                    Some(a) => bisect(a, x, |y| t_at(y) - level),
                    None => x,
                }));
            }
            if v.is_finite() {
                prev = Some(x);
            }
        }
        Ok(None)
    }

    /// Everything `sdctl analyze` reports.
    pub fn summary(&self) -> Result<Summary> {
        let (radius, stable) = self.stability()?;
        let (peak, peak_hz) = self.sensitivity_peak()?;
        let siso = self.p.nu() == 1 && self.p.ny() == 1;
        let ((gm_db, gm_hz), (pm, pm_hz), cross, bw) = if siso {
            let m = self.margins()?;
            let cross = m.lowest_gain_crossover_hz();
            (
                (m.gain_margin_db(), m.phase_crossover_hz),
                (m.phase_margin_deg, m.gain_crossover_hz),
                cross.unwrap_or(f64::NAN),
                self.bandwidth_hz()?.unwrap_or(f64::NAN),
            )
        } else {
            (
                (f64::NAN, f64::NAN),
                (f64::NAN, f64::NAN),
                f64::NAN,
                f64::NAN,
            )
        };
        Ok(Summary {
            stable,
            closed_loop_radius: radius,
            bandwidth_hz: bw,
            crossover_hz: cross,
            sensitivity_peak_db: 20.0 * peak.log10(),
            sensitivity_peak_hz: peak_hz,
            gain_margin_db: gm_db,
            gain_margin_hz: gm_hz,
            phase_margin_deg: pm,
            phase_margin_hz: pm_hz,
            modulus_margin: 1.0 / peak,
        })
    }
}

pub(crate) fn sigma_max(g: &nalgebra::DMatrix<C>) -> f64 {
    if g.nrows() == 1 && g.ncols() == 1 {
        return g[(0, 0)].norm();
    }
    nalgebra::linalg::SVD::try_new(g.clone(), false, false, f64::EPSILON, 1000)
        .map(|s| s.singular_values.iter().cloned().fold(0.0, f64::max))
        .unwrap_or(f64::NAN)
}

/// Bisection on a sign change of `g` in [a, b].
fn bisect(mut a: f64, mut b: f64, g: impl Fn(f64) -> f64) -> f64 {
    let ga = g(a);
    for _ in 0..tol::REFINE_STEPS {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            break;
        }
        if (g(m) > 0.0) == (ga > 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// Whether `sys` has a pole at DC (`s = 0`, or `z = 1` when discrete): `A` (or `I − A`) singular
/// to `10³·n·ε·‖·‖_F` (rounding of a similarity transform's conditioning included), by its
/// smallest singular value. Eigenvalues would not do: a pole of multiplicity k at the origin
/// comes out of the QR algorithm `ε^{1/k}` away from it.
fn pole_at_dc(sys: &StateSpace) -> Result<bool> {
    let n = sys.n();
    if n == 0 {
        return Ok(false);
    }
    let m = match sys.time() {
        SampleTime::Continuous => sys.a().clone(),
        SampleTime::Discrete { .. } => nalgebra::DMatrix::identity(n, n) - sys.a(),
    };
    let (_, s, _) = sd_model::linalg::convert::svd(&m)?;
    let smin = s.last().copied().unwrap_or(0.0);
    Ok(smin <= 1e3 * n as f64 * f64::EPSILON * m.norm())
}
