//! Invariant zeros against systems built with known zeros (the mathematics is the reference:
//! a system with invertible `D` has the zeros `eig(A − B D⁻¹ C)`, so `A = Z + B D⁻¹ C` has
//! the zeros of `Z`, whose eigenvalues are chosen; cascades and stacked copies keep them), and
//! against the pencil's rank drop at each computed zero.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{SampleTime, StateSpace, TransferFunction};

/// A small deterministic generator (xorshift64*) of uniform numbers in [−1, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (v >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.next())
    }

    /// A random orthogonal matrix (the Q of a random matrix's QR).
    fn orthogonal(&mut self, n: usize) -> DMatrix<f64> {
        self.matrix(n, n).qr().q()
    }
}

/// The eigenvalues wanted, as a real matrix `Q blockdiag(...) Qᵀ` (2×2 blocks `[[a, b], [−b,
/// a]]` for `a ± bj`, 1×1 for reals): normal, so its eigenvalues are perfectly conditioned.
fn with_eigenvalues(rng: &mut Rng, pairs: &[(f64, f64)], reals: &[f64]) -> (DMatrix<f64>, Vec<C>) {
    let n = 2 * pairs.len() + reals.len();
    let mut z = DMatrix::zeros(n, n);
    let mut eig = Vec::new();
    for (k, &(a, b)) in pairs.iter().enumerate() {
        let i = 2 * k;
        z[(i, i)] = a;
        z[(i + 1, i + 1)] = a;
        z[(i, i + 1)] = b;
        z[(i + 1, i)] = -b;
        eig.push(C::new(a, b));
        eig.push(C::new(a, -b));
    }
    for (k, &r) in reals.iter().enumerate() {
        let i = 2 * pairs.len() + k;
        z[(i, i)] = r;
        eig.push(C::new(r, 0.0));
    }
    let q = rng.orthogonal(n);
    (&q * z * q.transpose(), eig)
}

/// A square system (m inputs and outputs) with invertible `D` whose zeros are `eig`.
fn square_with_zeros(
    rng: &mut Rng,
    m: usize,
    pairs: &[(f64, f64)],
    reals: &[f64],
) -> (StateSpace, Vec<C>) {
    let (z, eig) = with_eigenvalues(rng, pairs, reals);
    let n = z.nrows();
    let b = rng.matrix(n, m);
    let c = rng.matrix(m, n);
    // a well-conditioned D: identity plus a small random part
    let d = DMatrix::identity(m, m) + 0.3 * rng.matrix(m, m);
    let a = z + &b * d.clone().try_inverse().unwrap() * &c;
    let sys = StateSpace::new(a, b, c, d, SampleTime::Continuous).unwrap();
    (sys, eig)
}

/// `sys` followed by `1/(s + a)^k` on every output: strictly proper of relative degree `k`,
/// the same finite zeros (the added stages have none).
fn cascade(sys: &StateSpace, a: f64, k: usize) -> StateSpace {
    let (n, m, p) = (sys.n(), sys.nu(), sys.ny());
    let nn = n + k * p;
    let mut aa = DMatrix::zeros(nn, nn);
    let mut bb = DMatrix::zeros(nn, m);
    aa.view_mut((0, 0), (n, n)).copy_from(sys.a());
    bb.view_mut((0, 0), (n, m)).copy_from(sys.b());
    for stage in 0..k {
        let o = n + stage * p;
        for i in 0..p {
            aa[(o + i, o + i)] = -a;
        }
        if stage == 0 {
            aa.view_mut((o, 0), (p, n)).copy_from(sys.c());
            bb.view_mut((o, 0), (p, m)).copy_from(sys.d());
        } else {
            for i in 0..p {
                aa[(o + i, o - p + i)] = 1.0;
            }
        }
    }
    let mut cc = DMatrix::zeros(p, nn);
    for i in 0..p {
        cc[(i, n + (k - 1) * p + i)] = 1.0;
    }
    StateSpace::new(aa, bb, cc, DMatrix::zeros(p, m), SampleTime::Continuous).unwrap()
}

