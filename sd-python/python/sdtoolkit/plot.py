"""Bode and loop-gain figures with matplotlib (an optional dependency: ``pip install
sdtoolkit[plot]``). The conventions of ``sdctl bode`` and ``sdctl analyze --loop-svg``: the
magnitude in dB re 1 unit (``unit`` names it), the phase unwrapped (on the branch whose first
value lies in (−300°, 60°]), measured FRDs drawn last (on top of the models) with their ±2σ
band from ``variance``, the legend outside the data."""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from . import Frd, StateSpace, _ss, analyze, freqresp


def _pyplot():
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # the extra is optional
        raise ImportError("sdtoolkit.plot needs matplotlib: pip install 'sdtoolkit[plot]' "
                          "(or pip install matplotlib)") from e
    return plt


def _figure(plt, axes):
    """The figure and its (magnitude, phase) axes: new ones, or those given."""
    if axes is None:
        return plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    return axes[0].figure, axes


def unwrap_deg(phase_deg: np.ndarray) -> np.ndarray:
    """Unwrapped phase (degrees) on the branch whose first value lies in (−300°, 60°] (a double
    integrator starts at −180°), as ``sdctl bode``."""
    p = np.rad2deg(np.unwrap(np.deg2rad(np.asarray(phase_deg, dtype=float))))
    if p.size:
        first = p[0]
        k = np.ceil((first - 60.0) / 360.0)
        p = p - 360.0 * k
    return p


def _grid(items, f_hz):
    if f_hz is not None:
        return np.asarray(f_hz, dtype=float)
    frds = [x for x in items if isinstance(x, Frd)]
    if frds:
        lo = min(float(x.freq_hz[x.freq_hz > 0].min()) for x in frds)
        hi = max(float(x.freq_hz.max()) for x in frds)
    else:
        nyq = [0.5 / _ss(x).dt for x in items if _ss(x).dt is not None]
        hi = min(nyq) * 0.999 if nyq else 1e3
        lo = hi * 1e-3
    return np.logspace(np.log10(lo), np.log10(hi), 2000)


def bode(*systems, f_hz=None, labels: Optional[Sequence[str]] = None, unit: str = "",
         entry=(0, 0), axes=None):
    """Models (``StateSpace`` or python-control) and measured ``Frd`` in one Bode figure:
    models on ``f_hz`` (default: the FRDs' band, else three decades below Nyquist), FRDs on
    their own lines and drawn last, with ±2σ where they carry a variance. ``entry`` = (output,
    input). Returns ``(fig, (ax_mag, ax_phase))``."""
    plt = _pyplot()
    if not systems:
        raise ValueError("bode: give at least one model or Frd")
    if labels is not None and len(labels) != len(systems):
        raise ValueError(f"bode: {len(labels)} labels for {len(systems)} systems")
    fig, (ax_m, ax_p) = _figure(plt, axes)
    f = _grid(systems, f_hz)
    i, j = entry
    order = sorted(range(len(systems)), key=lambda k: isinstance(systems[k], Frd))
    for k in order:
        s = systems[k]
        name = labels[k] if labels is not None else (f"FRD {k + 1}" if isinstance(s, Frd)
                                                      else f"model {k + 1}")
        if isinstance(s, Frd):
            x, g = s.freq_hz, s.response[i, j]
            (line,) = ax_m.semilogx(x, 20 * np.log10(np.abs(g)), ".", ms=2, label=name, zorder=3)
            if s.variance is not None:
                sd2 = 2 * np.sqrt(s.variance[i, j])
                lo = np.maximum(np.abs(g) - sd2, 1e-300)
                ax_m.fill_between(x, 20 * np.log10(lo), 20 * np.log10(np.abs(g) + sd2),
                                  color=line.get_color(), alpha=0.2, lw=0, zorder=2,
                                  label=f"{name} ±2σ")
        else:
            x, g = f, freqresp(_ss(s), f, squeeze=False)[i, j]
            (line,) = ax_m.semilogx(x, 20 * np.log10(np.abs(g)), label=name, zorder=1)
        ax_p.semilogx(x, unwrap_deg(np.angle(g, deg=True)), color=line.get_color(),
                      ls="" if isinstance(s, Frd) else "-", marker="." if isinstance(s, Frd) else "",
                      ms=2, zorder=3 if isinstance(s, Frd) else 1)
    ax_m.set_ylabel(f"magnitude [dB re 1 {unit}]" if unit else "magnitude [dB]")
    ax_p.set_ylabel("phase [°]")
    ax_p.set_xlabel("frequency [Hz]")
    for a in (ax_m, ax_p):
        a.grid(True, which="both", alpha=0.3)
    ax_m.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    fig.tight_layout()
    return fig, (ax_m, ax_p)


def loop(P, K, f_hz=None, axes=None):
    """The loop gain ``L = P K`` of a SISO loop (``P`` a model or a measured ``Frd``) with the
    gain and phase margins marked where they occur (from :func:`sdtoolkit.analyze`). Returns
    ``(fig, (ax_mag, ax_phase), result)``."""
    plt = _pyplot()
    r = analyze(P, K)
    Kss = _ss(K, "K")
    if isinstance(P, Frd):
        f = P.freq_hz
        g = P.response[0, 0] * freqresp(Kss, f)
    else:
        Pss = _ss(P, "P")
        if (Pss.noutputs, Pss.ninputs) != (1, 1):
            raise ValueError("loop: a SISO loop (use analyze for MIMO loops)")
        f = _grid([Pss], f_hz)
        g = freqresp(Pss, f) * freqresp(Kss, f)
    fig, (ax_m, ax_p) = _figure(plt, axes)
    ax_m.semilogx(f, 20 * np.log10(np.abs(g)), label="L = PK")
    ax_p.semilogx(f, unwrap_deg(np.angle(g, deg=True)))
    ax_m.axhline(0.0, color="k", lw=0.5)
    marks = [(r.phase_margin_hz, f"PM {r.phase_margin_deg:.1f}° @ {r.phase_margin_hz:.2f} Hz"),
             (r.gain_margin_hz, f"GM {r.gain_margin_db:.1f} dB @ {r.gain_margin_hz:.2f} Hz")]
    for at, text in marks:
        if at is not None and np.isfinite(at) and at > 0:
            for a in (ax_m, ax_p):
                a.axvline(at, color="0.5", lw=0.8)
            ax_m.annotate(text, (at, 0.98), xycoords=("data", "axes fraction"), ha="left",
                          va="top", fontsize="small")
    ax_m.set_ylabel("magnitude [dB]")
    ax_p.set_ylabel("phase [°]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.set_title(f"loop gain: phase margin {r.phase_margin_deg:.1f}°, gain margin "
                   f"{r.gain_margin_db:.1f} dB, |S| peak {r.sensitivity_peak_db:.1f} dB")
    for a in (ax_m, ax_p):
        a.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig, (ax_m, ax_p), r


__all__ = ["bode", "loop", "unwrap_deg"]
