"""sdtoolkit: sampled-data control design for high-precision motion systems.

The Python front of the sd-toolkit Rust crates: the same numbers as ``sdctl``, over numpy
arrays, with python-control's names where the two overlap.

Models are :class:`StateSpace` (``A``, ``B``, ``C``, ``D`` as float64 arrays, ``dt`` in seconds,
``None`` for continuous time); measured frequency responses are :class:`Frd` (``freq_hz``,
``response`` of shape ``(ny, nu, nf)``, ``variance`` of the same shape or ``None``). Both convert
to and from python-control (``to_control()``, ``from_control()``) when it is installed; it is
never required.

Errors: input that must be fixed raises ``ValueError``; a numerical failure on valid input
raises :class:`NumericalError` (an ``ArithmeticError``); both carry the library's one-line
message. Long calls release the interpreter lock.
"""

from __future__ import annotations

import json
import os
from typing import Any, Iterable, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import NumericalError

#: The virtual stage's default configuration (TOML): identification at 5 kHz (the model
#: experiment) and 1 kHz, five periods of one second, input injection. Prepend a
#: ``[nonideal]`` table (``hold_delay``, ``averaging``, ``clock_error``, ``quantization``) to
#: give the stage rate-tied non-idealities.
DEFAULT_TESTBED_CONFIG: str = _native.DEFAULT_TESTBED_CONFIG

def __dir__():
    """``dir(sdtoolkit)``: the public names (``__all__``), not the modules it imports."""
    return sorted(__all__)


__all__ = [
    "plot",
    "Uncertainty",
    "uncertainty",
    "coverage",
    "downsample_uncertainty",
    "robust_stability",
    "intersample",
    "multisine",
    "weight_notch",
    "weight_lowpass",
    "makeweight",
    "lsim",
    "step_response",
    "series",
    "parallel",
    "feedback",
    "hinfsyn",
    "h2syn",
    "mixsyn",
    "reduce_controller",
    "StateSpace",
    "Frd",
    "Result",
    "NumericalError",
    "DEFAULT_TESTBED_CONFIG",
    "c2d",
    "d2c",
    "alias",
    "downsample",
    "freqresp",
    "poles",
    "zeros",
    "tf",
    "norm",
    "balred",
    "dare",
    "care",
    "loopshape",
    "weight_pid",
    "frf",
    "frf_from_arrays",
    "fit",
    "fit_physical",
    "analyze",
    "diagnose",
    "predict",
    "testbed",
]


def _real(x: Any, name: str) -> np.ndarray:
    """``x`` as float64; ``TypeError`` naming ``name`` when it is complex (an imaginary part is
    never dropped: numpy's own conversion only warns)."""
    a = np.asarray(x)
    if np.iscomplexobj(a):
        raise TypeError(f"{name} is complex: this function takes real data only (its imaginary "
                        "part would be dropped); pass the real matrices of the problem")
    return np.asarray(a, dtype=np.float64)


def _cmatrix(x: Any, name: str) -> np.ndarray:
    """A complex128 2-D array (scalars and vectors promoted as :func:`_matrix` does)."""
    a = np.asarray(x)
    if a.dtype.kind not in "biufc":
        raise TypeError(f"{name} must be a numeric array, not {a.dtype}")
    a = np.asarray(a, dtype=np.complex128)
    if a.ndim == 0:
        a = a.reshape(1, 1)
    elif a.ndim == 1:
        a = a.reshape(-1, 1)
    elif a.ndim != 2:
        raise ValueError(f"{name} must be a matrix (2-D array), got {a.ndim} dimensions")
    return np.ascontiguousarray(a)


def _matrix(x: Any, name: str, rows: Optional[int] = None, cols: Optional[int] = None) -> np.ndarray:
    """A float64 2-D array (scalars and vectors promoted); ``TypeError`` for complex input.
    An empty input keeps its own 2-D shape; ``[]`` takes the shape ``(rows, cols)`` only where
    that shape holds no entry (a model without inputs, outputs or states) — an empty matrix is
    never filled with zeros."""
    a = _real(x, name)
    if a.size == 0:
        if a.ndim == 2 and (rows is None or a.shape[0] == rows) and (cols is None or a.shape[1] == cols):
            return np.ascontiguousarray(a)
        want = (rows or 0, cols or 0)
        if rows is not None and cols is not None and rows * cols == 0:
            return np.zeros(want)
        raise ValueError(f"{name} is empty but must be {rows if rows is not None else '?'}×"
                         f"{cols if cols is not None else '?'} for this model: give its entries")
    if a.ndim == 0:
        a = a.reshape(1, 1)
    elif a.ndim == 1:
        # a vector: a row for C, a column for B, as python-control reads them
        a = a.reshape(1, -1) if name == "C" else a.reshape(-1, 1)
    elif a.ndim != 2:
        raise ValueError(f"{name} must be a matrix (2-D array), got {a.ndim} dimensions")
    return np.ascontiguousarray(a)


