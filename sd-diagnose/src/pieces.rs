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
//!
//! **Windows without excitation** (burst random: excitation, then free decay; pauses between
//! levels) are never an experiment. A window is *quiet* when its rms is below [`QUIET`] times
//! the loudest window within one minimum piece ([`min_piece`]) on either side, or when it
//! follows or precedes a quiet window at no more than twice its rms (a pause longer than two
//! minimum pieces). The segmentation runs on the excited windows only; a quiet run belongs to
//! the excited run before it (its free decay: the response to that excitation, which `G·U` and
//! the LPM's transient term describe) and a cut before an excited run that follows a pause is
//! moved down to the whole second inside the pause; a piece ends at the first whole second
//! after its response has died out (the rest of its pause is dropped, `trimmed_end`). A
//! record whose excited parts keep one
//! amplitude is not cut: the whole record is one experiment, free decays included
//! ([`RecordUse`] says so). Each piece's rms is that of its excited windows.

use sd_ident::{Experiment, Role};
use serde::Serialize;

/// Samples per envelope window.
pub const WINDOW: usize = 256;
/// Smallest rms ratio between the two sides of a cut.
pub const STEP: f64 = 1.25;
/// Fewest samples in a piece (besides an eighth of the record).
pub const MIN_PIECE: usize = 4096;
/// A window below this fraction (−20 dB) of the loudest window within one minimum piece is
/// without excitation.
pub const QUIET: f64 = 0.1;

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
    /// Excitation rms over the piece's excited windows (the unit of the record's excitation
    /// column).
    pub rms: f64,
    /// Seconds of the piece with excitation; the rest is free decay or pause.
    pub excited_s: f64,
}

/// How a non-periodic record with windows without excitation, or cut into pieces, was used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordUse {
    /// The record (its experiment's name).
    pub record: String,
    /// Its length (s).
    pub length_s: f64,
    /// Seconds with excitation.
    pub excited_s: f64,
    /// Runs of excited windows (bursts); 1 for a record excited throughout.
    pub bursts: usize,
    /// Pieces it was cut into (1: used whole).
    pub pieces: usize,
}

/// The fewest samples of a piece of a record of `n` samples.
pub fn min_piece(n: usize) -> usize {
    MIN_PIECE.max(n / 8)
}

/// Per window of [`WINDOW`] samples its log-rms `½ ln(mean x²)`.
fn log_rms(x: &[f64]) -> Vec<f64> {
    x.chunks_exact(WINDOW)
        .map(|c| {
            0.5 * (c.iter().map(|v| v * v).sum::<f64>() / WINDOW as f64)
                .max(1e-300)
                .ln()
        })
        .collect()
}

/// Shortest run of quiet windows that counts (shorter dips of a narrow-band excitation's
/// envelope are excitation).
pub const QUIET_RUN: usize = 4;

/// The windows without excitation (module docs): below [`QUIET`] times the 90th percentile of
/// the windows within `reach` on either side, grown into neighbours at most twice as loud,
/// in runs of at least [`QUIET_RUN`] windows.
fn quiet_windows(l: &[f64], reach: usize) -> Vec<bool> {
    let n = l.len();
    let mut quiet: Vec<bool> = (0..n)
        .map(|k| {
            let lo = k.saturating_sub(reach);
            let hi = (k + reach + 1).min(n);
            let mut near = l[lo..hi].to_vec();
            near.sort_by(f64::total_cmp);
            let loud = near[((near.len() - 1) as f64 * 0.9).round() as usize];
            l[k] < loud + QUIET.ln()
        })
        .collect();
    let grow = std::f64::consts::LN_2;
    let mut changed = true;
    while changed {
        changed = false;
        for k in 0..n {
            if quiet[k] {
                continue;
            }
            let near = |j: usize| quiet[j] && l[k] <= l[j] + grow;
            if (k > 0 && near(k - 1)) || (k + 1 < n && near(k + 1)) {
                quiet[k] = true;
                changed = true;
            }
        }
    }
    // runs shorter than QUIET_RUN are excitation
    let mut k = 0;
    while k < n {
        if !quiet[k] {
            k += 1;
            continue;
        }
        let end = (k..n).find(|&j| !quiet[j]).unwrap_or(n);
        if end - k < QUIET_RUN {
            quiet[k..end].iter_mut().for_each(|q| *q = false);
        }
        k = end;
    }
    quiet
}

/// Where `x` (the excitation, sampled at `fs` Hz) is cut and which of its windows are quiet.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// Sample indices of the cuts, whole seconds apart; empty when the excited parts keep one
    /// amplitude.
    pub cuts: Vec<usize>,
    /// Per window of [`WINDOW`] samples: without excitation.
    pub quiet: Vec<bool>,
}

