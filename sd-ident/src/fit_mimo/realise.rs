//! The common-pole fit as a state-space model: each mode's rank-r residue realised with r
//! input columns, the rigid body's Jordan block (module documentation of [`super`]).

use super::*;

/// The modal realisation (module documentation) of factors `f` of the free poles, the rigid
/// and feedthrough coefficients `rest` per entry.
pub(super) fn realise(
    f: &[(DMatrix<C>, DMatrix<C>)],
    poles: &[(C, bool)],
    rest: &[Vec<f64>],
    (ny, nu, m, feed): (usize, usize, usize, bool),
    ts: f64,
) -> Result<StateSpace> {
    let (ra, rb, rc) = rigid_block(rest, (ny, nu, m));
    let nr = ra.nrows();
    let n: usize = nr
        + f.iter()
            .zip(poles)
            .map(|((u, _), &(_, pair))| u.ncols() * if pair { 2 } else { 1 })
            .sum::<usize>();
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DMatrix::<f64>::zeros(n, nu);
    let mut c = DMatrix::<f64>::zeros(ny, n);
    let mut d = DMatrix::<f64>::zeros(ny, nu);
    a.view_mut((0, 0), (nr, nr)).copy_from(&ra);
    b.view_mut((0, 0), (nr, nu)).copy_from(&rb);
    c.view_mut((0, 0), (ny, nr)).copy_from(&rc);
    let mut i = nr;
    for ((u, v), &(p, pair)) in f.iter().zip(poles) {
        for l in 0..u.ncols() {
            if pair {
                a[(i, i)] = p.re;
                a[(i, i + 1)] = -p.im;
                a[(i + 1, i)] = p.im;
                a[(i + 1, i + 1)] = p.re;
                for col in 0..nu {
                    b[(i, col)] = v[(col, l)].re;
                    b[(i + 1, col)] = v[(col, l)].im;
                }
                for row in 0..ny {
                    c[(row, i)] = 2.0 * u[(row, l)].re;
                    c[(row, i + 1)] = -2.0 * u[(row, l)].im;
                }
                i += 2;
            } else {
                a[(i, i)] = p.re;
                for col in 0..nu {
                    b[(i, col)] = v[(col, l)].re;
                }
                for row in 0..ny {
                    c[(row, i)] = u[(row, l)].re;
                }
                i += 1;
            }
        }
    }
    if feed {
        for row in 0..ny {
            for col in 0..nu {
                d[(row, col)] = rest[row * nu + col][m];
            }
        }
    }
    Ok(StateSpace::new(a, b, c, d, SampleTime::discrete(ts)?)?)
}

/// The rigid body `Σ_{l≤m} C_l/(z − 1)^l` (`C_l` from each entry's `rest`) realised with the
/// fewest states (Ho–Kalman): with `ζ = z − 1` it is `C (ζI − N)⁻¹ B` with `N` nilpotent and
/// Markov parameters `C_l = C N^{l−1} B`; the block Hankel matrix of `C_1 … C_m` (m + 1 block
/// rows, m block columns) factors by its SVD into observability and controllability parts
/// of its numerical rank r (singular values above 1e-9 of the largest), `N` follows from the
/// shift of the observability part, and `A = I + N`. r states: 2 for a rank-one double
/// integrator, where one chain per input would take `m·nu`.
pub(super) fn rigid_block(
    rest: &[Vec<f64>],
    (ny, nu, m): (usize, usize, usize),
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let empty = || {
        (
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, nu),
            DMatrix::zeros(ny, 0),
        )
    };
    if m == 0 {
        return empty();
    }
    let markov = |l: usize| -> DMatrix<f64> {
        if l == 0 || l > m {
            return DMatrix::zeros(ny, nu);
        }
        DMatrix::from_fn(ny, nu, |a, b| rest[a * nu + b][l - 1])
    };
    let mut h = DMatrix::<f64>::zeros((m + 1) * ny, m * nu);
    for i in 0..=m {
        for j in 0..m {
            h.view_mut((i * ny, j * nu), (ny, nu))
                .copy_from(&markov(i + j + 1));
        }
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return empty();
    };
    let s = &svd.singular_values;
    let top = s.iter().cloned().fold(0.0, f64::max);
    let r = s.iter().filter(|v| **v > 1e-9 * top).count();
    if r == 0 {
        return empty();
    }
    let sq: Vec<f64> = (0..r).map(|k| s[k].sqrt()).collect();
    let o = DMatrix::from_fn((m + 1) * ny, r, |i, k| u[(i, k)] * sq[k]);
    let q = DMatrix::from_fn(r, m * nu, |k, j| sq[k] * vt[(k, j)]);
    let up = o.rows(0, m * ny).into_owned();
    let down = o.rows(ny, m * ny).into_owned();
    let n = up
        .pseudo_inverse(1e-12 * top.sqrt())
        .map_or_else(|_| DMatrix::zeros(r, r), |p| p * down);
    let a = DMatrix::identity(r, r) + n;
    (a, q.columns(0, nu).into_owned(), o.rows(0, ny).into_owned())
}
