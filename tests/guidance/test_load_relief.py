"""Load relief: its one-step prediction against the env's own integrator, on the optimum's final pull-down."""

from __future__ import annotations

import numpy as np
import pytest

from rventry_env.core.backend import NUMPY
from rventry_env.envs.propagation import Propagator
from rventry_env.task import EntryTask
from rventry_env.guidance.load_relief import LoadRelief
from rventry_env.physics import EntryModel
from rventry_env.physics.entry import entry_forces, entry_rhs
from rventry_env.physics.model import scaled_model
from rventry_env.reference.data_file import load_reference


def _pull_down():
    """States of the optimum in the seconds its load factor climbs from 6 to 12 g."""
    ref = load_reference()
    return ref.x[(ref.t > ref.t[-1] - 15.0) & (ref.t < ref.t[-1] - 9.5)]


def _flown_peak(x, rates, truth: EntryModel, task: EntryTask):
    """The peak load factor (g) over one control step, by the env's RK4 substeps on the true model."""
    p = task.problem
    out = Propagator(task, NUMPY).step(tuple(x.T), entry_forces(tuple(x.T), truth), rates[:, 0] * p.u_alpha_max,
                                       rates[:, 1] * p.u_sigma_max, truth)  # fmt: skip
    return np.asarray(out.max_load_g)


@pytest.mark.parametrize("density", [1.0, 1.08, 0.92])
def test_capped_rates_keep_the_flown_load_in_bound_on_a_dispersed_vehicle(density):
    task, nominal = EntryTask(), EntryModel()
    truth = scaled_model(nominal, density=density)
    x = _pull_down()
    sensed = np.stack(entry_forces(tuple(x.T), truth).aero_b, axis=1)
    below = np.asarray(entry_forces(tuple(x.T), truth).aero_accel) / nominal.planet.g0 < 11.5
    assert below.sum() >= 5
    x, sensed = x[below], sensed[below]
    up = np.tile([1.0, 0.3], (len(x), 1))  # alpha up at full rate, some bank rate
    relief = LoadRelief(nominal, task, margin=0.01)
    capped = relief(up, x, sensed)
    assert (_flown_peak(x, up, truth, task) > 12.0).sum() >= len(x) - 1  # uncapped, the bound goes
    assert relief.active.sum() >= len(x) - 1 and np.all(capped[relief.active, 0] < 1.0)
    np.testing.assert_array_equal(capped[:, 1], up[:, 1])  # the bank rate is not the relief's
    assert _flown_peak(x, capped, truth, task).max() <= 12.0  # a_max, with the margin's 1 % spent on the prediction
    np.testing.assert_array_equal(relief.steps, relief.active.astype(int))


def test_the_sensed_acceleration_is_what_calibrates_the_prediction():
    task, nominal = EntryTask(), EntryModel()
    truth = scaled_model(nominal, density=1.08)
    x = _pull_down()[:4]
    up = np.tile([1.0, 0.0], (len(x), 1))
    blind = np.stack(entry_forces(tuple(x.T), nominal).aero_b, axis=1)  # what the nominal model would sense
    capped = LoadRelief(nominal, task, margin=0.01)(up, x, blind)
    assert _flown_peak(x, capped, truth, task).max() > 12.3  # 8 % more air than the model: over the bound


def test_no_cap_where_the_load_stays_low_and_a_counted_step_mask():
    task = EntryTask()
    x = load_reference().x[:5]  # the start: near 1 g
    sensed = np.stack(entry_forces(tuple(x.T), EntryModel()).aero_b, axis=1)
    rates = np.tile([1.0, -1.0], (5, 1))
    relief = LoadRelief(task=task)
    np.testing.assert_array_equal(relief(rates, x, sensed), rates)
    assert not relief.active.any()
    late = _pull_down()[:3]
    late_sensed = np.stack(entry_forces(tuple(late.T), EntryModel()).aero_b, axis=1)
    relief(np.tile([1.0, 0.0], (3, 1)), late, late_sensed, count=np.array([True, False, True]))
    np.testing.assert_array_equal(relief.steps, [1, 0, 1])  # frozen copies (count False) are not counted


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="margin must lie in"):
        LoadRelief(margin=1.0)
    with pytest.raises(ValueError, match="at least one halving of the rate interval"):
        LoadRelief(iterations=0)
    relief = LoadRelief()
    with pytest.raises(ValueError, match="sensed acceleration"):
        relief(np.zeros((1, 2)), np.zeros((1, 12)), None)
    with pytest.raises(ValueError, match=r"rates \(N, 2\), state \(N, 12\)"):
        relief(np.zeros((2, 2)), load_reference().x[:1], np.zeros((1, 3)))


