"""Models: c2d, d2c, alias, downsample, freqresp, JSON — each against `sdctl` (the Rust result)
and, where python-control has the operation, against python-control."""

import json

import control as ct
import numpy as np
import pytest

import sdtoolkit as sd

EPS = np.finfo(float).eps
# the same Rust code through sdctl and through Python: equal up to the last bits (the two
# builds may dispatch different SIMD kernels), relative to the largest entry
SAME = 1e3 * EPS


def close(a, b, rel):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (a.shape, b.shape)
    scale = max(np.max(np.abs(b)), 1.0)
    assert np.max(np.abs(a - b)) <= rel * scale, np.max(np.abs(a - b)) / scale


def from_cli(text):
    return sd.StateSpace.from_json(text)


def test_c2d_matches_sdctl_and_python_control(stage, sdctl, tmp_path):
    p = tmp_path / "p.json"
    p.write_text(stage.to_json())
    for dt in (1e-3, 2e-4):
        ours = sd.c2d(stage, dt)
        cli = from_cli(sdctl("c2d", p, "--ts", dt))
        for m in "ABCD":
            close(getattr(ours, m), getattr(cli, m), SAME)  # the same code, up to the last bits (SIMD dispatch)
        ref = ct.c2d(stage.to_control(), dt, "zoh")
        n = stage.nstates
        for m in "ABCD":
            close(getattr(ours, m), getattr(ref, m), 1e3 * n * EPS)
        assert ours.dt == dt
    # the five-argument form
    a = sd.c2d(stage.A, stage.B, stage.C, stage.D, 1e-3)
    close(a.A, sd.c2d(stage, 1e-3).A, SAME)


def test_c2d_nonideal_and_tustin_match_sdctl(stage, sdctl, tmp_path):
    p = tmp_path / "p.json"
    p.write_text(stage.to_json())
    ours = sd.c2d(stage, 1e-3, hold_delay=0.3, averaging=0.5)
    cli = from_cli(sdctl("c2d", p, "--ts", 1e-3, "--hold-delay", 0.3, "--averaging", 0.5))
    assert ours.nstates == stage.nstates + 2
    for m in "ABCD":
        close(getattr(ours, m), getattr(cli, m), SAME)
    t = sd.c2d(stage, 1e-3, method="tustin", prewarp_hz=100.0)
    ref = ct.c2d(stage.to_control(), 1e-3, "tustin", prewarp_frequency=2 * np.pi * 100.0)
    f = np.array([1.0, 50.0, 100.0, 300.0])
    g_ref = ref(np.exp(2j * np.pi * f * 1e-3))
    close(sd.freqresp(t, f), g_ref, 1e-9)


def test_d2c_inverts_c2d_and_finds_the_aliased_branch(stage):
    fast = sd.c2d(stage, 1e-4)
    back = sd.d2c(fast)
    f = np.array([1.0, 200.0, 653.0, 1650.0, 2300.0])
    close(sd.freqresp(back, f), sd.freqresp(stage, f), 1e-7)
    # the 653 Hz mode sampled at 1 kHz sits at 347 Hz on the principal branch
    slow = sd.c2d(sd.StateSpace(stage.A[:4, :4], stage.B[:4], stage.C[:, :4], stage.D), 1e-3)
    c, modes, picks = sd.d2c(slow, near_hz=653.0, return_aliases=True)
    assert any(abs(m.freq_hz - 347.0) < 0.5 for m in modes)
    assert len(picks) == 1 and abs(picks[0].freq_hz - 653.0) < 1e-6 * 653
    assert any(abs(f - 653.0) < 1e-6 * 653 for m in modes for f, _ in m.candidates)
    close(sd.freqresp(c, [653.0]), sd.freqresp(stage.__class__(stage.A[:4, :4], stage.B[:4], stage.C[:, :4], stage.D), [653.0]), 1e-6)


def test_alias_matches_sdctl(sdctl):
    ours = sd.alias(653, 1000, factor=5)
    cli = json.loads(sdctl("alias", "--freq-hz", 653, "--rate-hz", 1000, "--factor", 5, "--json"))
    assert ours.alias_hz == cli["alias_hz"] == 347.0
    assert ours.folding_frequencies_hz == cli["folding_frequencies_hz"]
    assert [(t.k, t.fast_hz, t.weight) for t in ours.fast_folds] == [
        (t["k"], t["fast_hz"], t["weight"]) for t in cli["fast_folds"]
    ]