class StateSpace:
    """A state-space model ``x' = A x + B u, y = C x + D u`` (``dt`` None: continuous).

    Attributes ``A``, ``B``, ``C``, ``D`` (float64 arrays) and ``dt`` follow python-control.
    Shapes are checked by the toolkit when the model is used.
    """

    def __init__(self, A: Any, B: Any, C: Any, D: Any, dt: Optional[float] = None):
        a = _matrix(A, "A")
        n = a.shape[0]
        if np.asarray(D).size == 0:
            # an empty D (no inputs or no outputs): its shape from B and C
            b = _matrix(B, "B", n, None if np.asarray(B).size else 0)
            c = _matrix(C, "C", None if np.asarray(C).size else 0, n)
            d = _matrix(D, "D", c.shape[0], b.shape[1])
        else:
            d = _matrix(D, "D")
            b = _matrix(B, "B", n, d.shape[1])
            c = _matrix(C, "C", d.shape[0], n)
        self.A, self.B, self.C, self.D = a, b, c, d
        if dt is not None and (dt is True or float(dt) == 0.0):
            raise ValueError(
                "dt must be a sample period in seconds, or None for continuous time "
                "(python-control's dt=0 means continuous: pass None)"
            )
        self.dt = None if dt is None else float(dt)

    @property
    def nstates(self) -> int:
        return self.A.shape[0]

    @property
    def ninputs(self) -> int:
        return self.D.shape[1]

    @property
    def noutputs(self) -> int:
        return self.D.shape[0]

    def isdtime(self) -> bool:
        return self.dt is not None

    def _tuple(self):
        return (self.A, self.B, self.C, self.D, self.dt)

    def to_control(self):
        """This model as ``control.StateSpace`` (python-control must be installed)."""
        import control

        return control.StateSpace(self.A, self.B, self.C, self.D, 0 if self.dt is None else self.dt)

    @classmethod
    def from_control(cls, sys) -> "StateSpace":
        """A python-control model as a StateSpace: a ``control.StateSpace`` (or anything with
        ``A, B, C, D, dt``) as it is; a ``control.TransferFunction`` through :func:`tf` (SISO:
        controllable canonical form; MIMO: each entry realized on its own states, stacked — exact,
        not minimal when entries share poles; reduce with :func:`balred` if needed)."""
        dt = getattr(sys, "dt", None)
        if dt is True:
            raise ValueError("the python-control model has dt=True (unspecified period): give it a period")
        dt = None if not dt else float(dt)
        if all(hasattr(sys, k) for k in ("A", "B", "C", "D")):
            return cls(sys.A, sys.B, sys.C, sys.D, dt)
        if hasattr(sys, "num") and hasattr(sys, "den"):
            ny, nu = len(sys.num), len(sys.num[0])
            if (ny, nu) == (1, 1):
                return tf(np.asarray(sys.num[0][0]), np.asarray(sys.den[0][0]), dt)
            return _tf_matrix(sys.num, sys.den, dt)
        raise TypeError(f"not a python-control model: {type(sys).__name__} (give a StateSpace or "
                        "TransferFunction)")

    def to_json(self) -> str:
        """The toolkit's model JSON (docs/formats.md), as ``sdctl`` reads it."""
        return _native.model_to_json(self._tuple())

    @classmethod
    def from_json(cls, text: Union[str, os.PathLike]) -> "StateSpace":
        """A model from the toolkit's model JSON (``{"type": "ss", ...}`` or ``"tf"``): the text,
        or the path of a file holding it."""
        return _from_tuple(_native.model_from_json(_json_text(text, "StateSpace.from_json")))

    def poles(self) -> np.ndarray:
        """:func:`poles` of this model."""
        return poles(self)

    def zeros(self) -> np.ndarray:
        """:func:`zeros` of this model."""
        return zeros(self)

    def freqresp(self, f_hz: Any, squeeze: bool = True):
        """:func:`freqresp` of this model at ``f_hz`` (Hz)."""
        return freqresp(self, f_hz, squeeze=squeeze)

    def norm(self, p: Any = 2):
        """:func:`norm` of this model."""
        return norm(self, p)

    def feedback(self, other: Any = None, sign: int = -1) -> "StateSpace":
        """:func:`feedback` of this model with ``other`` in the feedback path."""
        return feedback(self, other, sign)

    def __repr__(self) -> str:
        t = "continuous" if self.dt is None else f"dt={self.dt:g} s"
        return f"StateSpace({self.nstates} states, {self.ninputs} inputs, {self.noutputs} outputs, {t})"


def _tf_matrix(num, den, dt) -> StateSpace:
    """The transfer-function matrix ``num[i][j]/den[i][j]`` as one StateSpace: entry (i, j)
    realized by :func:`tf` on its own states, driven by input j and read by output i."""
    ny, nu = len(num), len(num[0])
    parts = [[tf(np.asarray(num[i][j]), np.asarray(den[i][j]), dt) for j in range(nu)] for i in range(ny)]
    n = sum(p.nstates for row in parts for p in row)
    A, B, C, D = np.zeros((n, n)), np.zeros((n, nu)), np.zeros((ny, n)), np.zeros((ny, nu))
    k = 0
    for i in range(ny):
        for j in range(nu):
            p, m = parts[i][j], parts[i][j].nstates
            A[k:k + m, k:k + m] = p.A
            B[k:k + m, j] = p.B[:, 0]
            C[i, k:k + m] = p.C[0, :]
            D[i, j] = p.D[0, 0]
            k += m
    return StateSpace(A, B, C, D, dt)


def _ss(sys: Any, name: str = "sys") -> StateSpace:
    if isinstance(sys, StateSpace):
        return sys
    if all(hasattr(sys, k) for k in ("A", "B", "C", "D")) or (hasattr(sys, "num") and hasattr(sys, "den")):
        return StateSpace.from_control(sys)
    raise TypeError(f"{name} must be a sdtoolkit.StateSpace or a python-control StateSpace or "
                    f"TransferFunction, got {type(sys).__name__}")


def _from_tuple(t) -> StateSpace:
    return StateSpace(*t)


class Frd:
    """A measured (or computed) frequency response.

    ``freq_hz`` (nf,), ``response`` complex ``(ny, nu, nf)``, ``variance`` ``(ny, nu, nf)`` or
    None (the variance of each entry's estimate), ``dt`` the sample period of the data (None:
    continuous), ``warnings`` the estimator's data-quality warnings.
    """

    def __init__(self, freq_hz: Any, response: Any, variance: Any = None, dt: Optional[float] = None,
                 warnings: Sequence[str] = ()):
        f = np.ascontiguousarray(_real(freq_hz, "freq_hz").reshape(-1))
        r = np.asarray(response, dtype=np.complex128)
        if r.ndim == 1:
            r = r.reshape(1, 1, -1)
        if r.ndim != 3:
            raise ValueError("response must be (nf,) or (ny, nu, nf)")
        self.freq_hz = f
        self.response = np.ascontiguousarray(r)
        if variance is not None:
            v = _real(variance, "variance")
            variance = np.ascontiguousarray(v.reshape(1, 1, -1) if v.ndim == 1 else v)
        self.variance = variance
        self.dt = None if dt is None else float(dt)
        self.warnings = list(warnings)

    def to_control(self):
        """This FRD as ``control.FrequencyResponseData`` (ω in rad/s)."""
        import control

        return control.FrequencyResponseData(self.response, 2 * np.pi * self.freq_hz,
                                             dt=0 if self.dt is None else self.dt)

    @classmethod
    def from_control(cls, frd, variance: Any = None) -> "Frd":
        """A ``control.FrequencyResponseData`` as an Frd (its ω in rad/s becomes Hz)."""
        dt = getattr(frd, "dt", None)
        r = np.asarray(frd.frdata if hasattr(frd, "frdata") else frd.fresp)
        return cls(np.asarray(frd.omega) / (2 * np.pi), r, variance, None if not dt or dt is True else float(dt))

    def to_json(self) -> str:
        """The toolkit's FRD JSON (docs/formats.md), as ``sdctl`` reads it."""
        return _native.frd_to_json(self.freq_hz, self.response, self.variance, self.dt)

    @classmethod
    def from_json(cls, text: Union[str, os.PathLike]) -> "Frd":
        """An FRD from the toolkit's FRD JSON: the text, or the path of a file holding it."""
        return _frd_from_native(_native.frd_from_json(_json_text(text, "Frd.from_json")), [])

    def __repr__(self) -> str:
        ny, nu, nf = self.response.shape
        return f"Frd({ny}x{nu}, {nf} lines, variance {'yes' if self.variance is not None else 'no'})"


