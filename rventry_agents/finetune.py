"""PPO from the imitation student: the student's network as the actor's starting point.

The DAgger student (:mod:`rventry_agents.imitation`) maps what a vehicle measures to commanded
angles, and a tracker with load relief turns them into rates. PPO fine-tuning keeps that whole
structure and lets PPO move only the network:

* :class:`StudentVecEnv` presents the task to PPO in the student's own terms: the observation is
  the student's input (the observation features without the angle-dependent ones, and the
  accelerometer's log-scale estimates), standardized with the student's statistics; the action is
  the student's output, standardized the same way, which the wrapper turns into rates with the
  student's tracker and load relief;
* :func:`init_actor_from_student` copies the student's layers into the PPO actor (an MLP of the
  same widths with tanh), so the deterministic policy at step 0 *is* the student;
* :class:`ActorCommands` is the other direction: a PPO policy's deterministic actor as a network
  with ``commands()``, which :class:`~rventry_agents.imitation.LearnedGuidance` flies like the
  student's own.

The reward is the environment's, with its success bonus. The critic starts untrained: a
``critic_warmup_steps`` phase trains the value function alone, with the actor frozen, before the
actor moves (a warm-started actor with a random critic takes its first updates from noise), and
``target_kl`` stops an update that overshoots the trust region.

With ``[policy] privileged_critic = true`` the critic also sees what the vehicle cannot measure
(an asymmetric actor-critic): :func:`privileged_features` appends the draw's effect at the true
state (the navigation error, and the density, dynamic pressure, lift and drag against the
nominal model's) to PPO's observation, :class:`PrivilegedCriticPolicy` feeds the actor only the
student's inputs and the critic all of them. Only training sees these features: the trained
actor flies on the student's inputs alone.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import MlpExtractor
from stable_baselines3.common.vec_env import VecEnvWrapper
from torch import nn

from rventry_agents.imitation import INPUTS, LOG_SCALE_GAIN, LearnedGuidance, tracking_rates
from rventry_agents.records import FineTunedSpec
from rventry_env.guidance.law import Measurement

ACTION_BOUND = 8.0  # standardized commands: the student's outputs lie within a few of their spreads
PRIVILEGED = ("nav_altitude_error_km", "nav_position_error_km", "nav_speed_error_10mps", "log_density_factor",
              "log_dynamic_pressure_factor", "log_lift_factor", "log_drag_factor")  # fmt: skip
LOG_FACTOR_BOUND = 3.0  # the log factors are clipped to +-3 (a factor of 20): beyond, the vehicle is lost anyway


def privileged_features(venv) -> np.ndarray:
    """(N, 7) float32, :data:`PRIVILEGED`: what the draw does at each vehicle's true state.

    The navigation's errors (altitude and position in km, speed in units of 10 m/s) and the log
    ratios of the true density, dynamic pressure, lift and drag accelerations (the copy's own
    atmosphere, winds, aerodynamics and mass) to the nominal model's at the same true state.

    :param venv: an :class:`~rventry_agents.sb3_vec.RvEntrySB3VecEnv` (NumPy backend).
    """
    from rventry_env.core.backend import NUMPY
    from rventry_env.core.conversions import cartesian_from_rv_euler
    from rventry_env.physics.entry import entry_forces

    x, nav = venv.true_state, venv.navigation_state
    true = venv.venv.true_forces
    nominal = entry_forces(tuple(x.T), venv.venv.model, NUMPY)
    r_true, _ = cartesian_from_rv_euler(x)
    r_nav, _ = cartesian_from_rv_euler(nav)

    def log_ratio(a, b):
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.log(np.asarray(a, float) / np.asarray(b, float))
        return np.clip(np.nan_to_num(v, nan=0.0), -LOG_FACTOR_BOUND, LOG_FACTOR_BOUND)

    cols = [(nav[:, 0] - x[:, 0]) / 1000.0, np.linalg.norm(r_nav - r_true, axis=1) / 1000.0, (nav[:, 5] - x[:, 5]) / 10.0,
            log_ratio(true.density, nominal.density), log_ratio(true.dynamic_pressure, nominal.dynamic_pressure),
            log_ratio(true.lift_accel, nominal.lift_accel), log_ratio(true.drag_accel, nominal.drag_accel)]  # fmt: skip
    return np.stack(cols, axis=1).astype(np.float32)


class StudentScales:
    """The student's standardization: inputs (mean, std) and commands (out_mean, out_scale)."""

    def __init__(self, mean, std, out_mean, out_scale):
        self.mean, self.std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
        self.out_mean, self.out_scale = np.asarray(out_mean, np.float32), np.asarray(out_scale, np.float32)

    @classmethod
    def of(cls, network) -> "StudentScales":
        """The scales of a single student network (an ensemble has one per member: distil it first)."""
        from rventry_agents.networks import Student

        if not isinstance(network, Student):
            raise ValueError(f"PPO starts from one student network, not a {type(network).__name__}; distil an "
                             "ensemble into one first ([distil] in the DAgger config)")  # fmt: skip
        return cls(*(getattr(network, k).detach().numpy() for k in ("mean", "std", "out_mean", "out_scale")))

    def as_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("mean", "std", "out_mean", "out_scale")}

    def inputs(self, f: np.ndarray) -> np.ndarray:
        """The standardized inputs (N, n_inputs) from recorded features ``f`` (N, 28)."""
        return ((f[:, INPUTS] - self.mean) / self.std).astype(np.float32)

    def commands(self, a: np.ndarray) -> np.ndarray:
        """Commands (N, 3) from standardized actions."""
        return np.asarray(a, np.float32) * self.out_scale + self.out_mean


