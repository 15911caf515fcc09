"""A learned guidance policy imitating the re-planning law (``mpc``), trained by DAgger.

The student is a small network that maps what a vehicle measures to the angles it should fly:

* its input: the env's observation features that describe the translational state (not
  alpha, sigma or what follows from them: the lift shares and the load factor), and the online
  estimate of the aerodynamic scales (ln k_D, ln k_LD) from the sensed acceleration, by the same
  :class:`~rventry_env.guidance.estimation.AeroScaleEstimator` the classical laws use;
* its output: the commanded angle of attack and bank angle (as cos and sin), which a deadbeat
  tracker turns into the environment's rates, within their bounds.

Commanding angles instead of rates is what made imitation work at all: a network that outputs
rates must learn the expert's feedback on alpha and sigma from data in which they never
deviate, and drifts (docs/learned.md).

Training is DAgger (Ross, Gordon and Bagnell, 2011): fly episodes in which each step's action is
the expert's with probability beta and the student's otherwise, label *every* visited state
with the expert's action, aggregate, and refit the student by regression. The expert is the
``mpc`` law run alongside the student on the same vehicle, so it re-plans from the states the
student leads it into. Regression on expert labels is supervised learning, not an RL algorithm;
the network is plain torch.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from rventry_env.envs.task import EntryTask
from rventry_env.guidance.estimation import AeroScaleEstimator
from rventry_env.physics import EntryModel

N_OBS = 26
N_FEATURES = N_OBS + 2  # what is recorded: the observation and the scaled log-estimates
LOG_SCALE_GAIN = 10.0  # ln-scale errors are a few hundredths: x10 puts them on the observation's scale
# observation features that depend on the current alpha or sigma: alpha, sin/cos sigma, the two
# lift shares, the load factor
ANGLE_FEATURES = (11, 12, 13, 14, 15, 25)
INPUTS = tuple(i for i in range(N_FEATURES) if i not in ANGLE_FEATURES)
N_INPUTS = len(INPUTS)


def features(obs: np.ndarray, estimator: AeroScaleEstimator) -> np.ndarray:
    """The recorded features (N, 28): the observation and the scaled log-estimates."""
    return np.concatenate([np.asarray(obs, np.float32), LOG_SCALE_GAIN * estimator.log_scales().astype(np.float32)], axis=1)


def angle_targets(x: np.ndarray, rates: np.ndarray, task: EntryTask) -> np.ndarray:
    """The expert's commanded angles (N, 3): (2 alpha_c / alpha_max - 1, cos sigma_c, sin sigma_c),
    where alpha_c, sigma_c are the angles its rates ``rates`` (fractions of the bounds) reach in one step."""
    p = task.problem
    alpha = (x[:, 11].astype(float) + 1.0) * p.alpha_max / 2.0
    sigma = np.arctan2(x[:, 12], x[:, 13]).astype(float)
    alpha_c = alpha + rates[:, 0] * p.u_alpha_max * task.dt
    sigma_c = sigma + rates[:, 1] * p.u_sigma_max * task.dt
    return np.stack([2.0 * alpha_c / p.alpha_max - 1.0, np.cos(sigma_c), np.sin(sigma_c)], axis=1).astype(np.float32)


def deadbeat_rates(commands: np.ndarray, state: np.ndarray, task: EntryTask) -> np.ndarray:
    """Rates (fractions of the bounds, clipped to [-1, 1]) that reach the commanded angles in one step."""
    p = task.problem
    alpha_c = (commands[:, 0] + 1.0) * p.alpha_max / 2.0
    sigma_c = np.arctan2(commands[:, 2], commands[:, 1])
    d_sigma = (sigma_c - state[:, 11] + np.pi) % (2.0 * np.pi) - np.pi
    rates = np.stack([(alpha_c - state[:, 10]) / (p.u_alpha_max * task.dt), d_sigma / (p.u_sigma_max * task.dt)], axis=1)
    return np.clip(rates, -1.0, 1.0).astype(np.float32)


class FeatureTracker:
    """Runs the estimator on the accelerometer and builds the student's features, per vehicle."""

    def __init__(self, model: EntryModel | None = None):
        self.estimator = AeroScaleEstimator(model)

    def reset(self, n: int) -> None:
        self.estimator.reset(n)

    def __call__(self, obs, time_s, state, sensed_accel_b) -> np.ndarray:
        if sensed_accel_b is None:
            raise ValueError("the learned policy needs the sensed acceleration (info['sensed_accel_b'])")
        if self.estimator.n != len(state):
            self.estimator.reset(len(state))
        self.estimator.update(time_s, state, sensed_accel_b)
        return features(obs, self.estimator)