/// Every wanted zero matched by one computed zero within `tol` relative (and no other).
fn assert_zeros(got: &[C], want: &[C], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
    let mut used = vec![false; got.len()];
    let mut worst = 0.0f64;
    for w in want {
        let (i, e) = got
            .iter()
            .enumerate()
            .filter(|(i, _)| !used[*i])
            .map(|(i, g)| (i, (*g - *w).norm() / w.norm().max(1.0)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!(e < tol, "{what}: zero {w} off by {e:.2e} (got {got:?})");
        used[i] = true;
        worst = worst.max(e);
    }
    println!(
        "{what}: {} zeros, worst relative error {worst:.1e}",
        want.len()
    );
}

/// Complex zeros come in exact conjugate pairs.
fn assert_conjugate_closed(z: &[C]) {
    for w in z.iter().filter(|w| w.im != 0.0) {
        assert!(
            z.iter().any(|v| *v == w.conj()),
            "{w} without its conjugate in {z:?}"
        );
    }
}

/// The smallest singular value of the pencil `[A − zI, B; C, D]` relative to its largest,
/// from the real embedding `[[Re P, −Im P], [Im P, Re P]]` (its singular values are the
/// pencil's, each twice) by the SVD.
fn rank_drop(sys: &StateSpace, z: C) -> f64 {
    let (n, m, p) = (sys.n(), sys.nu(), sys.ny());
    let (r, c) = (n + p, n + m);
    let mut re = DMatrix::zeros(r, c);
    re.view_mut((0, 0), (n, n)).copy_from(sys.a());
    re.view_mut((0, n), (n, m)).copy_from(sys.b());
    re.view_mut((n, 0), (p, n)).copy_from(sys.c());
    re.view_mut((n, n), (p, m)).copy_from(sys.d());
    let mut im = DMatrix::zeros(r, c);
    for i in 0..n {
        re[(i, i)] -= z.re;
        im[(i, i)] = -z.im;
    }
    let mut e = DMatrix::zeros(2 * r, 2 * c);
    e.view_mut((0, 0), (r, c)).copy_from(&re);
    e.view_mut((r, c), (r, c)).copy_from(&re);
    e.view_mut((0, c), (r, c)).copy_from(&(-&im));
    e.view_mut((r, 0), (r, c)).copy_from(&im);
    let (_, s, _) = sd_model::linalg::convert::svd(&e).unwrap();
    s.last().unwrap() / s[0]
}

#[test]
fn siso_complex_zeros_of_a_transfer_function() {
    // (s² + 2s + 101)/(s³ + 3s² + 10s + 5): zeros −1 ± 10j exactly
    let tf = TransferFunction::new(
        vec![1.0, 2.0, 101.0],
        vec![1.0, 3.0, 10.0, 5.0],
        SampleTime::Continuous,
    )
    .unwrap();
    let g = tf.to_ss().unwrap();
    let want = [C::new(-1.0, 10.0), C::new(-1.0, -10.0)];
    let z = g.zeros().unwrap();
    assert_zeros(&z, &want, 1e-13, "canonical form");
    assert_conjugate_closed(&z);
    // in a random orthogonal state basis, and labelled discrete (the pencil is the same)
    let mut rng = Rng(7);
    let t = rng.orthogonal(3);
    let a = t.transpose() * g.a() * &t;
    let b = t.transpose() * g.b();
    let c = g.c() * &t;
    let gd = StateSpace::new(a, b, c, g.d().clone(), SampleTime::Discrete { ts: 1e-3 }).unwrap();
    assert_zeros(&gd.zeros().unwrap(), &want, 1e-12, "rotated, discrete");
}

#[test]
fn square_mimo_with_feedthrough() {
    for seed in 1..6u64 {
        let mut rng = Rng(seed * 7919);
        let (g, want) = square_with_zeros(
            &mut rng,
            3,
            &[(-0.5, 3.0), (0.2, 1.5), (-4.0, 0.3)],
            &[-2.0, 1.5],
        );
        let z = g.zeros().unwrap();
        assert_zeros(&z, &want, 1e-10, &format!("seed {seed}"));
        assert_conjugate_closed(&z);
    }
}

#[test]
fn strictly_proper_mimo_of_relative_degree_one_and_two() {
    for seed in 1..6u64 {
        let mut rng = Rng(seed * 104_729);
        let (g, want) = square_with_zeros(&mut rng, 2, &[(-0.3, 5.0), (1.0, 2.0)], &[-7.0]);
        for k in [1, 2] {
            let s = cascade(&g, 3.0, k);
            let z = s.zeros().unwrap();
            assert_zeros(&z, &want, 1e-9, &format!("seed {seed} degree {k}"));
            assert_conjugate_closed(&z);
        }
    }
}

#[test]
fn non_square_systems() {
    let mut rng = Rng(99);
    let (g, want) = square_with_zeros(&mut rng, 2, &[(-1.0, 4.0)], &[-3.0, 0.5]);
    let g = cascade(&g, 2.0, 1);
    // tall: the outputs and a mixture of them, rotated: the rank drops where g's does
    let (n, m) = (g.n(), g.nu());
    let mix = DMatrix::from_row_slice(2, 2, &[0.7, -1.3, 2.0, 0.4]);
    let mut c = DMatrix::zeros(4, n);
    c.view_mut((0, 0), (2, n)).copy_from(g.c());
    c.view_mut((2, 0), (2, n)).copy_from(&(&mix * g.c()));
    let q = rng.orthogonal(4);
    let tall = StateSpace::new(
        g.a().clone(),
        g.b().clone(),
        &q * c,
        DMatrix::zeros(4, m),
        SampleTime::Continuous,
    )
    .unwrap();
    assert_zeros(&tall.zeros().unwrap(), &want, 1e-9, "tall");
    // wide: its dual
    let wide = StateSpace::new(
        tall.a().transpose(),
        tall.c().transpose(),
        tall.b().transpose(),
        DMatrix::zeros(m, 4),
        SampleTime::Continuous,
    )
    .unwrap();
    assert_zeros(&wide.zeros().unwrap(), &want, 1e-9, "wide");
    // a generic non-square system has no zeros
    let generic = StateSpace::new(
        rng.matrix(6, 6),
        rng.matrix(6, 2),
        rng.matrix(3, 6),
        DMatrix::zeros(3, 2),
        SampleTime::Continuous,
    )
    .unwrap();
    assert!(generic.zeros().unwrap().is_empty());
}

#[test]
fn decoupling_zero_and_degenerate_pencil() {
    // the mode at −2 does not reach the output: an output-decoupling zero
    let g = StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -2.0]),
        DMatrix::from_row_slice(2, 1, &[1.0, 1.0]),
        DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        DMatrix::zeros(1, 1),
        SampleTime::Continuous,
    )
    .unwrap();
    assert_zeros(
        &g.zeros().unwrap(),
        &[C::new(-2.0, 0.0)],
        1e-14,
        "decoupling",
    );
    // an identically zero transfer function: the pencil is normal-rank deficient
    let zero = StateSpace::new(
        DMatrix::from_row_slice(1, 1, &[-1.0]),
        DMatrix::zeros(1, 1),
        DMatrix::from_row_slice(1, 1, &[1.0]),
        DMatrix::zeros(1, 1),
        SampleTime::Continuous,
    )
    .unwrap();
    let e = zero.zeros().unwrap_err().to_string();
    assert!(e.contains("normal rank"), "{e}");
}

