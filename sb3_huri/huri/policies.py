"""Asymmetric actor-critic policy with a quantile (or scalar) critic, the network side of HuRi.

With a ``Dict`` observation holding a ``"policy"`` key, the actor reads only that key (proprioception)
while the critic reads every key (``"policy"`` first, then e.g. ``"critic"``: privileged state), the
asymmetric actor-critic of the paper (section 3.1). With a ``Box`` observation both read the whole vector,
an ordinary MLP actor-critic. The critic outputs ``n_quantiles`` atoms of the return distribution; with
``n_quantiles=1`` it is PPO's scalar value head, and the policy can be used by SB3's own ``PPO``.
"""

from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor, create_mlp
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from sb3_huri.common.rnd import RandomNetworkDistillation

ACTOR_KEY = "policy"


class PolicyCriticExtractor(BaseFeaturesExtractor):
    """Flattens a ``Dict`` observation into one vector, the actor's key first.

    ``actor_features_dim`` tells how many leading features the actor may read: the ``"policy"`` entry
    when the observation has one, all features otherwise.

    :param observation_space: a ``Dict`` space
    :param actor_key: the entry the actor reads
    """

    def __init__(self, observation_space: spaces.Dict, actor_key: str = ACTOR_KEY):
        keys = sorted(observation_space.spaces)
        if actor_key in keys:
            keys.remove(actor_key)
            keys.insert(0, actor_key)
        sizes = [spaces.flatdim(observation_space[key]) for key in keys]
        super().__init__(observation_space, features_dim=sum(sizes))
        self.keys = keys
        self.actor_features_dim = sizes[0] if keys[0] == actor_key else sum(sizes)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.cat([observations[key].flatten(start_dim=1) for key in self.keys], dim=1)


class AsymmetricMlpExtractor(nn.Module):
    """Separate actor and critic MLPs over a shared feature vector; the actor reads its leading slice.

    Same interface as SB3's ``MlpExtractor`` (``forward``, ``forward_actor``, ``forward_critic``,
    ``latent_dim_pi``, ``latent_dim_vf``).

    :param actor_dim: number of leading features the actor reads
    :param critic_dim: number of features the critic reads (all of them)
    :param net_arch: hidden sizes, a list for both networks or ``dict(pi=[...], vf=[...])``
    :param activation_fn: activation after each hidden layer
    """

    def __init__(
        self,
        actor_dim: int,
        critic_dim: int,
        net_arch: list[int] | dict[str, list[int]],
        activation_fn: type[nn.Module],
    ):
        super().__init__()
        pi_arch = list(net_arch.get("pi", [])) if isinstance(net_arch, dict) else list(net_arch)
        vf_arch = list(net_arch.get("vf", [])) if isinstance(net_arch, dict) else list(net_arch)
        self.actor_dim = actor_dim
        self.reads_all_features = actor_dim == critic_dim
        self.policy_net = nn.Sequential(*create_mlp(actor_dim, -1, pi_arch, activation_fn))
        self.value_net = nn.Sequential(*create_mlp(critic_dim, -1, vf_arch, activation_fn))
        self.latent_dim_pi = pi_arch[-1] if pi_arch else actor_dim
        self.latent_dim_vf = vf_arch[-1] if vf_arch else critic_dim

    def forward(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features: th.Tensor) -> th.Tensor:
        return self.policy_net(features if self.reads_all_features else features[:, : self.actor_dim])

    def forward_critic(self, features: th.Tensor) -> th.Tensor:
        return self.value_net(features)


