//! Modes tracked across excitation levels by the physics: each physical mode's frequency and
//! damping at each level from a local fit in its band, with standard errors — not from the
//! poles of one global fit, which on a real structure spends poles on distortion and splits
//! modes.
//!
//! # Method
//!
//! 1. **The modes.** The physical modal fit of the model experiment (the lowest level's BLA,
//!    [`sd_ident::physical_fit`]: stabilisation over orders up to [`MODE_FIT_ORDER`] on at most
//!    [`MODE_FIT_LINES`] lines, no pair narrower than the line spacing unless the held-out
//!    lines demand it) gives the lightly damped pairs in the band
//!    (ζ < [`MAX_DAMPING`]) with their share of the response. A pair at the bandwidth floor
//!    ([`sd_ident::FLOOR_RESOLUTION`]) inside a broader pair's half-power band whose own peak
//!    is below that pair's term at its frequency is a *ripple*
//!    ([`sd_ident::PhysicalMode::ripple`]), not a mode: it has no peak of its own in the
//!    response, and the fit spent it on what repeats from period to period (a full
//!    multisine of one realization leaves the distortion out of the variance the fit
//!    weighs by; on the level suite's full-multisine seeds such a pole beside a softening or
//!    hardening mode narrowed that mode's band below what its local fits need, and nothing
//!    was tracked). Ripples are neither tracked nor neighbours.
//! 2. **The band of each mode** has the half-width `B = max(4ζf, 6Δf)` (four half-power
//!    half-widths, at least six lines each side: room for a shift of about one bandwidth
//!    between neighbouring levels), narrowed to 45 % of the distance to the neighbouring
//!    pairs; `ζ, f` are the neighbouring level's fit (ζ at least the model experiment's), so a
//!    mode whose damping rises with the level keeps four of its bandwidths in the band.
//! 3. **Local fit per level** (one pole pair plus an affine background: on the FRF weighted
//!    by the level's total variance, [`sd_ident::local_mode_beside()`], its standard errors
//!    carrying an LPM estimate's line correlation; on an open-loop non-periodic record's own
//!    DFT lines, [`sd_ident::local_mode_dft_beside()`]; the neighbouring pairs whose skirts
//!    curve over the level's band beyond what the affine background takes up — the physical
//!    fit's term, whitened by that level's total variance, at least [`NEIGHBOUR_MIN`] from
//!    its least-squares line — enter with their poles fixed at the physical fit's and their
//!    residues free, at most [`MAX_NEIGHBOURS`]; a level whose distortion dwarfs the skirt's
//!    curvature keeps the plain form, whose extra freedom there only let a narrow pole settle
//!    on the scattered lines), from the model experiment
//!    outwards in level: each level's band centred on its peak of `|G|²` averaged over the
//!    half-power half-width `ζf` (a broad resonance's centre, not the largest of the lines the
//!    distortion scatters over it), sought within reach of the frequency fitted at the level
//!    next to it (45 % of the distance to the neighbouring pairs, at most [`MAX_STEP`] of the
//!    frequency; at the model experiment, near the physical fit's `f₀`). The fit is started
//!    there with the neighbour's damping, with three times it, and at the neighbour's
//!    frequency; the least cost among the fits the lines resolve (half-power bandwidth at
//!    least the band's median line spacing) is kept. A mode that hardens by several
//!    bandwidths over the levels stays in its band this way; a band fixed at `f₀` loses it
//!    (on the level suite's development seeds a 4 % shift of a ζ = 0.008 mode left it, and
//!    the fit inside settled on the skirt with the opposite sign). A level gives no point
//!    when the fit does not determine its damping (standard error above the value) or when
//!    the band's median `|G|²/σ²` is below [`MIN_BAND_SNR`] (the distortion buries the
//!    resonance; the local standard errors would not cover the cost's other minima). A pair
//!    that the model experiment's own local fit does not resolve is not tracked at all: with
//!    no anchor, the next level's band is sought from the physical fit's frequency and its
//!    fit can slide onto a neighbouring resonance's skirt (on a full-multisine friction case,
//!    seed 3903, a ζ = 0.007 pair at 1459 Hz that level 1 did not confirm was "found" at
//!    1622 and 1776 Hz on the way to the stage's 1837 Hz mode and named the trend).
//! 4. **Moves:** the levels' frequencies (dampings) differ beyond their standard errors when
//!    `Σ (x_k − x̄)²/σ_k² > χ²_{K−1}(1 − α/2)` (`x̄` the weighted mean) or when the weighted
//!    least-squares slope against `ln ρ` (ρ the relative excitation level) is beyond
//!    `χ²_1(1 − α/2)` in squared standard errors — two tests at `α/2` each, at most `α`
//!    together (Bonferroni); with two levels they are one test, at `α`. The slope test has
//!    the power where a stiffness or friction law moves the frequency monotonically with the
//!    level while the top level's point is wide; the trend's sign is the slope's, stated
//!    when it is beyond `z_{1−α/2}` standard errors.
//! 5. **Dominant:** among the moving modes the largest `|f(ρ_max) − f(ρ_min)|/(2ζ₀f₀)` (the
//!    shift in half-power bandwidths; the damping's relative change where the frequency does
//!    not move) weighted by the mode's share of the response. Its frequency trend is the
//!    diagnosis's `kind` and its damping trend the `damping_trend` ([`decided`]); when no
//!    tracked mode moves both are `none` (the amplitude model's poles may still move: a
//!    friction corner is no pair, and a global fit's weak pair is not a physical mode). A
//!    friction-damped rigid body's corner that moves competes with the pairs on the same
//!    scale — its shift over the levels in its own half-power bandwidth `2f_c` (a real
//!    pole's `2|Re s|` as a pair's `2ζω`), weighted by the share of the physical fit's
//!    rigid-body and real-pole terms: when it outweighs every moving pair, no pair is
//!    dominant and both trends are `none`, the corner's trend is the `corner_trend` (on the
//!    level suite, friction moves a stage's corner by most of its bandwidth while the
//!    flexible modes' BLA shift by thousandths of theirs — significant at the standard
//!    errors of long records, negligible for the response); the
//!    amplitude model's stand when no mode could be tracked, or when none moves but a mode
//!    was *buried* at a level above the model experiment's (its band's `|G|²/σ²` fell below
//!    [`MIN_BAND_SNR`] as the excitation rose: distortion, and the level where it would have
//!    moved most is missing from its track).
//!
//! Judged against each mode's best linear approximation computed apart (the level suite's
//! `sd_tests::modal_truth`: every mode integrated alone under random-phase forces with each
//! level's spectrum), the tracked frequencies lie within 2.576 standard errors on 98.0 % of
//! the points on periodic records, on 95.1–97.2 % on non-periodic ones (noise records,
//! rising and burst records) and on 97.0 % on full multisines of one realization (fresh
//! seeds 3800..3825, 3850..3866 and 3930..3955; 91.7 % on periodic development seeds before
//! the neighbouring modes entered the local fits); docs/diagnosis.md has the figures and the
//! command.

