"""The replay's exact Jacobian and the trace's screening, checked against independent computations.

The sensitivity replay (CasADi forward mode, results written straight into NumPy arrays, Hermite
interpolation as one sparse product) must predict what the NumPy replay predicts and have the
derivative its own finite differences have; the trace's screening at a coarse knot count, taken
from the finest count's Jacobian, must equal a replay at the coarse knots, and its subset solves
must equal least squares on the subset's columns.
"""

import numpy as np
import pytest

from rventry_env.validation.identify import fly_record
from rventry_env.validation.record import load_record
from rventry_env.validation.replay.sensitivity import SensitivityReplay
from rventry_env.validation.synthetic.simulate import parse_effects, simulate_record
from rventry_env.validation.trace.attribution import _knots, _stage_times
from rventry_env.validation.trace.forcing import CHANNELS, ChannelForcing


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    path = simulate_record(tmp_path_factory.mktemp("rec") / "rec.csv", parse_effects(["drag_coefficient=1.05"]),
                           noise=(20.0, 0.2), duration=120.0, rate=2.0, seed=3)  # fmt: skip
    setup, _, replay = fly_record(load_record(path), None, None, None, 1.0)
    return setup, replay


def _engine(setup, replay, axis, n_knots):
    forcing = ChannelForcing(CHANNELS, axis, _knots(replay, axis, n_knots), _stage_times(replay),
                             float(replay.grid.nodes[-1]))  # fmt: skip
    return SensitivityReplay(replay, lambda v: setup.model, tuple(forcing.names), forcing)


