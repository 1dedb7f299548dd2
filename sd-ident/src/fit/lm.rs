//! Step 2 of the fit: Levenberg–Marquardt on the weighted cost over poles, residues, rigid-body
//! residues and feedthrough (module documentation of [`super`]).

use super::*;

/// Parameter vector ↔ model for LM.
pub(super) fn to_params(pf: &Pf) -> Vec<f64> {
    let mut v = Vec::new();
    for &(p, r) in &pf.real {
        v.push(p);
        v.push(r);
    }
    for &(a, r) in &pf.pairs {
        v.extend([a.re, a.im, r.re, r.im]);
    }
    v.extend(pf.rigid.iter().cloned());
    v.push(pf.d);
    v
}

pub(super) fn from_params(template: &Pf, v: &[f64], data: &Data) -> Pf {
    let mut i = 0;
    let real = template
        .real
        .iter()
        .map(|_| {
            let t = (reflect(C::new(v[i], 0.0)).re, v[i + 1]);
            i += 2;
            t
        })
        .collect();
    let pairs = template
        .pairs
        .iter()
        .map(|_| {
            let a = data.constrain(C::new(v[i], v[i + 1]));
            let r = C::new(v[i + 2], v[i + 3]);
            i += 4;
            (a, r)
        })
        .collect();
    let rigid = template
        .rigid
        .iter()
        .map(|_| {
            i += 1;
            v[i - 1]
        })
        .collect();
    Pf {
        real,
        pairs,
        rigid,
        d: v[i],
    }
}

pub(super) fn jacobian(data: &Data, pf: &Pf, feed: bool) -> (Mat<f64>, Mat<f64>) {
    let np = 2 * pf.real.len() + 4 * pf.pairs.len() + pf.rigid.len() + 1;
    let k = data.z.len();
    let mut j = Mat::<f64>::zeros(2 * k, np);
    let mut e = Mat::<f64>::zeros(2 * k, 1);
    let jj = C::new(0.0, 1.0);
    for (i, ((&z, &g), &w)) in data.z.iter().zip(&data.g).zip(&data.w).enumerate() {
        let mut cols: Vec<C> = Vec::with_capacity(np);
        for &(p, r) in &pf.real {
            let u = 1.0 / (z - p);
            cols.push(u * u * r);
            cols.push(u);
        }
        for &(a, r) in &pf.pairs {
            let (u, v) = (1.0 / (z - a), 1.0 / (z - a.conj()));
            cols.push(u * u * r + v * v * r.conj());
            cols.push(jj * (u * u * r - v * v * r.conj()));
            cols.push(u + v);
            cols.push(jj * (u - v));
        }
        rigid_basis(pf.rigid.len(), z, &mut cols);
        cols.push(C::new(if feed { 1.0 } else { 0.0 }, 0.0));
        for (c, v) in cols.iter().enumerate() {
            j[(2 * i, c)] = w * v.re;
            j[(2 * i + 1, c)] = w * v.im;
        }
        let r = (pf.eval(z) - g) * w;
        e[(2 * i, 0)] = r.re;
        e[(2 * i + 1, 0)] = r.im;
    }
    (j, e)
}

/// `[J, −e]` reduced by one QR to `(R, c)` with `‖J s + e‖² = ‖R s − c‖² + ρ²` (R: np × np);
/// `(J, −e)` unchanged when there are not more rows than unknowns.
pub(super) fn reduced(j: &Mat<f64>, e: &Mat<f64>) -> (Mat<f64>, Vec<f64>) {
    let (rows, np) = (j.nrows(), j.ncols());
    if rows <= np {
        return (j.clone(), (0..rows).map(|r| -e[(r, 0)]).collect());
    }
    let mut je = Mat::<f64>::zeros(rows, np + 1);
    je.as_mut().submatrix_mut(0, 0, rows, np).copy_from(j);
    for r in 0..rows {
        je[(r, np)] = -e[(r, 0)];
    }
    let rf = sd_model::linalg::qr_r(je);
    (
        Mat::from_fn(np, np, |r, c| rf[(r, c)]),
        (0..np).map(|r| rf[(r, np)]).collect(),
    )
}

pub(super) fn lm(
    data: &Data,
    mut pf: Pf,
    opt: &FitOptions,
    history: &mut Vec<FitProgress>,
    progress: &mut dyn FnMut(&FitProgress),
) -> Result<Pf> {
    let mut v = cost(data, &pf);
    let mut lambda: f64 = 1e-3;
    let mut accepted = 0;
    for _ in 0..opt.lm_iterations {
        let (j, e) = jacobian(data, &pf, opt.feedthrough);
        let np = j.ncols();
        let dn: Vec<f64> = (0..np).map(|c| j.col(c).norm_l2()).collect();
        // one QR of [J, −e] per iteration (Moré's MINPACK): every damped trial then solves
        // `[R; √λ D] s ≈ [c; 0]` (2·np rows) instead of the full `[J; √λ D]`, with the same
        // singular values and the same step
        let (jr, cr) = reduced(&j, &e);
        let theta = to_params(&pf);
        let mut improved = false;
        for _ in 0..12 {
            let rows = jr.nrows();
            let mut aug = Mat::<f64>::zeros(rows + np, np);
            aug.as_mut().submatrix_mut(0, 0, rows, np).copy_from(&jr);
            let mut rhs = Mat::<f64>::zeros(rows + np, 1);
            for r in 0..rows {
                rhs[(r, 0)] = cr[r];
            }
            for c in 0..np {
                aug[(rows + c, c)] = lambda.sqrt() * dn[c].max(f64::MIN_POSITIVE);
            }
            let step = match lstsq(&aug, &rhs) {
                Ok(s) => s,
                Err(_) => {
                    lambda *= 10.0;
                    continue;
                }
            };
            let mut trial = theta.clone();
            for (t, s) in trial.iter_mut().zip(&step) {
                *t += s;
            }
            if !opt.feedthrough {
                if let Some(last) = trial.last_mut() {
                    *last = 0.0;
                }
            }
            let cand = from_params(&pf, &trial, data);
            let vc = cost(data, &cand);
            if vc.is_finite() && vc < v {
                let rel = (v - vc) / v;
                pf = cand;
                v = vc;
                lambda = (lambda / 3.0).max(1e-12);
                improved = true;
                accepted += 1;
                let p = FitProgress {
                    stage: "lm",
                    iteration: accepted,
                    cost: v,
                };
                progress(&p);
                history.push(p);
                if rel < tol::LM_STOP {
                    return Ok(pf);
                }
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    Ok(pf)
}