use crate::{DampingTrend, FreqTrend, Result};
use num_complex::Complex64 as C;
use rayon::prelude::*;
use sd_ident::{
    local_mode_beside, local_mode_dft_beside, physical_fit, LineNoise, LocalMode, ModeKind,
    StabilizationOptions, MIN_LINES,
};
use sd_model::{chi2_quantile, normal_quantile, Frd};
use serde::Serialize;
use std::f64::consts::TAU;

/// Pairs at or above this damping are not tracked (overdamped: no resonance to follow).
pub const MAX_DAMPING: f64 = 0.3;
/// Most lines the physical fit that finds the modes sees (every `⌈L/2048⌉`-th).
pub const MODE_FIT_LINES: usize = 2048;
/// Highest order of that fit (eight pairs; `sdctl fit --stabilization` goes to 24).
pub const MODE_FIT_ORDER: usize = 16;

/// One level's local fit of a tracked mode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackPoint {
    /// The experiment.
    pub experiment: String,
    /// Its excitation level relative to the model experiment's.
    pub relative_level: f64,
    /// Natural frequency (Hz) and its standard error.
    pub freq_hz: f64,
    /// Standard error (Hz).
    pub freq_std: f64,
    /// Damping ratio and its standard error.
    pub damping: f64,
    /// Standard error.
    pub damping_std: f64,
}

/// A physical mode followed over the levels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModeTrack {
    /// The physical fit's natural frequency at the model experiment (Hz).
    pub freq_hz: f64,
    /// Its damping ratio there.
    pub damping: f64,
    /// Its share of the model experiment's response ([`sd_ident::PhysicalMode::share`]).
    pub share: f64,
    /// The band of its local fit at the model experiment (Hz; every other level's band, as
    /// wide, is centred on that level's peak).
    pub band_hz: (f64, f64),
    /// The levels' frequencies differ beyond their standard errors.
    pub frequency_moves: bool,
    /// The levels' dampings differ beyond their standard errors.
    pub damping_moves: bool,
    /// The frequency's trend with the level.
    pub frequency_trend: FreqTrend,
    /// The damping's trend with the level.
    pub damping_trend: DampingTrend,
    /// Frequency at the highest level minus at the lowest, in half-power bandwidths `2ζ₀f₀`.
    pub shift_bandwidths: f64,
    /// The dominant moving mode (at most one).
    pub dominant: bool,
    /// Every level's local fit (levels whose fit failed are absent).
    pub points: Vec<TrackPoint>,
    /// Levels above the model experiment's at which the mode, resolved at the model
    /// experiment, was buried: its band's median `|G|²/σ²` fell below [`MIN_BAND_SNR`] although
    /// the excitation rose (on a linear structure the ratio rises with it), so the total
    /// variance there is nonlinear distortion. No point at those levels; [`decided`] then
    /// takes the amplitude model's trends when no tracked mode moves.
    pub buried: Vec<String>,
}

