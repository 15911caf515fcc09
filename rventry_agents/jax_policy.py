"""A policy trained in JAX (rejax PPO), flown as a guidance law in NumPy.

The training run exports the actor (:func:`export_actor`) to ``policy.npz``: the observation
statistics it normalized with, the hidden layers' weights, the mean head's and the exploration
noise it ended with. :class:`JaxPolicy` flies it deterministically, as evaluation should: each
decision normalizes the observation as training did, runs the tanh network, and returns the
mean action clipped to the environment's bounds. NumPy only: flying a shipped policy needs
neither JAX nor the training library.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rventry_agents.commands import ACTIONS, check_actions, policy_actions
from rventry_env.guidance.law import Law, Measurement
from rventry_env.task import EntryTask

ACTIVATIONS = {"tanh": np.tanh, "relu": lambda z: np.maximum(z, 0.0)}
NORM_EPS = 1e-8  # rejax's observation normalization: (obs - mean) / sqrt(var + 1e-8)


def export_actor(path: str | Path, actor_params: dict, obs_mean, obs_var, activation: str, actions: str = "rates",
                 command_time_s: float = 1.0) -> Path:  # fmt: skip
    """Write the actor of a rejax PPO training state (its ``actor_ts.params``) to ``path`` (.npz), whole or
    not at all; ``actions`` says what its outputs are (:data:`~rventry_agents.commands.ACTIONS`), and
    ``command_time_s`` the attitude commands' time constant."""
    from rventry_env.util.files import atomic_write

    p = actor_params["params"]
    hidden = p["features"]
    layers = {}
    for i in range(len(hidden)):
        layer = hidden[f"Dense_{i}"]
        layers[f"kernel_{i}"] = np.asarray(layer["kernel"], dtype=np.float64)
        layers[f"bias_{i}"] = np.asarray(layer["bias"], dtype=np.float64)
    arrays = dict(
        obs_mean=np.asarray(obs_mean, np.float64), obs_var=np.asarray(obs_var, np.float64),
        mean_kernel=np.asarray(p["action_mean"]["kernel"], np.float64),
        mean_bias=np.asarray(p["action_mean"]["bias"], np.float64),
        log_std=np.asarray(p["action_log_std"], np.float64), activation=np.array(activation),
        actions=np.array(check_actions(actions)), command_time_s=np.array(float(command_time_s)), **layers,
    )  # fmt: skip
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object: np.savez would add .npz to a bare path
            np.savez(f, **arrays)

    return atomic_write(path, write)


