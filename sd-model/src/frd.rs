//! Frequency-response data: complex responses (ny×nu) at frequencies in Hz, optionally with the
//! variance of each complex estimate.

use crate::error::{ModelError, Result};
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// The error of a response that is not finite at `f_hz`.
pub(crate) fn non_finite_response(f_hz: f64) -> ModelError {
    ModelError::NonFinite {
        what: format!("FRD response at {f_hz} Hz (a pole on the frequency axis?)"),
    }
}

/// Frequency-response data.
///
/// Invariants (checked by [`Frd::new`]): one ny×nu response per frequency, all of one shape;
/// frequencies finite and ≥ 0; responses finite; variances (if any) finite, ≥ 0, same shapes.
#[derive(Debug, Clone, PartialEq)]
pub struct Frd {
    freq_hz: Vec<f64>,
    response: Vec<DMatrix<C>>,
    variance: Option<Vec<DMatrix<f64>>>,
    time: SampleTime,
}

impl Frd {
    /// Builds and validates an FRD.
    pub fn new(
        freq_hz: Vec<f64>,
        response: Vec<DMatrix<C>>,
        variance: Option<Vec<DMatrix<f64>>>,
        time: SampleTime,
    ) -> Result<Self> {
        if freq_hz.len() != response.len() {
            return Err(ModelError::dim(
                "FRD responses (one per frequency)",
                freq_hz.len(),
                response.len(),
            ));
        }
        if let Some((i, f)) = freq_hz
            .iter()
            .enumerate()
            .find(|(_, f)| !(f.is_finite() && **f >= 0.0))
        {
            return Err(ModelError::InvalidArgument(format!(
                "FRD frequency #{i} = {f} must be finite and >= 0"
            )));
        }
        let shape = response.first().map(|r| r.shape()).unwrap_or((1, 1));
        for (i, r) in response.iter().enumerate() {
            if r.shape() != shape {
                return Err(ModelError::dim(
                    format!("FRD response #{i}"),
                    format!("{}x{}", shape.0, shape.1),
                    format!("{}x{}", r.nrows(), r.ncols()),
                ));
            }
            if r.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
                return Err(non_finite_response(freq_hz[i]));
            }
        }
        if let Some(var) = &variance {
            if var.len() != freq_hz.len() {
                return Err(ModelError::dim(
                    "FRD variances (one per frequency)",
                    freq_hz.len(),
                    var.len(),
                ));
            }
            for (i, v) in var.iter().enumerate() {
                if v.shape() != shape {
                    return Err(ModelError::dim(
                        format!("FRD variance #{i}"),
                        format!("{}x{}", shape.0, shape.1),
                        format!("{}x{}", v.nrows(), v.ncols()),
                    ));
                }
                if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(ModelError::InvalidArgument(format!(
                        "FRD variance at {} Hz must be finite and >= 0",
                        freq_hz[i]
                    )));
                }
            }
        }
        if let SampleTime::Discrete { ts } = time {
            SampleTime::discrete(ts)?;
        }
        Ok(Frd {
            freq_hz,
            response,
            variance,
            time,
        })
    }
    /// Frequencies in Hz.
    pub fn freq_hz(&self) -> &[f64] {
        &self.freq_hz
    }
    /// Responses, one ny×nu matrix per frequency.
    pub fn response(&self) -> &[DMatrix<C>] {
        &self.response
    }
    /// Variances of the complex estimates, if known.
    pub fn variance(&self) -> Option<&[DMatrix<f64>]> {
        self.variance.as_deref()
    }
    /// Sample time of the data.
    pub fn time(&self) -> SampleTime {
        self.time
    }
    /// Number of frequencies.
    pub fn len(&self) -> usize {
        self.freq_hz.len()
    }
    /// True when there are no frequencies.
    pub fn is_empty(&self) -> bool {
        self.freq_hz.is_empty()
    }

    /// The lines where `keep(index)` holds (same sample time, variances kept).
    ///
    /// # Errors
    /// None in practice (the subset of a valid FRD is valid).
    pub fn select(&self, keep: impl Fn(usize) -> bool) -> Result<Frd> {
        let idx: Vec<usize> = (0..self.len()).filter(|&i| keep(i)).collect();
        Frd::new(
            idx.iter().map(|&i| self.freq_hz[i]).collect(),
            idx.iter().map(|&i| self.response[i].clone()).collect(),
            self.variance
                .as_ref()
                .map(|v| idx.iter().map(|&i| v[i].clone()).collect()),
            self.time,
        )
    }

    /// (ny, nu).
    pub fn shape(&self) -> (usize, usize) {
        self.response.first().map(|r| r.shape()).unwrap_or((0, 0))
    }
    /// The SISO response `(out, inp)` as a vector.
    pub fn siso(&self, out: usize, inp: usize) -> Result<Vec<C>> {
        let (ny, nu) = self.shape();
        if out >= ny || inp >= nu {
            return Err(ModelError::InvalidArgument(format!(
                "channel ({out}, {inp}) outside {ny}x{nu}"
            )));
        }
        Ok(self.response.iter().map(|r| r[(out, inp)]).collect())
    }

    /// The column of input `inp` as an ny×1 FRD with its variances (same lines and sample
    /// time).
    ///
    /// # Errors
    /// An input outside the FRD.
    pub fn column(&self, inp: usize) -> Result<Frd> {
        let (ny, nu) = self.shape();
        if inp >= nu {
            return Err(ModelError::InvalidArgument(format!(
                "input {inp} outside {ny}x{nu}"
            )));
        }
        Frd::new(
            self.freq_hz.clone(),
            self.response
                .iter()
                .map(|r| r.columns(inp, 1).into_owned())
                .collect(),
            self.variance
                .as_ref()
                .map(|v| v.iter().map(|m| m.columns(inp, 1).into_owned()).collect()),
            self.time,
        )
    }

    /// The entry `(out, inp)` as a SISO FRD with its variance (same lines and sample time).
    ///
    /// # Errors
    /// A channel outside the FRD.
    pub fn entry(&self, out: usize, inp: usize) -> Result<Frd> {
        let g = self.siso(out, inp)?;
        Frd::new(
            self.freq_hz.clone(),
            g.into_iter()
                .map(|v| DMatrix::from_element(1, 1, v))
                .collect(),
            self.variance.as_ref().map(|v| {
                v.iter()
                    .map(|m| DMatrix::from_element(1, 1, m[(out, inp)]))
                    .collect()
            }),
            self.time,
        )
    }
}