/// One level: its name, relative excitation level and BLA.
pub struct TrackLevel<'a> {
    /// The experiment.
    pub name: &'a str,
    /// Excitation level relative to the model experiment's.
    pub level: f64,
    /// Its FRF with the total variance.
    pub frd: &'a Frd,
    /// Correlation `ρ(d)` of the errors of lines `d` spacings apart (empty: independent, as
    /// a periodic record's; an LPM estimate's from [`sd_ident::lpm_excitation_correlation`]):
    /// the local fit's standard errors carry it ([`sd_ident::LineNoise`]).
    pub correlation: &'a [f64],
    /// The DFT lines of its record with their noise variance (an open-loop non-periodic
    /// record): the local fits use them ([`sd_ident::local_mode_dft`]) — no LPM estimate,
    /// with its correlated lines and its local quadratic, in between.
    pub spectra: Option<&'a sd_ident::LineSpectra>,
}

/// What [`track_modes`] finds: the tracked pairs and the share of the rest.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tracked {
    /// The tracked pairs.
    pub modes: Vec<ModeTrack>,
    /// Share of the model experiment's response held by the physical fit's rigid-body and
    /// real-pole terms ([`sd_ident::PhysicalMode::share`]): the body a friction corner damps
    /// ([`corner_dominates`]).
    pub body_share: f64,
}

/// Weighted mean, χ² of constancy, and the weighted slope against `x` with its z-score.
fn spread(x: &[f64], y: &[f64], s: &[f64]) -> (f64, f64) {
    let w: Vec<f64> = s
        .iter()
        .map(|v| 1.0 / (v * v).max(f64::MIN_POSITIVE))
        .collect();
    let sw: f64 = w.iter().sum();
    let mean = y.iter().zip(&w).map(|(y, w)| y * w).sum::<f64>() / sw;
    let chi2 = y.iter().zip(&w).map(|(y, w)| (y - mean).powi(2) * w).sum();
    let xm = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / sw;
    let sxx: f64 = x.iter().zip(&w).map(|(x, w)| (x - xm).powi(2) * w).sum();
    let sxy: f64 = x
        .iter()
        .zip(y)
        .zip(&w)
        .map(|((x, y), w)| (x - xm) * (y - mean) * w)
        .sum();
    let z = if sxx > 0.0 {
        sxy / sxx * sxx.sqrt()
    } else {
        0.0
    };
    (chi2, z)
}

/// The tracked modes of `levels` at false-alarm probability `alpha` per test (module
/// documentation), the modes from the physical fit of `modes_from` (the model experiment's
/// FRF, thinned for long records); empty when it finds no pair.
///
/// # Errors
/// The physical fit's errors.
pub fn track_modes(modes_from: &Frd, levels: &[TrackLevel<'_>], alpha: f64) -> Result<Tracked> {
    // the modes only need finding here (the local fits use every line): at most
    // MODE_FIT_LINES lines and orders up to MODE_FIT_ORDER keep the stabilisation to seconds
    let step = modes_from.len().div_ceil(MODE_FIT_LINES).max(1);
    let thinned = modes_from.select(|i| i % step == 0)?;
    let opt = StabilizationOptions {
        max_order: MODE_FIT_ORDER,
        ..StabilizationOptions::default()
    };
    let phys = physical_fit(&thinned, &opt, &mut |_| {})?;
    let pairs: Vec<_> = phys
        .modes
        .iter()
        .zip(&phys.fit.terms)
        .filter(|(m, _)| {
            m.kind == ModeKind::Pair && m.in_band && m.damping < MAX_DAMPING && !m.ripple
        })
        .collect();
    let df = phys.line_spacing_hz;
    let body_share = phys
        .modes
        .iter()
        .filter(|m| m.kind != ModeKind::Pair)
        .map(|m| m.share)
        .sum();
    let z = normal_quantile(1.0 - alpha / 2.0);
    // the modes' local fits are independent: in parallel, collected in order
    let mut tracks: Vec<ModeTrack> = (0..pairs.len())
        .into_par_iter()
        .filter_map(|i| {
            let m = pairs[i].0;
            // the band's half-width is capped at 45 % of the distance to the neighbouring
            // pairs; how far a level's peak is sought from its neighbour's frequency too, and
            // at most MAX_STEP of the frequency
            let mut cap = f64::INFINITY;
            for (k, (o, _)) in pairs.iter().enumerate() {
                if k != i {
                    cap = cap.min(0.45 * (o.freq_hz - m.freq_hz).abs());
                }
            }
            let width = Width {
                lines: 6.0 * df,
                cap,
            };
            let half = width.half(m.freq_hz, m.damping);
            let band = (m.freq_hz - half, m.freq_hz + half);
            let reach = (MAX_STEP * m.freq_hz).min(cap).max(half);
            let beside = |lv: &TrackLevel<'_>, band: (f64, f64)| {
                let dft = lv.spectra.is_some();
                neighbours(lv.frd, (&pairs, phys.delay_samples), i, band, dft)
            };
            let (points, buried) = follow(levels, (m.freq_hz, m.damping), (width, reach), &beside);
            if points.len() < 2 {
                return None;
            }
            let mut t = track(m.freq_hz, m.damping, m.share, band, points, (alpha, z));
            t.buried = buried;
            Some(t)
        })
        .collect();
    mark_dominant(&mut tracks);
    Ok(Tracked {
        modes: tracks,
        body_share,
    })
}

