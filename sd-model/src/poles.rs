//! Poles: eigenvalues of A (faer's multishift QR), and a pole's natural frequency and damping.
//! Invariant zeros are in [`crate::zeros`].

use crate::error::Result;
use crate::linalg::convert::eigenvalues;
use crate::ss::StateSpace;
use num_complex::Complex64 as C;

impl StateSpace {
    /// Poles (eigenvalues of A), sorted by modulus then argument.
    pub fn poles(&self) -> Result<Vec<C>> {
        let mut p = eigenvalues(self.a())?;
        p.sort_by(|a, b| {
            a.norm()
                .total_cmp(&b.norm())
                .then(a.arg().total_cmp(&b.arg()))
        });
        Ok(p)
    }
}

/// `(natural frequency in Hz, damping ratio)` of a pole: of `p` itself for a continuous model
/// (`ts = None`), of the principal continuous pole `s = ln(p)/ts` for a discrete one;
/// `f = |s|/2π`, `ζ = −Re s/|s|` (ζ = 1 at s = 0). The toolkit's one definition of a pole's
/// frequency (`sdctl poles`, `sdctl d2c`, python-control's `damp`).
pub fn natural_frequency(p: C, ts: Option<f64>) -> (f64, f64) {
    let s = match ts {
        None => p,
        Some(h) => p.ln() / h,
    };
    let f = s.norm() / (2.0 * std::f64::consts::PI);
    let z = if s.norm() == 0.0 {
        1.0
    } else {
        -s.re / s.norm()
    };
    (f, z)
}