class StudentVecEnv(VecEnvWrapper):
    """PPO's view of the task in the student's terms (see the module docstring).

    :param venv: an :class:`~rventry_agents.sb3_vec.RvEntrySB3VecEnv` (its raw observations, the
        states and the sensors of every copy).
    :param law: the student's law: its tracker horizon and load relief (its network is not used).
    :param scales: the student's standardization.
    :param privileged: append :func:`privileged_features` to the observation (for a
        :class:`PrivilegedCriticPolicy`); the first ``len(scales.mean)`` columns stay the student's inputs.
    """

    def __init__(self, venv, law: LearnedGuidance, scales: StudentScales, privileged: bool = False):
        n = len(scales.mean) + (len(PRIVILEGED) if privileged else 0)
        obs_space = spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)
        act_space = spaces.Box(-ACTION_BOUND, ACTION_BOUND, shape=(3,), dtype=np.float32)
        super().__init__(venv, observation_space=obs_space, action_space=act_space)
        self.law, self.scales, self.privileged = law, scales, bool(privileged)
        self._f = None
        self._extra = None

    def _observation(self, inputs: np.ndarray) -> np.ndarray:
        if not self.privileged:
            return inputs
        self._extra = privileged_features(self.venv)
        return np.concatenate([inputs, self._extra], axis=1)

    def _measure(self, obs: np.ndarray) -> Measurement:
        info = self.venv.last_infos
        return Measurement.of(obs, info["time_s"], self.venv.navigation_state, info["sensed_accel_b"])

    def reset(self):
        obs = self.venv.reset()
        self.law.reset(self.num_envs)
        self._f = self.law.tracker(self._measure(obs))
        return self._observation(self.scales.inputs(self._f))

    def step_async(self, actions: np.ndarray) -> None:
        state = self.venv.navigation_state  # what the law flies by in evaluation, never the truth
        info = self.venv.last_infos
        rates = tracking_rates(self.scales.commands(actions).astype(float), state, self.law.task,
                               self.law.horizon.seconds(state, self.law.radius, self.law.task.dt))  # fmt: skip
        self.venv.step_async(self.law.limit(rates, state, info["sensed_accel_b"]))

    def step_wait(self):
        obs, reward, dones, infos = self.venv.step_wait()
        estimator = self.law.tracker.estimator
        ended = np.nonzero(dones)[0]
        if ended.size:
            # the terminal observation with the estimates the episode ended with, then fresh filters
            final = np.stack([infos[i]["terminal_observation"] for i in ended])
            logs = (LOG_SCALE_GAIN * estimator.log_scales()[ended]).astype(np.float32)
            term = self.scales.inputs(np.concatenate([final.astype(np.float32), logs], axis=1))
            if self.privileged:  # the true state at the end is gone (reset): the last step's features stand in
                term = np.concatenate([term, self._extra[ended]], axis=1)
            for j, i in enumerate(ended):
                infos[i]["terminal_observation"] = term[j]
            estimator.reset_rows(ended)
        self._f = self.law.tracker(self._measure(obs))
        return self._observation(self.scales.inputs(self._f)), reward, dones, infos


class SplitMlpExtractor(nn.Module):
    """SB3's actor and critic MLPs on different inputs: the actor the first ``n_actor`` features,
    the critic all of them."""

    def __init__(self, feature_dim: int, n_actor: int, net_arch: dict, activation_fn, device):
        super().__init__()
        self.n_actor = int(n_actor)
        actor = MlpExtractor(self.n_actor, {"pi": list(net_arch["pi"]), "vf": []}, activation_fn, device)
        critic = MlpExtractor(feature_dim, {"pi": [], "vf": list(net_arch["vf"])}, activation_fn, device)
        self.policy_net, self.value_net = actor.policy_net, critic.value_net
        self.latent_dim_pi, self.latent_dim_vf = actor.latent_dim_pi, critic.latent_dim_vf

    def forward(self, features):
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features):
        return self.policy_net(features[..., : self.n_actor])

    def forward_critic(self, features):
        return self.value_net(features)


class PrivilegedCriticPolicy(ActorCriticPolicy):
    """An asymmetric actor-critic: SB3's ``MlpPolicy`` whose actor sees the first
    ``n_actor_inputs`` observation columns (the student's inputs) and whose critic sees all of
    them (with :func:`privileged_features`)."""

    def __init__(self, *args, n_actor_inputs: int, **kwargs):
        self.n_actor_inputs = int(n_actor_inputs)
        super().__init__(*args, **kwargs)

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = SplitMlpExtractor(self.features_dim, self.n_actor_inputs, self.net_arch,
                                               self.activation_fn, self.device)  # fmt: skip

    def _get_constructor_parameters(self) -> dict:
        return {**super()._get_constructor_parameters(), "n_actor_inputs": self.n_actor_inputs}