/// Least whitened size `Σ 2|r_k|²/σ²_k` of the part of a neighbouring mode's skirt over a
/// band that no affine background takes up (module documentation, step 3) for the
/// neighbour's pole to enter the band's local fit: about the square of the standard
/// errors by which the skirt's curvature could move the fitted frequency.
pub const NEIGHBOUR_MIN: f64 = 1.0;

/// Most neighbouring modes one local fit takes.
pub const MAX_NEIGHBOURS: usize = 2;

/// The pairs beside pair `i` (frequency and damping) whose skirts curve over `band` of
/// `frd` (the level's FRF: its total variance) beyond what the local fit's affine background takes up
/// ([`NEIGHBOUR_MIN`]; each term of the physical fit, its delay included, evaluated at the
/// band's lines, the least-squares line in `δ` removed with the lines' weights), the strongest
/// first, as many as the band's lines leave residual degrees of freedom for
/// (`dft`: the fit on a record's DFT lines, four real parameters per neighbour).
fn neighbours(
    frd: &Frd,
    (pairs, delay): (&[(&sd_ident::PhysicalMode, &sd_ident::ModalTerm)], f64),
    i: usize,
    band: (f64, f64),
    dft: bool,
) -> Vec<(f64, f64)> {
    let (Some(ts), Some(var)) = (frd.time().ts(), frd.variance()) else {
        return Vec::new();
    };
    let fr = frd.freq_hz();
    let lines: Vec<usize> = (0..fr.len())
        .filter(|&k| (band.0..=band.1).contains(&fr[k]) && var[k][(0, 0)] > 0.0)
        .collect();
    let room = if dft {
        lines.len().saturating_sub(MIN_LINES + 4) / 2
    } else {
        lines.len().saturating_sub(MIN_LINES)
    };
    let centre = 0.5 * (band.0 + band.1);
    let mut sized: Vec<(f64, (f64, f64))> = pairs
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != i)
        .map(|(_, (o, term))| {
            let pts: Vec<(f64, C, f64)> = lines
                .iter()
                .map(|&k| {
                    let z = C::from_polar(1.0, TAU * fr[k] * ts);
                    let t = term.eval(z) * C::from_polar(1.0, -TAU * fr[k] * ts * delay);
                    ((fr[k] - centre) / centre, t, 2.0 / var[k][(0, 0)])
                })
                .collect();
            (curvature(&pts), (o.freq_hz, o.damping))
        })
        .filter(|(size, _)| *size >= NEIGHBOUR_MIN)
        .collect();
    sized.sort_by(|a, b| b.0.total_cmp(&a.0));
    sized
        .into_iter()
        .take(room.min(MAX_NEIGHBOURS))
        .map(|(_, m)| m)
        .collect()
}

/// `min_{a,b} Σ w_k |t_k − a − b·δ_k|²` over the points `(δ_k, t_k, w_k)` (complex `a, b`):
/// what of `t` no weighted line in `δ` takes up.
fn curvature(pts: &[(f64, C, f64)]) -> f64 {
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    let (mut t0, mut t1) = (C::new(0.0, 0.0), C::new(0.0, 0.0));
    for &(d, t, w) in pts {
        (s0, s1, s2) = (s0 + w, s1 + w * d, s2 + w * d * d);
        (t0, t1) = (t0 + t * w, t1 + t * (w * d));
    }
    let det = s0 * s2 - s1 * s1;
    if det.is_nan() || det <= 0.0 {
        return 0.0;
    }
    let a = (t0 * s2 - t1 * s1) / det;
    let b = (t1 * s0 - t0 * s1) / det;
    pts.iter()
        .map(|&(d, t, w)| w * (t - a - b * d).norm_sqr())
        .sum()
}

/// A level's neighbouring modes `(f_n Hz, ζ)` for its band ([`neighbours`] on its FRF).
type Beside<'a> = dyn Fn(&TrackLevel<'_>, (f64, f64)) -> Vec<(f64, f64)> + 'a;

/// Largest relative step of a mode's frequency between neighbouring levels that its peak is
/// sought over (module documentation, step 3).
pub const MAX_STEP: f64 = 0.1;

/// A local fit's band (module documentation, step 2): four half-power half-widths `4ζf`, at
/// least `lines` (six line spacings), at most `cap`.
#[derive(Debug, Clone, Copy)]
struct Width {
    lines: f64,
    cap: f64,
}

impl Width {
    /// The half-width for a mode at `f` with damping `zeta`.
    fn half(&self, f: f64, zeta: f64) -> f64 {
        (4.0 * zeta * f).max(self.lines).min(self.cap)
    }
}

/// The frequency of the largest `|G|²` averaged over `±smooth` Hz, within `reach` of `f`
/// (`None` without a line there): a broad resonance's centre, not the largest of the lines
/// the distortion scatters over it.
fn peak(frd: &Frd, f: f64, reach: f64, smooth: f64) -> Option<f64> {
    let fr = frd.freq_hz();
    let g2: Vec<f64> = frd
        .response()
        .iter()
        .map(|g| g[(0, 0)].norm_sqr())
        .collect();
    let averaged = |k: usize| -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        // the lines within ±smooth of line k, outwards from it (the grid is sorted)
        for j in (0..=k).rev().take_while(|&j| fr[k] - fr[j] <= smooth) {
            sum += g2[j];
            n += 1;
        }
        for j in (k + 1..fr.len()).take_while(|&j| fr[j] - fr[k] <= smooth) {
            sum += g2[j];
            n += 1;
        }
        sum / n.max(1) as f64
    };
    (0..fr.len())
        .filter(|&k| (fr[k] - f).abs() <= reach)
        .map(|k| (k, averaged(k)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| fr[k])
}

