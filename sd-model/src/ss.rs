//! The state-space model `x⁺ = A x + B u`, `y = C x + D u` (x⁺ = ẋ in continuous time).

use crate::error::{ModelError, Result};
use crate::time::SampleTime;
use nalgebra::DMatrix;

/// A linear time-invariant state-space model with validated shapes and finite entries.
///
/// Invariants (checked once by [`StateSpace::new`]): `A` is n×n, `B` n×nu, `C` ny×n, `D` ny×nu;
/// all entries are finite. `n = 0` (a static gain) is valid. Fields are private so that every
/// value of this type satisfies the invariants.
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
    time: SampleTime,
    name: Option<String>,
    inputs: Option<Vec<String>>,
    outputs: Option<Vec<String>>,
}

pub(crate) fn check_finite(m: &DMatrix<f64>, what: &str) -> Result<()> {
    if m.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ModelError::NonFinite {
            what: what.to_string(),
        })
    }
}

impl StateSpace {
    /// Builds a model, checking that the shapes agree and that every entry is finite.
    ///
    /// # Errors
    /// [`ModelError::DimensionMismatch`] naming the matrix whose shape is wrong,
    /// [`ModelError::NonFinite`] for NaN/Inf entries.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        time: SampleTime,
    ) -> Result<Self> {
        let n = a.nrows();
        if a.ncols() != n {
            return Err(ModelError::dim(
                "A (must be square)",
                format!("{n}x{n}"),
                format!("{}x{}", n, a.ncols()),
            ));
        }
        let (ny, nu) = d.shape();
        if b.shape() != (n, nu) {
            return Err(ModelError::dim(
                "B",
                format!("{n}x{nu}"),
                format!("{}x{}", b.nrows(), b.ncols()),
            ));
        }
        if c.shape() != (ny, n) {
            return Err(ModelError::dim(
                "C",
                format!("{ny}x{n}"),
                format!("{}x{}", c.nrows(), c.ncols()),
            ));
        }
        check_finite(&a, "A")?;
        check_finite(&b, "B")?;
        check_finite(&c, "C")?;
        check_finite(&d, "D")?;
        if let SampleTime::Discrete { ts } = time {
            SampleTime::discrete(ts)?;
        }
        Ok(StateSpace {
            a,
            b,
            c,
            d,
            time,
            name: None,
            inputs: None,
            outputs: None,
        })
    }

    /// A static gain `y = D u` (no states).
    pub fn gain(d: DMatrix<f64>, time: SampleTime) -> Result<Self> {
        let (ny, nu) = d.shape();
        Self::new(
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, nu),
            DMatrix::zeros(ny, 0),
            d,
            time,
        )
    }

    /// State matrix A (n×n).
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }
    /// Input matrix B (n×nu).
    pub fn b(&self) -> &DMatrix<f64> {
        &self.b
    }
    /// Output matrix C (ny×n).
    pub fn c(&self) -> &DMatrix<f64> {
        &self.c
    }
    /// Feedthrough D (ny×nu).
    pub fn d(&self) -> &DMatrix<f64> {
        &self.d
    }
    /// Sample time.
    pub fn time(&self) -> SampleTime {
        self.time
    }
    /// Sampling period, `None` in continuous time.
    pub fn ts(&self) -> Option<f64> {
        self.time.ts()
    }
    /// Number of states.
    pub fn n(&self) -> usize {
        self.a.nrows()
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.d.ncols()
    }
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.d.nrows()
    }
    /// Optional model name.
    pub fn name(&self) -> Option<&str> {
        self.name.as_deref()
    }
    /// Optional input names.
    pub fn input_names(&self) -> Option<&[String]> {
        self.inputs.as_deref()
    }
    /// Optional output names.
    pub fn output_names(&self) -> Option<&[String]> {
        self.outputs.as_deref()
    }
    /// Sets the name.
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }
    /// Sets input and output names; their counts must equal nu and ny.
    pub fn with_signal_names(
        mut self,
        inputs: Option<Vec<String>>,
        outputs: Option<Vec<String>>,
    ) -> Result<Self> {
        if let Some(i) = &inputs {
            if i.len() != self.nu() {
                return Err(ModelError::dim("input names", self.nu(), i.len()));
            }
        }
        if let Some(o) = &outputs {
            if o.len() != self.ny() {
                return Err(ModelError::dim("output names", self.ny(), o.len()));
            }
        }
        self.inputs = inputs;
        self.outputs = outputs;
        Ok(self)
    }
    /// This model with `from`'s name, and its input and output names where the counts match:
    /// every transform that keeps the signals (c2d, d2c, Lemma 6, non-ideal discretisation)
    /// keeps the labels.
    pub fn with_labels_of(self, from: &StateSpace) -> StateSpace {
        let named = match from.name() {
            Some(n) => self.with_name(n),
            None => self,
        };
        let inputs = from
            .input_names()
            .filter(|i| i.len() == named.nu())
            .map(<[String]>::to_vec);
        let outputs = from
            .output_names()
            .filter(|o| o.len() == named.ny())
            .map(<[String]>::to_vec);
        match named.clone().with_signal_names(inputs, outputs) {
            Ok(labelled) => labelled,
            Err(_) => named,
        }
    }
    /// Consumes the model and returns `(A, B, C, D, time)`.
    pub fn into_parts(
        self,
    ) -> (
        DMatrix<f64>,
        DMatrix<f64>,
        DMatrix<f64>,
        DMatrix<f64>,
        SampleTime,
    ) {
        (self.a, self.b, self.c, self.d, self.time)
    }
    /// Similarity transform `(T⁻¹ A T, T⁻¹ B, C T, D)` with `tinv = T⁻¹` given.
    pub fn similarity(&self, t: &DMatrix<f64>, tinv: &DMatrix<f64>) -> Result<Self> {
        let n = self.n();
        if t.shape() != (n, n) || tinv.shape() != (n, n) {
            return Err(ModelError::dim(
                "similarity transform",
                format!("{n}x{n}"),
                format!("{}x{}", t.nrows(), t.ncols()),
            ));
        }
        Self::new(
            tinv * &self.a * t,
            tinv * &self.b,
            &self.c * t,
            self.d.clone(),
            self.time,
        )
    }
    /// Sub-model with the given input and output indices.
    pub fn select(&self, inputs: &[usize], outputs: &[usize]) -> Result<Self> {
        if let Some(&i) = inputs.iter().find(|&&i| i >= self.nu()) {
            return Err(ModelError::InvalidArgument(format!(
                "input index {i} out of range (nu = {})",
                self.nu()
            )));
        }
        if let Some(&o) = outputs.iter().find(|&&o| o >= self.ny()) {
            return Err(ModelError::InvalidArgument(format!(
                "output index {o} out of range (ny = {})",
                self.ny()
            )));
        }
        let b = self.b.select_columns(inputs.iter());
        let c = self.c.select_rows(outputs.iter());
        let d = self
            .d
            .select_rows(outputs.iter())
            .select_columns(inputs.iter());
        Self::new(self.a.clone(), b, c, d, self.time)
    }
}
