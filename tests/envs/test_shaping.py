"""Potential-based shaping changes no optimal decision: the shaped return is the return less Phi(s_0)."""

from __future__ import annotations

import numpy as np
import pytest

from rventry_env.envs.reward import RewardWeights
from rventry_env.envs.rv_entry import RvEntryEnv
from rventry_env.envs.shaping import PotentialShaping
from rventry_env.envs.vector import RvEntryVectorEnv
from rventry_env.evaluation.rungs import rung_starts
from rventry_env.reference.shaping import energy_range_profile, fade_energies

GAMMA = 0.99


def _terminal(**kw):
    """The late flight's terminal terms, taken on over the reference's last 60 s (a late start is in it)."""
    return dict(terminal=RewardWeights(miss_per_km=1.0, vertical_per_deg=2.0, speed_per_mps=0.1, alpha_per_deg=0.5),
                terminal_energies=fade_energies(60.0), final_speed=1219.0) | kw  # fmt: skip


def _shapings():
    e, r = energy_range_profile()
    fade = fade_energies(60.0)
    return [PotentialShaping("range", GAMMA), PotentialShaping("energy", GAMMA, 0.5, energies=e, ranges=r),
            PotentialShaping("energy", GAMMA, 0.5, energies=e, ranges=r, fade_energies=fade),
            PotentialShaping("energy", GAMMA, 0.5, energies=e, ranges=r, fade_energies=fade, **_terminal())]


def _shaping_id(s):
    return s.potential + ("-fading" if s.fade_energies else "") + ("-terminal" if s.terminal else "")


def _discounted(rewards, gamma=GAMMA):
    return float(sum(gamma**k * r for k, r in enumerate(rewards)))


@pytest.mark.parametrize("shaping", _shapings(), ids=_shaping_id)
def test_the_shaped_return_is_the_return_less_the_starting_potential(shaping):
    """Any actions, any start: sum_k gamma^k (r_k + F_k) - sum_k gamma^k r_k = -Phi(s_0) on an episode that
    terminates, so every policy's return moves by the same constant and no decision changes."""
    starts = rung_starts("late")
    shaped, plain = RvEntryEnv(starts=starts, shaping=shaping), RvEntryEnv(starts=starts)
    rng = np.random.default_rng(0)
    for seed in range(4):
        shaped.reset(seed=seed)
        plain.reset(seed=seed)
        phi0 = shaped._phi
        a, b = [], []
        while True:
            act = rng.uniform(-0.5, 0.5, 2)
            _, ra, term, trunc, _ = shaped.step(act)
            _, rb, term_b, _, _ = plain.step(act)
            a.append(ra)
            b.append(rb)
            assert term == term_b
            if term or trunc:
                break
        assert term  # impact or failure: a terminal state, potential 0
        assert _discounted(a) - _discounted(b) == pytest.approx(-phi0, rel=1e-9, abs=1e-9)
        assert phi0 < 0  # the potential is a (negative) predicted penalty


