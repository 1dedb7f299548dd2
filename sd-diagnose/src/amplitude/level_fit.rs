//! One level's modal fit (Gauss–Newton on the candidates' poles and the residues), the
//! candidates it may move, and what the linear basis alone describes (module documentation of
//! [`super`]).

use super::*;

/// Weighted rows of a modal fit: `(line, 1/σ)` for lines with a variance.
pub(super) fn rows(est: &Estimate) -> Vec<(usize, f64)> {
    est.frd.variance().map_or_else(Vec::new, |v| {
        (0..est.frd.len())
            .filter(|&i| v[i][(0, 0)] > 0.0)
            .map(|i| (i, 1.0 / v[i][(0, 0)].sqrt()))
            .collect()
    })
}

/// Weighted cost `Σ |G − Φ r|²/σ²` and the residues of a basis on an estimate.
pub(super) fn project(basis: &ModalBasis, h: f64, est: &Estimate) -> Result<(f64, Residues)> {
    let f = est.frd.freq_hz();
    let phi = basis.responses(h, NonIdeal::ideal(), f)?;
    let res = Residues::fit(&est.frd, &phi)?;
    let cost = rows(est)
        .iter()
        .map(|&(i, w)| {
            let p: C = phi[i].iter().zip(&res.r).map(|(a, b)| a * *b).sum();
            (w * (est.frd.response()[i][(0, 0)] - p)).norm_sqr()
        })
        .sum();
    Ok((cost, res))
}

/// How well `basis` (its poles fixed, its residues fitted to the level) describes a level:
/// the verdict's statistic on the level's lines at `alpha`.
pub(crate) fn describes(
    basis: &ModalBasis,
    h: f64,
    lv: &Level<'_>,
    alpha: f64,
) -> Result<crate::stats::Statistic> {
    let phi = basis.responses(h, NonIdeal::ideal(), lv.est.frd.freq_hz())?;
    let res = Residues::fit(&lv.est.frd, &phi)?;
    let lines = predicted_lines(lv.est, &phi, &res);
    Ok(statistic([(lines.as_slice(), lv.est.inflation)], alpha))
}

/// The statistic of a level's own modal fit on its lines inside `bands` (all lines when
/// there are none): the candidates at the poles `fit` found on this level, the residues
/// fitted to it. What the amplitude model's class reaches with the level's own data — the
/// floor a prediction of the level from the others can approach (a fit has seen the lines it
/// is judged on, so the floor is optimistic).
pub(crate) fn level_floor(
    (basis, cand): (&ModalBasis, &[usize]),
    fit: &LevelFit,
    h: f64,
    lv: &Level<'_>,
    bands: &[(f64, f64)],
    alpha: f64,
) -> Result<f64> {
    let mut poles = basis.poles();
    for (m, &pm) in cand.iter().enumerate() {
        let (f, z, _, _) = fit.modal[m];
        poles[pm] = if basis.is_real(pm) {
            C::new(-TAU * f, 0.0)
        } else {
            pair_of(f, z)
        };
    }
    let b = basis.with_poles(&poles)?;
    let phi = b.responses(h, NonIdeal::ideal(), lv.est.frd.freq_hz())?;
    let res = Residues::fit(&lv.est.frd, &phi)?;
    let lines: Vec<Line> = predicted_lines(lv.est, &phi, &res)
        .into_iter()
        .filter(|l| bands.is_empty() || bands.iter().any(|(lo, hi)| l.f >= *lo && l.f <= *hi))
        .collect();
    Ok(statistic([(lines.as_slice(), lv.est.inflation)], alpha).value)
}

/// An estimate's lines against the prediction `Σ r_j φ_j` with the residues' variance.
pub(super) fn predicted_lines(est: &Estimate, phi: &[Vec<C>], res: &Residues) -> Vec<Line> {
    let np = res.n_params();
    compare(est, |i, _| {
        let (value, var) = res.predict(&phi[i]);
        Some(Pred {
            value,
            var,
            dof: f64::INFINITY,
            params: np,
        })
    })
}

