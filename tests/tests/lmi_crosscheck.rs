//! the achieved loopshaping levels confirmed by an independent method,
//! the bounded-real lemma solved as an SDP by clarabel (`sd_hinf::lmi`).
//! Run: `cargo test --release -p sd-tests --features lmi --test lmi_crosscheck` (CI does).
#![cfg(feature = "lmi")]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_hinf::lmi::hinf_norm_lmi;
use sd_hinf::loopshape::four_block;
use sd_hinf::{loopshape, weights, LoopshapeOptions};
use sd_model::StateSpace;
use sd_tests::designs::{paper_stage_1khz, resonance, sb10kd_plant, sp93, sp93_discrete};

fn confirm(name: &str, p: &StateSpace, w1: Option<&StateSpace>, opt: LoopshapeOptions) {
    let d = loopshape(p, w1, None, &opt).unwrap();
    let t = four_block(&d.shaped_plant, &d.shaped_controller).unwrap();
    let ours = t.hinf_norm().unwrap().value;
    let lmi = hinf_norm_lmi(&t).unwrap();
    let rel = (lmi.gamma - ours).abs() / ours;
    println!(
        "{name}: γ {:.6}, H∞ norm {ours:.7}, LMI {:.7} ({}), relative difference {rel:.1e}",
        d.gamma, lmi.gamma, lmi.status
    );
    assert!(rel <= 1e-5, "{name}: LMI {} vs H∞ {ours}", lmi.gamma);
    assert!(
        lmi.gamma <= d.gamma * (1.0 + 1e-6),
        "{name}: LMI level above γ"
    );
}

#[test]
fn lmi_confirms_achieved_gamma() {
    let (g, w) = sp93();
    confirm(
        "S&P 9.3 continuous",
        &g,
        Some(&w),
        LoopshapeOptions::default(),
    );
    let (g, w) = sp93_discrete();
    confirm(
        "S&P 9.3 discrete",
        &g,
        Some(&w),
        LoopshapeOptions::default(),
    );
    let (g, w) = resonance();
    confirm("resonance", &g, Some(&w), LoopshapeOptions::default());
    let g = sb10kd_plant();
    confirm("SB10KD", &g, None, LoopshapeOptions::default());
    confirm(
        "SB10KD strictly proper",
        &g,
        None,
        LoopshapeOptions {
            factor: 1.1,
            strictly_proper: true,
        },
    );
    let p = paper_stage_1khz();
    let w1 = weights::pid(65.0, 20.0, Some(1e-3), &Default::default()).unwrap();
    confirm(
        "paper stage 1 kHz",
        &p,
        Some(&w1),
        LoopshapeOptions::default(),
    );
}
