//! The simple poles' share of a frequency response, `Σ_k R_k/(s − t_k)`, at `L` points at once
//! (the points in SIMD lanes), with the conjugate pairs of a real model combined so that each
//! pair costs one real division instead of two.
//!
//! For a pole `t` (Im t > 0) with residue `R = x + iy` and its partner `t̄` with `R̄`, write
//! `d₁ = s − t = a + ib₁` and `d₂ = s − t̄ = a + ib₂` (a = Re s − Re t, b₁,₂ = Im s ∓ Im t).
//! Then
//!
//! ```text
//! R/d₁ + R̄/d₂ = (R d₂ + R̄ d₁)/(d₁ d₂),   R d₂ + R̄ d₁ = 2(x a − y Im t) + i·2x Im s,
//! d₁ d₂ = (a² − b₁b₂) + i·2a Im s,
//! ```
//!
//! and the quotient is `num·conj(den)/|den|²`. Rounding: the complex product `d₁d₂` has a
//! normwise relative error below √5·ε, and the numerator's absolute error is below
//! `4ε|R||d₂|`, so the pair's error is `O(ε)(|R|/|d₁| + |R|/|d₂|)`, the same bound as the two
//! terms summed one by one — no cancellation is introduced near a lightly damped pole
//! (where `d₁` is small, `d₁d₂` is formed as a product, never as `s² − 2Re t·s + |t|²`).
//!
//! Pairs are matched from the computed eigenvalues of the (complex) block-diagonal form: a
//! pole with Im t > 0 and the pole nearest its conjugate, when they agree within
//! [`PAIR_TOL`] relative and so do their residues; the pair's pole and residue are then the
//! mean of the two (so the response at conjugate points is exactly conjugate). Everything
//! else (real poles, unmatched ones) is summed term by term, `R·conj(d)/|d|²`.

use num_complex::Complex64 as C;

/// Relative agreement of a pole (and of its residues) with its partner's conjugate for the two
/// to be summed as a pair.
pub(crate) const PAIR_TOL: f64 = 1e-9;

/// Points per batch of [`PoleSum::accumulate`] in the many-point evaluations.
pub(crate) const LANES: usize = 4;

/// The simple poles as arrays (`*_x[e·np + k]`, `*_y`: real and imaginary parts of entry `e`'s
/// residue at pole `k`, entries column-major).
#[derive(Debug, Clone, Default)]
pub(crate) struct PoleSum {
    /// Pairs: the member with Im t > 0.
    pair_re: Vec<f64>,
    pair_im: Vec<f64>,
    pair_x: Vec<f64>,
    pair_y: Vec<f64>,
    /// Poles summed term by term.
    one_re: Vec<f64>,
    one_im: Vec<f64>,
    one_x: Vec<f64>,
    one_y: Vec<f64>,
    entries: usize,
}

/// The residues of pole `k` (`r[e·n + k]`, `n` poles).
fn residue(r: &[C], n: usize, entries: usize, k: usize) -> impl Iterator<Item = C> + '_ {
    (0..entries).map(move |e| r[e * n + k])
}

