//! The residue matrices of the common-pole fit at a stated or supported rank: the rank the
//! data support, rank-r factors by alternating least squares (module documentation of
//! [`super`]).

use super::*;

/// A free pole's columns in an entry's coefficients: `(first column, pair?)`.
pub(super) fn pole_columns(nr: usize, npairs: usize) -> Vec<(usize, bool)> {
    (0..nr)
        .map(|q| (q, false))
        .chain((0..npairs).map(|q| (nr + 2 * q, true)))
        .collect()
}

/// The residue matrix of the free pole at `(col, pair)` (ny × nu; real for a real pole).
pub(super) fn residue_matrix(
    xs: &[Vec<f64>],
    ny: usize,
    nu: usize,
    (col, pair): (usize, bool),
) -> DMatrix<C> {
    DMatrix::from_fn(ny, nu, |a, b| {
        let x = &xs[a * nu + b];
        C::new(x[col], if pair { x[col + 1] } else { 0.0 })
    })
}

/// The rank the data support for one free pole's residues (module documentation, step 3).
pub(super) fn supported_rank(
    fits: &[EntryFit],
    ny: usize,
    nu: usize,
    (col, pair): (usize, bool),
    alpha: f64,
) -> usize {
    let xs: Vec<Vec<f64>> = fits.iter().map(|f| f.x.clone()).collect();
    let r = residue_matrix(&xs, ny, nu, (col, pair));
    let svd = r.clone().svd(true, true);
    let (Some(u), Some(vt)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
        return ny.min(nu);
    };
    let s = &svd.singular_values;
    let full = ny.min(nu);
    for k in 1..full {
        // variance of s_{k+1} from the residues' covariance: δs = Re(u_{k+1}ᴴ δR v_{k+1})
        let var: f64 = (0..ny)
            .flat_map(|a| (0..nu).map(move |b| (a, b)))
            .map(|(a, b)| {
                let g = u[(a, k)].conj() * vt[(k, b)].conj();
                let cov = &fits[a * nu + b].cov;
                if pair {
                    let v = [g.re, -g.im];
                    (0..2)
                        .map(|i| {
                            (0..2)
                                .map(|j| v[i] * cov[(col + i, col + j)] * v[j])
                                .sum::<f64>()
                        })
                        .sum::<f64>()
                } else {
                    g.re * g.re * cov[(col, col)]
                }
            })
            .sum();
        let rest: f64 = (k..full).map(|l| s[l] * s[l]).sum();
        let dof = ((ny - k) * (nu - k) * if pair { 2 } else { 1 }) as f64;
        if var > 0.0 && rest / var <= sd_model::chi2_quantile(1.0 - alpha, dof) {
            return k;
        }
    }
    full
}

/// Rank-`k` factors `(U, V)` of each free pole (`R ≈ U Vᵀ`, `U` ny × k, `V` nu × k) from the
/// truncated SVD of its free residues.
pub(super) fn factors(
    xs: &[Vec<f64>],
    ny: usize,
    nu: usize,
    cols: &[(usize, bool)],
    ranks: &[usize],
) -> Vec<(DMatrix<C>, DMatrix<C>)> {
    cols.iter()
        .zip(ranks)
        .map(|(&pc, &k)| {
            let r = residue_matrix(xs, ny, nu, pc);
            if !pc.1 {
                // a real pole's residues are real: real factors
                let svd = r.map(|v| v.re).svd(true, true);
                let s = &svd.singular_values;
                let (u, vt) = match (svd.u, svd.v_t) {
                    (Some(u), Some(vt)) => (u, vt),
                    _ => (
                        DMatrix::identity(ny, ny.min(nu)),
                        DMatrix::identity(ny.min(nu), nu),
                    ),
                };
                let uf = DMatrix::from_fn(ny, k, |a, l| C::new(u[(a, l)] * s[l], 0.0));
                let vf = DMatrix::from_fn(nu, k, |b, l| C::new(vt[(l, b)], 0.0));
                return (uf, vf);
            }
            let svd = r.svd(true, true);
            let (u, vt) = match (svd.u, svd.v_t) {
                (Some(u), Some(vt)) => (u, vt),
                _ => (
                    DMatrix::identity(ny, ny.min(nu)),
                    DMatrix::identity(ny.min(nu), nu),
                ),
            };
            let s = &svd.singular_values;
            let uf = DMatrix::from_fn(ny, k, |a, l| u[(a, l)] * s[l]);
            let vf = DMatrix::from_fn(nu, k, |b, l| vt[(l, b)]);
            (uf, vf)
        })
        .collect()
}