/// One level's modal fit (module documentation): the candidates' pole pairs free, from the
/// linear basis.
pub(crate) fn fit_level(
    basis: &ModalBasis,
    cand: &[usize],
    h: f64,
    lv: &Level<'_>,
) -> Result<LevelFit> {
    let thin = lv.est.thinned()?;
    let est = &thin;
    let f = est.frd.freq_hz();
    let rw = rows(est);
    let mut b = basis.clone();
    let (mut cost, mut res) = project(&b, h, est)?;
    // each candidate's first parameter in the pole block: one for a real pole, two for a pair
    let width = |pm: usize| if basis.is_real(pm) { 1 } else { 2 };
    let offs: Vec<usize> = cand
        .iter()
        .scan(0, |o, &pm| {
            let at = *o;
            *o += width(pm);
            Some(at)
        })
        .collect();
    let np: usize = cand.iter().map(|&pm| width(pm)).sum();
    let mut jac_cov: Option<(DMatrix<f64>, Vec<usize>)> = None;
    for it in 0..=GN_ITERATIONS {
        let phi = b.responses(h, NonIdeal::ideal(), f)?;
        let dphi = b.pole_sensitivities(&res.r, h, NonIdeal::ideal(), f)?;
        let nb = res.r.len();
        let mut j = DMatrix::zeros(2 * rw.len(), nb + np);
        let mut e = DVector::zeros(2 * rw.len());
        for (k, &(i, w)) in rw.iter().enumerate() {
            let p: C = phi[i].iter().zip(&res.r).map(|(a, r)| a * *r).sum();
            let d = w * (est.frd.response()[i][(0, 0)] - p);
            e[2 * k] = d.re;
            e[2 * k + 1] = d.im;
            for c in 0..nb {
                j[(2 * k, c)] = w * phi[i][c].re;
                j[(2 * k + 1, c)] = w * phi[i][c].im;
            }
            for (m, &pm) in cand.iter().enumerate() {
                let col = b.sensitivity_column(pm);
                for t in 0..width(pm) {
                    j[(2 * k, nb + offs[m] + t)] = w * dphi[i][col + t].re;
                    j[(2 * k + 1, nb + offs[m] + t)] = w * dphi[i][col + t].im;
                }
            }
        }
        let Ok(ls) = lstsq(&j, &e) else {
            break;
        };
        jac_cov = Some((ls.cov.view((nb, nb), (np, np)).into_owned(), offs.clone()));
        if it == GN_ITERATIONS {
            break;
        }
        // halving line search on the poles, residues re-solved (variable projection)
        let mut improved = false;
        for step in (0..8).map(|k| 0.5f64.powi(k)) {
            let mut poles = b.poles();
            for (m, &pm) in cand.iter().enumerate() {
                let old = poles[pm];
                let d_im = if basis.is_real(pm) {
                    0.0
                } else {
                    ls.x[nb + offs[m] + 1]
                };
                let new = old + C::new(ls.x[nb + offs[m]], d_im) * step;
                // a step may not leave the stable (upper half) plane: at most halfway to it
                poles[pm] = C::new(new.re.min(0.5 * old.re), new.im.max(0.5 * old.im));
            }
            let trial = b.with_poles(&poles)?;
            let Ok((c2, r2)) = project(&trial, h, est) else {
                continue;
            };
            if c2 < cost {
                let rel = (cost - c2) / cost.max(f64::MIN_POSITIVE);
                (b, cost, res) = (trial, c2, r2);
                improved = rel > 1e-9;
                break;
            }
        }
        if !improved {
            // one more pass computes the covariance at the final point
            let cov = jac_cov.take();
            return finish((b, basis), cand, (cost, rw.len()), est, lv, cov);
        }
    }
    finish((b, basis), cand, (cost, rw.len()), est, lv, jac_cov)
}