def make_network(hidden: tuple[int, ...] = (256, 256)):
    """An MLP from the inputs to the commanded angles, standardized on both sides (buffers set
    from the data)."""
    import torch
    from torch import nn

    class Student(nn.Module):
        def __init__(self):
            super().__init__()
            self.register_buffer("mean", torch.zeros(N_INPUTS))
            self.register_buffer("std", torch.ones(N_INPUTS))
            self.register_buffer("out_mean", torch.zeros(3))
            self.register_buffer("out_scale", torch.ones(3))
            layers, width = [], N_INPUTS
            for h in hidden:
                layers += [nn.Linear(width, h), nn.Tanh()]
                width = h
            layers += [nn.Linear(width, 3)]
            self.body = nn.Sequential(*layers)

        def forward(self, x):
            """The commands, standardized; :meth:`commands` gives them in their own units."""
            return self.body((x - self.mean) / self.std)

        def commands(self, x):
            return self.forward(x) * self.out_scale + self.out_mean

    return Student()


class LearnedGuidance:
    """The student as a guidance law: ``law(obs, time_s, state, sensed_accel_b) -> actions``."""

    uses_sensed_acceleration = True

    def __init__(self, network, model: EntryModel | None = None, task: EntryTask | None = None):
        import torch

        self.network = network.eval()
        self.tracker = FeatureTracker(model)
        self.task = EntryTask() if task is None else task
        self._torch = torch

    def reset(self, n_episodes: int) -> None:
        self.tracker.reset(n_episodes)

    def __call__(self, obs, time_s, state, sensed_accel_b=None):
        return self.act(self.tracker(obs, time_s, state, sensed_accel_b), state)

    def act(self, f: np.ndarray, state) -> np.ndarray:
        """The rates for the recorded features ``f`` (N, 28) of vehicles in ``state``."""
        with self._torch.no_grad():
            commands = self.network.commands(self._torch.from_numpy(np.ascontiguousarray(f[:, INPUTS]))).numpy()
        return deadbeat_rates(commands.astype(float), np.asarray(state, float), self.task)


class DAggerLaw:
    """Flies the expert's action with probability ``beta`` per step, else the student's; records
    the student's features and the expert's action at every step."""

    uses_sensed_acceleration = True

    def __init__(self, expert, student: LearnedGuidance | None, beta: float, seed: int, model: EntryModel | None = None):
        self.expert, self.student, self.beta = expert, student, float(beta)
        self.tracker = FeatureTracker(model) if student is None else student.tracker
        self.rng = np.random.default_rng(seed)
        self.x, self.y = [], []

    def reset(self, n: int) -> None:
        self.expert.reset(n)
        self.tracker.reset(n)  # the student's own, when there is one

    def __call__(self, obs, time_s, state, sensed_accel_b=None):
        a_exp = np.asarray(self.expert(obs, time_s, state, sensed_accel_b=sensed_accel_b), np.float32)
        f = self.tracker(obs, time_s, state, sensed_accel_b)
        act = a_exp
        if self.student is not None:
            use = self.rng.random(len(obs)) < self.beta
            act = np.where(use[:, None], a_exp, self.student.act(f, state))
        self.x.append(f)
        self.y.append(a_exp)
        return act


def network_bytes(network) -> bytes:
    import torch

    buf = io.BytesIO()
    torch.save(network.state_dict(), buf)
    return buf.getvalue()