@pytest.mark.parametrize("axis", ["altitude", "time"])
def test_sensitivities_are_the_derivative_of_the_numpy_replay(flown, axis):
    setup, replay = flown
    eng = _engine(setup, replay, axis, 3)
    offsets = np.array([30.0, -20.0, 10.0, 0.1, -0.2, 0.05])
    rng = np.random.default_rng(0)
    params = 0.01 * rng.standard_normal(len(eng.names))
    y, jac = eng.evaluate(offsets, params)
    # at zero corrections the prediction is the NumPy replay's (an independent integrator loop)
    y0, _ = eng.evaluate(offsets, np.zeros(len(eng.names)))
    numpy_y = replay.observe(replay.states(setup.model, replay.init.rv_euler(offsets[None, :])), setup.model)[..., 0]
    assert np.max(np.abs(y0 - numpy_y)) < 1e-6 * np.max(np.abs(numpy_y))
    # every column is the central difference of the prediction (entry state and corrections)
    theta = np.concatenate([offsets, params])
    steps = np.concatenate([[1.0] * 3 + [1e-2] * 3, [1e-1 if "wind" in n else 1e-5 for n in eng.names]])  # m/s
    for i in [0, 4, 6, 6 + len(params) // 2, len(theta) - 1]:
        d = np.zeros(len(theta))
        d[i] = steps[i]
        yp, _ = eng.evaluate((theta + d)[:6], (theta + d)[6:])
        ym, _ = eng.evaluate((theta - d)[:6], (theta - d)[6:])
        fd = (yp - ym) / (2 * steps[i])
        assert np.max(np.abs(jac[:, :, i] - fd)) <= 1e-5 * np.max(np.abs(fd)), eng.names[i - 6] if i >= 6 else i


def test_the_time_offsets_column_is_the_derivative_of_the_shifted_replay(flown):
    """The record's time offset reads the controls later: the prediction is the NumPy replay's with the
    controls shifted, its Jacobian column the central difference, and at zero offset the replay is the
    one without the effect to the last bit."""
    from rventry_env.validation.search.effects import Structure, build_model

    setup, replay = flown
    st = Structure(("time_offset", "wind"))
    names = ("time_offset_s", "wind_east_mps", "wind_north_mps")
    eng = SensitivityReplay(replay, lambda v: build_model(setup, st, v), names)
    offsets = np.array([30.0, -20.0, 10.0, 0.1, -0.2, 0.05])
    for tau in (0.37, -0.61):
        params = np.array([tau, 4.0, -3.0])
        y, jac = eng.evaluate(offsets, params)
        assert np.array_equal(eng.predict(offsets, params), y)
        model = build_model(setup, st, {"wind_east_mps": 4.0, "wind_north_mps": -3.0})
        numpy_y = replay.predict(model, offsets[None, :], tau)[..., 0]
        assert np.max(np.abs(y - numpy_y)) < 1e-6 * np.max(np.abs(numpy_y))
        d = np.array([1e-4, 0.0, 0.0])
        fd = (eng.evaluate(offsets, params + d)[0] - eng.evaluate(offsets, params - d)[0]) / 2e-4
        assert np.max(np.abs(fd)) > 1.0  # m/s: the offset moves the replay
        assert np.max(np.abs(jac[:, :, 6] - fd)) <= 1e-5 * np.max(np.abs(fd))
    # the shift is real: a replay with the controls of another time is another replay
    assert not np.array_equal(eng.predict(offsets, np.array([0.3, 0.0, 0.0])), eng.predict(offsets, np.zeros(3)))
    plain = SensitivityReplay(replay, lambda v: build_model(setup, Structure(("wind",)), v), names[1:])
    assert np.array_equal(plain.evaluate(offsets, np.array([4.0, -3.0]))[0],
                          eng.evaluate(offsets, np.array([0.0, 4.0, -3.0]))[0])  # fmt: skip


def test_control_rates_are_the_derivatives_of_the_schedule():
    """The time derivatives the time offset needs: of the Akima cubics, of the linear fallback, and of a
    bank from the vertical L/D (the arccos), 0 where a control is held beyond its samples."""
    from rventry_env.validation.replay.controls import ControlSchedule, Interpolant

    t = np.linspace(0.0, 100.0, 41)
    sched = ControlSchedule(Interpolant(t, 0.2 + 0.03 * np.sin(t / 9.0)), Interpolant(t, np.sin(t / 15.0)),
                            Interpolant(t, 0.25 * np.cos(t / 11.0)), 0.368)  # fmt: skip
    s = np.linspace(1.3, 98.7, 57)
    h = 1e-6
    for i in range(2):
        fd = (sched.many(s + h)[i] - sched.many(s - h)[i]) / (2 * h)
        assert np.max(np.abs(sched.rates(s)[i] - fd)) < 1e-6 * np.max(np.abs(fd)), i
    short = Interpolant(t[:3], np.array([0.0, 1.0, 4.0]))  # samples at 0, 2.5, 5 s: too few for a cubic, linear
    assert np.allclose(short.rate(np.array([1.0, 4.0, 6.0])), [1.0 / 2.5, 3.0 / 2.5, 0.0])
    assert np.array_equal(sched.rates(np.array([-5.0, 105.0]))[0], [0.0, 0.0])


def test_the_reverse_mode_jacobian_is_the_forward_modes(flown, monkeypatch):
    """Above a number of parameters the step's Jacobian is taken by reverse mode and chained with the
    sensitivities: the same derivative as forward mode along them, to rounding."""
    from rventry_env.validation.replay import sensitivity

    setup, replay = flown
    offsets = np.array([30.0, -20.0, 10.0, 0.1, -0.2, 0.05])
    out = {}
    for above in (10_000, 0):
        monkeypatch.setattr(sensitivity, "REVERSE_ABOVE", above)
        eng = _engine(setup, replay, "altitude", 3)
        params = 0.01 * np.random.default_rng(0).standard_normal(len(eng.names))
        out[eng.mode] = eng.evaluate(offsets, params)
    (y_f, j_f), (y_r, j_r) = out["forward"], out["reverse"]
    assert np.allclose(y_r, y_f, rtol=1e-12, atol=0)
    assert np.max(np.abs(j_r - j_f)) <= 1e-10 * np.max(np.abs(j_f))


@pytest.mark.parametrize("axis", ["altitude", "time"])
def test_the_prediction_without_sensitivities_is_the_sensitivity_replays_to_the_last_bit(flown, axis):
    """A fit's rejected trial points are replayed without derivatives: the same numbers, not close ones."""
    setup, replay = flown
    eng = _engine(setup, replay, axis, 3)
    rng = np.random.default_rng(1)
    for scale in (0.0, 0.01, 0.05):
        offsets = np.array([30.0, -20.0, 10.0, 0.1, -0.2, 0.05]) * (1 + scale)
        params = scale * rng.standard_normal(len(eng.names))
        y, _ = eng.evaluate(offsets, params)
        assert np.array_equal(eng.predict(offsets, params), y)
    assert not np.array_equal(eng.predict(offsets, params), eng.predict(offsets, 0.0 * params))


def test_a_coarse_trace_jacobian_from_the_finest_is_a_replay_at_the_coarse_knots(flown):
    setup, replay = flown
    offsets = np.zeros(6)
    fine = _engine(setup, replay, "altitude", 13)
    coarse = _engine(setup, replay, "altitude", 4)
    _, j_fine = fine.evaluate(offsets, np.zeros(len(fine.names)))
    _, j_coarse = coarse.evaluate(offsets, np.zeros(len(coarse.names)))
    from rventry_env.validation.trace.forcing import hat_values
    from scipy.linalg import block_diag

    t = hat_values(np.asarray(_knots(replay, "altitude", 13)), _knots(replay, "altitude", 4)).T
    embed = block_diag(np.eye(6), *[t] * 5)  # drag, vertical, lateral, wind east and north
    mapped = np.einsum("nmk,kj->nmj", j_fine, embed)
    assert np.max(np.abs(mapped - j_coarse)) < 1e-6 * np.max(np.abs(j_coarse))


def test_screening_subsets_from_one_factorisation_are_least_squares_on_their_columns():
    from rventry_env.validation.trace.attribution import _Linearized

    rng = np.random.default_rng(4)
    lin = object.__new__(_Linearized)  # only the Jacobian and residual matter here
    lin.jac = rng.standard_normal((600, 12)) * np.logspace(-3, 3, 12)  # badly scaled columns
    lin.r, lin._qr = rng.standard_normal(600), None
    for cols in ([0, 1, 2], [0, 5, 11], list(range(12)), [3, 7]):
        step, r_new = lin.screen(cols)
        ref, *_ = np.linalg.lstsq(lin.jac[:, cols], -lin.r, rcond=None)
        assert np.allclose(step, ref, rtol=1e-8, atol=0.0)
        assert np.allclose(r_new, lin.r + lin.jac[:, cols] @ ref, rtol=1e-10, atol=1e-12)


def test_the_written_out_observation_jacobian_is_the_symbolic_one(flown):
    """An ECEF record's observation Jacobian, written out over all samples, is CasADi's symbolic Jacobian of
    the same observation to rounding, also off the unit norm of the Euler parameters."""
    import casadi as ca

    from rventry_env.core.euler_parameters import dcm
    from rventry_env.validation.replay.sensitivity import ecef_observation_jacobian

    setup, replay = flown
    xs = replay.states(setup.model, replay.init.rv_euler(np.zeros((1, 6))))[..., 0]
    xs = xs * (1.0 + 1e-3 * np.random.default_rng(2).standard_normal(xs.shape))  # norms off 1
    x = ca.SX.sym("x", 10)
    qa, qb = x[1:5] / ca.norm_2(x[1:5]), x[6:10] / ca.norm_2(x[6:10])
    c_ae, c_ba = dcm(*[qa[i] for i in range(4)]), dcm(*[qb[i] for i in range(4)])
    y = ca.vertcat(*[x[0] * c_ae[0][j] for j in range(3)],
                   *[x[5] * sum(c_ba[0][i] * c_ae[i][j] for i in range(3)) for j in range(3)])  # fmt: skip
    symbolic = ca.Function("symbolic", [x], [ca.jacobian(y, x)])
    mine = ecef_observation_jacobian(xs)
    for k in range(0, len(xs), 37):
        ref = np.asarray(symbolic(xs[k]))  # (6, 10)
        assert np.max(np.abs(mine[k].T - ref)) <= 1e-12 * np.max(np.abs(ref)), k


def test_a_kept_replay_is_a_new_one_and_the_fit_counts_it_alike(flown):
    """A fit that starts where a screening step was taken gets that replay kept: the same fit, bit for bit,
    with the same count of replays, as one that replays every point. The screening is a problem of its
    own sharing the kept replays, so the fit's first point is asked of them (a problem's own last point
    would serve it otherwise, and whether its later points are asked again depends on the solver's path)."""
    from rventry_env.validation.replay.sensitivity import ReplayCache
    from rventry_env.validation.search.effects import Structure
    from rventry_env.validation.search.fit import OutputErrorProblem

    setup, replay = flown
    sigma, groups = np.array([20.0] * 3 + [0.2] * 3), np.array([0] * 3 + [1] * 3)
    fits = {}
    for size in (0, 8):
        kept, engines = ReplayCache(size), {}
        screen, prob = (OutputErrorProblem(replay, setup, Structure(("drag_coefficient", "wind")), sigma, groups,
                                           engines=engines, replays=kept) for _ in range(2))  # fmt: skip
        screen.linearized(screen.start, {"all": list(range(len(screen.names)))})
        fits[size] = (prob.solve(prob.start), kept.served)
    (plain, served_plain), (kept_fit, served) = fits[0], fits[8]
    assert served_plain == 0 and served >= 1
    assert np.array_equal(plain.values, kept_fit.values) and np.array_equal(plain.stderr, kept_fit.stderr)
    assert plain.nfev == kept_fit.nfev and plain.bic == kept_fit.bic
    assert kept_fit.values[6] == pytest.approx(1.05, abs=0.01)  # the record's C_D x 1.05