/// The residues of every entry from the factors (free columns) and `rest` (rigid and
/// feedthrough coefficients per entry).
pub(super) fn compose(
    f: &[(DMatrix<C>, DMatrix<C>)],
    cols: &[(usize, bool)],
    rest: &[Vec<f64>],
    ny: usize,
    nu: usize,
    nf: usize,
) -> Vec<Vec<f64>> {
    (0..ny * nu)
        .map(|e| {
            let (a, b) = (e / nu, e % nu);
            let mut x = vec![0.0; nf];
            for ((u, v), &(col, pair)) in f.iter().zip(cols) {
                let r: C = (0..u.ncols()).map(|l| u[(a, l)] * v[(b, l)]).sum();
                x[col] = r.re;
                if pair {
                    x[col + 1] = r.im;
                }
            }
            x.extend_from_slice(&rest[e]);
            x
        })
        .collect()
}

/// Which factor an alternating step solves for.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Side {
    /// Row `a` of every `U` (and the rest of the entries `(a, ·)`).
    Output(usize),
    /// Row `b` of every `V` (and the rest of the entries `(·, b)`).
    Input(usize),
}

/// Problem of the rank-constrained residues with the poles fixed.
pub(super) struct Ranked<'a> {
    pub(super) e: &'a Entries,
    pub(super) real: &'a [f64],
    pub(super) pairs: &'a [C],
    pub(super) m: usize,
    pub(super) feed: bool,
}