def test_downsample_is_lemma6_and_matches_sdctl(stage, sdctl, tmp_path):
    fast = sd.c2d(stage, 2e-4)
    slow = sd.downsample(fast, 5)
    direct = sd.c2d(stage, 1e-3)
    n = stage.nstates
    for m in "ABCD":
        close(getattr(slow, m), getattr(direct, m), 1e4 * n * EPS)
    p = tmp_path / "fast.json"
    p.write_text(fast.to_json())
    cli = from_cli(sdctl("downsample", p, "--factor", 5))
    for m in "ABCD":
        close(getattr(slow, m), getattr(cli, m), SAME)
    with pytest.raises(ValueError, match="positive integer"):
        sd.downsample(fast, 2.5)


def test_freqresp_at_a_pole_is_infinite():
    """Issue #40 item 2: an integrator's response at 0 Hz (z = 1) is inf, not a huge finite
    number; the other points and an uncontrollable pole's entry stay finite."""
    h = 1e-3
    d = sd.StateSpace([[1.0, h], [0.0, 1.0]], [[0.0], [h]], [[1.0, 0.0]], [[0.0]], h)
    g = sd.freqresp(d, [0.0, 0.5, 10.0])
    assert np.isinf(g[0].real)
    z = np.exp(2j * np.pi * np.array([0.5, 10.0]) * h)
    close(g[1:], h * h / (z - 1) ** 2, 1e-8)  # C(zI − A)⁻¹B of this realization
    # two inputs: the integrator from the first only, a lag from the second
    m = sd.StateSpace([[0.0, 0.0], [0.0, -1.0]], np.eye(2), [[1.0, 1.0]], [[0.0, 0.0]])
    g = sd.freqresp(m, [0.0], squeeze=False)
    assert np.isinf(g[0, 0, 0].real) and abs(g[0, 1, 0] - 1.0) < 1e-12


def test_freqresp_matches_sdctl_and_python_control(stage, sdctl, tmp_path):
    d = sd.c2d(stage, 2e-4)
    f = np.linspace(1.0, 2400.0, 500)
    g, path = sd.freqresp(d, f, return_path=True)
    assert g.shape == (500,) and path in ("block_diagonal", "hessenberg", "dense")
    assert sd.freqresp(d, f, squeeze=False).shape == (1, 1, 500)
    ref = d.to_control()(np.exp(2j * np.pi * f * 2e-4))
    close(g, ref, 1e-8)
    p = tmp_path / "d.json"
    p.write_text(d.to_json())
    cli = sd.Frd.from_json(sdctl("freqresp", p, "--grid", "1:2400:500"))
    close(g, cli.response[0, 0], 1e-12)


def test_json_and_python_control_round_trips(stage):
    back = sd.StateSpace.from_json(stage.to_json())
    for m in "ABCD":
        close(getattr(back, m), getattr(stage, m), SAME)
    assert back.dt is None
    d = sd.c2d(stage, 1e-3)
    c = sd.StateSpace.from_control(d.to_control())
    assert c.dt == 1e-3
    for m in "ABCD":
        close(getattr(c, m), getattr(d, m), SAME)
    frd = sd.Frd([1.0, 2.0], [1 + 1j, 0.5 - 0.1j], [1e-6, 2e-6], dt=1e-3)
    f2 = sd.Frd.from_json(frd.to_json())
    close(f2.response, frd.response, SAME)
    close(f2.variance, frd.variance, SAME)
    f3 = sd.Frd.from_control(frd.to_control())
    close(f3.freq_hz, frd.freq_hz, 1e-15)
    close(f3.response, frd.response, SAME)
    assert f3.dt == 1e-3


def test_d2c_matches_sdctl(stage, sdctl, tmp_path):
    fast = sd.c2d(stage, 1e-4)
    p = tmp_path / "fast.json"
    p.write_text(fast.to_json())
    cli = from_cli(sdctl("d2c", p))
    ours = sd.d2c(fast)
    for m in "ABCD":
        close(getattr(ours, m), getattr(cli, m), 1e-9)


