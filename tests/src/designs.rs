//! The loopshaping reference designs shared by the loopshaping and LMI tests.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_model::{c2d, Discretization, SampleTime, StateSpace, TransferFunction};

/// Polynomial product (descending powers).
pub fn conv(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// A continuous SISO transfer function as a state-space model.
pub fn tf(num: Vec<f64>, den: Vec<f64>) -> StateSpace {
    TransferFunction::new(num, den, SampleTime::Continuous)
        .unwrap()
        .to_ss()
        .unwrap()
}

/// Skogestad & Postlethwaite Ex. 9.3: G = 200/((10s+1)(0.05s+1)²), W1 = (s+2)/(s+1e-6).
pub fn sp93() -> (StateSpace, StateSpace) {
    let g = tf(
        vec![200.0],
        conv(&[10.0, 1.0], &conv(&[0.05, 1.0], &[0.05, 1.0])),
    );
    let w1 = tf(vec![1.0, 2.0], vec![1.0, 1e-6]);
    (g, w1)
}

/// The same, each factor ZOH-discretised at 0.01 s.
pub fn sp93_discrete() -> (StateSpace, StateSpace) {
    let (g, w1) = sp93();
    (
        c2d(&g, 0.01, Discretization::Zoh).unwrap(),
        c2d(&w1, 0.01, Discretization::Zoh).unwrap(),
    )
}

/// MathWorks' lightly damped resonance G = 16/(s² + 0.16 s + 16) with
/// W1 = (1 + 0.8/s)/(s/20 + 1) (negative-feedback sign).
pub fn resonance() -> (StateSpace, StateSpace) {
    (
        tf(vec![16.0], vec![1.0, 0.16, 16.0]),
        tf(vec![20.0, 16.0], vec![1.0, 20.0, 0.0]),
    )
}

/// The SLICOT SB10KD documentation example (n = 6, 2×2, discrete), ts = 1.
pub fn sb10kd_plant() -> StateSpace {
    let a = DMatrix::from_row_slice(
        6,
        6,
        &[
            0.2, 0.0, 0.3, 0.0, -0.3, -0.1, -0.3, 0.2, -0.4, -0.3, 0.0, 0.0, -0.1, 0.1, -0.1, 0.0,
            0.0, -0.3, 0.1, 0.0, 0.0, -0.1, -0.1, 0.0, 0.0, 0.3, 0.6, 0.2, 0.1, -0.4, 0.2, -0.4,
            0.0, 0.0, 0.2, -0.2,
        ],
    );
    let b = DMatrix::from_row_slice(
        6,
        2,
        &[
            -1.0, -2.0, 1.0, 3.0, -3.0, -4.0, 1.0, -2.0, 0.0, 1.0, 1.0, 5.0,
        ],
    );
    let c = DMatrix::from_row_slice(
        2,
        6,
        &[
            1.0, -1.0, 2.0, -2.0, 0.0, -3.0, -3.0, 0.0, 1.0, -1.0, 1.0, -1.0,
        ],
    );
    StateSpace::new(
        a,
        b,
        c,
        DMatrix::zeros(2, 2),
        SampleTime::discrete(1.0).unwrap(),
    )
    .unwrap()
}

/// The paper's 1 kHz stage model (653 Hz mode at 347 Hz).
pub fn paper_stage_1khz() -> StateSpace {
    c2d(
        &sd_model::stage::paper_stage(0.01).unwrap(),
        1e-3,
        Discretization::Zoh,
    )
    .unwrap()
}
