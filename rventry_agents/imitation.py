"""A learned guidance policy imitating the re-planning law (``mpc``), trained by DAgger.

The student is a small network that maps what a vehicle measures to the angles it should fly:

* its input: the env's observation features that describe the translational state (not
  alpha, sigma or what follows from them: the lift shares and the load factor), and the online
  estimate of the aerodynamic scales (ln k_D, ln k_LD) from the sensed acceleration, by the same
  :class:`~rventry_env.guidance.estimation.AeroScaleEstimator` the classical laws use;
* its output: the commanded angle of attack and bank angle (as cos and sin), which a tracker
  (:func:`tracking_rates`) turns into the environment's rates, within their bounds.

The labels are the angles the expert *wants*, a horizon ahead (:class:`Horizon`): for ``mpc``
its current plan's angles then
(:meth:`~rventry_env.guidance.replanning.ReplanningGuidance.planned_angles`), for an expert
without a plan the angles its rates would reach by then. The tracker closes the loop with the
same horizon: rate = (command - current) / horizon, which flies a plan's angle profile exactly
where it is linear over the horizon. Labels one step ahead are mostly the current angles, which
the student does not see: both ``mpc``'s gentle TV-LQR and its plans, which start from the
current angles, keep them there for a second or two. Labelled so, a student that had drifted
learned to drift on. The horizon shortens near the ground, where the final pull-down drives alpha
to zero within seconds and a slow tracker holds it high into the densest air (docs/learned.md).

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

import math
from dataclasses import dataclass

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.task import EntryTask
from rventry_env.envs.observation import feature_names
from rventry_env.guidance.estimation import AeroScaleEstimator
from rventry_env.guidance.law import Law, Measurement
from rventry_env.guidance.load_relief import LoadRelief
from rventry_env.guidance.q_floor import QFloor
from rventry_env.physics import EntryModel

OBSERVATION_NAMES = feature_names()
N_OBS = len(OBSERVATION_NAMES)
# what is recorded: the observation and the scaled log-estimates of the aerodynamic scales
FEATURE_NAMES = (*OBSERVATION_NAMES, "ln_k_drag_x10", "ln_k_lift_to_drag_x10")
N_FEATURES = len(FEATURE_NAMES)
LOG_SCALE_GAIN = 10.0  # ln-scale errors are a few hundredths: x10 puts them on the observation's scale
# observation features that depend on the current alpha or sigma, which the student does not see
ANGLE_FEATURES = tuple(FEATURE_NAMES.index(n) for n in ("alpha", "sin_sigma", "cos_sigma", "lift_up", "lift_right",
                                                        "load_factor"))  # fmt: skip
INPUTS = tuple(i for i in range(N_FEATURES) if i not in ANGLE_FEATURES)
INPUT_NAMES = tuple(FEATURE_NAMES[i] for i in INPUTS)
N_INPUTS = len(INPUTS)


def features(obs: np.ndarray, estimator: AeroScaleEstimator) -> np.ndarray:
    """The recorded features (N, 28): the observation and the scaled log-estimates."""
    return np.concatenate([np.asarray(obs, np.float32), LOG_SCALE_GAIN * estimator.log_scales().astype(np.float32)], axis=1)


@dataclass(frozen=True)
class Horizon:
    """How far ahead the labels look and how fast the tracker closes: the altitude over
    ``descent_mps``, between ``min_s`` and ``max_s``, in whole control steps (at least one).
    The default is one step everywhere: labels of the next step and a deadbeat tracker."""

    max_s: float = 1.0
    min_s: float = 1.0
    descent_mps: float = math.inf

    def __post_init__(self):
        if not (0 < self.min_s <= self.max_s < math.inf and self.descent_mps > 0):
            raise ValueError(f"a horizon needs 0 < min_s <= max_s (finite) and descent_mps > 0, got {self!r}")

    def check_step(self, dt: float) -> None:
        """Raise unless the horizon is at least one control step ``dt`` everywhere."""
        if self.min_s < dt:
            raise ValueError(f"the horizon must be at least one control step ({dt} s), got min_s = {self.min_s}")

    def seconds(self, state: np.ndarray, radius_m: float, dt: float) -> np.ndarray:
        """The horizon (N,) in seconds for vehicles in ``state`` (N, 12) above a planet of ``radius_m``."""
        h = np.asarray(state, dtype=float)[:, IDX.r] - radius_m
        tau = np.clip(h / self.descent_mps, self.min_s, self.max_s)
        return np.maximum(np.rint(tau / dt), 1.0) * dt


def commands_from_angles(angles: np.ndarray, task: EntryTask) -> np.ndarray:
    """The network's outputs (N, 3) for angles (N, 2) = (alpha, sigma) in rad:
    (2 alpha / alpha_max - 1, cos sigma, sin sigma)."""
    a = np.asarray(angles, dtype=float)
    return np.stack([2.0 * a[:, 0] / task.problem.alpha_max - 1.0, np.cos(a[:, 1]), np.sin(a[:, 1])], 1).astype(np.float32)


def reached_angles(state: np.ndarray, rates: np.ndarray, task: EntryTask, ahead_s=None) -> np.ndarray:
    """The angles (N, 2) that ``rates`` (fractions of the bounds) held for ``ahead_s`` (a number or
    one per vehicle; default one step) reach from ``state``, ignoring the angle bounds."""
    p = task.problem
    state = np.asarray(state, dtype=float)
    h = task.dt if ahead_s is None else np.asarray(ahead_s, dtype=float)
    return np.stack([state[:, IDX.alpha] + rates[:, 0] * p.u_alpha_max * h, state[:, IDX.sigma] + rates[:, 1] * p.u_sigma_max * h], 1)


def expert_angles(expert, time_s, state, rates, task: EntryTask, ahead_s=None) -> np.ndarray:
    """The expert's label ``ahead_s`` ahead: its plan's angles when it has a plan, else the angles its rates reach."""
    if hasattr(expert, "planned_angles"):
        return np.asarray(expert.planned_angles(time_s, state, ahead_s), dtype=float)
    return reached_angles(state, rates, task, ahead_s)


def tracking_rates(commands: np.ndarray, state: np.ndarray, task: EntryTask, ahead_s=None) -> np.ndarray:
    """Rates (fractions of the bounds, clipped to [-1, 1]) that reach the commanded angles in
    ``ahead_s`` (a number or one per vehicle; default one step, a deadbeat tracker)."""
    p = task.problem
    h = task.dt if ahead_s is None else np.asarray(ahead_s, dtype=float)
    alpha_c = (commands[:, 0] + 1.0) * p.alpha_max / 2.0
    sigma_c = np.arctan2(commands[:, 2], commands[:, 1])
    d_sigma = (sigma_c - state[:, IDX.sigma] + np.pi) % (2.0 * np.pi) - np.pi
    rates = np.stack([(alpha_c - state[:, IDX.alpha]) / (p.u_alpha_max * h), d_sigma / (p.u_sigma_max * h)], axis=1)
    return np.clip(rates, -1.0, 1.0).astype(np.float32)


class FeatureTracker:
    """Runs the estimator on the accelerometer and builds the student's features, per vehicle."""

    def __init__(self, model: EntryModel | None = None):
        self.estimator = AeroScaleEstimator(model)

    def reset(self, n: int) -> None:
        self.estimator.reset(n)

    def __call__(self, m: Measurement) -> np.ndarray:
        self.estimator.observe(m)
        return features(m.observation, self.estimator)