def init_actor_from_student(policy, network) -> None:
    """Copy the student's layers into an SB3 ``ActorCriticPolicy`` of the same widths (tanh): the
    actor's mean is then the student's standardized commands."""
    import torch
    from torch import nn

    body = [m for m in network.body if isinstance(m, nn.Linear)]
    actor = [m for m in policy.mlp_extractor.policy_net if isinstance(m, nn.Linear)] + [policy.action_net]
    if [tuple(m.weight.shape) for m in body] != [tuple(m.weight.shape) for m in actor]:
        raise ValueError(f"the PPO actor's layers {[tuple(m.weight.shape) for m in actor]} do not match the "
                         f"student's {[tuple(m.weight.shape) for m in body]}: give [policy] net_arch the student's widths")
    with torch.no_grad():
        for src, dst in zip(body, actor):
            dst.weight.copy_(src.weight)
            dst.bias.copy_(src.bias)


def set_actor_trainable(policy, trainable: bool) -> None:
    """Freeze or free the actor (its layers and the action noise); the critic always trains."""
    for module in (policy.mlp_extractor.policy_net, policy.action_net):
        for p in module.parameters():
            p.requires_grad_(trainable)
    policy.log_std.requires_grad_(trainable)


class ActorCommands:
    """A PPO policy's deterministic actor as a student network: ``commands(x)`` for the inputs
    ``x`` (N, n_inputs) in their own units, for :class:`~rventry_agents.imitation.LearnedGuidance`."""

    def __init__(self, policy, scales: StudentScales):
        import torch

        self.policy, self.scales = policy, scales
        self._mean, self._std = torch.from_numpy(scales.mean), torch.from_numpy(scales.std)
        self._out_mean, self._out_scale = torch.from_numpy(scales.out_mean), torch.from_numpy(scales.out_scale)

    def eval(self):
        self.policy.set_training_mode(False)
        return self

    def commands(self, x):
        z = (x - self._mean) / self._std
        latent = self.policy.mlp_extractor.forward_actor(self.policy.extract_features(z, self.policy.pi_features_extractor))
        return self.policy.action_net(latent) * self._out_scale + self._out_mean


def load_start(start: str, task, q_floor_margin: float | None = None) -> LearnedGuidance:
    """The student PPO starts from: an agent name (``dagger``) or a DAgger run's directory.

    :param q_floor_margin: when given, the student's law flies a q floor of this margin in
        training (the student's own, if any, is replaced): PPO then learns the policy that the
        floor completes, and the fine-tuned policy flies the same floor (``policy.json``).
    """
    from rventry_env.evaluation.agents import load_agent
    from rventry_env.guidance.q_floor import QFloor

    law = load_agent(start, task)
    if not isinstance(law, LearnedGuidance):
        raise ValueError(f"PPO fine-tuning starts from an imitation student (the agent 'dagger' or a DAgger run), "
                         f"not {start!r} ({type(law).__name__})")  # fmt: skip
    if q_floor_margin is not None:
        margin = QFloor(task=task, margin=q_floor_margin).margin  # a bad margin fails here, naming itself
        law = LearnedGuidance(law.network, task=task, horizon=law.horizon, load_relief_margin=law.load_relief_margin,
                              q_floor_margin=margin)  # fmt: skip
    return law


def student_spec(law: LearnedGuidance, scales: StudentScales, start: str) -> FineTunedSpec:
    """How to fly a fine-tuned policy (``policy.json``'s ``student``): the student it started from (its
    name and the SHA-256 of its saved weights, which name one network when a name is shipped anew),
    its standardization, its tracker horizon, its load relief and its q floor."""
    import hashlib

    from rventry_agents.imitation import network_bytes
    from rventry_agents.records import horizon_keys

    return FineTunedSpec.from_dict({
        "start": start, "start_sha256": hashlib.sha256(network_bytes(law.network)).hexdigest(),
        "scales": scales.as_dict(), **horizon_keys(law.horizon, "tracking"),
        "load_relief_margin": law.load_relief_margin, "q_floor_margin": law.q_floor_margin,
    }, "the student's spec")  # fmt: skip


def fine_tuned_law(policy, spec: FineTunedSpec | dict, task) -> LearnedGuidance:
    """A PPO policy trained from a student (``spec`` from :func:`student_spec`, or its dict) as a guidance law."""
    spec = FineTunedSpec.from_dict(spec, "the student's spec")
    scales = StudentScales(**spec.scales.to_dict())
    return LearnedGuidance(ActorCommands(policy, scales), task=task, **spec.law(task))


__all__ = ["ACTION_BOUND", "PRIVILEGED", "ActorCommands", "PrivilegedCriticPolicy", "StudentScales", "StudentVecEnv",
           "fine_tuned_law", "init_actor_from_student", "load_start", "privileged_features", "set_actor_trainable",
           "student_spec"]  # fmt: skip