class JaxPolicy(Law):
    """An exported actor (``policy.npz``) as a deterministic guidance law.

    :param path: the ``policy.npz``, or a run or shipped directory holding it (with its
        ``metadata.json``, whose provenance and training task are read).
    :param task: the task to fly; a policy is refused, naming the difference, on a task with
        another control step or substeps than it was trained with.
    """

    retargets = True  # it aims where the observation's target features point

    def __init__(self, path: str | Path, task: EntryTask | None = None):
        path = Path(path)
        folder = path if path.is_dir() else path.parent
        path = path / "policy.npz" if path.is_dir() else path
        if not path.is_file():
            raise FileNotFoundError(f"no exported policy at {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError) as exc:
            raise ValueError(f"{path} is not an exported policy ({type(exc).__name__}: {exc})") from None
        self.task = EntryTask() if task is None else task
        self.layers, self.obs_mean, self.obs_scale, self.head, self.act = _network(data, path)
        self.outputs = str(data["actions"]) if "actions" in data else "rates"
        self.command_time_s = float(data["command_time_s"]) if "command_time_s" in data else self.task.dt
        if self.outputs not in ACTIONS:
            raise ValueError(f"{path}: unknown actions {self.outputs!r}; known: {ACTIONS}")
        meta = folder / "metadata.json"
        self.metadata = _read_json(meta) if meta.is_file() else {}
        trained = self.metadata.get("task")
        if trained is not None:
            self.task.check_trained(trained, f"the policy {path}")
        self.provenance = self.metadata.get("provenance")

    def actions(self, obs: np.ndarray) -> np.ndarray:
        """The environment's actions (N, 2) for observations (N, 26): the network's mean output,
        flown as attitude commands where the policy gives them."""
        obs = np.asarray(obs, np.float64)
        z = (obs - self.obs_mean) / self.obs_scale
        for kernel, bias in self.layers:
            z = self.act(z @ kernel + bias)
        out = z @ self.head[0] + self.head[1]  # clipped where the map clips it (policy_actions)
        return policy_actions(obs, out, self.outputs, self.task, np, self.command_time_s).astype(np.float32)

    def __call__(self, m: Measurement) -> np.ndarray:
        return self.actions(m.observation)


_DATA = Path(__file__).resolve().parent / "data"
# agent name -> shipped run: the staged recipe on `standard` (ppo_scratch.toml), the same run with
# one stage more on `wide` (ppo_scratch_wide.toml), and that one with one stage more on `flight`
# (ppo_scratch_flight.toml); and one run of the landing recipe (ppo_scratch_landing.toml), one config from
# step 0 in two hours of its own clock
SHIPPED = {"ppo-scratch": _DATA / "ppo_scratch", "ppo-scratch-wide": _DATA / "ppo_scratch_wide",
           "ppo-scratch-flight": _DATA / "ppo_scratch_flight", "ppo-scratch-2h": _DATA / "ppo_scratch_2h"}


def load_shipped(name: str = "ppo-scratch", task: EntryTask | None = None) -> JaxPolicy:
    """A policy trained in JAX and shipped with this package (the entry points named in ``SHIPPED``)."""
    if name not in SHIPPED:
        raise ValueError(f"no shipped JAX-trained policy named {name!r}; shipped: {', '.join(SHIPPED)}")
    if not (SHIPPED[name] / "policy.npz").is_file():
        raise FileNotFoundError(f"the shipped policy {name} is missing from {SHIPPED[name]}")
    return JaxPolicy(SHIPPED[name], task)


def load_saved(path: str, task: EntryTask | None = None) -> JaxPolicy:
    """An exported policy or a ``rventry train ppo-scratch`` run folder (entry point ``rventry.agent_files``)."""
    p = Path(path)
    if not (p.suffix == ".npz" or (p / "policy.npz").is_file()):
        raise ValueError(f"{p} is not a policy trained in JAX (no policy.npz)")
    return JaxPolicy(p, task)


def _network(data: dict, path: Path):
    """The layers, normalization, head and activation of an exported actor, checked."""
    need = {"obs_mean", "obs_var", "mean_kernel", "mean_bias", "activation", "kernel_0", "bias_0"}
    missing = sorted(need - set(data))
    if missing:
        raise ValueError(f"{path} is not an exported policy: it lacks {', '.join(missing)}")
    activation = str(data["activation"])
    if activation not in ACTIVATIONS:
        raise ValueError(f"{path}: unknown activation {activation!r}; known: {sorted(ACTIVATIONS)}")
    layers, i, width = [], 0, data["obs_mean"].shape[-1]
    while f"kernel_{i}" in data:
        kernel, bias = data[f"kernel_{i}"], data[f"bias_{i}"]
        if kernel.ndim != 2 or kernel.shape[0] != width or bias.shape != (kernel.shape[1],):
            raise ValueError(f"{path}: layer {i} has shapes {kernel.shape} and {bias.shape}, which do not chain")
        layers.append((kernel, bias))
        width, i = kernel.shape[1], i + 1
    head = (data["mean_kernel"], data["mean_bias"])
    if head[0].shape != (width, 2) or head[1].shape != (2,):
        raise ValueError(f"{path}: the action head has shape {head[0].shape}, expected ({width}, 2)")
    arrays = [data["obs_mean"], data["obs_var"], *(a for pair in layers for a in pair), *head]
    if not all(np.all(np.isfinite(a)) for a in arrays) or np.any(data["obs_var"] < 0):
        raise ValueError(f"{path}: the policy holds NaN, infinite or negative-variance numbers")
    return layers, data["obs_mean"], np.sqrt(data["obs_var"] + NORM_EPS), head, ACTIVATIONS[activation]


def _read_json(path: Path) -> dict:
    try:
        value = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path} is not readable JSON ({exc})") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path} must hold a JSON object, got {type(value).__name__}")
    return value


__all__ = ["SHIPPED", "JaxPolicy", "export_actor", "load_saved", "load_shipped"]