impl Segmentation {
    /// Runs of excited windows.
    pub fn bursts(&self) -> usize {
        let mut prev = true;
        let mut n = 0;
        for &q in &self.quiet {
            n += usize::from(prev && !q);
            prev = q;
        }
        n
    }

    /// Excited samples in `[a, b)`.
    pub fn excited(&self, a: usize, b: usize) -> usize {
        (a / WINDOW..b.div_ceil(WINDOW).min(self.quiet.len()))
            .filter(|&k| !self.quiet[k])
            .map(|k| (b.min((k + 1) * WINDOW)).saturating_sub(a.max(k * WINDOW)))
            .sum()
    }
}

/// The segmentation of `x` (module docs).
pub fn segment(x: &[f64], fs: f64) -> Segmentation {
    let l = log_rms(x);
    let min_w = min_piece(x.len()).div_ceil(WINDOW);
    let quiet = quiet_windows(&l, min_w);
    // the excited windows' log-rms, and their window indices
    let idx: Vec<usize> = (0..l.len()).filter(|&k| !quiet[k]).collect();
    let le: Vec<f64> = idx.iter().map(|&k| l[k]).collect();
    // the minimum piece scaled by the excited fraction: a piece of burst random is its
    // bursts and their decays
    let min_e = ((min_piece(x.len()) * idx.len()) as f64 / l.len().max(1) as f64 / WINDOW as f64)
        .ceil()
        .max(1.0) as usize;
    let mut cuts = Vec::new();
    if le.len() >= 2 * min_e {
        split(&le, 0, le.len(), min_e, &mut cuts);
    }
    cuts.sort_unstable();
    let second = (fs.round() as usize).max(1);
    let min = min_piece(x.len());
    let mut out: Vec<usize> = Vec::new();
    for c in cuts {
        let (w, prev) = (idx[c], idx[c - 1]);
        let start = w * WINDOW;
        let nearest = (start as f64 / second as f64).round() as usize * second;
        // after a pause: the last whole second before the excitation (which begins inside
        // window `w`), so that the next burst stays whole
        let down = (start + WINDOW) / second * second;
        let snapped = if w > prev + 1 && down >= (prev + 1) * WINDOW {
            down
        } else {
            nearest
        };
        if snapped >= out.last().copied().unwrap_or(0) + min && snapped + min <= x.len() {
            out.push(snapped);
        }
    }
    Segmentation { cuts: out, quiet }
}

/// Sample indices where `x` (the excitation, sampled at `fs` Hz) is cut, whole seconds apart;
/// empty when its excited parts keep one amplitude ([`segment`]).
pub fn cut_points(x: &[f64], fs: f64) -> Vec<usize> {
    segment(x, fs).cuts
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
/// pieces (in place, in time order), the pieces, and how every non-periodic record with
/// windows without excitation or cuts was used; `None` when nothing was cut and no record has
/// windows without excitation.
pub fn cut_records(experiments: &[Experiment]) -> Option<Cut> {
    let mut out = Vec::with_capacity(experiments.len());
    let (mut pieces, mut records) = (Vec::new(), Vec::new());
    for e in experiments {
        let x = e.r.as_deref().unwrap_or(&e.u);
        let fs = e.spec.sample_rate_hz;
        if e.spec.period_samples.is_some() {
            out.push(e.clone());
            continue;
        }
        let seg = segment(x, fs);
        let excited = seg.excited(0, x.len());
        if excited == 0 {
            out.push(e.clone());
            continue;
        }
        if !seg.cuts.is_empty() || excited < x.len() {
            records.push(RecordUse {
                record: e.spec.name.clone(),
                length_s: x.len() as f64 / fs,
                excited_s: excited as f64 / fs,
                bursts: seg.bursts(),
                pieces: seg.cuts.len() + 1,
            });
        }
        if seg.cuts.is_empty() {
            out.push(e.clone());
            continue;
        }
        let mut bounds = vec![0];
        bounds.extend(&seg.cuts);
        bounds.push(x.len());
        let rms: Vec<f64> = bounds
            .windows(2)
            .map(|b| excited_rms(x, &seg, b[0], b[1]))
            .collect();
        let lowest = (0..rms.len())
            .min_by(|a, b| rms[*a].total_cmp(&rms[*b]))
            .unwrap_or(0);
        let second = (fs.round() as usize).max(1);
        for (k, b) in bounds.windows(2).enumerate() {
            let b = [b[0], trimmed_end(&seg, &e.y, (b[0], b[1]), second)];
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
                excited_s: seg.excited(b[0], b[1]) as f64 / fs,
            });
        }
    }
    (!pieces.is_empty() || !records.is_empty()).then_some(Cut {
        experiments: out,
        pieces,
        records,
    })
}