def make_network(hidden: tuple[int, ...] = (256, 256), members: int = 1):
    """An MLP from the inputs to the commanded angles (:class:`rventry_agents.networks.Student`),
    standardized on both sides (buffers set from the data); with ``members`` > 1, an ensemble of
    such MLPs whose commands are the mean of theirs (each fitted with its own seed: :func:`fit`)."""
    from rventry_agents.networks import build

    return build(N_INPUTS, hidden, members)


class LearnedGuidance(Law):
    """The student as a guidance law (:class:`~rventry_env.guidance.law.GuidanceLaw`).

    :param horizon: the tracker's :class:`Horizon`, as trained (default: one step).
    :param load_relief_margin: when given, the tracker's rates pass through
        :class:`~rventry_env.guidance.load_relief.LoadRelief` with this margin, which caps the
        alpha rate where the load factor predicted one step ahead would pass ``a_max (1 - margin)``;
        :attr:`relief` then reports the capped steps, and :meth:`episode_stats` each episode's
        count of them (``load_relief_steps``), over the calls in which it was flying (the
        measurement's ``flying`` mask).
    :param q_floor_margin: when given, the rates first pass through
        :class:`~rventry_env.guidance.q_floor.QFloor` with this margin, which rolls the lift away
        from the vertical where the coming apex of a climb is predicted below ``q_min (1 + margin)``;
        :meth:`episode_stats` then counts those steps too (``q_floor_steps``).
    """

    retargets = True  # its inputs see the target through the observation's target features

    def __init__(self, network, model: EntryModel | None = None, task: EntryTask | None = None,
                 horizon: Horizon | None = None, load_relief_margin: float | None = None,
                 q_floor_margin: float | None = None):  # fmt: skip
        model = EntryModel() if model is None else model
        self.network = network.eval()
        self.tracker = FeatureTracker(model)
        self.radius = model.planet.radius
        self.task = EntryTask() if task is None else task
        self.horizon = Horizon() if horizon is None else horizon
        self.horizon.check_step(self.task.dt)
        self.load_relief_margin = load_relief_margin
        self.relief = None if load_relief_margin is None else LoadRelief(model, self.task, load_relief_margin)
        self.q_floor_margin = q_floor_margin
        self.q_floor = None if q_floor_margin is None else QFloor(model, self.task, q_floor_margin)

    def reset(self, n_episodes: int) -> None:
        self.tracker.reset(n_episodes)
        for limiter in (self.q_floor, self.relief):
            if limiter is not None:
                limiter.reset(n_episodes)

    def __call__(self, m: Measurement) -> np.ndarray:
        return self.act(self.tracker(m), m.navigation_state, m.sensed_accel_b, m.flying)

    def act(self, f: np.ndarray, state, sensed_accel_b, flying=None) -> np.ndarray:
        """The rates for the recorded features ``f`` (N, 28) of vehicles in ``state`` that sense
        ``sensed_accel_b`` (N, 3); ``flying`` (N,) bool, when given, tells the episodes still
        flying from the frozen copies of ended ones, which the load relief's count leaves out."""
        commands = network_commands(self.network, f)
        state = np.asarray(state, float)
        rates = tracking_rates(commands.astype(float), state, self.task, self.horizon.seconds(state, self.radius, self.task.dt))
        return self.limit(rates, state, sensed_accel_b, flying)

    def limit(self, rates, state, sensed_accel_b, flying=None) -> np.ndarray:
        """The tracker's ``rates`` through the law's limiters: the q floor (the bank rate, and alpha
        where the bank alone cannot hold it), then the load relief (the alpha rate)."""
        for limiter in (self.q_floor, self.relief):
            if limiter is not None:
                rates = limiter(rates, state, sensed_accel_b, count=flying).astype(np.float32)
        return rates

    def episode_stats(self) -> list[dict]:
        """Per episode since :meth:`reset`: ``load_relief_steps``, the steps the load relief capped,
        and ``q_floor_steps``, the steps the q floor took the bank (each only where the law has it)."""
        counts = {name: lim.steps for name, lim in (("load_relief_steps", self.relief), ("q_floor_steps", self.q_floor))
                  if lim is not None}  # fmt: skip
        if not counts:
            return []
        n = len(next(iter(counts.values())))
        return [{name: int(steps[i]) for name, steps in counts.items()} for i in range(n)]