def _json_text(text: Union[str, os.PathLike], who: str) -> str:
    """JSON text as given (a string whose first non-blank character is ``{``), or read from
    the path given; anything else is refused naming what was passed."""
    if isinstance(text, str) and text.lstrip().startswith("{"):
        return text
    if isinstance(text, (str, os.PathLike)):
        path = os.fspath(text)
        if os.path.isfile(path):
            with open(path, encoding="utf-8") as f:
                return f.read()
        raise ValueError(f"{who}: {path[:60]!r} is neither JSON text (starting with '{{') nor an existing file")
    raise TypeError(f"{who} takes JSON text or a path, not {type(text).__name__}")


def _frd_from_native(t, warnings) -> Frd:
    f, r, v, dt = t
    return Frd(f, r, v, dt, warnings)


class Result:
    """A result object: the fields of the toolkit's JSON output as attributes (and keys).

    Nested objects are Results too, lists stay lists; ``to_dict()`` gives the plain data back.
    """

    def __init__(self, fields: dict):
        self.__dict__["_fields"] = {k: _wrap(v) for k, v in fields.items()}

    def __getattr__(self, k: str):
        try:
            return self.__dict__["_fields"][k]
        except KeyError:
            raise AttributeError(f"no field {k!r}; fields: {', '.join(self._fields)}") from None

    def __getitem__(self, k: str):
        return self._fields[k]

    def __contains__(self, k: str) -> bool:
        return k in self._fields

    def keys(self):
        return self._fields.keys()

    def to_dict(self) -> dict:
        return {k: _unwrap(v) for k, v in self._fields.items()}

    def __repr__(self) -> str:
        return "Result(" + ", ".join(f"{k}={_short(v, 1)}" for k, v in self._fields.items()) + ")"

    def summary(self) -> str:
        """One line per field, ``name: value`` (long lists and arrays abbreviated, nested results
        indented)."""
        return "\n".join(self._summary_lines(""))

    def _summary_lines(self, indent: str):
        for k, v in self._fields.items():
            if isinstance(v, Result):
                yield f"{indent}{k}:"
                yield from v._summary_lines(indent + "  ")
            else:
                yield f"{indent}{k}: {_short(v)}"

    def __dir__(self):
        return list(self._fields) + ["to_dict", "keys", "summary"]


def _short(v, depth: int = 0) -> str:
    """A value as ``repr`` shows it: numbers to 6 digits, lists and arrays abbreviated beyond
    four items (with their length), nested results by their fields' names."""
    if isinstance(v, bool) or v is None:
        return repr(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.6g}"
    if isinstance(v, complex):
        return f"({v.real:.6g}{v.imag:+.6g}j)"
    if isinstance(v, str):
        return repr(v if len(v) <= 60 else v[:57] + "...")
    if isinstance(v, np.ndarray):
        if v.size <= 4:
            return np.array2string(v, precision=6, separator=", ")
        return f"array(shape={v.shape}, dtype={v.dtype})"
    if isinstance(v, Result):
        return "Result(" + ", ".join(v.keys()) + ")" if depth else repr(v)
    if isinstance(v, (list, tuple)):
        items = [_short(x, depth + 1) for x in v[:4]]
        if len(v) > 4:
            return "[" + ", ".join(items[:3]) + f", … ({len(v)} items)]"
        return "[" + ", ".join(items) + "]"
    return repr(v)


def _wrap(v):
    if isinstance(v, dict):
        return Result(v)
    if isinstance(v, list):
        return [_wrap(x) for x in v]
    return v


def _unwrap(v):
    if isinstance(v, Result):
        return v.to_dict()
    if isinstance(v, list):
        return [_unwrap(x) for x in v]
    return v


# ---------------------------------------------------------------- models


def c2d(*args, method: str = "zoh", hold_delay: float = 0.0, averaging: float = 0.0,
        prewarp_hz: Optional[float] = None) -> StateSpace:
    """Exact discretisation: ``c2d(sys, dt)`` or ``c2d(A, B, C, D, dt)``.

    ``method`` "zoh" (exact zero-order hold), "foh" (triangle hold), "tustin" (bilinear,
    optionally prewarped at ``prewarp_hz``), "matched" (pole-zero mapping, SISO: zeros at
    infinity but one to z = −1, the low-frequency gain kept, a rigid body's included) or
    "impulse" (impulse-invariant, strictly proper models). ``hold_delay`` (fraction of the period the hold
    switches late, may exceed 1) and ``averaging`` (the sampler returns the mean of the last
    fraction of the period) give the rate-tied non-ideal ZOH.
    """
    if len(args) == 2:
        sys, dt = _ss(args[0]), args[1]
    elif len(args) == 5:
        sys, dt = StateSpace(*args[:4]), args[4]
    else:
        raise TypeError("c2d(sys, dt) or c2d(A, B, C, D, dt)")
    if sys.dt is not None:
        raise ValueError("c2d takes a continuous model (dt is None)")
    return _from_tuple(_native.c2d(sys._tuple(), float(dt), method, float(hold_delay), float(averaging),
                                   prewarp_hz))


def d2c(sys, near_hz: Union[float, Iterable[float], None] = None, max_hz: Optional[float] = None,
        return_aliases: bool = False):
    """The continuous model of a discrete one (inverse of exact ZOH).

    A sampled mode has many continuous candidates (its aliases); the principal one is the
    default and ``near_hz`` picks, per mode, the branch nearest each given frequency (e.g. 653
    to turn a 347 Hz mode sampled at 1 kHz back into 653 Hz). With ``return_aliases`` the
    result is ``(model, modes, picks)``: per mode its candidates up to ``max_hz`` (default 3 ×
    the sample rate) as ``(freq_hz, damping)`` and the branches chosen.
    """
    s = _ss(sys)
    near = [] if near_hz is None else [float(x) for x in np.atleast_1d(near_hz)]
    t, modes, picks = _native.d2c(s._tuple(), near, max_hz)
    out = _from_tuple(t)
    if return_aliases:
        return out, [Result(m) for m in modes], [Result(p) for p in picks]
    return out