/// The level fit's frequencies and dampings with errors, and its amplitudes; `cov` is the
/// pole block's covariance with each candidate's first column.
pub(super) fn finish(
    (b, linear_basis): (ModalBasis, &ModalBasis),
    cand: &[usize],
    (cost, lines): (f64, usize),
    est: &Estimate,
    lv: &Level<'_>,
    cov: Option<(DMatrix<f64>, Vec<usize>)>,
) -> Result<LevelFit> {
    let (cov, offs) = cov.ok_or_else(|| {
        DiagnoseError::Numerical(format!("the modal fit of `{}` is singular", lv.name))
    })?;
    let nu = est.dof;
    let weights = if nu.is_finite() && nu > 2.0 {
        nu / (nu - 2.0)
    } else {
        1.0
    };
    let misfit = (cost / lines.max(1) as f64).max(1.0);
    let k = weights * est.inflation.max(1.0) * misfit;
    let poles = b.poles();
    let y = Records::of(lv.exp).y;
    let mut modal = Vec::new();
    let mut amplitude = Vec::new();
    for (m, &pm) in cand.iter().enumerate() {
        let real = b.is_real(pm);
        let c = |r: usize, s: usize| {
            if real && (r > 0 || s > 0) {
                0.0
            } else {
                k * cov[(offs[m] + r, offs[m] + s)]
            }
        };
        let nat = natural(poles[pm], [[c(0, 0), c(0, 1)], [c(1, 0), c(1, 1)]]);
        amplitude.push(mode_amplitude(linear_basis, pm, poles[pm], &y));
        modal.push(nat);
    }
    let linear = cand
        .iter()
        .map(|&pm| natural(linear_basis.poles()[pm], [[0.0; 2]; 2]))
        .collect();
    let fit_of = vec![PointFit::Level; modal.len()];
    Ok(LevelFit {
        modal,
        amplitude,
        linear,
        fit_of,
    })
}

/// Whether a level's fit determines a mode: its frequency within 30 % of the linear one and
/// known to better than half the linear half-power half-width `ζf` (a weak or band-edge mode
/// wanders off in a level fit; such points are left out of the trends).
pub(super) fn determined(fit: (f64, f64, f64, f64), lin: (f64, f64, f64, f64)) -> bool {
    let (f, z, sf, sz) = fit;
    let finite = f.is_finite() && z.is_finite() && sf.is_finite() && sz.is_finite();
    if is_real_pole(lin.1) {
        // a real pole (a corner, ζ = 1) may move by two decades down (a friction corner
        // falls as 1/amplitude) and one up, known to half its value
        finite && f > 0.01 * lin.0 && f < 10.0 * lin.0 && sf < 0.5 * f
    } else {
        finite && (f / lin.0 - 1.0).abs() < 0.3 && sf < 0.5 * lin.1 * lin.0
    }
}

/// Whether a damping ratio is a real pole's (`natural` gives ζ = 1 for `s = −a + 0j`).
pub(super) fn is_real_pole(z: f64) -> bool {
    z >= 1.0 - 1e-12
}

/// Candidates, as indices of [`ModalBasis::poles`]. Pairs: inside the estimate's band with at
/// least a few lines around them, apart from every other pair by more than twice their
/// half-power half-widths together (two modes closer than that trade frequency and damping
/// in a fit; they keep their linear poles). Of the real poles only a damped rigid body's
/// corner `a/2π` ([`ModalBasis::with_damped_rigid_body`], whose residues do not change when
/// friction moves it): below the band's top with at least three lines under ten times the
/// corner (where it turns the phase by more than 6°), and a factor 3 from any other real
/// pole. Other real poles keep their linear values (their residues would have to move with
/// them).
pub(crate) fn candidates(basis: &ModalBasis, est: &Estimate) -> Vec<usize> {
    let f = est.frd.freq_hz();
    let (lo, hi) = (
        f.first().copied().unwrap_or(0.0),
        f.last().copied().unwrap_or(0.0),
    );
    let poles = basis.poles();
    let nat: Vec<(f64, f64)> = poles
        .iter()
        .map(|p| {
            let n = natural(*p, [[0.0; 2]; 2]);
            (n.0, n.1)
        })
        .collect();
    let pair_ok = |i: usize| {
        let (fi, zi) = nat[i];
        let lines = f.iter().filter(|x| (**x - fi).abs() < 0.05 * fi).count();
        let apart = (0..nat.len())
            .filter(|&j| j != i && !basis.is_real(j))
            .all(|j| (fi - nat[j].0).abs() > 2.0 * (zi * fi + nat[j].1 * nat[j].0));
        fi > lo && fi < hi && lines >= 3 && apart
    };
    let real_ok = |i: usize| {
        let fi = nat[i].0;
        let lines = f.iter().filter(|x| **x < 10.0 * fi).count();
        let apart = (0..nat.len())
            .filter(|&j| j != i && basis.is_real(j))
            .all(|j| (nat[j].0 / fi).ln().abs() > 3f64.ln());
        fi > 0.0 && fi < hi && lines >= 3 && apart
    };
    (0..nat.len())
        .filter(|&i| {
            if basis.is_rigid_damping(i) {
                real_ok(i)
            } else {
                !basis.is_real(i) && pair_ok(i)
            }
        })
        .collect()
}