def test_the_capped_rate_is_the_highest_that_meets_the_limit_by_a_whole_step_of_the_model():
    """The search moves alpha alone; checked against a whole explicit step of the equations of
    motion at the capped rate and one resolution above it."""
    task, model = EntryTask(), EntryModel()
    p = task.problem
    x = _pull_down()
    sensed = 1.03 * np.stack(entry_forces(tuple(x.T), model).aero_b, axis=1)  # 3 % more load than the model
    relief = LoadRelief(model, task, margin=0.01, iterations=14)
    capped = relief(np.tile([1.0, 0.5], (len(x), 1)), x, sensed)
    on = relief.active & (capped[:, 0] > -1.0)
    assert on.sum() >= 5

    g0 = model.planet.g0
    calib = np.linalg.norm(sensed, axis=1) / np.asarray(entry_forces(tuple(x.T), model).aero_accel)

    def predicted(rate):  # the sensed-calibrated load factor (g) after a whole step at this alpha rate
        u = (rate * p.u_alpha_max, np.full(len(x), 0.5 * p.u_sigma_max))
        ahead = x + task.dt * np.stack(entry_rhs(tuple(x.T), u, model), axis=1)
        return calib * np.asarray(entry_forces(tuple(ahead.T), model).aero_accel) / g0

    limit = relief.limit_g
    assert np.all(predicted(capped[:, 0])[on] <= limit)
    assert np.all(predicted(capped[:, 0] + 2.0 / 2**14)[on] > limit)


def test_the_load_limiter_holds_the_bound_under_an_injected_density_step():
    """The optimum replayed open loop into air 8 % denser below 16 km passes 12 g; with the relief,
    calibrated on the accelerometer, it stays within the bound all the way down."""
    import math

    from rventry_env.evaluation.rollout import rollout
    from rventry_env.guidance.law import Law
    from rventry_env.guidance.reference_replay import ReferencePolicy
    from rventry_env.physics import DensityCorrection, ExponentialAtmosphere

    class Relieved(Law):
        def __init__(self, relief):
            self.law, self.relief = ReferencePolicy(), relief

        def reset(self, n):
            self.relief.reset(n)

        def __call__(self, m):
            return self.relief(self.law(m), m.navigation_state, m.sensed_accel_b, count=m.flying).astype(np.float32)

    step = DensityCorrection(ExponentialAtmosphere(), (0.0, 15_990.0, 16_000.0, 80e3),
                             (math.log(1.08), math.log(1.08), 0.0, 0.0))  # fmt: skip
    model = EntryModel(atmosphere=step)
    bound = EntryTask().problem.a_max_g
    open_loop = rollout(ReferencePolicy(), 1, model=model)
    assert open_loop.max_load_factor_g[0] > 1.05 * bound  # above 12.6 g: the step breaks the bound without feedback
    relieved = rollout(Relieved(LoadRelief(margin=0.02)), 1, model=model)
    assert relieved.max_load_factor_g[0] <= bound and relieved.failure[0] == ""
    assert relieved.law_stats == [] and relieved.miss_km[0] < 1.0


def test_the_chance_margin_holds_the_bound_through_denser_air_one_step_down():
    """Air 4 % denser from the next altitude kilometre down (a density step the calibration, made
    where the vehicle is, cannot see): with the fixed 1 % margin the flown peak passes 12 g; with
    the limit lowered by 2 sigma of the flight set's density bands over the step's descent, it holds."""
    from dataclasses import replace

    from rventry_env.physics.atmosphere import ExponentialAtmosphere
    from rventry_env.physics.uncertainty import ProfileAtmosphere
    from rventry_env.task import FLIGHT_GRADE_ERRORS

    task, nominal = EntryTask(), EntryModel()
    x = _pull_down()
    h = x[:, 0] - nominal.planet.radius
    grid = np.arange(0.0, 101e3, 1e3)
    log_f = np.where(grid[None, :] >= np.floor(h[:, None] / 1e3) * 1e3, 0.0, np.log(1.04))  # one profile each
    truth = replace(nominal, atmosphere=ProfileAtmosphere(ExponentialAtmosphere(), 0.0, 1e3, log_f))
    f = entry_forces(tuple(x.T), truth)
    keep = np.asarray(f.aero_accel) / nominal.planet.g0 < 11.5
    assert keep.sum() >= 6
    sensed = np.stack(f.aero_b, axis=1)
    up = np.tile([1.0, 0.3], (len(x), 1))
    fixed = LoadRelief(nominal, task, margin=0.01)(up, x, sensed)
    chance = LoadRelief(nominal, task, margin=0.01, sigmas=2.0, density_bands=FLIGHT_GRADE_ERRORS.density_bands)
    held = chance(up, x, sensed)
    assert np.all(_flown_peak(x, fixed, truth, task)[keep] > 12.0)
    assert np.all(_flown_peak(x, held, truth, task)[keep] <= 12.0)
    # it costs where the air changes fast: in the dive (a kilometre a second) over 2 % of the limit,
    # in the glide at the start (tens of metres a second) under 1 %
    _, _, _, dive = chance._loads(x, np.zeros(len(x)), np.zeros(len(x)))
    assert np.all(dive < 0.98 * chance.limit_g)
    glide = load_reference().x[:3]
    g_sensed = np.stack(entry_forces(tuple(glide.T), nominal).aero_b, axis=1)
    _, _, _, limit = chance._loads(glide, np.zeros(3), np.zeros(3))
    assert np.all(limit > 0.99 * chance.limit_g)
    np.testing.assert_array_equal(chance(np.tile([0.5, 0.0], (3, 1)), glide, g_sensed), np.tile([0.5, 0.0], (3, 1)))


def test_the_chance_margin_names_what_it_needs():
    with pytest.raises(ValueError, match="sigmas need the uncertainty they count"):
        LoadRelief(sigmas=1.0)
    with pytest.raises(ValueError, match="sigmas must be a finite number"):
        LoadRelief(sigmas=-1.0, aero_mach_rms=0.03)