/// The local fit of `frd` in `band` with the least cost over the starts `(centre, ζ)`,
/// `(centre, 3ζ)` and `(f, ζ)` (`from = (f, ζ)`: the neighbouring level's fit), among the
/// fits the lines resolve: a half-power bandwidth `2ζf_n` of at least the band's median line
/// spacing. A pole narrower than that sits on one or two scattered lines (on the level
/// suite's development seeds, a level whose distortion buried its resonance gave a pole of
/// ζ = 0.001 on one line, its frequency 3 % from the truth at 18 standard errors); `None`
/// when no start gives a resolved fit.
fn best_local(
    lv: &TrackLevel<'_>,
    band: (f64, f64),
    centre: f64,
    from: (f64, f64),
    beside: &[(f64, f64)],
) -> Option<LocalMode> {
    let spacing = median_spacing(lv.frd, band)?;
    let noise = LineNoise {
        correlation: lv.correlation.to_vec(),
        spacing_hz: spacing,
    };
    [(centre, from.1), (centre, (3.0 * from.1).min(0.9)), from]
        .into_iter()
        .filter_map(|start| match lv.spectra {
            Some(spec) => local_mode_dft_beside(spec, band, start, beside).ok(),
            None => local_mode_beside(lv.frd, band, start, &noise, beside).ok(),
        })
        .filter(|m| 2.0 * m.damping * m.freq_hz >= spacing)
        .min_by(|a, b| a.cost_per_dof.total_cmp(&b.cost_per_dof))
}

/// Least median `|G|²/σ²` over a band's lines for its local fit to count: below it the
/// distortion buries the resonance, the projected cost has several minima and the local
/// standard errors do not cover them. Set on the level suite's development seeds `0..8`, where
/// the levels whose fits missed their BLA truth by 5–18 standard errors (a pole of ζ ≈ 0.001
/// on one scattered line; `LEVEL_EVIDENCE=1` prints each point's z) had a median below 4,
/// and the linear modes' levels hundreds.
pub const MIN_BAND_SNR: f64 = 4.0;

/// The median `|G|²/σ²` of the lines of `frd` inside `band` (`None` without lines or
/// variance).
fn band_snr(frd: &Frd, band: (f64, f64)) -> Option<f64> {
    let var = frd.variance()?;
    let fr = frd.freq_hz();
    let snr: Vec<f64> = (0..fr.len())
        .filter(|&k| (band.0..=band.1).contains(&fr[k]))
        .map(|k| frd.response()[k][(0, 0)].norm_sqr() / var[k][(0, 0)].max(f64::MIN_POSITIVE))
        .collect();
    (!snr.is_empty()).then(|| sd_model::median(&snr))
}

/// The median spacing (Hz) of the lines of `frd` inside `band` (`None` with fewer than two).
fn median_spacing(frd: &Frd, band: (f64, f64)) -> Option<f64> {
    let f: Vec<f64> = frd
        .freq_hz()
        .iter()
        .copied()
        .filter(|f| (band.0..=band.1).contains(f))
        .collect();
    let gaps: Vec<f64> = f.windows(2).map(|w| w[1] - w[0]).collect();
    (!gaps.is_empty()).then(|| sd_model::median(&gaps))
}

