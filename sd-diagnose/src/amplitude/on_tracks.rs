//! The amplitude model on the tracked modes: a candidate pair that a tracked physical mode
//! ([`crate::tracks`]) follows takes, at every level, the track's local fit in place of the
//! level's global modal fit (module documentation of [`super`]).
//!
//! **Why.** The level fit frees the candidates' poles inside the linear model's whole basis;
//! on a real structure that basis spends poles on distortion, and the freed pair is pulled by
//! its neighbours' residues and by the distortion the basis absorbs. The track's local fit
//! (one pair and an affine background in the mode's own band, its standard errors from the
//! level's total variance and its line correlation) is the estimate whose coverage the level
//! suite measures against each mode's separately computed truth. The trend, the pole the
//! amplitude model predicts at an amplitude, and the report's points then come from it.
//!
//! **Which pair.** The candidate whose model-experiment fit `(f_c, ζ_c, σ_c)` lies nearest the
//! track's model-experiment point `(f_t, σ_t)`, within `max(ζ_c·f_c, 3·√(σ_c² + σ_t²))` (its
//! half-power half-width, or three standard errors of the difference); each track names at
//! most one candidate; real poles (corners) keep their level fits.
//!
//! **Levels without a point.** A level where the track has no local fit keeps its level fit
//! ([`PointFit::Level`]). That is mostly the highest level: the band's SNR gate drops a level
//! whose distortion buries the resonance, and the level that moves the mode furthest is the
//! one the trend most needs. With the tracks forced on every case (exploratory builds, not in
//! the repository), the held-out levels' predicted-shift error on the level suite's
//! development seeds 0..10 was a median 0.20 of the shift when such levels were left out of
//! the trend and 0.16 when they kept their level fits (0.07 without the tracks), mostly where
//! three levels leave two to train on; the two fits of one level agreed within their standard
//! errors where both existed.

use super::*;
use crate::tracks::{ModeTrack, TrackPoint};

/// Replaces the level fits of the candidates that `tracks` follow (module documentation);
/// `names[k]` is the experiment of `fits[k]`, `names[0]` the model experiment. Returns how
/// many candidates took a track.
pub(crate) fn on_tracks(
    basis: &ModalBasis,
    cand: &[usize],
    fits: &mut [LevelFit],
    names: &[&str],
    tracks: &[ModeTrack],
) -> usize {
    let (Some(first), Some(&reference)) = (fits.first(), names.first()) else {
        return 0;
    };
    let point = |t: &ModeTrack, name: &str| -> Option<TrackPoint> {
        t.points.iter().find(|p| p.experiment == name).cloned()
    };
    let mut taken = vec![false; tracks.len()];
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for (m, &pm) in cand.iter().enumerate() {
        let Some(&(fc, zc, sfc, _)) = first.modal.get(m) else {
            continue;
        };
        if basis.is_real(pm) || !(fc.is_finite() && zc.is_finite()) {
            continue;
        }
        let nearest = tracks
            .iter()
            .enumerate()
            .filter(|(t, _)| !taken[*t])
            .filter_map(|(t, tr)| {
                let p = point(tr, reference)?;
                let d = (p.freq_hz - fc).abs();
                let tol = (zc * fc).max(3.0 * p.freq_std.hypot(sfc.max(0.0)));
                (d <= tol).then_some((t, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((t, _)) = nearest {
            taken[t] = true;
            pairs.push((m, t));
        }
    }
    for &(m, t) in &pairs {
        for (fit, name) in fits.iter_mut().zip(names) {
            if let Some(p) = point(&tracks[t], name) {
                fit.modal[m] = (p.freq_hz, p.damping, p.freq_std, p.damping_std);
                fit.fit_of[m] = PointFit::Local;
            }
        }
    }
    pairs.len()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::{DampingTrend, FreqTrend};

    fn point(name: &str, f: f64, z: f64) -> TrackPoint {
        TrackPoint {
            experiment: name.into(),
            relative_level: 1.0,
            freq_hz: f,
            freq_std: 0.01,
            damping: z,
            damping_std: 1e-4,
        }
    }

    fn track(f: f64, points: Vec<TrackPoint>) -> ModeTrack {
        ModeTrack {
            freq_hz: f,
            damping: 0.01,
            share: 0.5,
            band_hz: (f - 5.0, f + 5.0),
            frequency_moves: true,
            damping_moves: false,
            frequency_trend: FreqTrend::Softening,
            damping_trend: DampingTrend::None,
            shift_bandwidths: 1.0,
            dominant: true,
            points,
            buried: Vec::new(),
        }
    }

    fn level(modal: Vec<(f64, f64, f64, f64)>) -> LevelFit {
        let n = modal.len();
        LevelFit {
            linear: modal.clone(),
            modal,
            amplitude: vec![1.0; n],
            fit_of: vec![PointFit::Level; n],
        }
    }

    #[test]
    fn the_nearest_pair_takes_the_track_and_a_missing_level_keeps_its_level_fit() {
        // a corner at 2 Hz, pairs at 50 and 120 Hz; the track follows the 120 Hz mode at the
        // reference and the third level, not the second
        let basis = ModalBasis::build(
            (0, 0.0),
            &[-TAU * 2.0],
            &[pair_of(50.0, 0.01), pair_of(120.0, 0.01)],
        )
        .unwrap();
        assert!(basis.is_real(0) && !basis.is_real(1) && !basis.is_real(2));
        let cand: Vec<usize> = (0..basis.poles().len()).collect();
        let row = |f2: f64| {
            vec![
                (2.0, 1.0, 0.1, 0.0),
                (50.0, 0.01, 0.02, 1e-4),
                (f2, 0.01, 0.02, 1e-4),
            ]
        };
        let mut fits = vec![level(row(120.3)), level(row(119.0)), level(row(118.0))];
        let tr = track(
            120.0,
            vec![point("a", 120.1, 0.012), point("c", 117.5, 0.02)],
        );
        let n = on_tracks(
            &basis,
            &cand,
            &mut fits,
            &["a", "b", "c"],
            std::slice::from_ref(&tr),
        );
        assert_eq!(n, 1);
        assert_eq!(fits[0].modal[2], (120.1, 0.012, 0.01, 1e-4));
        assert_eq!(fits[0].fit_of[2], PointFit::Local);
        assert_eq!(fits[1].fit_of[2], PointFit::Level);
        assert_eq!(fits[1].modal[2].0, 119.0);
        assert_eq!(fits[2].modal[2].0, 117.5);
        // the other candidates are untouched
        for f in &fits {
            assert_eq!(f.fit_of[0], PointFit::Level);
            assert_eq!(f.fit_of[1], PointFit::Level);
        }
        // a track further than the half-power half-width and three standard errors names none
        let mut far = vec![level(row(122.0))];
        assert_eq!(on_tracks(&basis, &cand, &mut far, &["a"], &[tr]), 0);
        assert_eq!(far[0].fit_of[2], PointFit::Level);
    }
}