class DAggerLaw(Law):
    """Flies the expert's action with probability ``beta`` per step, else the student's; records
    the student's features and the expert's label (:func:`expert_angles`) at every step."""

    def __init__(self, expert, student: LearnedGuidance | None, beta: float, seed: int, model: EntryModel | None = None,
                 task: EntryTask | None = None, horizon: Horizon | None = None):  # fmt: skip
        model = EntryModel() if model is None else model
        self.expert, self.student, self.beta = expert, student, float(beta)
        self.task = EntryTask() if task is None else task
        self.horizon = Horizon() if horizon is None else horizon
        self.radius = model.planet.radius
        self.tracker = FeatureTracker(model) if student is None else student.tracker
        self.rng = np.random.default_rng(seed)
        self.x, self.y = [], []

    def reset(self, n: int) -> None:
        self.expert.reset(n)
        self.tracker.reset(n)  # the student's own, when there is one

    def __call__(self, m: Measurement) -> np.ndarray:
        a_exp = np.asarray(self.expert(m), np.float32)
        f = self.tracker(m)
        time_s, state = m.time_s, m.navigation_state
        act = a_exp
        if self.student is not None:
            use = self.rng.random(m.n) < self.beta
            act = np.where(use[:, None], a_exp, self.student.act(f, state, m.sensed_accel_b))
        self.x.append(f)
        ahead = self.horizon.seconds(state, self.radius, self.task.dt)
        self.y.append(expert_angles(self.expert, time_s, state, a_exp, self.task, ahead).astype(np.float32))
        return act