def test_a_cut_episode_keeps_its_last_potential_and_the_vector_env_shapes_alike():
    """A time-limit cut is not terminal: the sum telescopes to gamma^T Phi(s_T) - Phi(s_0). The vector env
    pays each copy what the single env pays it."""
    shaping = _shapings()[1]
    n, limit = 4, 12
    vec = RvEntryVectorEnv(n, starts=rung_starts("late"), shaping=shaping, max_episode_steps=limit)
    vec.reset(seed=20)
    rows = np.array([vec.step(np.zeros((n, 2)))[1] for _ in range(limit)]).T
    for i in range(n):
        shaped = RvEntryEnv(starts=rung_starts("late"), shaping=shaping, max_episode_steps=limit)
        plain = RvEntryEnv(starts=rung_starts("late"), max_episode_steps=limit)
        shaped.reset(seed=20 + i)
        plain.reset(seed=20 + i)
        phi0 = shaped._phi
        a, b = [], []
        for _ in range(limit):
            _, ra, term, trunc, _ = shaped.step(np.zeros(2))
            a.append(ra)
            b.append(plain.step(np.zeros(2))[1])
        assert trunc and not term
        assert _discounted(a) - _discounted(b) == pytest.approx(GAMMA**limit * shaped._phi - phi0, rel=1e-9)
        assert np.allclose(rows[i], a, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("shaping", _shapings()[1::2], ids=_shaping_id)
def test_the_functional_env_shapes_as_the_numpy_env_does_and_charges_a_cut_as_a_failure(shaping):
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from rventry_env.core.backend import NUMPY
    from rventry_env.envs.functional import RvEntryFunctional
    from rventry_env.envs.outcome import TerminalMetrics, time_limit_penalty

    starts = rung_starts("late")
    plain = RvEntryFunctional(starts=starts, dtype="float64", max_episode_steps=12)
    shaped = RvEntryFunctional(starts=starts, dtype="float64", max_episode_steps=12, shaping=shaping,
                               time_limit_is_failure=True)  # fmt: skip
    key = jax.random.PRNGKey(5)
    _, sa = shaped.reset(key, shaped.default_params)
    _, sb = plain.reset(key, plain.default_params)
    phi0 = float(sa.potential)
    ra, rb = [], []
    for k in range(12):
        _, sa, r1, _, info = shaped.step_env(key, sa, jnp.zeros(2), shaped.default_params)
        _, sb, r2, _, _ = plain.step_env(key, sb, jnp.zeros(2), plain.default_params)
        ra.append(float(r1))
        rb.append(float(r2))
    assert bool(info["truncated"]) and not bool(info["terminated"])
    m = TerminalMetrics(*(np.asarray(float(info[k])) for k in TerminalMetrics._fields))
    charged = float(time_limit_penalty(m, shaped.reward, NUMPY))
    assert charged > shaped.reward.failure
    # the cut is final there (Phi = 0) and charged: the difference telescopes to -Phi(s_0) - gamma^(T-1) charge
    diff = _discounted(ra) - _discounted(rb)
    assert diff == pytest.approx(-phi0 - GAMMA**11 * charged, rel=1e-9)


def test_a_fading_potential_is_whole_above_the_fade_none_below_it_and_linear_in_energy_between():
    """Phi_fade(s) = f(e(s)) Phi(s), f from 1 at e_full to 0 at e_zero, on states off the reference's
    profile (its states 5% fast) before, across and after the fade; e_full and e_zero are the
    reference's energies 60 s before its end and at it."""
    from rventry_env.core.backend import NUMPY
    from rventry_env.core.euler_parameters import dcm
    from rventry_env.core.targeting import specific_energy
    from rventry_env.physics.model import EntryModel
    from rventry_env.reference import load_reference
    from rventry_env.task import EntryProblem

    whole, fading = _shapings()[1:3]
    full, zero = fading.fade_energies
    ref, planet = load_reference(), EntryModel().planet
    target = tuple(float(c) for c in EntryProblem().target_unit_vector())
    on = tuple(ref.state(ref.tf - np.array([300.0, 60.0, 40.0, 20.0, 5.0, 0.0])).T)
    e_on = specific_energy(on, planet.mu, planet.radius)
    assert e_on[1] == pytest.approx(full, rel=1e-12) and e_on[-1] == pytest.approx(zero, rel=1e-12)

    def phis(speed_factor):
        x = tuple(v * (speed_factor if k == 5 else 1.0) for k, v in enumerate(on))
        args = (x, dcm(*x[1:5]), target, planet.mu, planet.radius, NUMPY)
        return specific_energy(x, planet.mu, planet.radius), whole.phi(*args), fading.phi(*args)

    e, a, b = phis(1.05)
    f = np.clip((e - zero) / (full - zero), 0.0, 1.0)
    assert np.all(a < 0)  # 5% fast is off the profile everywhere
    assert np.sum((f > 0) & (f < 1)) >= 3 and f[0] == 1.0  # the states sample the fade and above it
    assert b == pytest.approx(f * a, rel=1e-12)
    e, a, b = phis(0.5)
    assert e[4] < zero and a[4] < 0 and b[4] == 0.0  # none below the impact energy (5 s out, half the speed)


def test_the_terminal_terms_are_taken_on_at_the_end_as_an_independent_reading_of_the_miss_and_the_dive():
    """Phi = Phi_fade - g(e) * penalty(s), g from 0 at e_none to 1 at e_whole, where the penalty reads the
    state as if the flight ended there; checked against the miss and the angle from vertical computed
    anew from the ECEF position and velocity (arccos of dot products, not the quaternion's half-angle)."""
    from rventry_env.core.backend import NUMPY
    from rventry_env.core.euler_parameters import dcm
    from rventry_env.core.targeting import specific_energy
    from rventry_env.physics.model import EntryModel
    from rventry_env.reference import load_reference
    from rventry_env.task import EntryProblem

    e, r = energy_range_profile()
    w = RewardWeights(miss_per_km=3.0, vertical_per_deg=5.0, speed_per_mps=0.25, alpha_per_deg=0.5)
    none, whole = fade_energies(20.0)[0], fade_energies(60.0)[1]
    base = PotentialShaping("energy", GAMMA, 0.5, energies=e, ranges=r, fade_energies=fade_energies(60.0))
    late = PotentialShaping("energy", GAMMA, 0.5, energies=e, ranges=r, fade_energies=fade_energies(60.0),
                            terminal=w, terminal_energies=(none, whole), final_speed=1219.0)  # fmt: skip
    ref, planet = load_reference(), EntryModel().planet
    target = np.asarray(EntryProblem().target_unit_vector(), dtype=float)
    x = tuple(ref.state(ref.tf - np.array([200.0, 30.0, 15.0, 10.0, 5.0, 1.0])).T)
    c = dcm(*x[1:5])
    args = (x, c, tuple(target), planet.mu, planet.radius, NUMPY)
    cab = np.moveaxis(np.asarray(c, dtype=float), -1, 0)  # (n, 3, 3): rows a1, a2, a3 in E
    cba = np.moveaxis(np.asarray(dcm(*x[6:10]), dtype=float), -1, 0)
    a1 = cab[:, 0, :]
    b1 = np.einsum("nj,njk->nk", cba[:, 0, :], cab)  # the velocity's direction in E
    miss_km = planet.radius * np.arccos(np.clip(a1 @ target, -1, 1)) / 1000.0
    from_vertical = np.degrees(np.arccos(np.clip(-np.sum(b1 * a1, axis=1), -1, 1)))
    penalty = (3.0 * miss_km + 5.0 * from_vertical + 0.25 * np.abs(x[5] - 1219.0) + 0.5 * np.abs(np.degrees(x[10])))
    g = np.clip((none - specific_energy(x, planet.mu, planet.radius)) / (none - whole), 0.0, 1.0)
    assert g[0] == 0.0 and g[-1] > 0.9 and np.sum((g > 0) & (g < 1)) >= 3
    # the interpolated reference's quaternions are unit to about 1e-7, which the two readings of the
    # angle take differently: 1e-3 of penalty is 2e-4 deg at 5 per deg
    assert late.phi(*args) == pytest.approx(base.phi(*args) - g * penalty, rel=0, abs=1e-3)
    assert 5 < from_vertical[3] < 80 and from_vertical[-1] < 5  # the reference's dive is what it reads
    with pytest.raises(ValueError, match="terminal_energies must be two numbers"):
        PotentialShaping("range", GAMMA, terminal=w, final_speed=1219.0)
    with pytest.raises(ValueError, match=r"terminal_energies \(e_none, e_whole\) must be finite with e_none > e_whole"):
        PotentialShaping("range", GAMMA, terminal=w, terminal_energies=(whole, none), final_speed=1219.0)
    with pytest.raises(ValueError, match="terminal needs final_speed"):
        PotentialShaping("range", GAMMA, terminal=w, terminal_energies=(none, whole))
    with pytest.raises(ValueError, match="terminal must be RewardWeights"):
        PotentialShaping("range", GAMMA, terminal={"miss_per_km": 1.0}, terminal_energies=(none, whole), final_speed=1.0)
    with pytest.raises(ValueError, match="read by the terminal terms alone"):
        PotentialShaping("range", GAMMA, terminal_energies=(none, whole))
    assert late != base and late == PotentialShaping(**{k: getattr(late, k) for k in late.__dataclass_fields__})


def test_bad_shaping_settings_are_refused_with_their_name():
    with pytest.raises(ValueError, match="potential must be one of"):
        PotentialShaping("height", 0.99)
    with pytest.raises(ValueError, match="gamma must be the learner's discount"):
        PotentialShaping("range", 1.5)
    with pytest.raises(ValueError, match="weight must be a finite number > 0"):
        PotentialShaping("range", 0.99, float("nan"))
    with pytest.raises(ValueError, match="needs energies and ranges"):
        PotentialShaping("energy", 0.99)
    with pytest.raises(ValueError, match="increase strictly"):
        PotentialShaping("energy", 0.99, energies=[2.0, 1.0], ranges=[0.0, 1.0])
    with pytest.raises(ValueError, match="fade_energies .* must be finite with e_full > e_zero"):
        PotentialShaping("range", 0.99, fade_energies=(1e6, 2e6))
    with pytest.raises(ValueError, match="fade_energies must be two numbers"):
        PotentialShaping("range", 0.99, fade_energies=1e6)
    with pytest.raises(ValueError, match="less than the reference's 1033.9 s"):
        fade_energies(2000.0)
    with pytest.raises(TypeError, match="PotentialShaping"):
        RvEntryEnv(shaping="range")


def test_the_energy_profile_runs_from_the_target_to_the_entry():
    e, r = energy_range_profile()
    assert np.all(np.diff(e) > 0)
    assert r[0] < 1.0 and 2.7e6 < r[-1] < 2.9e6  # impact at the target; entry 2800 km out
    assert e[0] == pytest.approx(0.5 * 1219.0**2, rel=0.15)  # the impact speed's energy, on the surface