def network_from_bytes(data: bytes, hidden: tuple[int, ...]):
    import torch

    net = make_network(hidden)
    net.load_state_dict(torch.load(io.BytesIO(data), weights_only=True))
    return net


@dataclass(frozen=True)
class CollectJob:
    """One DAgger episode: which vehicle, which student (None: the expert alone) and beta."""

    seed: int
    dispersion: object
    beta: float
    student: bytes | None
    hidden: tuple[int, ...]
    task: EntryTask
    expert: str = "mpc"
    expert_settings: tuple = ()  # (name, value) pairs of ReplanningSettings for the mpc expert


_EXPERT = {}


def collect_episode(job: CollectJob) -> dict:
    """Fly one DAgger episode (a worker's unit of work): features, expert labels and the outcome."""
    import torch

    from rventry_env.evaluation.agents import load_agent
    from rventry_env.evaluation.rollout import rollout

    torch.set_num_threads(1)
    key = (job.expert, job.task, job.expert_settings)
    if key not in _EXPERT:  # built once per process (mpc: its transcription)
        options = {}
        if job.expert_settings:
            from rventry_env.guidance.replanning import ReplanningSettings

            options["settings"] = ReplanningSettings(**dict(job.expert_settings))
        _EXPERT[key] = load_agent(job.expert, job.task, **options)
    student = None if job.student is None else LearnedGuidance(network_from_bytes(job.student, job.hidden))
    law = DAggerLaw(_EXPERT[key], student, job.beta, seed=job.seed)
    b = rollout(law, seeds=[job.seed], dispersion=job.dispersion, task=job.task)
    return {
        "x": np.concatenate(law.x).astype(np.float32),
        "y": np.concatenate(law.y).astype(np.float32),
        "success": bool(b.is_success[0]),
        "miss_km": float(b.miss_km[0]),
    }


def collect(jobs: list[CollectJob], workers: int, progress=None) -> list[dict]:
    """Fly the jobs, on a local process pool when ``workers`` > 1; results in job order."""
    from rventry_env.evaluation.parallel import map_local

    results: list = [None] * len(jobs)

    def done(i, result):
        results[i] = result
        if progress:
            progress(1)

    map_local(collect_episode, [(j,) for j in jobs], workers, done)
    return results


def fit(network, x: np.ndarray, y: np.ndarray, epochs: int, batch_size: int, lr: float, seed: int,
        weight_decay: float = 0.0, task: EntryTask | None = None) -> list[float]:  # fmt: skip
    """Regress the network's commands on the expert's, from recorded features ``x`` (N, 28) and
    expert rates ``y`` (N, 2), by mean squared error with Adam; returns the loss per epoch
    (in units of the commands' spread)."""
    import torch

    torch.manual_seed(seed)
    task = EntryTask() if task is None else task
    xt = torch.from_numpy(np.ascontiguousarray(x[:, INPUTS]))
    yt = torch.from_numpy(angle_targets(x, y, task))
    with torch.no_grad():
        network.mean.copy_(xt.mean(0))
        network.std.copy_(xt.std(0).clamp_min(1e-3))
        network.out_mean.copy_(yt.mean(0))
        network.out_scale.copy_(yt.std(0).clamp_min(1e-4))
    yt = (yt - network.out_mean) / network.out_scale
    opt = torch.optim.Adam(network.parameters(), lr=lr, weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs)
    gen = torch.Generator().manual_seed(seed)
    losses = []
    network.train()
    for _ in range(epochs):
        perm = torch.randperm(len(xt), generator=gen)
        total = 0.0
        for i in range(0, len(xt), batch_size):
            idx = perm[i : i + batch_size]
            loss = torch.mean((network(xt[idx]) - yt[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        sched.step()
        losses.append(total / len(xt))
    network.eval()
    return losses


__all__ = [
    "INPUTS",
    "N_FEATURES",
    "CollectJob",
    "DAggerLaw",
    "FeatureTracker",
    "LearnedGuidance",
    "angle_targets",
    "collect",
    "collect_episode",
    "deadbeat_rates",
    "features",
    "fit",
    "make_network",
    "network_bytes",
    "network_from_bytes",
]  # fmt: skip