impl Ranked<'_> {
    /// The free poles as `(pole, pair?)`, in the order of [`pole_columns`].
    pub(super) fn poles(&self) -> Vec<(C, bool)> {
        self.real
            .iter()
            .map(|&p| (C::new(p, 0.0), false))
            .chain(self.pairs.iter().map(|&p| (p, true)))
            .collect()
    }

    /// One alternating step: the least squares of one side's factor row and the rest
    /// coefficients of the entries it touches, the other side fixed.
    pub(super) fn step(
        &self,
        f: &mut [(DMatrix<C>, DMatrix<C>)],
        rest: &mut [Vec<f64>],
        side: Side,
    ) -> Result<()> {
        let (ny, nu) = (self.e.ny, self.e.nu);
        let poles = self.poles();
        let entries: Vec<usize> = match side {
            Side::Output(a) => (0..nu).map(|b| a * nu + b).collect(),
            Side::Input(b) => (0..ny).map(|a| a * nu + b).collect(),
        };
        let nrest = self.m + usize::from(self.feed);
        let nfac: usize = f
            .iter()
            .zip(&poles)
            .map(|((u, _), &(_, pair))| u.ncols() * if pair { 2 } else { 1 })
            .sum();
        let ncol = nfac + nrest * entries.len();
        let k = self.e.data[0].z.len();
        let mut a = Mat::<f64>::zeros(2 * k * entries.len(), ncol);
        let mut rhs = vec![0.0; 2 * k * entries.len()];
        let mut rb = Vec::new();
        for (ei, &en) in entries.iter().enumerate() {
            let d = &self.e.data[en];
            let (ea, eb) = (en / nu, en % nu);
            for (i, ((&z, &g), &w)) in d.z.iter().zip(&d.g).zip(&d.w).enumerate() {
                let row = 2 * (ei * k + i);
                let mut c = 0;
                let mut put = |c: usize, v: C| {
                    a[(row, c)] = w * v.re;
                    a[(row + 1, c)] = w * v.im;
                };
                for ((u, v), &(p, pair)) in f.iter().zip(&poles) {
                    for l in 0..u.ncols() {
                        // the fixed side's factor of this entry
                        let other = match side {
                            Side::Output(_) => v[(eb, l)],
                            Side::Input(_) => u[(ea, l)],
                        };
                        if pair {
                            let (uz, vz) = (1.0 / (z - p), 1.0 / (z - p.conj()));
                            put(c, other * uz + other.conj() * vz);
                            put(c + 1, C::new(0.0, 1.0) * (other * uz - other.conj() * vz));
                            c += 2;
                        } else {
                            put(c, C::new(other.re, 0.0) / (z - p.re));
                            c += 1;
                        }
                    }
                }
                rb.clear();
                crate::fit::rigid_basis(self.m, z, &mut rb);
                if self.feed {
                    rb.push(C::new(1.0, 0.0));
                }
                for (j, v) in rb.iter().enumerate() {
                    put(nfac + ei * nrest + j, *v);
                }
                rhs[row] = w * g.re;
                rhs[row + 1] = w * g.im;
            }
        }
        let ls = sd_model::linalg::lstsq_faer(a.as_ref(), &rhs).map_err(|err| {
            IdentError::Numerical(format!("the rank-constrained residues failed: {err}"))
        })?;
        let x: Vec<f64> = ls.x.iter().copied().collect();
        let mut c = 0;
        for ((u, v), &(_, pair)) in f.iter_mut().zip(&poles) {
            for l in 0..u.ncols() {
                let val = if pair {
                    c += 2;
                    C::new(x[c - 2], x[c - 1])
                } else {
                    c += 1;
                    C::new(x[c - 1], 0.0)
                };
                match side {
                    Side::Output(a) => u[(a, l)] = val,
                    Side::Input(b) => v[(b, l)] = val,
                }
            }
        }
        for (ei, &en) in entries.iter().enumerate() {
            rest[en] = x[nfac + ei * nrest..nfac + (ei + 1) * nrest].to_vec();
        }
        Ok(())
    }

    /// Alternating least squares from `f`, `rest` (updated in place) until the cost settles;
    /// the entries' coefficients and the cost.
    pub(super) fn solve_into(
        &self,
        f: &mut [(DMatrix<C>, DMatrix<C>)],
        rest: &mut [Vec<f64>],
    ) -> Result<(Vec<Vec<f64>>, f64)> {
        let (ny, nu) = (self.e.ny, self.e.nu);
        let nf = self.real.len() + 2 * self.pairs.len();
        let cols = pole_columns(self.real.len(), self.pairs.len());
        let cost_of = |f: &[(DMatrix<C>, DMatrix<C>)], rest: &[Vec<f64>]| {
            let xs = compose(f, &cols, rest, ny, nu, nf);
            let c: f64 = entry_costs(self.e, &xs, self.real, self.pairs, self.m, self.feed)
                .iter()
                .sum();
            (xs, c)
        };
        let (mut xs, mut cost) = cost_of(f, rest);
        for _ in 0..ALS_SWEEPS {
            for a in 0..ny {
                self.step(f, rest, Side::Output(a))?;
            }
            for b in 0..nu {
                self.step(f, rest, Side::Input(b))?;
            }
            // each step solves its own least squares exactly: the cost never rises
            let (x2, c2) = cost_of(f, rest);
            let settled = (cost - c2).abs() <= 1e-10 * cost.max(f64::MIN_POSITIVE);
            (xs, cost) = (x2, c2);
            if settled {
                break;
            }
        }
        Ok((xs, cost))
    }
}

/// Most alternating sweeps of the rank-constrained residues.
pub(super) const ALS_SWEEPS: usize = 50;
