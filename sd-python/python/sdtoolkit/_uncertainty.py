"""Uncertainty, the intersample error, multisines and weights (``sdctl uncertainty``,
``coverage``, ``downsample --uncertainty``, ``analyze --uncertainty``, ``intersample``,
``multisine``, ``weight notch|lowpass|makeweight``); re-exported by :mod:`sdtoolkit`."""

from __future__ import annotations

import json
import os
from typing import Optional, Union

import numpy as np

from . import _native
from . import Frd, Result, StateSpace, _json_text, _ss  # defined before this module is imported


class Uncertainty(Result):
    """A model's error bound on measured lines (the uncertainty JSON of docs/formats.md):
    ``form``, ``confidence``, ``ts``, ``freq_hz``, the nominal response, the bound per line, and
    the overbounding ``weight`` when one was fitted. ``to_json()`` gives the exact text
    ``sdctl`` reads; ``Uncertainty.from_json(path_or_text)`` reads one."""

    def __init__(self, text: str, extra: Optional[dict] = None):
        fields = json.loads(text)
        fields.update(extra or {})
        Result.__init__(self, fields)
        self.__dict__["_text"] = text

    def to_json(self) -> str:
        return self._text

    @classmethod
    def from_json(cls, source: Union[str, os.PathLike]) -> "Uncertainty":
        return cls(_json_text(source, "Uncertainty.from_json"))


def _frd_args(frd, name: str):
    if not isinstance(frd, Frd):
        raise TypeError(f"{name} must be a sdtoolkit.Frd, got {type(frd).__name__}")
    return (frd.freq_hz, frd.response, frd.variance, frd.dt)


def _bound_text(bound, name: str = "bound") -> str:
    if isinstance(bound, Uncertainty):
        return bound.to_json()
    if isinstance(bound, (str, os.PathLike)):
        return _json_text(bound, name)
    raise TypeError(f"{name} must be an Uncertainty, JSON text or a path, not {type(bound).__name__}")


def _order(v, name: str) -> Optional[int]:
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
        raise TypeError(f"{name} must be a positive int or None, not {v!r}")
    return int(v)


def uncertainty(model, frd: Frd, form: str = "additive", confidence: float = 0.95,
                simultaneous: bool = False, weight_order: Optional[int] = None) -> Uncertainty:
    """The model's error bound from measured data with variances, as ``sdctl uncertainty``:
    per line, ``|residual| + κ·σ`` at ``confidence`` per line (``simultaneous``: on all lines
    at once), ``form`` ``"additive"`` (plant units) or ``"multiplicative"`` (relative); with
    ``weight_order`` the overbounding weight ``W(z)`` (``|W| ≥`` bound on every line)."""
    return Uncertainty(_native.uncertainty(_ss(model, "model")._tuple(), _frd_args(frd, "frd"),
                                           str(form), float(confidence), bool(simultaneous),
                                           _order(weight_order, "weight_order")))


def coverage(bound, frd: Frd) -> Result:
    """How many lines of the measurement ``frd`` lie inside nominal ± bound (its own variance
    widening the bound), as ``sdctl coverage --json``: ``covered``, ``lines``, ``fraction``."""
    return Result(json.loads(_native.coverage(_bound_text(bound), _frd_args(frd, "frd"))))


def downsample_uncertainty(bound, factor: int, hold_delay: float = 0.0,
                           averaging: float = 0.0) -> Uncertainty:
    """A fast-rate bound taken to the slow rate ``factor·ts`` through Lemma 6's fold sum (with
    a hold that switches ``hold_delay`` of a slow period late and a sampler averaging the last
    ``averaging`` of it), as ``sdctl downsample --uncertainty``; ``missing_hz``: the slow lines
    whose folds are not all fast lines."""
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise TypeError(f"factor must be a positive int, not {factor!r}")
    text, missing = _native.downsample_uncertainty(_bound_text(bound), int(factor),
                                                   float(hold_delay), float(averaging))
    return Uncertainty(text, {"missing_hz": missing})


def robust_stability(P, K, bound, weight_order: Optional[int] = None) -> Result:
    """Robust stability of the loop (``P``, ``K``) against every plant inside the bound, as
    ``sdctl analyze --uncertainty --json``'s ``robust``: ``margin_lines`` (> 1: robustly stable
    on the lines), ``margin_weight`` (with the bound's weight, or one fitted of
    ``weight_order``: between the lines too), ``worst_sensitivity_db``, ``destabilising``."""
    return Result(json.loads(_native.robust_stability(_ss(P, "P")._tuple(), _ss(K, "K")._tuple(),
                                                      _bound_text(bound),
                                                      _order(weight_order, "weight_order"))))


