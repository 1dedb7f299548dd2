//! bad input returns errors that say what to fix — one test per kind.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_model::{c2d, model_from_json_str, Discretization, ModelError, SampleTime, StateSpace};

fn m(r: usize, c: usize) -> DMatrix<f64> {
    DMatrix::zeros(r, c)
}

#[test]
fn wrong_shapes() {
    let e =
        StateSpace::new(m(2, 2), m(3, 1), m(1, 2), m(1, 1), SampleTime::Continuous).unwrap_err();
    assert!(
        matches!(e, ModelError::DimensionMismatch { .. }) && e.to_string().contains("B"),
        "{e}"
    );
    let e =
        StateSpace::new(m(2, 3), m(2, 1), m(1, 2), m(1, 1), SampleTime::Continuous).unwrap_err();
    assert!(e.to_string().contains("square"), "{e}");
}

#[test]
fn ragged_rows() {
    let e = model_from_json_str(
        r#"{"type":"ss","ts":null,"a":[[1,2],[3]],"b":[[1],[1]],"c":[[1,0]],"d":[[0]]}"#,
    )
    .unwrap_err();
    assert!(e.to_string().contains("row 1"), "{e}");
}

#[test]
fn nan_and_inf() {
    let mut a = m(1, 1);
    a[(0, 0)] = f64::NAN;
    assert!(matches!(
        StateSpace::new(a, m(1, 1), m(1, 1), m(1, 1), SampleTime::Continuous),
        Err(ModelError::NonFinite { .. })
    ));
    let mut d = m(1, 1);
    d[(0, 0)] = f64::INFINITY;
    assert!(matches!(
        StateSpace::new(m(1, 1), m(1, 1), m(1, 1), d, SampleTime::Continuous),
        Err(ModelError::NonFinite { .. })
    ));
    assert!(model_from_json_str(
        r#"{"type":"ss","ts":null,"a":[[NaN]],"b":[[1]],"c":[[1]],"d":[[0]]}"#
    )
    .is_err());
}

#[test]
fn nonpositive_sample_time() {
    for ts in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            SampleTime::discrete(ts),
            Err(ModelError::InvalidSampleTime { .. })
        ));
    }
    assert!(model_from_json_str(
        r#"{"type":"ss","ts":-0.1,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#
    )
    .is_err());
    let g = StateSpace::gain(DMatrix::from_element(1, 1, 1.0), SampleTime::Continuous).unwrap();
    assert!(c2d(&g, 0.0, Discretization::Zoh).is_err());
}

#[test]
fn c2d_of_discrete_model() {
    let g = StateSpace::gain(
        DMatrix::from_element(1, 1, 1.0),
        SampleTime::discrete(0.1).unwrap(),
    )
    .unwrap();
    let e = c2d(&g, 0.1, Discretization::Zoh).unwrap_err();
    assert!(matches!(e, ModelError::WrongDomain { .. }), "{e}");
}

#[test]
fn sample_time_mismatch() {
    let a = StateSpace::gain(
        DMatrix::from_element(1, 1, 1.0),
        SampleTime::discrete(0.1).unwrap(),
    )
    .unwrap();
    let b = StateSpace::gain(
        DMatrix::from_element(1, 1, 1.0),
        SampleTime::discrete(0.2).unwrap(),
    )
    .unwrap();
    let c = StateSpace::gain(DMatrix::from_element(1, 1, 1.0), SampleTime::Continuous).unwrap();
    for r in [
        sd_model::series(&a, &b),
        sd_model::parallel(&a, &c),
        sd_model::feedback(&a, &b, -1.0),
        sd_model::append(&c, &a),
    ] {
        assert!(matches!(r, Err(ModelError::SampleTimeMismatch { .. })));
    }
}

#[test]
fn unreadable_json() {
    for txt in [
        "",
        "{",
        "[1,2]",
        r#"{"type":"zpk"}"#,
        r#"{"type":"ss","ts":null}"#,
    ] {
        let e = model_from_json_str(txt).unwrap_err();
        assert!(matches!(e, ModelError::Parse { .. }), "{txt}: {e}");
    }
    assert!(sd_model::frd_from_json_str(
        r#"{"type":"frd","ts":0.001,"freq_hz":[1,2],"re":[[[1]]],"im":[[[0]]]}"#
    )
    .is_err());
}