def test_zeros_of_known_systems():
    # (s² + 2s + 101)/(s³ + 3s² + 10s + 5): zeros −1 ± 10j, exact conjugates
    g = sd.StateSpace([[-3.0, -10.0, -5.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                      [[1.0], [0.0], [0.0]], [[1.0, 2.0, 101.0]], [[0.0]])
    z = sd.zeros(g)
    assert z.shape == (2,)
    assert np.max(np.abs(np.sort_complex(z) - np.array([-1 - 10j, -1 + 10j]))) < 1e-12
    assert z[0] == np.conj(z[1])
    # a square 2×2 system with invertible D has the zeros eig(A − B D⁻¹ C): build A from
    # the wanted zeros Z = diag(−2, 0.5) + a pair −1 ± 3j, rotated
    rng = np.random.default_rng(3)
    zm = np.array([[-2.0, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, -1.0, 3.0], [0, 0, -3.0, -1.0]])
    q, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    zm = q @ zm @ q.T
    b, c = rng.standard_normal((4, 2)), rng.standard_normal((2, 4))
    d = np.eye(2) + 0.3 * rng.standard_normal((2, 2))
    a = zm + b @ np.linalg.solve(d, c)
    z = np.sort_complex(sd.zeros(sd.StateSpace(a, b, c, d, dt=1e-3)))
    want = np.sort_complex(np.array([-2.0, 0.5, -1 - 3j, -1 + 3j]))
    assert np.max(np.abs(z - want)) < 1e-11
    # a generic non-square system has none; the poles are A's eigenvalues
    wide = sd.StateSpace(rng.standard_normal((5, 5)), rng.standard_normal((5, 3)),
                         rng.standard_normal((2, 5)), np.zeros((2, 3)))
    assert sd.zeros(wide).size == 0
    p = sd.poles(wide)
    assert np.max(np.abs(np.sort_complex(p) - np.sort_complex(np.linalg.eigvals(wide.A)))) < 1e-12


def test_complex_input_is_refused_not_made_real():
    a = np.array([[1.0 + 0.5j]])
    with pytest.raises(TypeError, match="A is complex"):
        sd.StateSpace(a, [[1.0]], [[1.0]], [[0.0]], 0.001)
    with pytest.raises(TypeError, match="B is complex"):
        sd.StateSpace([[0.0]], [[1j]], [[1.0]], [[0.0]])
    with pytest.raises(TypeError, match="u is complex"):
        sd.frf_from_arrays(None, np.ones(64) * 1j, np.ones(64), 1000.0)


def test_from_json_takes_a_path_or_text(tmp_path):
    m = sd.StateSpace([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.001)
    p = tmp_path / "m.json"
    p.write_text(m.to_json())
    for arg in (p, str(p), m.to_json(), "  \n" + m.to_json()):
        back = sd.StateSpace.from_json(arg)
        assert back.dt == 0.001 and np.allclose(back.A, m.A)
    f = sd.Frd(np.array([1.0, 2.0]), np.ones((1, 1, 2), complex), None, 0.001)
    q = tmp_path / "f.json"
    q.write_text(f.to_json())
    assert np.allclose(sd.Frd.from_json(q).response, f.response)
    with pytest.raises(ValueError, match="neither JSON text"):
        sd.StateSpace.from_json(tmp_path / "missing.json")
    with pytest.raises(TypeError):
        sd.Frd.from_json(42)


def test_result_repr_shows_values_and_summary():
    r = sd.Result({"gamma": 2.531427, "stable": True, "name": "k", "freq_hz": [1.0, 2.0, 3.0, 4.0, 5.0],
                   "pair": [1, 2], "inner": {"a": 1, "b": [0.5]}, "missing": None})
    text = repr(r)
    assert "gamma=2.53143" in text and "stable=True" in text and "name='k'" in text
    assert "freq_hz=[1, 2, 3, … (5 items)]" in text and "pair=[1, 2]" in text
    assert "inner=Result(a, b)" in text and "missing=None" in text
    lines = r.summary().splitlines()
    assert lines[0] == "gamma: 2.53143" and "inner:" in lines and "  b: [0.5]" in lines
    assert "summary" in dir(r)


def test_dir_lists_the_public_names_only():
    names = dir(sd)
    assert "fit" in names and "StateSpace" in names
    assert not {"np", "os", "json", "_native"} & set(names)


def test_series_parallel_feedback_match_python_control():
    rng = np.random.default_rng(7)
    dt = 1e-3
    f = np.array([3.0, 40.0, 170.0, 420.0])
    z = np.exp(2j * np.pi * f * dt)

    def rand(n, ny, nu):
        g = ct.drss(n, ny, nu, dt=dt)
        g = ct.ss(g.A, g.B, g.C, rng.normal(size=(ny, nu)) * 0.3, dt)
        return g, sd.StateSpace.from_control(g)

    def resp(g):  # python-control's response at the frequencies: (ny, nu, nf)
        return np.stack([np.asarray(g(zk)).reshape(g.noutputs, g.ninputs) for zk in z], axis=-1)

    c1, s1 = rand(3, 2, 2)
    c2, s2 = rand(2, 2, 2)
    for ours, theirs in [
        (sd.series(s1, s2), ct.series(c1, c2)),
        (sd.parallel(s1, s2), ct.parallel(c1, c2)),
        (sd.feedback(s1, s2), ct.feedback(c1, c2)),
        (sd.feedback(s1, s2, sign=1), ct.feedback(c1, c2, sign=1)),
        (s1.feedback(), ct.feedback(c1, np.eye(2))),
    ]:
        got = sd.freqresp(ours, f, squeeze=False)
        want = resp(theirs)
        assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, np.max(np.abs(want)))
    # chained series (three blocks) and the poles method
    c3, s3 = rand(1, 2, 2)
    got = sd.freqresp(sd.series(s1, s2, s3), f, squeeze=False)
    assert np.allclose(got, resp(ct.series(c1, c2, c3)), rtol=1e-9, atol=1e-12)
    assert np.allclose(np.sort_complex(s1.poles()), np.sort_complex(np.linalg.eigvals(c1.A)))
    with pytest.raises(ValueError, match="sample times"):
        sd.series(s1, sd.StateSpace(s2.A, s2.B, s2.C, s2.D, 2e-3))
    with pytest.raises(ValueError, match="outputs"):
        sd.series(s1, sd.StateSpace([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt))
    with pytest.raises(ValueError, match="not well posed"):
        g = sd.StateSpace([[0.5]], [[1.0]], [[1.0]], [[1.0]], dt)
        sd.feedback(g, sd.StateSpace([[0.5]], [[1.0]], [[1.0]], [[1.0]], dt), sign=1)


def test_lsim_and_step_response_match_python_control():
    rng = np.random.default_rng(11)
    dt = 1e-3
    g = ct.drss(4, 2, 2, dt=dt)
    g = ct.ss(g.A, g.B, g.C, rng.normal(size=(2, 2)) * 0.2, dt)
    s = sd.StateSpace.from_control(g)
    n = 300
    u = rng.normal(size=(n, 2))
    x0 = rng.normal(size=4)
    r = sd.lsim(s, u, x0=x0)
    ref = ct.forced_response(g, T=np.arange(n) * dt, U=u.T, X0=x0)
    assert np.allclose(r.y, np.asarray(ref.outputs).T, rtol=1e-10, atol=1e-12)
    assert np.allclose(r.x_final, g.A @ ref.states[:, -1] + g.B @ u[-1], rtol=1e-10, atol=1e-12)
    assert np.allclose(r.t, np.arange(n) * dt)
    st = sd.step_response(s, 50)
    ref = ct.step_response(g, T=np.arange(50) * dt)
    assert np.allclose(st.y, np.asarray(ref.outputs).reshape(2, 2, 50), rtol=1e-10, atol=1e-12)
    # a continuous model through the hold: python-control's exact ZOH discretisation
    c = ct.rss(3, 1, 1)
    c = ct.ss(c.A, c.B, c.C, c.D)
    uc = rng.normal(size=n)
    rc = sd.lsim(sd.StateSpace.from_control(c), uc, dt=dt)
    refc = ct.forced_response(ct.c2d(c, dt, "zoh"), T=np.arange(n) * dt, U=uc)
    assert np.allclose(rc.y[:, 0], np.asarray(refc.outputs).reshape(-1), rtol=1e-8, atol=1e-10)
    with pytest.raises(ValueError, match="hold period"):
        sd.lsim(sd.StateSpace.from_control(c), uc)
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        sd.lsim(s, rng.normal(size=(n, 3)))
    with pytest.raises(TypeError):
        sd.lsim(s, u + 1j)


def test_a_python_control_transfer_function_is_accepted_where_a_model_is():
    """#43 item 4: a ``control.TransferFunction`` (SISO and MIMO, continuous and discrete) is a
    model everywhere: its response equals python-control's own evaluation of the fraction."""
    import control
    G = control.tf([1.0, 3.0], [1.0, 2.0, 10.0])
    assert np.allclose(np.sort_complex(sd.poles(G)), np.sort_complex(np.roots([1, 2, 10])))
    Gd = control.tf([0.5, 0.1], [1.0, -0.9], 0.01)
    f = np.array([1.0, 10.0])
    close(sd.freqresp(Gd, f), Gd(np.exp(2j * np.pi * f * 0.01)), 1e-13)
    M = control.tf([[[1], [2]], [[1, 0], [3]]], [[[1, 1], [1, 2]], [[1, 3], [1, 4]]])
    got = sd.freqresp(M, f, squeeze=False)
    for k, fk in enumerate(f):
        close(got[:, :, k], M(2j * np.pi * fk), 1e-13)
    a = sd.analyze(control.tf([1.0], [1.0, 1.0, 0.0]), control.tf([2.0], [1.0]))
    assert a.stable