def alias(freq_hz: float, rate_hz: float, max_hz: Optional[float] = None, factor: Optional[int] = None) -> Result:
    """Where ``freq_hz`` appears when sampled at ``rate_hz`` (``alias_hz``, ``fold_index``,
    ``mirrored``), the continuous frequencies up to ``max_hz`` (default 5 × the rate) that appear
    there, and with ``factor`` F the frequencies of a model F times faster that fold onto it,
    as ``(k, fast_hz, weight)`` with the slow hold's weight ``|H_F|/F``."""
    d = _native.alias(float(freq_hz), float(rate_hz), max_hz, factor)
    if "fast_folds" in d:
        d["fast_folds"] = [{"k": k, "fast_hz": f, "weight": w} for k, f, w in d["fast_folds"]]
    return Result(d)


def downsample(sys, F: int, hold_delay: float = 0.0, averaging: float = 0.0) -> StateSpace:
    """Lemma 6: the exact model at the rate F times slower (the slow hold and sampler applied to
    the fast model, same state coordinates). ``hold_delay`` and ``averaging`` are fractions of
    the slow period, multiples of 1/F."""
    if isinstance(F, bool) or int(F) != F or F < 1:
        raise ValueError(f"F = {F!r}: the rate factor must be a positive integer")
    return _from_tuple(_native.downsample(_ss(sys)._tuple(), int(F), float(hold_delay), float(averaging)))


def freqresp(sys, f_hz: Any, squeeze: bool = True, return_path: bool = False):
    """The frequency response at ``f_hz`` (Hz): complex ``(ny, nu, nf)``, or ``(nf,)`` for a
    SISO model when ``squeeze``. ``return_path`` adds which evaluator ran ("block_diagonal" O(n)
    per point, "hessenberg" O(n²), "dense" O(n³))."""
    f = np.ascontiguousarray(_real(f_hz, "f_hz").reshape(-1))
    g, path = _native.freqresp(_ss(sys)._tuple(), f)
    if squeeze and g.shape[0] == 1 and g.shape[1] == 1:
        g = g[0, 0]
    return (g, path) if return_path else g


def poles(sys) -> np.ndarray:
    """The poles (eigenvalues of A), complex, sorted by modulus then argument."""
    return _native.poles(_ss(sys)._tuple())


def tf(num: Any, den: Any, dt: Optional[float] = None) -> "StateSpace":
    """A SISO transfer function ``num/den`` (descending powers, as python-control's ``tf``;
    ``dt`` the sample time, None continuous) as a :class:`StateSpace`. An improper function or
    a zero leading denominator coefficient raises ValueError."""
    n = _real(np.atleast_1d(num), "num").ravel()
    d = _real(np.atleast_1d(den), "den").ravel()
    return StateSpace(*_native.tf(n, d, dt))


def norm(sys, p: Any = 2, return_peak: bool = False):
    """The H2 norm (``p=2``; stable models, a continuous one needs D = 0) or the H∞ norm
    (``p="inf"`` or ``np.inf``: the peak gain over frequency, by Hamiltonian level sets),
    as python-control's ``norm``. With ``return_peak`` the H∞ norm comes with the peak's
    frequency in Hz. An unstable model's H∞ value is its L∞ norm (python-control returns inf
    for it): a UserWarning says so."""
    if isinstance(p, str):
        if p.lower() not in ("inf", "infinity"):
            raise ValueError(f"p = {p!r}: the norm is 2 or 'inf'")
        p = np.inf
    value, peak, stable = _native.norm(_ss(sys)._tuple(), float(p))
    if not stable:
        import warnings
        warnings.warn("the model is not stable: this is its L∞ norm, not an H∞ norm", UserWarning)
    return (value, peak) if (return_peak and peak is not None) else value