#[test]
fn the_stage_models_zeros_are_zeros_of_their_transfer_functions() {
    // no reference values: at every computed zero the (SISO, minimal) stage model's response
    // vanishes against its value 1 % beside it, and the complex zeros are closed under
    // conjugation. (The pencil's smallest singular value does not resolve this: the 60-state
    // model's entries span 0.05 to 1e9, so σ_min/σ_max sits at rounding level everywhere.)
    for g in [
        sd_model::stage::paper_stage(0.01).unwrap(),
        sd_model::stage::stage60().unwrap(),
    ] {
        let z = g.zeros().unwrap();
        assert_conjugate_closed(&z);
        assert!(!z.is_empty());
        let gain = |s: C| g.eval_direct(s).unwrap()[(0, 0)].norm();
        for w in &z {
            let (at, off) = (gain(*w), gain(*w * 1.01 + 1.0));
            println!(
                "stage model ({} states) zero {w:.4}: |G| {at:.1e} (1 % beside {off:.1e})",
                g.n()
            );
            assert!(
                at < 1e-6 * off,
                "zero {w}: |G| {at:.2e}, beside it {off:.2e}"
            );
        }
        // and the pencil of the small model drops its rank there
        if g.n() < 10 {
            for w in &z {
                let (at, off) = (rank_drop(&g, *w), rank_drop(&g, *w * 1.01 + 1.0));
                assert!(
                    at < 1e-6 * off,
                    "zero {w}: σ_min/σ_max {at:.2e}, beside {off:.2e}"
                );
            }
        }
    }
}
