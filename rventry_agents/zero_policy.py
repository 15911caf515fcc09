"""An SB3 actor-critic whose action mean is exactly zero on the reference.

For the residual guidance of :mod:`rventry_agents.residual` the observation is
``[o, d]``: the raw features and the (scaled) deviation from the reference.
This policy's mean action is

    mu(o, d) = a(o, d) - a(o, 0)

for the usual MLP actor ``a``, so a vehicle exactly on the reference gets no
correction whatever the weights are. Why: this trajectory is so sensitive that
a constant residual of 0.02 (0.9 deg of bank) moves the impact by ~265 km, and
with an ordinary actor the weights random-walk under noisy advantages into
exactly such a bias (measured: dispersed mean miss 222 km with no correction,
655 km after 0.5M PPO steps). With the subtraction, drift can only change the
feedback gains, which act through the deviation d. Exploration (gSDE or
Gaussian) is unchanged: its noise is drawn from the actual features.
"""

from __future__ import annotations

import torch as th
from stable_baselines3.common.distributions import StateDependentNoiseDistribution
from stable_baselines3.common.policies import ActorCriticPolicy


class ZeroOnReferencePolicy(ActorCriticPolicy):
    """:class:`ActorCriticPolicy` with mu(o, d) = a(o, d) - a(o, 0).

    :param n_raw_features: how many leading observation features are ``o``; the
        rest are the deviation ``d``.
    """

    def __init__(self, *args, n_raw_features: int = 26, **kwargs):
        self.n_raw_features = int(n_raw_features)
        super().__init__(*args, **kwargs)
        if not self.share_features_extractor:
            raise ValueError("ZeroOnReferencePolicy needs share_features_extractor=True")

    def _get_constructor_parameters(self) -> dict:
        data = super()._get_constructor_parameters()
        data["n_raw_features"] = self.n_raw_features
        return data

    def _actor_distribution(self, features: th.Tensor):
        latent = self.mlp_extractor.forward_actor(features)
        on_reference = features.clone()
        on_reference[:, self.n_raw_features :] = 0.0
        latent_0 = self.mlp_extractor.forward_actor(on_reference)
        mean = self.action_net(latent) - self.action_net(latent_0)
        if isinstance(self.action_dist, StateDependentNoiseDistribution):
            return self.action_dist.proba_distribution(mean, self.log_std, latent)
        return self.action_dist.proba_distribution(mean, self.log_std)

    def forward(self, obs: th.Tensor, deterministic: bool = False):
        features = self.extract_features(obs)
        values = self.value_net(self.mlp_extractor.forward_critic(features))
        distribution = self._actor_distribution(features)
        actions = distribution.get_actions(deterministic=deterministic)
        log_prob = distribution.log_prob(actions)
        return actions.reshape((-1, *self.action_space.shape)), values, log_prob

    def evaluate_actions(self, obs: th.Tensor, actions: th.Tensor):
        features = self.extract_features(obs)
        distribution = self._actor_distribution(features)
        values = self.value_net(self.mlp_extractor.forward_critic(features))
        return values, distribution.log_prob(actions), distribution.entropy()

    def get_distribution(self, obs: th.Tensor):
        return self._actor_distribution(self.extract_features(obs))