def balred(sys, order: int) -> Result:
    """Balanced truncation to ``order`` states: ``model`` (the stable part reduced, unstable
    and marginal poles kept exactly), ``hankel_sv`` (of the stable part, descending) and
    ``error_bound`` (``2Σ`` of the discarded ones, the a-priori bound on ‖G − G_r‖∞)."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise TypeError(f"order must be an int, not {type(order).__name__}")
    m, hsv, bound = _native.balred(_ss(sys)._tuple(), int(order))
    return Result({"model": StateSpace(*m), "hankel_sv": np.asarray(hsv), "error_bound": bound})


def zeros(sys) -> np.ndarray:
    """The invariant zeros: the finite values where the system pencil ``[A − λI, B; C, D]``
    loses rank, complex (conjugate pairs exact), sorted by modulus. Square and non-square,
    continuous and discrete models (Emami-Naeini & Van Dooren's reduction, then the
    eigenvalues of the reduced pencil). ``NumericalError`` when the pencil is normal-rank
    deficient (a transfer matrix singular at every frequency, e.g. a zero channel)."""
    return _native.zeros(_ss(sys)._tuple())


def lsim(sys, u: Any, x0: Any = None, dt: Optional[float] = None) -> Result:
    """The response to the input samples ``u`` (``(N,)`` for one input, else ``(N, nu)``, one
    row per sample) from the state ``x0`` (zero when None): ``x_{k+1} = A x_k + B u_k``,
    ``y_k = C x_k + D u_k``. A continuous model is driven through a zero-order hold of period
    ``dt`` (exact at the samples); a discrete one takes ``dt`` None or its own period.
    Returns ``t`` (s, ``k·dt``), ``y`` (``(N, ny)``) and ``x_final``."""
    g = _ss(sys)
    u = np.asarray(u)
    if np.iscomplexobj(u):
        raise TypeError("lsim: the input samples u are complex; a simulation takes real signals")
    u = u.astype(float).reshape(-1, 1) if u.ndim == 1 else np.asarray(u, dtype=float)
    if u.ndim != 2 or u.shape[1] != g.ninputs:
        raise ValueError(f"lsim: u must be (N,) or (N, {g.ninputs}) for a model with {g.ninputs} inputs, "
                         f"not {np.shape(u)}")
    if g.dt is None and dt is None:
        raise ValueError("lsim: a continuous model needs the hold period dt of its input samples")
    if g.dt is not None and dt is not None and dt != g.dt:
        raise ValueError(f"lsim: dt {dt} differs from the model's sample period {g.dt}")
    x = None if x0 is None else np.ascontiguousarray(_real(x0, "x0").reshape(-1))
    y, xf = _native.lsim(g._tuple(), np.ascontiguousarray(u), x, None if g.dt is not None else float(dt))
    period = g.dt if g.dt is not None else float(dt)
    return Result({"t": np.arange(u.shape[0]) * period, "y": y, "x_final": xf})


def step_response(sys, n: int, dt: Optional[float] = None) -> Result:
    """The response to a unit step at every input in turn over ``n`` samples (from rest):
    ``t`` and ``y`` of shape ``(ny, nu, n)`` (python-control's layout); a continuous model
    through a zero-order hold of period ``dt``."""
    g = _ss(sys)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"step_response: n must be a positive number of samples, not {n!r}")
    y = np.empty((g.noutputs, g.ninputs, int(n)))
    t = None
    for j in range(g.ninputs):
        u = np.zeros((int(n), g.ninputs))
        u[:, j] = 1.0
        r = lsim(g, u, dt=dt)
        y[:, j, :] = r.y.T
        t = r.t
    return Result({"t": t, "y": y})


def _same_time(a: StateSpace, b: StateSpace, what: str) -> Optional[float]:
    if a.dt != b.dt:
        raise ValueError(f"{what}: the models have sample times {a.dt} and {b.dt} (None: continuous); "
                         "discretise or resample one of them first")
    return a.dt


def series(sys1, sys2, *more) -> StateSpace:
    """``sys1`` then ``sys2`` (then each of ``more``): the product ``… sys2·sys1`` as one
    state-space model, states of ``sys1`` first (python-control's ``series``)::

        A = [A1 0; B2 C1 A2],  B = [B1; B2 D1],  C = [D2 C1  C2],  D = D2 D1
    """
    g1, g2 = _ss(sys1, "sys1"), _ss(sys2, "sys2")
    dt = _same_time(g1, g2, "series")
    if g2.ninputs != g1.noutputs:
        raise ValueError(f"series: sys1 has {g1.noutputs} outputs but sys2 {g2.ninputs} inputs")
    n1, n2 = g1.nstates, g2.nstates
    a = np.block([[g1.A, np.zeros((n1, n2))], [g2.B @ g1.C, g2.A]])
    b = np.vstack([g1.B, g2.B @ g1.D])
    c = np.hstack([g2.D @ g1.C, g2.C])
    out = StateSpace(a, b, c, g2.D @ g1.D, dt)
    return series(out, *more) if more else out


def parallel(sys1, sys2, *more) -> StateSpace:
    """``sys1 + sys2`` (+ each of ``more``): the same input to both, outputs summed
    (python-control's ``parallel``): ``A = diag(A1, A2)``, ``B = [B1; B2]``,
    ``C = [C1 C2]``, ``D = D1 + D2``."""
    g1, g2 = _ss(sys1, "sys1"), _ss(sys2, "sys2")
    dt = _same_time(g1, g2, "parallel")
    if (g1.noutputs, g1.ninputs) != (g2.noutputs, g2.ninputs):
        raise ValueError(f"parallel: the models are {g1.noutputs}x{g1.ninputs} and {g2.noutputs}x{g2.ninputs}")
    n1, n2 = g1.nstates, g2.nstates
    a = np.block([[g1.A, np.zeros((n1, n2))], [np.zeros((n2, n1)), g2.A]])
    out = StateSpace(a, np.vstack([g1.B, g2.B]), np.hstack([g1.C, g2.C]), g1.D + g2.D, dt)
    return parallel(out, *more) if more else out


def feedback(sys1, sys2=None, sign: int = -1) -> StateSpace:
    """The closed loop ``y = sys1·e``, ``e = u + sign·sys2·y`` (``sign`` −1: negative feedback,
    python-control's ``feedback``; ``sys2`` None: unit feedback). With
    ``F = (I − sign·D1 D2)⁻¹`` (refused when singular: the loop is not well posed)::

        A = [A1 + s B1 D2 F C1,  s B1 (I + s D2 F D1) C2;  B2 F C1,  A2 + s B2 F D1 C2]
        B = [B1 (I + s D2 F D1);  B2 F D1],   C = [F C1,  s F D1 C2],   D = F D1
    """
    g1 = _ss(sys1, "sys1")
    if sys2 is None:
        sys2 = StateSpace(np.zeros((0, 0)), np.zeros((0, g1.noutputs)), np.zeros((g1.ninputs, 0)),
                          np.eye(g1.ninputs, g1.noutputs), g1.dt)
    g2 = _ss(sys2, "sys2")
    if sign not in (-1, 1):
        raise ValueError(f"feedback: sign must be -1 or +1, not {sign!r}")
    dt = _same_time(g1, g2, "feedback")
    if (g2.ninputs, g2.noutputs) != (g1.noutputs, g1.ninputs):
        raise ValueError(f"feedback: sys1 is {g1.noutputs}x{g1.ninputs}, so sys2 must be "
                         f"{g1.ninputs}x{g1.noutputs}, not {g2.noutputs}x{g2.ninputs}")
    m = np.eye(g1.noutputs) - sign * g1.D @ g2.D
    if np.linalg.cond(m) > 1.0 / np.finfo(float).eps:
        raise ValueError("feedback: I − sign·D1·D2 is singular: the loop is not well posed "
                         "(an algebraic loop with no solution)")
    f = np.linalg.inv(m)
    s = float(sign)
    k = np.eye(g1.ninputs) + s * g2.D @ f @ g1.D
    a = np.block([[g1.A + s * g1.B @ g2.D @ f @ g1.C, s * g1.B @ k @ g2.C],
                  [g2.B @ f @ g1.C, g2.A + s * g2.B @ f @ g1.D @ g2.C]])
    b = np.vstack([g1.B @ k, g2.B @ f @ g1.D])
    c = np.hstack([f @ g1.C, s * f @ g1.D @ g2.C])
    return StateSpace(a, b, c, f @ g1.D, dt)


# ---------------------------------------------------------------- design and analysis


def _riccati(continuous: bool, A, B, Q, R, S, E) -> Result:
    """One Riccati solver: real data to the real solver; when any argument is complex, all of
    them as complex to the complex solver (never an imaginary part dropped)."""
    args = [(A, "A"), (B, "B"), (Q, "Q"), (R, "R")] + [(x, n) for x, n in ((S, "S"), (E, "E"))
                                                         if x is not None]
    if any(np.iscomplexobj(np.asarray(x)) for x, _ in args):
        m = {n: _cmatrix(x, n) for x, n in args}
        return Result(_native.riccati_complex(continuous, m["A"], m["B"], m["Q"], m["R"],
                                              m.get("S"), m.get("E")))
    m = [_matrix(x, n) for x, n in ((A, "A"), (B, "B"), (Q, "Q"), (R, "R"))]
    s = None if S is None else _matrix(S, "S")
    e = None if E is None else _matrix(E, "E")
    return Result((_native.care if continuous else _native.dare)(*m, s, e))


def dare(A, B, Q, R, S=None, E=None) -> Result:
    """The stabilising solution of the discrete algebraic Riccati equation
    ``AᵀXA − X − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0``: ``X``, ``K`` (``u = −K x``),
    the relative ``residual``, ``closed_loop`` (spectral radius of A − BK) and ``condition``.
    With ``E`` (nonsingular, κ₁(E) ≤ 1e8) the generalized equation with ``EᵀXE`` in place of
    ``X`` (scipy's ``e=``), its residual reported. Complex data (any argument complex) solves
    the equation with conjugate transposes ``ᴴ`` (Q, R Hermitian) for the Hermitian ``X``,
    returned complex. No stabilising solution raises ValueError with the reason."""
    return _riccati(False, A, B, Q, R, S, E)


def care(A, B, Q, R, S=None, E=None) -> Result:
    """The stabilising solution of ``AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0`` (fields as
    :func:`dare`, ``closed_loop`` the spectral abscissa); with ``E`` the generalized
    ``AᵀXE + EᵀXA − (EᵀXB + S)R⁻¹(BᵀXE + Sᵀ) + Q = 0``; complex data as in :func:`dare`."""
    return _riccati(True, A, B, Q, R, S, E)


def loopshape(P, W1=None, W2=None, factor: float = 1.1, strictly_proper: bool = False) -> Result:
    """McFarlane–Glover H∞ loopshaping of plant ``P`` with weights ``W1`` (pre) and ``W2``
    (post): ``controller`` (the StateSpace to implement, ``W1 K∞ W2``), ``shaped_controller``,
    ``shaped_plant``, ``gamma_min``, ``gamma`` (= factor·γ_min), ``achieved``,
    ``stability_margin`` (1/achieved), ``closed_loop_stable``, ``closed_loop_radius``,
    ``riccati`` (equation, residual, condition)."""
    w1 = None if W1 is None else _ss(W1, "W1")._tuple()
    w2 = None if W2 is None else _ss(W2, "W2")._tuple()
    d = _native.loopshape(_ss(P, "P")._tuple(), w1, w2, float(factor), bool(strictly_proper))
    for k in ("controller", "shaped_controller", "shaped_plant"):
        d[k] = _from_tuple(d[k])
    d["riccati"] = [{"equation": e, "residual": r, "condition": c} for e, r, c in d["riccati"]]
    return Result(d)


def _synthesis_result(d) -> Result:
    out = json.loads(d.pop("report_json"))
    for k, v in d.items():
        out[k] = _from_tuple(v)
    return Result(out)


def hinfsyn(P, nmeas: int, ncon: int, gamma: Optional[float] = None, tol: float = 1e-3) -> Result:
    """H∞ synthesis on the generalized plant ``P`` (the last ``nmeas`` outputs measured, the
    last ``ncon`` inputs controlled; ``u = K y``), as ``sdctl hinfsyn --json``: ``controller``,
    ``gamma``, ``gamma_min``, ``gamma_infeasible``, ``achieved_norm`` (the toolkit's own H∞ norm
    of the loop), ``closed_loop_stable``, ``steps`` (every γ tried and its outcome), …
    A γ below γ_min, a wrong partition or a rank-deficient D12/D21 raise ValueError."""
    return _synthesis_result(_native.hinfsyn(_ss(P, "P")._tuple(), int(nmeas), int(ncon),
                                             None if gamma is None else float(gamma), float(tol)))


def h2syn(P, nmeas: int, ncon: int) -> Result:
    """H2 synthesis on the generalized plant ``P`` (``u = K y``), as ``sdctl h2syn --json``:
    ``controller``, ``achieved_norm`` (from the closed loop's Gramian), ``closed_loop_stable``."""
    return _synthesis_result(_native.h2syn(_ss(P, "P")._tuple(), int(nmeas), int(ncon)))


def mixsyn(G, W1=None, W2=None, W3=None, Wd=None, gamma: Optional[float] = None,
           tol: float = 1e-3, factor: Optional[int] = None, Wr=None, wn: Optional[float] = None,
           W2_slow=None, at_samples: Optional[float] = None) -> Result:
    """Mixed-sensitivity H∞ design ``[W1 S; W2 K S; W3 T]`` (``Wd``: an input disturbance,
    adding the process sensitivity), as ``sdctl mixsyn --json``: ``controller`` (negative
    feedback ``u = K (r − y)``), ``generalized_plant``, ``gamma``, ``gamma_min``,
    ``achieved_norm``, …

    With ``factor`` F the multirate design (``sdctl mixsyn --factor``): ``G`` and the weights are
    at the fast rate, the controller runs at F times ``G``'s period and the error between its
    samples counts (the lifted plant); ``Wr`` shapes a smooth reference (without it: disturbance
    rejection only), ``wn`` is the sensor noise at the slow samples, ``W2_slow`` an effort weight
    on the controller's samples (discrete at the slow period), ``at_samples`` W1's extra factor
    at the controller's sample instants (above 1 the error there counts more than between)."""
    ws = [None if w is None else _ss(w, n)._tuple() for w, n in ((W1, "W1"), (W2, "W2"), (W3, "W3"), (Wd, "Wd"))]
    extra = [None if w is None else _ss(w, n)._tuple() for w, n in ((Wr, "Wr"), (W2_slow, "W2_slow"))]
    if factor is not None and (isinstance(factor, bool) or int(factor) != factor):
        raise TypeError(f"factor must be a whole number, got {factor!r}")
    d = _native.mixsyn(_ss(G, "G")._tuple(), *ws, None if gamma is None else float(gamma), float(tol),
                       None if factor is None else int(factor), extra[0],
                       None if wn is None else float(wn), extra[1],
                       None if at_samples is None else float(at_samples))
    report = json.loads(d.pop("report_json"))
    if factor is not None:
        report["factor"] = int(factor)
    for k, v in d.items():
        report[k] = _from_tuple(v)
    return Result(report)


def reduce_controller(P, K, order: int, method: str = "auto") -> Result:
    """Reduce controller ``K`` (negative feedback around ``P``) to ``order`` states keeping the
    loop, as ``sdctl reduce --controller --json``: ``controller``, ``order_before`` /
    ``order_after``, ``hankel_sv``, ``band_hz``, ``max_delta_s_db``, ``max_delta_t_db``,
    ``before`` / ``after`` (stability and margins). ``method``: ``"auto"`` (``"fit"`` for a
    SISO discrete loop, else ``"weighted"``; ``method`` in the result names the one used),
    ``"fit"`` (the rational fit of K's response weighted by the loop's ``max(|S|,|T|)/|K|``),
    ``"weighted"`` (balanced truncation with the closed-loop weight), ``"coprime"`` (the
    loop-scaled controller's normalized coprime factors) or ``"plain"``. A reduced controller
    that loses the loop raises NumericalError."""
    d = _native.reduce_controller(_ss(P, "P")._tuple(), _ss(K, "K")._tuple(), int(order), str(method))
    d["controller"] = _from_tuple(d["controller"])
    return Result(d)


def weight_pid(bandwidth_hz: float, mass: float, dt: Optional[float] = None, integrator_ratio: float = 5.0,
               lead_ratio: float = 3.0, lowpass_ratio: float = 0.0, lowpass_zeta: float = 0.7) -> StateSpace:
    """A PID-like loopshaping weight for a rigid body of ``mass`` with crossover near
    ``bandwidth_hz``: integrator at ω_c/integrator_ratio, lead between ω_c/lead_ratio and
    ω_c·lead_ratio, an optional low-pass at ω_c·lowpass_ratio (0: none); discrete (Tustin) when
    ``dt`` is given."""
    return _from_tuple(_native.weight_pid(float(bandwidth_hz), float(mass), dt, float(integrator_ratio),
                                          float(lead_ratio), float(lowpass_ratio), float(lowpass_zeta)))


def analyze(P, K, *, integrators: Optional[int] = None, unstable_poles: int = 0,
            downsample: Optional[int] = None) -> Result:
    """The loop of plant ``P`` and controller ``K`` (negative feedback), as ``sdctl analyze``:
    ``stable``, ``closed_loop_radius``, ``bandwidth_hz``, ``crossover_hz``,
    ``sensitivity_peak_db`` / ``_hz``, ``gain_margin_db`` / ``_hz``, ``phase_margin_deg`` / ``_hz``,
    ``modulus_margin``; for a stable loop ``loop_at_a_time`` (per input and output channel the
    classic and disk margins, and the simultaneous disk margins); ``nyquist``: the generalised
    Nyquist criterion (``encirclements`` of the origin by det(I + L), ``open_loop_unstable``,
    ``closed_loop_unstable``, and whether it ``agrees`` with the closed-loop eigenvalues).

    A *measured* plant (``P`` an :class:`Frd`) is analysed on its lines, as ``sdctl analyze
    --plant-frd``: ``S`` and ``T`` (Frd), the peaks over the lines, SISO margins interpolated
    between lines (``gain_margin_db`` / ``_hz``, ``phase_margin_deg`` / ``_hz``, every crossing
    in ``all_gain_crossovers`` / ``all_phase_crossovers``), and ``nyquist`` with ``verdict``
    ``"counted"`` (``stable``, ``closed_loop_unstable``, …) or ``"undetermined"`` with the
    ``reason`` (what to measure). ``integrators``: the plant's poles at z = 1 / s = 0 (a rigid
    body: 2; None reads them from the lowest lines, SISO); ``unstable_poles``: its poles in the
    unstable region; ``downsample=F``: ``P`` is a fast FRF at h and ``K`` runs at T = F·h —
    the FRF is folded by Lemma 6 first (no model)."""
    if isinstance(P, Frd):
        for v, n in ((integrators, "integrators"), (downsample, "downsample")):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0):
                raise TypeError(f"analyze: {n} must be a non-negative int or None, not {v!r}")
        text, s, t = _native.analyze_measured(P.freq_hz, P.response, P.variance, P.dt,
                                              _ss(K, "K")._tuple(), integrators,
                                              int(unstable_poles), downsample)
        d = json.loads(text)
        d["S"] = _frd_from_native(s, [])
        d["T"] = _frd_from_native(t, [])
        return Result(d)
    if integrators is not None or unstable_poles or downsample is not None:
        raise ValueError("analyze: integrators, unstable_poles and downsample apply to a measured "
                         "plant (an Frd); a model's poles are its own")
    d = _native.analyze(_ss(P, "P")._tuple(), _ss(K, "K")._tuple())
    text = d.pop("loop_at_a_time_json", None)
    if text is not None:
        d["loop_at_a_time"] = json.loads(text)
    d["nyquist"] = json.loads(d.pop("nyquist_json"))
    return Result(d)


# ---------------------------------------------------------------- data


def frf(manifest: Union[str, os.PathLike], experiment: str, excited_fraction: Optional[float] = None,
        keep_low_snr: bool = False) -> Frd:
    """The FRF of one experiment of a manifest (docs/formats.md), as ``sdctl frf``: periodic
    records by the period average (closed loop through the reference when there is one), others
    by the local polynomial method; lines without excitation dropped unless ``keep_low_snr``."""
    t, w = _native.frf(os.fspath(manifest), experiment, excited_fraction, bool(keep_low_snr))
    return _frd_from_native(t, w)


def frf_from_arrays(r, u, y, fs: float, period: Optional[int] = None, skip_periods: int = 0,
                    excited_fraction: Optional[float] = None, keep_low_snr: bool = False) -> Frd:
    """The FRF of recorded arrays at ``fs`` Hz: ``period`` samples per period (None: the
    local polynomial method for non-periodic data), ``skip_periods`` transient periods, ``r`` the
    reference (None: open loop ``Y/U``)."""
    vec = lambda x, name: np.ascontiguousarray(_real(x, name).reshape(-1))
    t, w = _native.frf_from_arrays(None if r is None else vec(r, "r"), vec(u, "u"), vec(y, "y"), float(fs),
                                   None if period is None else int(period), int(skip_periods),
                                   excited_fraction, bool(keep_low_snr))
    return _frd_from_native(t, w)


def fit(frd: Frd, order: Union[int, str], rigid_body: Optional[int] = None, strictly_proper: bool = False,
        weighting: str = "variance", min_damping: float = 0.0, rank: Union[str, int] = "select",
        input_delay: Union[str, Sequence[int]] = "none", max_order: int = 24, max_delay: int = 0) -> Result:
    """A discrete-time rational model of a SISO FRD (order up to ~60; SK iterations then
    Levenberg–Marquardt on the variance-weighted cost; ``rigid_body`` poles fixed at z = 1):
    ``model`` (StateSpace), ``cost``, ``median_rel_error``, ``line_cost``, ``poles``,
    ``warnings``. A MIMO FRD gets one set of poles for every entry (``order`` counts them once)
    with residue matrices of rank ``rank`` (``"select"``: the rank the data support;
    ``"full"``; or a number): ``model``, ``cost``, ``full_rank_cost``, ``entry_cost``,
    ``median_rel_error``, ``poles``, ``ranks``, ``singular_values``, ``states``, and with
    ``input_delay`` (MIMO only: ``"none"``, ``"auto"`` (±8 samples), ``"auto:N"`` or one whole
    number of samples per input; negative: the outputs respond before that input is recorded)
    ``input_delay`` (the delays used; the model maps u_j(t − δ_j)) and ``delay_scans`` (per
    estimated input: ``input``, ``delay``, ``cost`` as (δ, V) pairs, ``threshold``).

    ``order="auto"`` (SISO, ``sdctl fit --order auto``): the order, rigid body (``None``:
    chosen among 0, 1, 2) and input delay (up to ``max_delay`` samples) the held-out lines
    choose up to ``max_order``, as :func:`fit_physical`, whose result it returns; refused with
    another ``weighting``, a ``min_damping`` or an ``input_delay``."""
    if not isinstance(frd, Frd):
        frd = Frd.from_control(frd)
    if frd.dt is None:
        raise ValueError("fit needs a discrete-time FRD (its dt fixes z = e^{jωT})")
    if isinstance(order, str):
        if order.lower() != "auto":
            raise ValueError(f"order {order!r} is no model order: give a number of poles or 'auto'")
        if weighting != "variance" or min_damping != 0.0 or input_delay != "none":
            raise ValueError("order='auto' chooses the order of a SISO FRD with variance weights and free "
                             "dampings; give a number of poles for weighting, min_damping or input_delay")
        return fit_physical(frd, max_order=max_order, rigid_body=rigid_body, max_delay=max_delay,
                            strictly_proper=strictly_proper)
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise TypeError(f"order must be an int or 'auto', not {type(order).__name__}")
    rigid_body = 0 if rigid_body is None else rigid_body
    d = _native.fit(frd.freq_hz, frd.response, frd.variance, frd.dt, int(order), int(rigid_body),
                    bool(strictly_proper), weighting, float(min_damping), str(rank),
                    input_delay if isinstance(input_delay, str) else ",".join(str(int(v)) for v in input_delay))
    d["model"] = _from_tuple(d["model"])
    return Result(d)


def fit_physical(frd: Frd, max_order: int = 24, rigid_body: Optional[int] = None, max_delay: int = 0,
                 strictly_proper: bool = False) -> Result:
    """The physical modal model of a SISO discrete FRD (``sdctl fit --stabilization``): a
    stabilisation diagram over the orders up to ``max_order``, no pole pair narrower than the
    line spacing unless the data demand it, order and rigid body (``None``: chosen from the
    data among 0, 1, 2) chosen by the held-out odd-indexed lines, an input delay up to
    ``max_delay`` samples (a fraction allowed). ``model`` is the model with its delay; the other
    fields are those of ``modes.json`` (docs/formats.md): ``order``, ``rigid_body``,
    ``delay_samples``, ``delay_interval``, ``delay_phase_error_deg``, ``cost_per_line``,
    ``line_spacing_hz``, ``heldout_factor``, ``modes``, ``orders``, ``diagram``,
    ``delay_scan``, ``warnings`` (messages)."""
    if not isinstance(frd, Frd):
        frd = Frd.from_control(frd)
    if frd.dt is None:
        raise ValueError("fit_physical needs a discrete-time FRD (its dt fixes z = e^{jωT})")
    rb = None if rigid_body is None else int(rigid_body)
    model, text = _native.fit_physical(frd.freq_hz, frd.response, frd.variance, frd.dt,
                                       int(max_order), rb, int(max_delay), bool(strictly_proper))
    d = json.loads(text)
    d["model"] = _from_tuple(model)
    return Result(d)


def diagnose(manifest: Union[str, os.PathLike], model=None, alpha: float = 0.01, max_order: int = 60,
             out: Union[str, os.PathLike, None] = None) -> Result:
    """Why a model misses experiments at other rates (``sdctl diagnose``): the fields of
    ``diagnosis.json`` (docs/diagnosis.md) — ``verdict``, ``cause``, ``causes``, ``parameters``,
    ``gain``, ``experiments``, ``evidence``, … . ``model`` (a StateSpace at the model
    experiment's rate) replaces the fitted one; ``out`` also writes the report folder. A
    manifest of MIMO experiments runs the MIMO diagnosis (``kind`` = ``"mimo"``: ``verdict``,
    ``channels`` with each actuator's hold delay and each sensor's averaging window,
    ``entries``, ``gain``; docs/diagnosis.md)."""
    m = None if model is None else _ss(model, "model")._tuple()
    text = _native.diagnose(os.fspath(manifest), m, float(alpha), int(max_order),
                            None if out is None else os.fspath(out))
    return Result(json.loads(text))


def predict(diagnosis_dir: Union[str, os.PathLike], manifest: Union[str, os.PathLike],
            alpha: float = 0.01, out: Union[str, os.PathLike, None] = None) -> Result:
    """What a diagnosis's model and extension predict on new experiments (``sdctl predict``):
    ``diagnosis_dir`` is a folder written by ``diagnose(out=...)`` (its ``predictor.json``),
    ``manifest`` the new experiments. Returns the fields of ``prediction.json``
    (docs/diagnosis.md): ``extension``, ``experiments`` with ``name``, ``plain``, ``extended``
    (the calibrated statistics, 1 = noise level), ``ratio``, ``threshold``, ``in_band``,
    ``amplitudes`` and ``why`` (None, or why it cannot be predicted). ValueError when no
    experiment can be predicted; ``out`` also writes the report folder."""
    text = _native.predict(os.fspath(diagnosis_dir), os.fspath(manifest), float(alpha),
                           None if out is None else os.fspath(out))
    return Result(json.loads(text))


def testbed(config: Union[str, os.PathLike, None] = None, out: Union[str, os.PathLike, None] = None) -> Result:
    """The virtual wafer stage (``sdctl testbed``). ``config``: a TOML file or TOML text (None:
    identification at 5 kHz and 1 kHz). Returns ``experiments`` (name, rate_hz, period,
    skip_periods, role, r, u, y arrays; for a multi-axis ``[stage]`` configuration r, u and y are
    lists of arrays, one per actuator or sensor), ``truth`` (the continuous linear model) and, with
    ``out``, ``manifest`` (the path of the experiments.toml written there with the CSVs and
    truth.json)."""
    text = None
    if config is not None:
        c = os.fspath(config)
        text = open(c).read() if os.path.isfile(c) else c
    o = None if out is None else os.fspath(out)
    exps, truth = _native.testbed(text, o)
    return Result({"experiments": exps, "truth": _from_tuple(truth),
                   "manifest": None if o is None else os.path.join(o, "experiments.toml")})


# re-exported from their own module (it imports the definitions above)
from ._uncertainty import (  # noqa: E402
    Uncertainty,
    coverage,
    downsample_uncertainty,
    intersample,
    makeweight,
    multisine,
    robust_stability,
    uncertainty,
    weight_lowpass,
    weight_notch,
)

from . import plot  # noqa: E402  (matplotlib is imported only when a figure is drawn)
