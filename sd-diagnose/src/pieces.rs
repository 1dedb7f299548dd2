//! Non-periodic records whose excitation amplitude changes within them (a noise test of rising
//! force, a sweep through levels) are cut into pieces of roughly constant amplitude, each an
//! experiment of its own level, before the diagnosis reads them.
//!
//! **Method: binary segmentation of the log-envelope.** The excitation (the reference, or the
//! input without one) is cut into windows of [`WINDOW`] samples; `l_k = ½ ln(mean x²)` is each
//! window's log-rms. A segment is split at the window boundary `c` that minimises
//! `Σ_{k<c}(l_k − l̄_left)² + Σ_{k≥c}(l_k − l̄_right)²` (the least-squares change point of a
//! piecewise-constant mean), provided both sides keep at least [`min_piece`] samples and their
//! mean rms differ by more than the factor [`STEP`]; each side is segmented again. A record of
//! constant amplitude (whose window rms scatter by a few percent) is never cut; a stepped
//! record is cut at its steps (to within one window); a smooth ramp is cut until each piece
//! spans less than about a factor `STEP²` (or the pieces reach the minimum length). The cuts
//! are then moved to the nearest whole second (whole `round(fs)` samples): every piece lasts
//! whole seconds, so the LPM lines of all pieces share the 1 Hz grid on which the model-free
//! comparison of two levels is made (pieces of unrelated lengths would share almost no line).
//!
//! The piece with the lowest amplitude of a model experiment keeps the role `model` (a linear
//! model belongs to the smallest excitation), the other pieces become validation experiments.
//! Each piece is estimated by the LPM, whose transient term absorbs the state at its start.

use sd_ident::{Experiment, Role};
use serde::Serialize;

/// Samples per envelope window.
pub const WINDOW: usize = 256;
/// Smallest rms ratio between the two sides of a cut.
pub const STEP: f64 = 1.25;
/// Fewest samples in a piece (besides an eighth of the record).
pub const MIN_PIECE: usize = 4096;

/// One piece of a record that was cut.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Piece {
    /// The record it comes from.
    pub record: String,
    /// Its name as an experiment: `<record>[<start>–<end> s]`.
    pub name: String,
    /// Start and end (s from the record's first sample).
    pub start_s: f64,
    /// End (s).
    pub end_s: f64,
    /// Excitation rms over the piece (the unit of the record's excitation column).
    pub rms: f64,
}

/// The fewest samples of a piece of a record of `n` samples.
pub fn min_piece(n: usize) -> usize {
    MIN_PIECE.max(n / 8)
}

/// Sample indices where `x` (the excitation, sampled at `fs` Hz) is cut, whole seconds apart;
/// empty when it keeps one amplitude.
pub fn cut_points(x: &[f64], fs: f64) -> Vec<usize> {
    let w = x.len() / WINDOW;
    let min_w = min_piece(x.len()).div_ceil(WINDOW);
    if w < 2 * min_w {
        return Vec::new();
    }
    let l: Vec<f64> = x
        .chunks_exact(WINDOW)
        .map(|c| {
            0.5 * (c.iter().map(|v| v * v).sum::<f64>() / WINDOW as f64)
                .max(1e-300)
                .ln()
        })
        .collect();
    let mut cuts = Vec::new();
    split(&l, 0, l.len(), min_w, &mut cuts);
    cuts.sort_unstable();
    let second = (fs.round() as usize).max(1);
    let min = min_piece(x.len());
    let mut out: Vec<usize> = Vec::new();
    for c in cuts {
        let snapped = ((c * WINDOW) as f64 / second as f64).round() as usize * second;
        if snapped >= out.last().copied().unwrap_or(0) + min && snapped + min <= x.len() {
            out.push(snapped);
        }
    }
    out
}

