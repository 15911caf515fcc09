"""Short seeded rollouts of the vector env on each stepper, recorded as arrays.

``tests/envs/data/stepper_rollouts.npz`` holds these rollouts as the vector env flew them before its
stepping was delegated to stepper objects; ``test_steppers`` flies them again and asserts the very
same bits. Regenerate (only where a change is meant to move the episodes) with
``python tests/envs/stepper_rollouts.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).parent / "data" / "stepper_rollouts.npz"
STEPS = 40
INFO_KEYS = ("r_ecef_m", "time_s", "cost", "navigation_state", "miss_km", "failure", "is_success")

# name: (backend, num_envs, constructor keywords, reset options); the numpy cases of 2 copies are
# stepped on floats, those of 5 on arrays
CASES = {
    "floats_flight": ("numpy", 2, {"dispersion": "flight", "max_episode_steps": 15}, {}),
    "floats_standard_same_step": ("numpy", 2, {"dispersion": "standard", "max_episode_steps": 12,
                                              "autoreset_mode": "SameStep"}, {}),
    "arrays_flight": ("numpy", 5, {"dispersion": "flight", "max_episode_steps": 15}, {}),
    "arrays_peer_footprint": ("numpy", 5, {"dispersion": "peer", "targets": "footprint", "max_episode_steps": 12}, {}),
    "arrays_wide_disabled": ("numpy", 5, {"dispersion": "wide", "dt": 50.0, "autoreset_mode": "Disabled"}, {}),
    "jax_flight": ("jax", 3, {"dispersion": "flight", "max_episode_steps": 15}, {}),
    "jax_wide_float32": ("jax", 3, {"dispersion": "wide", "dtype": "float32", "max_episode_steps": 12}, {}),
}


def make(backend: str, n: int, kw: dict):
    import gymnasium as gym

    import rventry_env  # noqa: F401  (registers RvEntry-v0)

    return gym.make_vec("RvEntry-v0", num_envs=n, vectorization_mode="vector_entry_point", backend=backend, **kw)


def rollout(backend: str, n: int, kw: dict, options: dict, seed: int = 11) -> dict[str, np.ndarray]:
    """Observations, rewards, endings and a few info values over ``STEPS`` seeded steps."""
    env = make(backend, n, kw)
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed, options=options or None)
    out = {"obs": [obs], "reward": [], "terminated": [], "truncated": []}
    out.update({k: [info[k]] for k in INFO_KEYS})
    for _ in range(STEPS):
        a = np.column_stack([rng.uniform(-0.4, 0.2, n), rng.uniform(-1, 1, n)]).astype(np.float32)
        obs, r, te, tr, info = env.step(a)
        for k, v in (("obs", obs), ("reward", r), ("terminated", te), ("truncated", tr)):
            out[k].append(v)
        for k in INFO_KEYS:
            out[k].append(info[k])
    return {k: np.array([np.asarray(v) for v in vs], dtype=str if k == "failure" else None) for k, vs in out.items()}


def record() -> None:
    arrays = {}
    for name, case in CASES.items():
        for k, v in rollout(*case).items():
            arrays[f"{name}/{k}"] = v
    FIXTURE.parent.mkdir(exist_ok=True)
    np.savez_compressed(FIXTURE, **arrays)


if __name__ == "__main__":
    record()
