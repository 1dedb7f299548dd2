//! SISO transfer functions `N(s)/D(s)` or `N(z)/D(z)`, coefficients in descending powers.

use crate::error::{ModelError, Result};
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// A proper SISO transfer function. Invariant: finite coefficients, `den` has a nonzero leading
/// coefficient, `deg num ≤ deg den`.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferFunction {
    num: Vec<f64>,
    den: Vec<f64>,
    time: SampleTime,
}

fn trim(mut v: Vec<f64>) -> Vec<f64> {
    while v.len() > 1 && v[0] == 0.0 {
        v.remove(0);
    }
    v
}

impl TransferFunction {
    /// Builds a transfer function from descending-power coefficients.
    pub fn new(num: Vec<f64>, den: Vec<f64>, time: SampleTime) -> Result<Self> {
        if num.iter().chain(den.iter()).any(|v| !v.is_finite()) {
            return Err(ModelError::NonFinite {
                what: "transfer-function coefficients".into(),
            });
        }
        let num = trim(num);
        let den = trim(den);
        if den.is_empty() || den[0] == 0.0 {
            return Err(ModelError::InvalidArgument(
                "the denominator is zero".into(),
            ));
        }
        if num.is_empty() {
            return Err(ModelError::InvalidArgument("the numerator is empty".into()));
        }
        if num.len() > den.len() && !(num.len() == 1 || num.iter().all(|v| *v == 0.0)) {
            return Err(ModelError::InvalidArgument(format!(
                "improper transfer function (numerator degree {} > denominator degree {})",
                num.len() - 1,
                den.len() - 1
            )));
        }
        Ok(TransferFunction { num, den, time })
    }
    /// Numerator coefficients.
    pub fn num(&self) -> &[f64] {
        &self.num
    }
    /// Denominator coefficients.
    pub fn den(&self) -> &[f64] {
        &self.den
    }
    /// Sample time.
    pub fn time(&self) -> SampleTime {
        self.time
    }
    /// Value at a complex point (Horner).
    pub fn eval_at(&self, s: C) -> C {
        let h = |p: &[f64]| p.iter().fold(C::new(0.0, 0.0), |acc, &c| acc * s + c);
        h(&self.num) / h(&self.den)
    }
    /// Observable canonical realisation.
    pub fn to_ss(&self) -> Result<StateSpace> {
        let a0 = self.den[0];
        let den: Vec<f64> = self.den.iter().map(|v| v / a0).collect();
        let n = den.len() - 1;
        let mut num = vec![0.0; n + 1 - self.num.len().min(n + 1)];
        num.extend(self.num.iter().map(|v| v / a0));
        let d = num[0];
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, 1);
        let mut c = DMatrix::zeros(1, n);
        for i in 0..n {
            a[(i, 0)] = -den[i + 1];
            if i + 1 < n {
                a[(i, i + 1)] = 1.0;
            }
            b[(i, 0)] = num[i + 1] - den[i + 1] * d;
        }
        if n > 0 {
            c[(0, 0)] = 1.0;
        }
        StateSpace::new(a, b, c, DMatrix::from_element(1, 1, d), self.time)
    }
}