/// One mode's local fits over the levels (module documentation, step 3): from the model
/// experiment (the first level) outwards in level, each level's band centred on its smoothed
/// `|G|²` peak ([`peak`]) within `reach` of the frequency fitted at the level next to it, as
/// wide as `width`
/// makes it for that level's frequency and damping (at least the model experiment's: a mode
/// whose damping rises with the level keeps four of its bandwidths), and its fit started
/// there with that damping (a mode that shifts by more than its band over the levels is
/// followed, not lost); in the order of `levels`, levels whose band holds no measurable
/// resonance ([`MIN_BAND_SNR`]), whose fits failed ([`best_local`]) or did not determine the
/// damping (standard error above the value) left out; `beside` names a level's neighbouring
/// modes from its FRF and band ([`neighbours`]). No points at all when the model experiment's
/// own local fit does not resolve the mode: the physical fit found it on those data, so a pair
/// its full-resolution lines do not confirm is no mode to follow, and the other levels' bands,
/// sought from its frequency without an anchor, would slide onto the next resonance's skirt.
fn follow(
    levels: &[TrackLevel<'_>],
    start: (f64, f64),
    (width, reach): (Width, f64),
    beside: &Beside<'_>,
) -> (Vec<TrackPoint>, Vec<String>) {
    let mut order: Vec<usize> = (0..levels.len()).collect();
    order.sort_by(|&a, &b| levels[a].level.total_cmp(&levels[b].level));
    let at = order.iter().position(|&i| i == 0).unwrap_or(0);
    let mut fitted: Vec<Option<TrackPoint>> = vec![None; levels.len()];
    let mut buried = Vec::new();
    // upwards from the reference (itself included), then downwards from it
    for walk in [
        order[at..].to_vec(),
        order[..at].iter().rev().copied().collect(),
    ] {
        let mut from = fitted[0].as_ref().map_or(start, |p| (p.freq_hz, p.damping));
        for i in walk {
            if i != 0 && fitted[0].is_none() {
                return (Vec::new(), Vec::new());
            }
            let lv = &levels[i];
            let zeta = from.1.max(start.1);
            let centre = peak(lv.frd, from.0, reach, zeta * from.0).unwrap_or(from.0);
            let half = width.half(from.0, zeta);
            let band = (centre - half, centre + half);
            // a band whose lines are mostly within 2σ of zero holds no measurable resonance
            if band_snr(lv.frd, band).is_none_or(|s| s < MIN_BAND_SNR) {
                // above the reference (which resolved the mode, or no other level is fitted),
                // more excitation buried it: the total variance there is distortion
                if lv.level > levels[0].level {
                    buried.push(lv.name.to_string());
                }
                continue;
            }
            let Some(fit) = best_local(lv, band, centre, from, &beside(lv, band)) else {
                continue;
            };
            // a fit that does not determine its damping found no resonance in the band
            let determined = fit.damping_std < fit.damping;
            if !determined {
                continue;
            }
            from = (fit.freq_hz, fit.damping);
            fitted[i] = Some(TrackPoint {
                experiment: lv.name.to_string(),
                relative_level: lv.level,
                freq_hz: fit.freq_hz,
                freq_std: fit.freq_std,
                damping: fit.damping,
                damping_std: fit.damping_std,
            });
        }
    }
    (fitted.into_iter().flatten().collect(), buried)
}

/// Whether `K` points with constancy statistic `χ²` and slope z-score `z` ([`spread`]) move
/// at false-alarm probability `alpha` (module documentation, step 4): for `K = 2` the two
/// tests are one (`χ² = z²`); for `K ≥ 3` the omnibus `χ²_{K−1}` and the slope's `χ²_1` each
/// at `α/2` (Bonferroni: at most `α` together; the slope test has the power where the
/// frequency follows the level monotonically, as a stiffness or friction law makes it).
fn moves_test(k: usize, alpha: f64) -> impl Fn(f64, f64) -> bool {
    let (omnibus, slope) = if k <= 2 {
        (chi2_quantile(1.0 - alpha, 1.0), f64::INFINITY)
    } else {
        (
            chi2_quantile(1.0 - alpha / 2.0, (k - 1) as f64),
            chi2_quantile(1.0 - alpha / 2.0, 1.0),
        )
    };
    move |chi2, z| chi2 > omnibus || z * z > slope
}

/// The tests of one mode's points (module documentation, step 4).
fn track(
    f0: f64,
    zeta0: f64,
    share: f64,
    band_hz: (f64, f64),
    points: Vec<TrackPoint>,
    (alpha, z): (f64, f64),
) -> ModeTrack {
    let x: Vec<f64> = points
        .iter()
        .map(|p| p.relative_level.max(1e-12).ln())
        .collect();
    let col =
        |g: fn(&TrackPoint) -> (f64, f64)| -> (Vec<f64>, Vec<f64>) { points.iter().map(g).unzip() };
    let (f, fs) = col(|p| (p.freq_hz, p.freq_std));
    let (d, ds) = col(|p| (p.damping, p.damping_std));
    let (cf, zf) = spread(&x, &f, &fs);
    let (cd, zd) = spread(&x, &d, &ds);
    let moves = moves_test(points.len(), alpha);
    let frequency_moves = moves(cf, zf);
    let damping_moves = moves(cd, zd);
    let frequency_trend = match (frequency_moves, zf) {
        (true, s) if s > z => FreqTrend::Hardening,
        (true, s) if s < -z => FreqTrend::Softening,
        _ => FreqTrend::None,
    };
    let damping_trend = match (damping_moves, zd) {
        (true, s) if s > z => DampingTrend::Increasing,
        (true, s) if s < -z => DampingTrend::Decreasing,
        _ => DampingTrend::None,
    };
    let by_level = |hi: bool| {
        points
            .iter()
            .max_by(|a, b| {
                let o = a.relative_level.total_cmp(&b.relative_level);
                if hi {
                    o
                } else {
                    o.reverse()
                }
            })
            .map_or(f0, |p| p.freq_hz)
    };
    ModeTrack {
        freq_hz: f0,
        damping: zeta0,
        share,
        band_hz,
        frequency_moves,
        damping_moves,
        frequency_trend,
        damping_trend,
        shift_bandwidths: (by_level(true) - by_level(false)) / (2.0 * zeta0 * f0),
        dominant: false,
        points,
        buried: Vec::new(),
    }
}

/// `kind` and `damping_trend` from the tracked modes (module documentation, step 5): none
/// when a moving friction `corner` dominates ([`corner_dominates`]); else the dominant moving
/// mode's frequency and damping trends; none when no tracked mode moves and none was buried
/// ([`ModeTrack::buried`]); `fallback`'s (the amplitude model's) when no mode could be
/// tracked, or none moves and one was buried.
pub fn decided(
    tracks: &[ModeTrack],
    fallback: (FreqTrend, DampingTrend),
    corner: bool,
) -> (FreqTrend, DampingTrend) {
    if corner {
        // the friction corner dominates: its trend is the corner trend, no pair's
        return (FreqTrend::None, DampingTrend::None);
    }
    if tracks.is_empty() {
        return fallback;
    }
    match tracks.iter().find(|t| t.dominant) {
        Some(d) => (d.frequency_trend, d.damping_trend),
        // the levels where a mode would have moved most are buried in its distortion: the
        // amplitude model, fitted over every level, speaks for them
        None if tracks.iter().any(|t| !t.buried.is_empty()) => fallback,
        None => (FreqTrend::None, DampingTrend::None),
    }
}

impl ModeTrack {
    /// Its claim to be the dominant moving mode (module documentation, step 5): the shift
    /// over the levels in half-power bandwidths (the damping's relative change where the
    /// frequency does not move) times the mode's share; 0 when it does not move.
    pub fn dominance(&self) -> f64 {
        if !(self.frequency_moves || self.damping_moves) {
            return 0.0;
        }
        let moved = if self.frequency_trend != FreqTrend::None {
            self.shift_bandwidths.abs()
        } else {
            let (lo, hi) = self
                .points
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
                    (lo.min(p.damping), hi.max(p.damping))
                });
            (hi - lo) / self.damping.max(f64::MIN_POSITIVE)
        };
        moved * self.share
    }
}