#[test]
fn bad_frequency_grids() {
    assert!(sd_model::grid(10.0, 1.0, 5, false).is_err());
    assert!(sd_model::grid(0.0, 1.0, 5, true).is_err());
    assert!(sd_model::grid(1.0, f64::NAN, 5, false).is_err());
    assert!(sd_model::grid(1.0, 2.0, 0, false).is_err());
    let g = StateSpace::gain(DMatrix::from_element(1, 1, 1.0), SampleTime::Continuous).unwrap();
    assert!(g.freqresp(&[f64::NAN]).is_err());
}

#[test]
fn ill_posed_problems() {
    // algebraic loop 1 + D1 D2 = 0
    let g = StateSpace::gain(DMatrix::from_element(1, 1, 1.0), SampleTime::Continuous).unwrap();
    let k = StateSpace::gain(DMatrix::from_element(1, 1, -1.0), SampleTime::Continuous).unwrap();
    assert!(matches!(
        sd_model::feedback(&g, &k, -1.0),
        Err(ModelError::Singular { .. })
    ));
    // balanced truncation below the number of marginal states
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    assert!(p.balanced_truncation(1).is_err());
    assert!(p.balanced_truncation(100).is_err());
    // H2 of an unstable model
    assert!(matches!(p.h2_norm(), Err(ModelError::Unstable { .. })));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    use sd_hinf::{care, dare, loopshape, LoopshapeOptions};
    use sd_multirate::{c2d_nonideal, downsample, lift, MultirateLoop, NonIdeal};
    let d = |v: &[f64], r: usize| DMatrix::from_row_slice(r, v.len() / r, v);
    let a = d(&[0.5, 0.1, 0.0, 0.7], 2);
    let b = d(&[0.0, 1.0], 2);
    let q = DMatrix::<f64>::identity(2, 2);
    let r = d(&[1.0], 1);
    // NaN, wrong shapes, asymmetric Q
    let mut an = a.clone();
    an[(0, 0)] = f64::NAN;
    assert!(dare(&an, &b, &q, &r, None)
        .unwrap_err()
        .to_string()
        .contains("NaN"));
    assert!(care(&a, &d(&[1.0, 2.0, 3.0], 3), &q, &r, None).is_err());
    assert!(dare(&a, &b, &d(&[1.0, 1.0, 0.0, 1.0], 2), &r, None)
        .unwrap_err()
        .to_string()
        .contains("symmetric"));
    assert!(dare(&a, &b, &q, &r, Some(&m(3, 1))).is_err());
    // loopshaping: mixed domains, wrong weight shape, bad factor
    let pd = StateSpace::new(
        a.clone(),
        b.clone(),
        d(&[1.0, 0.0], 1),
        m(1, 1),
        SampleTime::discrete(0.1).unwrap(),
    )
    .unwrap();
    let pc = StateSpace::new(
        a.clone(),
        b.clone(),
        d(&[1.0, 0.0], 1),
        m(1, 1),
        SampleTime::Continuous,
    )
    .unwrap();
    assert!(loopshape(&pd, Some(&pc), None, &LoopshapeOptions::default()).is_err());
    let w2x2 =
        StateSpace::gain(DMatrix::identity(2, 2), SampleTime::discrete(0.1).unwrap()).unwrap();
    assert!(loopshape(&pd, Some(&w2x2), None, &LoopshapeOptions::default()).is_err());
    assert!(loopshape(
        &pd,
        None,
        None,
        &LoopshapeOptions {
            factor: f64::NAN,
            strictly_proper: false
        }
    )
    .is_err());
    assert!(loopshape(
        &pc,
        None,
        None,
        &LoopshapeOptions {
            factor: 1.1,
            strictly_proper: true
        }
    )
    .is_err());
    // multirate: domains, factors, fractions, rates
    assert!(downsample(&pc, 2).is_err() && lift(&pd, 0).is_err());
    assert!(c2d_nonideal(
        &pc,
        0.1,
        NonIdeal {
            hold_delay: -0.1,
            averaging: 0.0
        }
    )
    .is_err());
    assert!(c2d_nonideal(&pc, f64::INFINITY, NonIdeal::hold_delay(0.5)).is_err());
    let kslow = StateSpace::gain(d(&[1.0], 1), SampleTime::discrete(0.3).unwrap()).unwrap();
    assert!(MultirateLoop::new(&pd, &kslow, 2)
        .unwrap_err()
        .to_string()
        .contains("ts"));
}