def intersample(P_fast, K, force_rms: float = 0.05, sensor_rms: float = 3e-10,
                points: int = 2000, uncertainty=None, weight_order: Optional[int] = None) -> Result:
    """The error of a slow controller ``K`` (period F·h) on a fast plant ``P_fast`` (period h)
    under white force and sensor disturbances (rms per fast sample), as ``sdctl intersample
    --json``: ``rms_fast`` (every fast sample: the intersample error), ``rms_slow`` (at the
    controller's samples), the spectra and ``control_sensitivity`` |K S|, the dominant
    frequencies; with ``uncertainty`` (of the fast plant) the error bounded over every plant
    inside its weight (``robust``) and the slow margin on the bound's lines (``robust_lines``)."""
    P, Kd = _ss(P_fast, "P_fast"), _ss(K, "K")
    if P.dt is None or Kd.dt is None:
        raise ValueError("intersample needs discrete plant and controller models")
    ratio = Kd.dt / P.dt
    if not (ratio >= 1 and abs(ratio - round(ratio)) <= 1e-9 * ratio):
        raise ValueError(f"the controller period {Kd.dt} s must be an integer multiple of the "
                         f"plant period {P.dt} s")
    text = None if uncertainty is None else _bound_text(uncertainty, "uncertainty")
    d = json.loads(_native.intersample(P._tuple(), Kd._tuple(), int(round(ratio)),
                                       float(force_rms), float(sensor_rms), int(points), text,
                                       _order(weight_order, "weight_order")))
    for key, f, v in (("dominant_hz_fast", "fast_hz", "fast_psd"),
                      ("dominant_hz_slow", "slow_hz", "slow_psd"),
                      ("control_sensitivity_peak_hz", "slow_hz", "control_sensitivity")):
        d[key] = float(d[f][int(np.argmax(d[v]))]) if d[v] else float("nan")
    for k in ("fast_hz", "fast_psd", "slow_hz", "slow_psd", "control_sensitivity"):
        d[k] = np.asarray(d[k])
    return Result(d)


def multisine(fs: float, period: int, f_min: float, f_max: float, lines: str = "full",
              seed: int = 1, rms: float = 1.0, inputs: int = 1) -> Result:
    """One period of a multisine, as ``sdctl multisine`` designs it: ``signal`` (``period``
    samples at ``fs``), ``excited_hz`` / ``excited_bins`` (``lines`` ``"full"``: every line
    from ``f_min`` to ``f_max``; ``"random_odd"``: odd lines, one detection line left out per
    group of three), ``detection_odd_bins`` / ``detection_even_bins``, ``f0``,
    ``crest_factor``; with ``inputs`` > 1 ``signals[e][j]``, input j of experiment e of the
    orthogonal set (every line turned by 2π·j·e/inputs)."""
    return Result(_native.multisine(float(fs), int(period), float(f_min), float(f_max),
                                    str(lines), int(seed), float(rms), int(inputs)))


def weight_notch(freq_hz: float, zeta_zero: float = 0.01, zeta_pole: float = 0.2,
                 dt: Optional[float] = None) -> StateSpace:
    """The notch ``(s² + 2ζz ω s + ω²)/(s² + 2ζp ω s + ω²)`` at ``freq_hz`` (depth ζz/ζp,
    width ζp); discrete (Tustin, prewarped at the notch) when ``dt`` is given."""
    return StateSpace(*_native.weight_notch(float(freq_hz), float(zeta_zero), float(zeta_pole), dt))


def weight_lowpass(freq_hz: float, zeta: float = 0.7, dt: Optional[float] = None) -> StateSpace:
    """The second-order low-pass ``ω²/(s² + 2ζω s + ω²)``; discrete (Tustin, prewarped) when
    ``dt`` is given."""
    return StateSpace(*_native.weight_lowpass(float(freq_hz), float(zeta), dt))


def makeweight(dc: float, freq_hz: float, mag: float, hf: float, order: int = 1,
               dt: Optional[float] = None) -> StateSpace:
    """MATLAB-like ``makeweight``: gain ``dc`` at low frequency, ``mag`` at ``freq_hz``, ``hf``
    at high frequency, of ``order`` 1 or 2; discrete (prewarped) when ``dt`` is given."""
    return StateSpace(*_native.makeweight(float(dc), float(freq_hz), float(mag), float(hf),
                                          int(order), dt))