/// Marks the dominant moving mode (module documentation, step 5).
fn mark_dominant(tracks: &mut [ModeTrack]) {
    let best = (0..tracks.len())
        .filter(|&i| tracks[i].dominance() > 0.0)
        .max_by(|&a, &b| tracks[a].dominance().total_cmp(&tracks[b].dominance()));
    if let Some(i) = best {
        tracks[i].dominant = true;
    }
}

/// Whether a moving friction corner outweighs every moving pair (module documentation,
/// step 5): `corner_shift` is the corner's move over the levels in its own half-power
/// bandwidth (`|f_c(ρ_max) − f_c(ρ_min)|/(2f_c)`, a real pole's `2|Re s|` as a pair's
/// `2ζω`), weighted by `body_share`; when it exceeds the dominant pair's
/// [`ModeTrack::dominance`], no pair is dominant (their `dominant` flags are cleared).
pub fn corner_dominates(tracks: &mut [ModeTrack], corner_shift: f64, body_share: f64) -> bool {
    let corner = corner_shift * body_share;
    let pairs = tracks
        .iter()
        .map(ModeTrack::dominance)
        .fold(0.0f64, f64::max);
    let wins = corner > 0.0 && corner > pairs;
    if wins {
        for t in tracks.iter_mut() {
            t.dominant = false;
        }
    }
    wins
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(level: f64, f: f64, fs: f64, d: f64) -> TrackPoint {
        TrackPoint {
            experiment: format!("l{level}"),
            relative_level: level,
            freq_hz: f,
            freq_std: fs,
            damping: d,
            damping_std: 1e-3,
        }
    }

    #[test]
    fn a_shift_beyond_the_errors_moves_and_has_its_sign() {
        let pts = vec![
            point(1.0, 7.30, 0.005, 0.010),
            point(2.0, 7.25, 0.005, 0.015),
            point(4.0, 7.18, 0.005, 0.025),
        ];
        let t = track(7.3, 0.01, 0.5, (7.0, 7.6), pts, (0.01, 2.576));
        assert!(t.frequency_moves && t.damping_moves);
        assert_eq!(t.frequency_trend, FreqTrend::Softening);
        assert_eq!(t.damping_trend, DampingTrend::Increasing);
        assert!((t.shift_bandwidths + 0.12 / 0.146).abs() < 1e-9);
    }

    #[test]
    fn a_scatter_within_the_errors_does_not_move() {
        let pts = vec![
            point(1.0, 7.300, 0.01, 0.010),
            point(2.0, 7.305, 0.01, 0.0105),
            point(4.0, 7.297, 0.01, 0.0098),
        ];
        let t = track(7.3, 0.01, 0.5, (7.0, 7.6), pts, (0.01, 2.576));
        assert!(!t.frequency_moves && !t.damping_moves);
        assert_eq!(t.frequency_trend, FreqTrend::None);
        let mut v = vec![t];
        mark_dominant(&mut v);
        assert!(!v[0].dominant);
    }

    /// Three and four levels of a constant frequency with unequal standard errors: the two
    /// tests at α/2 together move at most α of the time (20 000 draws, α = 0.05: the
    /// binomial standard error of the rate is 0.0015, the bound checked 0.05 + 4 of them);
    /// a monotone shift the omnibus χ² misses even at α is found by the slope at α/2.
    #[test]
    fn the_two_tests_together_keep_alpha() {
        let alpha = 0.05;
        let mut rng = sd_ident::rng::SplitMix::new(11);
        for k in [3usize, 4] {
            let moves = moves_test(k, alpha);
            let x: Vec<f64> = (0..k).map(|i| (i as f64) * 2f64.ln()).collect();
            let s: Vec<f64> = (0..k).map(|i| 0.5 * 3f64.powi(i as i32)).collect();
            let draws = 20_000;
            let hits = (0..draws)
                .filter(|_| {
                    let y: Vec<f64> = s.iter().map(|s| 100.0 + s * rng.normal()).collect();
                    let (c, z) = spread(&x, &y, &s);
                    moves(c, z)
                })
                .count();
            let rate = hits as f64 / draws as f64;
            assert!(rate <= alpha + 0.006, "K = {k}: rate {rate}");
        }
        // a straight line through four levels: χ² = z² = 7, below χ²₃(0.95) = 7.81 (the
        // omnibus alone would not move), above χ²₁(0.975) = 5.02
        let x: Vec<f64> = (0..4).map(|i| f64::from(i) * 2f64.ln()).collect();
        let b = (7.0 / (5.0 * 2f64.ln().powi(2))).sqrt();
        let y: Vec<f64> = x.iter().map(|x| 100.0 + b * x).collect();
        let (c, z) = spread(&x, &y, &[1.0; 4]);
        assert!((c - 7.0).abs() < 1e-9 && (z * z - 7.0).abs() < 1e-9);
        assert!(c < chi2_quantile(0.95, 3.0));
        assert!(moves_test(4, 0.05)(c, z));
        assert!(!moves_test(4, 0.01)(c, z));
    }

    /// A friction corner that moves by most of its bandwidth outweighs a pair holding a
    /// thousandth of the response moved by a hundredth of its own (seeds 2913, 2962 of the
    /// level suite); a pair holding half the response, moved by a bandwidth, outweighs it.
    #[test]
    fn a_moving_corner_outweighs_a_negligible_pair() {
        let pts = |df: f64| {
            vec![
                point(1.0, 100.0, 0.001, 0.010),
                point(2.0, 100.0 + df / 2.0, 0.001, 0.010),
                point(4.0, 100.0 + df, 0.001, 0.010),
            ]
        };
        // ζ = 0.01 at 100 Hz: a half-power bandwidth of 2 Hz
        let mut weak = vec![track(
            100.0,
            0.01,
            1e-3,
            (95.0, 105.0),
            pts(-0.02),
            (0.01, 2.576),
        )];
        mark_dominant(&mut weak);
        assert!(weak[0].dominant && weak[0].frequency_trend == FreqTrend::Softening);
        assert!((weak[0].dominance() - 0.01 * 1e-3).abs() < 1e-12);
        // the corner: 40 → 8 Hz over the levels, 0.4 of its 2f_c, the body 0.9 of the response
        assert!(corner_dominates(&mut weak, 0.4, 0.9));
        assert!(!weak[0].dominant);
        let mut strong = vec![track(
            100.0,
            0.01,
            0.5,
            (95.0, 105.0),
            pts(-2.0),
            (0.01, 2.576),
        )];
        mark_dominant(&mut strong);
        assert!(!corner_dominates(&mut strong, 0.4, 0.9));
        assert!(strong[0].dominant);
        // no moving corner: nothing changes
        assert!(!corner_dominates(&mut strong, 0.0, 0.9));
    }

    /// No tracked mode moves: `none`, unless a mode was buried at a level above the model
    /// experiment's, where the amplitude model (the fallback) speaks.
    /// What of a skirt no weighted line takes up: nothing of a complex line, `2/3` of `δ²` on
    /// `δ = −1, 0, 1` (the line `2/3`; residuals `1/3, −2/3, 1/3`), scaled by the weights.
    #[test]
    fn curvature_is_what_no_line_takes_up() {
        let line: Vec<(f64, C, f64)> = (0..7)
            .map(|k| {
                let d = k as f64 * 0.1 - 0.3;
                (d, C::new(1.0, -2.0) + C::new(0.5, 3.0) * d, 1.0 + k as f64)
            })
            .collect();
        assert!(curvature(&line) < 1e-24, "{}", curvature(&line));
        let parabola = |w: f64| -> Vec<(f64, C, f64)> {
            [-1.0, 0.0, 1.0]
                .iter()
                .map(|&d| (d, C::new(d * d, 0.0), w))
                .collect()
        };
        assert!((curvature(&parabola(1.0)) - 2.0 / 3.0).abs() < 1e-14);
        assert!((curvature(&parabola(3.0)) - 2.0).abs() < 1e-14);
    }

    #[test]
    fn a_buried_level_defers_to_the_amplitude_model() {
        let pts = vec![point(1.0, 7.30, 0.01, 0.010), point(2.0, 7.30, 0.01, 0.010)];
        let mut t = track(7.3, 0.01, 0.5, (7.0, 7.6), pts, (0.01, 2.576));
        assert!(!t.frequency_moves && !t.dominant);
        let fallback = (FreqTrend::Hardening, DampingTrend::Increasing);
        assert_eq!(
            decided(std::slice::from_ref(&t), fallback, false),
            (FreqTrend::None, DampingTrend::None)
        );
        t.buried = vec!["l4".into()];
        assert_eq!(decided(std::slice::from_ref(&t), fallback, false), fallback);
        assert_eq!(
            decided(&[t], fallback, true),
            (FreqTrend::None, DampingTrend::None)
        );
    }
}