/// The end of the piece `[a, b)` without the part of its trailing pause after the response
/// has died out: the first whole second (of `second` samples from `a`) at or after the first
/// window past the last excited one where the output `y`'s sample-to-sample change (free of a
/// position offset the stage keeps) is back within a factor 2 of its level over the pause's
/// last quarter (the noise). Before `b` only; a response still decaying over the pause's third
/// quarter (more than a factor 2 above the last) has not settled and keeps the whole pause.
///
/// Why both limits: the nonlinear distortion lives in the burst and its decay, so over a piece
/// that is largely settled pause it is not stationary, its DFT lines are correlated over
/// neighbouring bins, and the LPM's local residuals (which take them for independent)
/// underestimate it; but a piece cut while lightly damped modes still ring carries a final
/// transient narrower than the LPM's window, which its polynomial cannot absorb. Cut where the
/// decay has ended, a burst keeps what makes burst random leakage-free.
fn trimmed_end(seg: &Segmentation, y: &[f64], (a, b): (usize, usize), second: usize) -> usize {
    // the windows wholly inside the piece (the next piece's burst may begin inside the last)
    let last = (a.div_ceil(WINDOW)..(b / WINDOW).min(seg.quiet.len()))
        .rev()
        .find(|&k| !seg.quiet[k]);
    let Some(k) = last else { return b };
    let first_quiet = (k + 1).max(a.div_ceil(WINDOW));
    // log-rms of the output's first difference per window after the excitation ([`log_rms`]
    // of the differenced output, the windows aligned with the excitation's)
    let lo = first_quiet * WINDOW;
    let hi = (b / WINDOW * WINDOW).min(y.len().saturating_sub(1));
    if hi <= lo {
        return b;
    }
    let diff: Vec<f64> = (lo..hi).map(|i| y[i + 1] - y[i]).collect();
    let change = log_rms(&diff);
    if change.len() < 4 {
        return b;
    }
    let median = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    let noise = median(&change[change.len() * 3 / 4..]);
    // still decaying at the end of the pause (the third quarter above the last): not settled
    if median(&change[change.len() / 2..change.len() * 3 / 4]) > noise + std::f64::consts::LN_2 {
        return b;
    }
    let Some(settled) = change
        .iter()
        .position(|l| *l <= noise + std::f64::consts::LN_2)
    else {
        return b;
    };
    let end = (first_quiet + settled) * WINDOW;
    let whole = a + end.saturating_sub(a).div_ceil(second) * second;
    whole.min(b)
}

/// The rms of `x[a..b]` over its excited windows (over all of it when none is excited).
fn excited_rms(x: &[f64], seg: &Segmentation, a: usize, b: usize) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (i, v) in x.iter().enumerate().take(b).skip(a) {
        if !seg.quiet.get(i / WINDOW).copied().unwrap_or(false) {
            s += v * v;
            n += 1;
        }
    }
    if n == 0 {
        return sd_model::rms(&x[a..b]);
    }
    (s / n as f64).sqrt()
}

/// What [`cut_records`] made of a set of experiments.
#[derive(Debug, Clone)]
pub struct Cut {
    /// The experiments, every cut record replaced by its pieces.
    pub experiments: Vec<Experiment>,
    /// The pieces.
    pub pieces: Vec<Piece>,
    /// Every non-periodic record with windows without excitation or cuts.
    pub records: Vec<RecordUse>,
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

    /// A first-order low-pass of `x` with corner `fc` (Hz) at `fs`, rescaled to unit rms.
    fn lowpass(x: &[f64], fc: f64, fs: f64) -> Vec<f64> {
        let a = (-std::f64::consts::TAU * fc / fs).exp();
        let mut s = 0.0;
        let y: Vec<f64> = x
            .iter()
            .map(|v| {
                s = a * s + (1.0 - a) * v;
                s
            })
            .collect();
        let r = sd_model::rms(&y);
        y.iter().map(|v| v / r).collect()
    }

    /// Burst random at 1024 Hz: per level `bursts` cycles of 4 s excitation and 4 s of
    /// silence (sensor noise 1e-4).
    fn burst(levels: &[f64], bursts: usize, seed: u64) -> Vec<f64> {
        let cycle = 8 * 1024;
        let n = cycle * bursts * levels.len();
        let x = noise(n, seed);
        let floor = noise(n, seed + 99);
        (0..n)
            .map(|i| {
                let on = (i % cycle) < cycle / 2;
                let level = levels[i / (cycle * bursts)];
                if on {
                    x[i] * level
                } else {
                    1e-4 * floor[i]
                }
            })
            .collect()
    }