def network_bytes(network) -> bytes:
    """A student network as self-describing bytes (architecture, input names, weights)."""
    from rventry_agents.networks import save_bytes

    return save_bytes(network, INPUT_NAMES)


def network_from_bytes(data: bytes, hidden: tuple[int, ...] | None = None, members: int | None = None):
    """A student network from :func:`network_bytes` (``hidden`` and ``members``, when given, are
    checked; a bare state dict of an older run needs them); refused, with the features named, when
    it reads its inputs in another order than this package builds them."""
    from rventry_agents.networks import load_bytes

    return load_bytes(data, INPUT_NAMES, hidden, members)


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
    expert_settings: tuple = ()  # (name, value) pairs of ReplanningSettings on the re-planning expert's preset
    horizon: Horizon | None = None  # the labels' and the tracker's (default one step)
    load_relief_margin: float | None = None  # the student's load relief (default none)
    members: int = 1  # the student's member networks


REPLANNING_EXPERTS = ("mpc", "mpc-flight")


def expert_options(expert: str, settings: tuple = ()) -> tuple:
    """The law options for a re-planning ``expert`` told ``settings`` ((name, value) pairs of
    :class:`~rventry_env.guidance.replanning.ReplanningSettings`): each on top of the expert's own
    preset (``mpc``: the defaults; ``mpc-flight``: :meth:`ReplanningSettings.flight_grade`). A bad
    name or value fails here, naming it."""
    if not settings:
        return ()
    from rventry_env.guidance.replanning import ReplanningSettings

    if expert not in REPLANNING_EXPERTS:
        raise ValueError(f"[expert] settings {sorted(k for k, _ in settings)} apply to the re-planning experts "
                         f"{list(REPLANNING_EXPERTS)} only, not {expert!r}")  # fmt: skip
    made = ReplanningSettings.flight_grade if expert == "mpc-flight" else ReplanningSettings
    return (("settings", made(**dict(settings))),)