impl PoleSum {
    /// From the poles `t` and their residues `r[e·n + k]` (entry `e` of `entries`, pole `k`).
    pub(crate) fn new(t: &[C], r: &[C], entries: usize) -> Self {
        let n = t.len();
        let mut used = vec![false; n];
        let mut ps = PoleSum {
            entries,
            ..Default::default()
        };
        let (mut px, mut py, mut ox, mut oy) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let rmax = |k: usize| {
            residue(r, n, entries, k)
                .map(|z| z.norm())
                .fold(0.0, f64::max)
        };
        for k in 0..n {
            if used[k] || t[k].im <= 0.0 {
                continue;
            }
            let target = t[k].conj();
            let partner = (0..n)
                .filter(|&j| !used[j] && j != k && t[j].im < 0.0)
                .min_by(|&i, &j| (t[i] - target).norm().total_cmp(&(t[j] - target).norm()));
            let Some(j) = partner else { continue };
            let close = (t[j] - target).norm() <= PAIR_TOL * t[k].norm().max(1.0);
            let scale = rmax(k).max(rmax(j));
            let same = residue(r, n, entries, k)
                .zip(residue(r, n, entries, j))
                .all(|(a, b)| (a - b.conj()).norm() <= PAIR_TOL * scale);
            if !(close && same) {
                continue;
            }
            used[k] = true;
            used[j] = true;
            let tm = (t[k] + t[j].conj()) * 0.5;
            ps.pair_re.push(tm.re);
            ps.pair_im.push(tm.im);
            let rm: Vec<C> = residue(r, n, entries, k)
                .zip(residue(r, n, entries, j))
                .map(|(a, b)| (a + b.conj()) * 0.5)
                .collect();
            px.push(rm.iter().map(|z| z.re).collect::<Vec<f64>>());
            py.push(rm.iter().map(|z| z.im).collect::<Vec<f64>>());
        }
        for k in (0..n).filter(|&k| !used[k]) {
            ps.one_re.push(t[k].re);
            ps.one_im.push(t[k].im);
            ox.push(
                residue(r, n, entries, k)
                    .map(|z| z.re)
                    .collect::<Vec<f64>>(),
            );
            oy.push(
                residue(r, n, entries, k)
                    .map(|z| z.im)
                    .collect::<Vec<f64>>(),
            );
        }
        // entry-major arrays: [e·np + k]
        let flat = |v: &[Vec<f64>]| -> Vec<f64> {
            (0..entries)
                .flat_map(|e| v.iter().map(move |row| row[e]))
                .collect()
        };
        ps.pair_x = flat(&px);
        ps.pair_y = flat(&py);
        ps.one_x = flat(&ox);
        ps.one_y = flat(&oy);
        ps
    }

    /// Number of simple poles.
    pub(crate) fn count(&self) -> usize {
        2 * self.pair_re.len() + self.one_re.len()
    }

    /// `(pairs, poles summed one by one)`.
    pub(crate) fn counts(&self) -> (usize, usize) {
        (self.pair_re.len(), self.one_re.len())
    }

    /// `g[e][l] += Σ_k R_k,e/(s_l − t_k)` for the `L` points `s_l = sr[l] + i·si[l]`
    /// (`gr`/`gi`: real and imaginary parts, one row of `L` lanes per entry).
    pub(crate) fn accumulate<const L: usize>(
        &self,
        sr: &[f64; L],
        si: &[f64; L],
        gr: &mut [[f64; L]],
        gi: &mut [[f64; L]],
    ) {
        // the same loops compiled for the widest vector unit this processor has (AVX2 and FMA
        // where present: pulp checks the CPU once and calls the matching copy)
        pulp::Arch::new().dispatch(Kernel {
            ps: self,
            sr,
            si,
            gr,
            gi,
        });
    }

    #[inline(always)]
    fn accumulate_lanes<const L: usize>(
        &self,
        sr: &[f64; L],
        si: &[f64; L],
        gr: &mut [[f64; L]],
        gi: &mut [[f64; L]],
    ) {
        let np = self.pair_re.len();
        for k in 0..np {
            let (tr, ti) = (self.pair_re[k], self.pair_im[k]);
            let (mut a, mut dr, mut di, mut inv) = ([0.0; L], [0.0; L], [0.0; L], [0.0; L]);
            for l in 0..L {
                a[l] = sr[l] - tr;
                let (b1, b2) = (si[l] - ti, si[l] + ti);
                dr[l] = a[l] * a[l] - b1 * b2;
                di[l] = 2.0 * a[l] * si[l];
                inv[l] = 1.0 / (dr[l] * dr[l] + di[l] * di[l]);
            }
            for e in 0..self.entries {
                let (x, y) = (self.pair_x[e * np + k], self.pair_y[e * np + k]);
                let (ge_r, ge_i) = (&mut gr[e], &mut gi[e]);
                for l in 0..L {
                    let nr = 2.0 * (x * a[l] - y * ti);
                    let ni = 2.0 * x * si[l];
                    ge_r[l] += (nr * dr[l] + ni * di[l]) * inv[l];
                    ge_i[l] += (ni * dr[l] - nr * di[l]) * inv[l];
                }
            }
        }
        let no = self.one_re.len();
        for k in 0..no {
            let (dr, di, inv) = offsets(sr, si, C::new(self.one_re[k], self.one_im[k]));
            for e in 0..self.entries {
                let (x, y) = (self.one_x[e * no + k], self.one_y[e * no + k]);
                let (ge_r, ge_i) = (&mut gr[e], &mut gi[e]);
                for l in 0..L {
                    // R·conj(d)/|d|²
                    ge_r[l] += (x * dr[l] + y * di[l]) * inv[l];
                    ge_i[l] += (y * dr[l] - x * di[l]) * inv[l];
                }
            }
        }
    }
}