    #[test]
    fn narrow_band_noise_is_excitation_throughout() {
        // a 5 Hz low-pass at 1 kHz: the 256-sample windows' rms scatter by tens of percent
        let x = lowpass(&noise(120_000, 4), 5.0, 1000.0);
        let seg = segment(&x, 1000.0);
        assert!(seg.cuts.is_empty(), "{:?}", seg.cuts);
        assert!(seg.quiet.iter().all(|q| !q));
    }

    #[test]
    fn a_burst_record_at_one_level_is_one_experiment() {
        let x = burst(&[1.0], 4, 5);
        let seg = segment(&x, 1024.0);
        assert!(seg.cuts.is_empty(), "{:?}", seg.cuts);
        assert_eq!(seg.bursts(), 4);
        // half the record excited, to within one window per edge
        let e = seg.excited(0, x.len()) as f64 / x.len() as f64;
        assert!(
            (e - 0.5).abs() < 8.0 * WINDOW as f64 / x.len() as f64,
            "{e}"
        );
    }

    #[test]
    fn bursts_at_rising_levels_are_cut_in_the_pauses() {
        let levels = [1.0, 2.0, 4.0];
        let x = burst(&levels, 2, 6);
        let seg = segment(&x, 1024.0);
        let per = 2 * 8 * 1024;
        assert_eq!(seg.cuts.len(), 2, "{:?}", seg.cuts);
        for (k, c) in seg.cuts.iter().enumerate() {
            // inside the pause before the level's first burst, on a whole second
            let start = (k + 1) * per;
            assert!(*c <= start && *c + 4 * 1024 >= start, "{c} vs {start}");
            assert_eq!(c % 1024, 0);
        }
        // every piece has excitation, and the lowest piece is the first level
        let mut b = vec![0];
        b.extend(&seg.cuts);
        b.push(x.len());
        let rms: Vec<f64> = b
            .windows(2)
            .map(|w| excited_rms(&x, &seg, w[0], w[1]))
            .collect();
        for (w, r) in b.windows(2).zip(&rms) {
            assert!(seg.excited(w[0], w[1]) >= 6 * 1024, "{w:?}");
            assert!(*r > 0.2, "{rms:?}");
        }
        assert!(rms[0] < rms[1] && rms[1] < rms[2], "{rms:?}");
    }

    #[test]
    fn a_pause_between_steps_stays_with_the_step_before() {
        // 20 s at 1, 10 s of silence, 20 s at 3 (1 kHz)
        let n = 50_000;
        let x: Vec<f64> = noise(n, 7)
            .iter()
            .enumerate()
            .map(|(i, v)| match i {
                0..20_000 => *v,
                20_000..30_000 => 1e-6 * v,
                _ => 3.0 * v,
            })
            .collect();
        let seg = segment(&x, 1000.0);
        assert_eq!(seg.cuts.len(), 1, "{:?}", seg.cuts);
        assert!((20_000..=30_000).contains(&seg.cuts[0]), "{:?}", seg.cuts);
        assert_eq!(seg.bursts(), 2);
        // an output that decays with τ = 0.25 s after the excitation stops (plus a 1e-7
        // sensor noise): the first piece ends on a whole second after the decay (some ten τ
        // to the noise), the rest of the pause dropped; the last piece keeps its end
        let noise_y = noise(n, 8);
        let mut y = vec![0.0; n];
        for i in 1..n {
            y[i] = 0.996 * y[i - 1] + x[i];
        }
        let y: Vec<f64> = y.iter().zip(&noise_y).map(|(v, e)| v + 1e-7 * e).collect();
        let end = trimmed_end(&seg, &y, (0, seg.cuts[0]), 1000);
        assert!(
            end % 1000 == 0 && (21_000..seg.cuts[0]).contains(&end),
            "{end}"
        );
        assert_eq!(trimmed_end(&seg, &y, (seg.cuts[0], n), 1000), n);
        // an output still decaying at the piece's end (τ = 2 s) keeps the whole pause
        let mut slow = vec![0.0; n];
        for i in 1..n {
            slow[i] = 0.9995 * slow[i - 1] + x[i];
        }
        assert_eq!(
            trimmed_end(&seg, &slow, (0, seg.cuts[0]), 1000),
            seg.cuts[0]
        );
    }
}