def collect_episode(job: CollectJob) -> dict:
    """Fly one DAgger episode (a worker's unit of work): features, expert labels and the outcome."""
    import torch

    from rventry_env.evaluation.parallel import cached_law
    from rventry_env.evaluation.rollout import rollout

    torch.set_num_threads(1)
    expert = cached_law(job.expert, job.task, expert_options(job.expert, job.expert_settings))
    student = None if job.student is None else LearnedGuidance(network_from_bytes(job.student, job.hidden, job.members),
                                                                task=job.task, horizon=job.horizon,
                                                                load_relief_margin=job.load_relief_margin)  # fmt: skip
    law = DAggerLaw(expert, student, job.beta, seed=job.seed, task=job.task, horizon=job.horizon)
    b = rollout(law, seeds=[job.seed], dispersion=job.dispersion, task=job.task)
    return {
        "x": np.concatenate(law.x).astype(np.float32),
        "angles": np.concatenate(law.y).astype(np.float32),
        "success": bool(b.is_success[0]),
        "miss_km": float(b.miss_km[0]),
    }


def collect(jobs: list[CollectJob], workers: int, progress=None, cluster: str | None = None) -> list[dict]:
    """Fly the jobs, on a local process pool when ``workers`` > 1, or on the Dask cluster at
    ``cluster``; results in job order, the same wherever they were flown."""
    from rventry_env.evaluation.parallel import map_tasks

    results: list = [None] * len(jobs)

    def done(i, result):
        results[i] = result
        if progress:
            progress(1)

    map_tasks(collect_episode, [(j,) for j in jobs], workers, done, cluster)
    return results


def fit(network, x: np.ndarray, angles: np.ndarray, epochs: int, batch_size: int, lr: float, seed: int,
        weight_decay: float = 0.0, task: EntryTask | None = None) -> list[float]:  # fmt: skip
    """Regress the network's commands on the expert's, from recorded features ``x`` (N, 28) and
    the expert's angles ``angles`` (N, 2), by mean squared error with Adam; returns the loss per
    epoch (in units of the commands' spread). An ensemble's members are fitted one by one, member
    k with seed ``seed + k``, and the losses are their mean."""
    task = EntryTask() if task is None else task
    return fit_commands(network, x, commands_from_angles(angles, task), epochs, batch_size, lr, seed, weight_decay)


def network_commands(network, x: np.ndarray, batch_size: int = 65_536) -> np.ndarray:
    """A network's (a student's, an ensemble's) commands (N, 3) for recorded features ``x``
    (N, 28), in batches."""
    import torch

    out = []
    with torch.no_grad():
        for i in range(0, len(x), batch_size):
            out.append(network.commands(torch.from_numpy(np.ascontiguousarray(x[i : i + batch_size, INPUTS]))).numpy())
    return np.concatenate(out).astype(np.float32)


def fit_commands(network, x: np.ndarray, commands: np.ndarray, epochs: int, batch_size: int, lr: float, seed: int,
                 weight_decay: float = 0.0) -> list[float]:  # fmt: skip
    """:func:`fit` on target commands (N, 3) (:func:`commands_from_angles`, or a teacher
    network's: :func:`network_commands`) instead of angles."""
    import torch

    from rventry_agents.networks import Ensemble

    if isinstance(network, Ensemble):
        per_member = [fit_commands(m, x, commands, epochs, batch_size, lr, seed + k, weight_decay)
                      for k, m in enumerate(network.members)]  # fmt: skip
        network.eval()
        return [float(v) for v in np.mean(per_member, axis=0)]

    torch.manual_seed(seed)
    xt = torch.from_numpy(np.ascontiguousarray(x[:, INPUTS]))
    yt = torch.from_numpy(np.ascontiguousarray(commands, dtype=np.float32))
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
    "FEATURE_NAMES",
    "INPUTS",
    "INPUT_NAMES",
    "N_FEATURES",
    "CollectJob",
    "DAggerLaw",
    "FeatureTracker",
    "Horizon",
    "LearnedGuidance",
    "collect",
    "commands_from_angles",
    "collect_episode",
    "expert_angles",
    "features",
    "fit",
    "fit_commands",
    "make_network",
    "network_bytes",
    "network_commands",
    "network_from_bytes",
    "reached_angles",
    "tracking_rates",
]  # fmt: skip