class HuRiPolicy(ActorCriticPolicy):
    """Actor-critic policy with an asymmetric observation split and a quantile critic.

    Takes every argument of SB3's ``ActorCriticPolicy``, with its defaults (``[64, 64]`` for each network,
    ``tanh``); the paper's networks are ``net_arch=[512, 256, 128], activation_fn=nn.ELU`` (the rsl_rl stack
    it trains with, ``hyperparams/huri_paper.yml``). The value outputs (``forward``, ``evaluate_actions``,
    ``predict_values``) have shape ``(batch, n_quantiles)``: unsorted atoms of the return distribution.

    :param n_quantiles: number of critic atoms; 1 gives a scalar value head (usable by SB3's ``PPO``)
    :param rnd_kwargs: keyword arguments of a :class:`RandomNetworkDistillation` over the critic's input,
        kept as ``self.rnd``; ``None`` (default) for no RND
    :param critic_param_group: give the critic's parameters a parameter group of their own in the
        optimizer (named ``"critic"``; the rest is ``"actor"``), so that they can learn at another rate
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.Tanh,
        n_quantiles: int = 64,
        rnd_kwargs: dict[str, Any] | None = None,
        critic_param_group: bool = False,
        features_extractor_class: type[BaseFeaturesExtractor] | None = None,
        **kwargs: Any,
    ):
        if not isinstance(n_quantiles, (int, np.integer)) or n_quantiles < 1:
            raise ValueError(
                f"n_quantiles must be a positive integer (1 for a scalar critic), got {n_quantiles!r}"
            )
        # Read by _build(), which the parent constructor calls.
        self.n_quantiles = int(n_quantiles)
        self.critic_param_group = bool(critic_param_group)
        if features_extractor_class is None:
            is_dict = isinstance(observation_space, spaces.Dict)
            features_extractor_class = PolicyCriticExtractor if is_dict else FlattenExtractor
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            net_arch,
            activation_fn,
            features_extractor_class=features_extractor_class,
            **kwargs,
        )
        self.rnd_kwargs = rnd_kwargs
        # Created after the policy optimizer: the RND predictor is trained by its own optimizer only.
        self.rnd = (
            RandomNetworkDistillation(self.features_dim, **rnd_kwargs) if rnd_kwargs is not None else None
        )

    def _build_mlp_extractor(self) -> None:
        actor_dim = getattr(self.pi_features_extractor, "actor_features_dim", self.features_dim)
        self.mlp_extractor = AsymmetricMlpExtractor(
            actor_dim, self.features_dim, self.net_arch, self.activation_fn
        )

    def _build(self, lr_schedule: Schedule) -> None:
        super()._build(lr_schedule)
        if self.n_quantiles != 1:
            # Widen SB3's scalar value head to one output per atom, with the same init, and rebuild the
            # optimizer over the new parameters.
            self.value_net = nn.Linear(self.mlp_extractor.latent_dim_vf, self.n_quantiles)
            if self.ortho_init:
                self.init_weights(self.value_net, gain=1.0)
        if self.n_quantiles != 1 or self.critic_param_group:  # rebuilt over the new head or in groups
            self.optimizer = self.optimizer_class(
                self._parameter_groups(), lr=lr_schedule(1), **self.optimizer_kwargs
            )

    def critic_parameters(self) -> list[nn.Parameter]:
        """The parameters only the critic uses: its MLP and value head."""
        return [*self.mlp_extractor.value_net.parameters(), *self.value_net.parameters()]

    def _parameter_groups(self) -> Any:
        """Every parameter (the RND predictor has its own optimizer), as actor and critic groups if asked."""
        if not self.critic_param_group:
            return self.parameters()
        critic = self.critic_parameters()
        critic_ids = {id(p) for p in critic}
        actor = [p for p in self.parameters() if id(p) not in critic_ids]
        return [{"params": actor, "name": "actor"}, {"params": critic, "name": "critic"}]

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            n_quantiles=self.n_quantiles,
            rnd_kwargs=self.rnd_kwargs,
            critic_param_group=self.critic_param_group,
            share_features_extractor=self.share_features_extractor,
        )
        return data

    def actor_mean(self, actor_observations: th.Tensor) -> th.Tensor:
        """The action mean for the actor's own inputs (batch, n): the ``"policy"`` entry of a ``Dict``
        observation, the whole vector of a ``Box`` one (e.g. to compare it on mirrored inputs)."""
        return self.action_net(self.mlp_extractor.policy_net(actor_observations))

    def critic_features(self, obs: PyTorchObs) -> th.Tensor:
        """The flat critic input (every observation entry), which RND measures the novelty of."""
        return BasePolicy.extract_features(self, obs, self.vf_features_extractor)


MlpPolicy = HuRiPolicy
MultiInputPolicy = HuRiPolicy
