"""Bad input raises ValueError (or TypeError for a wrong Python type) with the library's one-line
message; no panic crosses the boundary."""

import numpy as np
import pytest

import sdtoolkit as sd


def one_line(e):
    s = str(e.value)
    assert s and "\n" not in s, s
    return s


def test_bad_models(stage):
    with pytest.raises(ValueError) as e:
        sd.c2d(stage, -1.0)
    assert "sampling period" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.c2d(sd.StateSpace(np.eye(2), np.ones((3, 1)), np.ones((1, 2)), [[0.0]]), 1e-3)
    assert "B" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.c2d(sd.StateSpace([[np.nan]], [[1.0]], [[1.0]], [[0.0]]), 1e-3)
    one_line(e)
    with pytest.raises(ValueError) as e:
        sd.c2d(stage, 1e-3, method="zho")
    assert "zoh" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.downsample(stage, 5)
    assert "continuous" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.freqresp(sd.c2d(stage, 1e-3), [600.0])
    assert "Nyquist" in one_line(e)
    with pytest.raises(ValueError):
        sd.StateSpace([[1.0]], [[1.0]], [[1.0]], [[0.0]], dt=0)
    with pytest.raises(TypeError):
        sd.freqresp("plant.json", [1.0])
    with pytest.raises(ValueError) as e:
        sd.StateSpace.from_json('{"type": "ss", "ts": 0.001, "a": [[1]], "b": [[1]], "c": [[1]], "dd": [[0]]}')
    one_line(e)


def test_bad_data(tmp_path):
    with pytest.raises(ValueError) as e:
        sd.frf(tmp_path / "missing.toml", "fast")
    assert "missing.toml" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.frf_from_arrays(None, np.ones(10), np.ones(9), 1000.0, period=5)
    assert "same length" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.frf_from_arrays(None, np.ones(10), np.ones(10), 1000.0, period=20)
    assert "need at least" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.fit(sd.Frd([1.0, 2.0], [1.0, 1.0], dt=None), 2)
    one_line(e)
    with pytest.raises(ValueError) as e:
        sd.testbed('[[experiment]]\nkind = "identification"\nnmae = "x"\n')
    assert "nmae" in one_line(e)
    with pytest.raises(ValueError) as e:
        sd.diagnose(tmp_path / "missing.toml")
    one_line(e)


def test_numerical_error_is_an_arithmetic_error():
    assert issubclass(sd.NumericalError, ArithmeticError)


def test_empty_matrices_are_refused_or_shaped_never_filled():
    # B and C empty beside a one-state A and a 1×1 D: refused, not filled with zeros
    with pytest.raises(ValueError, match="B is empty"):
        sd.StateSpace([[1.0]], [], [], [[1.0]])
    # a model without outputs is legal (C 0×n, D 0×m)
    g = sd.StateSpace([[-1.0]], [[1.0, 2.0]], np.zeros((0, 1)), np.zeros((0, 2)))
    assert g.C.shape == (0, 1) and g.D.shape == (0, 2)
    assert sd.StateSpace.from_json(g.to_json()).D.shape == (0, 2)
    # and without inputs, D given as []
    h = sd.StateSpace([[-1.0]], [], [[3.0]], [])
    assert h.B.shape == (1, 0) and h.D.shape == (1, 0)
