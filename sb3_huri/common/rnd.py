"""Random network distillation (Burda et al. 2018): novelty of critic states, HuRi's parameter uncertainty."""

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.torch_layers import create_mlp
from stable_baselines3.common.utils import obs_as_tensor
from torch import nn


class RandomNetworkDistillation(nn.Module):
    """A frozen random target network ``g`` and a predictor ``f`` trained to imitate it.

    The prediction error ``mean_k (f(s)_k - g(s)_k)^2`` (paper eq. 9, averaged over the output units) is
    large on states unlike those the predictor was trained on. Inputs are standardized with running
    statistics (SB3's ``RunningMeanStd``) and clipped, so the error does not depend on the input scale.
    The normalizer statistics are part of ``state_dict()`` (as the module's extra state) and the predictor
    has its own Adam optimizer (``self.optimizer``), so both travel with a saved model.

    :param input_dim: size of the (flat) critic state
    :param target_net_arch: hidden layer sizes of the target network (paper: [32, 32])
    :param predictor_net_arch: hidden layer sizes of the predictor network (paper: [32])
    :param output_dim: size of the embedding both networks output
    :param learning_rate: Adam learning rate of the predictor (paper: 1e-3)
    :param clip_obs: normalized inputs are clipped to ``[-clip_obs, clip_obs]``
    :param activation_fn: activation after each hidden layer
    """

    def __init__(
        self,
        input_dim: int,
        target_net_arch: Sequence[int] = (32, 32),
        predictor_net_arch: Sequence[int] = (32,),
        output_dim: int = 16,
        learning_rate: float = 1e-3,
        clip_obs: float = 5.0,
        activation_fn: type[nn.Module] = nn.LeakyReLU,
    ):
        super().__init__()
        self.clip_obs = clip_obs
        self.target = nn.Sequential(*create_mlp(input_dim, output_dim, list(target_net_arch), activation_fn))
        self.target.requires_grad_(False)
        self.predictor = nn.Sequential(
            *create_mlp(input_dim, output_dim, list(predictor_net_arch), activation_fn)
        )
        self.obs_rms = RunningMeanStd(shape=(input_dim,))
        self.optimizer = th.optim.Adam(self.predictor.parameters(), lr=learning_rate)

    def update_normalizer(self, inputs: th.Tensor) -> None:
        """Add a batch of critic states ``(B, input_dim)`` to the running input statistics."""
        self.obs_rms.update(inputs.detach().cpu().numpy())

    def normalize(self, inputs: th.Tensor) -> th.Tensor:
        """Standardize with the running statistics and clip."""
        mean = th.as_tensor(self.obs_rms.mean, dtype=inputs.dtype, device=inputs.device)
        std = th.as_tensor(np.sqrt(self.obs_rms.var + 1e-8), dtype=inputs.dtype, device=inputs.device)
        return th.clamp((inputs - mean) / std, -self.clip_obs, self.clip_obs)

    def _squared_error(self, normalized: th.Tensor) -> th.Tensor:
        return (self.predictor(normalized) - self.target(normalized)).pow(2).mean(dim=-1)

    def prediction_error(self, inputs: th.Tensor) -> th.Tensor:
        """Novelty of each critic state, shape ``(B,)``, without gradient."""
        with th.no_grad():
            return self._squared_error(self.normalize(inputs))

    def fit(self, inputs: th.Tensor, n_epochs: int, batch_size: int) -> float:
        """Train the predictor on a batch of critic states; returns the mean loss of the last epoch."""
        normalized = self.normalize(inputs.detach())
        losses = []
        for _ in range(n_epochs):
            losses = []
            for indices in th.randperm(len(normalized), device=normalized.device).split(batch_size):
                loss = self._squared_error(normalized[indices]).mean()
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                losses.append(loss.item())
        # Leave no gradient behind: the algorithm clips the gradient norm of all the policy's parameters.
        self.optimizer.zero_grad(set_to_none=True)
        return float(np.mean(losses))

    def get_extra_state(self) -> dict[str, th.Tensor]:
        return {
            "mean": th.as_tensor(self.obs_rms.mean),
            "var": th.as_tensor(self.obs_rms.var),
            "count": th.tensor(float(self.obs_rms.count), dtype=th.float64),
        }

    def set_extra_state(self, state: dict[str, Any]) -> None:
        self.obs_rms.mean = state["mean"].cpu().numpy().astype(np.float64)
        self.obs_rms.var = state["var"].cpu().numpy().astype(np.float64)
        self.obs_rms.count = float(state["count"])


class RNDTrainingCallback(BaseCallback):
    """Trains the policy's RND predictor on the critic states of each rollout, once it is collected.

    ``HuRiPPO`` installs this callback itself when RND is enabled. The predictor trains after the rollout's
    novelty was measured (the buffer's risk parameters use the error before training), with the same
    number of epochs and minibatch size as the PPO update. Logs ``train/rnd_loss``.
    """

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        policy = self.model.policy
        buffer = self.model.rollout_buffer
        observations = obs_as_tensor(buffer.flat_observations(), policy.device)
        with th.no_grad():
            inputs = policy.critic_features(observations)
        loss = policy.rnd.fit(inputs, n_epochs=self.model.n_epochs, batch_size=self.model.batch_size)
        self.logger.record("train/rnd_loss", loss)