/// Binary segmentation of `l[lo..hi]` (window indices of cuts pushed to `cuts`).
fn split(l: &[f64], lo: usize, hi: usize, min_w: usize, cuts: &mut Vec<usize>) {
    if hi - lo < 2 * min_w {
        return;
    }
    let seg = &l[lo..hi];
    let total: f64 = seg.iter().sum();
    let total2: f64 = seg.iter().map(|v| v * v).sum();
    let n = seg.len() as f64;
    let (mut best, mut best_c, mut left) = (f64::INFINITY, 0, 0.0);
    let (mut s, mut s2) = (0.0, 0.0);
    for (i, v) in seg.iter().enumerate().take(seg.len() - min_w) {
        s += v;
        s2 += v * v;
        let c = i + 1;
        if c < min_w {
            continue;
        }
        let (nl, nr) = (c as f64, n - c as f64);
        let sse = (s2 - s * s / nl) + ((total2 - s2) - (total - s).powi(2) / nr);
        if sse < best {
            (best, best_c, left) = (sse, c, s);
        }
    }
    if best_c == 0 {
        return;
    }
    let ml = left / best_c as f64;
    let mr = (total - left) / (n - best_c as f64);
    if (ml - mr).abs() <= STEP.ln() {
        return;
    }
    cuts.push(lo + best_c);
    split(l, lo, lo + best_c, min_w, cuts);
    split(l, lo + best_c, hi, min_w, cuts);
}

/// The experiments with every non-periodic record of changing amplitude replaced by its
/// pieces (in place, in time order), and the pieces; `None` when nothing was cut.
pub fn cut_records(experiments: &[Experiment]) -> Option<(Vec<Experiment>, Vec<Piece>)> {
    let mut out = Vec::with_capacity(experiments.len());
    let mut pieces = Vec::new();
    for e in experiments {
        let x = e.r.as_deref().unwrap_or(&e.u);
        let cuts = if e.spec.period_samples.is_none() {
            cut_points(x, e.spec.sample_rate_hz)
        } else {
            Vec::new()
        };
        if cuts.is_empty() {
            out.push(e.clone());
            continue;
        }
        let mut bounds = vec![0];
        bounds.extend(cuts);
        bounds.push(x.len());
        let fs = e.spec.sample_rate_hz;
        let rms: Vec<f64> = bounds
            .windows(2)
            .map(|b| sd_model::rms(&x[b[0]..b[1]]))
            .collect();
        let lowest = (0..rms.len())
            .min_by(|a, b| rms[*a].total_cmp(&rms[*b]))
            .unwrap_or(0);
        for (k, b) in bounds.windows(2).enumerate() {
            let (start_s, end_s) = (b[0] as f64 / fs, b[1] as f64 / fs);
            let name = format!("{}[{start_s:.1}–{end_s:.1} s]", e.spec.name);
            let mut spec = e.spec.clone();
            spec.name = name.clone();
            if spec.role == Role::Model && k != lowest {
                spec.role = Role::Validation;
            }
            out.push(Experiment {
                spec,
                r: e.r.as_ref().map(|r| r[b[0]..b[1]].to_vec()),
                u: e.u[b[0]..b[1]].to_vec(),
                y: e.y[b[0]..b[1]].to_vec(),
                extra: Default::default(),
            });
            pieces.push(Piece {
                record: e.spec.name.clone(),
                name,
                start_s,
                end_s,
                rms: rms[k],
            });
        }
    }
    (!pieces.is_empty()).then_some((out, pieces))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-noise (a linear congruential sequence) of unit-order rms.
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn constant_amplitude_is_not_cut() {
        assert!(cut_points(&noise(100_000, 1), 1000.0).is_empty());
    }

    #[test]
    fn steps_are_cut_on_the_nearest_whole_second() {
        let n = 30_000;
        let x: Vec<f64> = noise(3 * n, 2)
            .iter()
            .enumerate()
            .map(|(i, v)| v * [1.0, 2.0, 4.0][i / n])
            .collect();
        // at 1 kHz the steps fall on whole seconds, and the cuts on them exactly
        assert_eq!(cut_points(&x, 1000.0), vec![n, 2 * n]);
        // at 1024 Hz on the nearest whole second
        let c = cut_points(&x, 1024.0);
        assert_eq!(c, vec![29 * 1024, 59 * 1024], "{c:?}");
    }

    #[test]
    fn a_ramp_is_cut_into_pieces_of_small_range() {
        let n = 120_000;
        let x: Vec<f64> = noise(n, 3)
            .iter()
            .enumerate()
            .map(|(i, v)| v * 8f64.powf(i as f64 / n as f64))
            .collect();
        let c = cut_points(&x, 1000.0);
        assert!(c.iter().all(|c| c % 1000 == 0), "{c:?}");
        let mut b = vec![0];
        b.extend(&c);
        b.push(n);
        assert!(c.len() >= 3, "{c:?}");
        for w in b.windows(2) {
            // the envelope's range inside a piece
            let range = 8f64.powf((w[1] - w[0]) as f64 / n as f64);
            assert!(range < STEP * STEP * 1.2, "{c:?}");
        }
    }
}