/// `d = s_l − t` and `1/|d|²` in each of the `L` lanes (one real division each): what the
/// term-by-term poles here and the clusters' diagonals in `freqresp.rs` divide by.
#[inline(always)]
pub(crate) fn offsets<const L: usize>(
    sr: &[f64; L],
    si: &[f64; L],
    t: C,
) -> ([f64; L], [f64; L], [f64; L]) {
    let (mut dr, mut di, mut inv) = ([0.0; L], [0.0; L], [0.0; L]);
    for l in 0..L {
        dr[l] = sr[l] - t.re;
        di[l] = si[l] - t.im;
        inv[l] = 1.0 / (dr[l] * dr[l] + di[l] * di[l]);
    }
    (dr, di, inv)
}

/// [`PoleSum::accumulate`]'s arguments, for pulp's dispatch (its `with_simd` is inlined into
/// a copy compiled with the processor's vector features).
struct Kernel<'a, const L: usize> {
    ps: &'a PoleSum,
    sr: &'a [f64; L],
    si: &'a [f64; L],
    gr: &'a mut [[f64; L]],
    gi: &'a mut [[f64; L]],
}

impl<const L: usize> pulp::WithSimd for Kernel<'_, L> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        self.ps.accumulate_lanes(self.sr, self.si, self.gr, self.gi);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pairs, a real pole and an unpaired complex pole against the terms summed one by one
    /// with complex arithmetic, at points near and far from the poles.
    #[test]
    fn pairs_match_the_terms_one_by_one() {
        let t = vec![
            C::from_polar(0.99999, 0.3),
            C::new(0.4, 0.0),
            C::from_polar(0.99999, -0.3),
            C::from_polar(0.9, 1.2),
            C::new(0.2, 0.5),
            C::from_polar(0.9, -1.2),
        ];
        let n = t.len();
        // two entries; conjugate residues for the conjugate poles, none for 0.2 + 0.5i
        let base = [
            C::new(1.0, 0.3),
            C::new(0.7, 0.0),
            C::new(1.0, -0.3),
            C::new(-0.2, 0.8),
            C::new(0.1, 0.1),
            C::new(-0.2, -0.8),
        ];
        let r: Vec<C> = (0..2)
            .flat_map(|e| base.iter().map(move |z| z * (1.0 + e as f64)))
            .collect();
        let ps = PoleSum::new(&t, &r, 2);
        assert_eq!(ps.counts(), (2, 2));
        assert_eq!(ps.count(), n);
        let pts = [
            C::from_polar(1.0, 0.3 + 1e-6),
            C::from_polar(1.0, 0.2),
            C::from_polar(1.0, 2.5),
            C::from_polar(1.0, 1.2001),
        ];
        let (sr, si) = (pts.map(|z| z.re), pts.map(|z| z.im));
        let (mut gr, mut gi) = (vec![[0.0; 4]; 2], vec![[0.0; 4]; 2]);
        ps.accumulate(&sr, &si, &mut gr, &mut gi);
        for (l, &s) in pts.iter().enumerate() {
            for e in 0..2 {
                let want: C = (0..n).map(|k| r[e * n + k] / (s - t[k])).sum();
                let got = C::new(gr[e][l], gi[e][l]);
                let scale: f64 = (0..n).map(|k| (r[e * n + k] / (s - t[k])).norm()).sum();
                assert!(
                    (got - want).norm() <= 16.0 * f64::EPSILON * scale,
                    "point {l} entry {e}: {got} vs {want}"
                );
            }
        }
    }
}
