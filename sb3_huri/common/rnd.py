"""Random network distillation (Burda et al. 2018): novelty of critic states, HuRi's parameter uncertainty."""

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback, ConvertCallback
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.torch_layers import create_mlp
from stable_baselines3.common.type_aliases import MaybeCallback
from stable_baselines3.common.utils import obs_as_tensor
from torch import nn


class RandomNetworkDistillation(nn.Module):
    """A frozen random target network ``g`` and a predictor ``f`` trained to imitate it.

    The prediction error ``||f(s) - g(s)||^2`` (paper eq. 9) is large on states unlike those the predictor
    was trained on. Inputs are standardized with running statistics (SB3's ``RunningMeanStd``) and clipped,
    so the error does not depend on the input scale. The error is then divided by the running total variance
    of the target's outputs, ``sum_k Var(g_k)`` (a second ``RunningMeanStd``), so that its scale means the
    same thing for any network size and input: above 1 for a state the predictor has never been trained on
    (an untrained predictor misses the target by more than the target's own spread), falling towards 0 as
    the state becomes familiar. Unnormalized, the mean error of a 16-output target on standardized inputs is
    a few thousandths, and ``tanh`` of it (paper eq. 10) is negligible next to the IQR's risk levels -1, 0, 1.
    Both sets of statistics are part of ``state_dict()`` (as the module's extra state) and the predictor has
    its own Adam optimizer (``self.optimizer``, fused), so they travel with a saved model.

    :param input_dim: size of the (flat) critic state
    :param target_net_arch: hidden layer sizes of the target network (paper: [32, 32])
    :param predictor_net_arch: hidden layer sizes of the predictor network (paper: [32])
    :param output_dim: size of the embedding both networks output
    :param learning_rate: Adam learning rate of the predictor (paper: 1e-3)
    :param clip_obs: normalized inputs are clipped to ``[-clip_obs, clip_obs]``
    :param activation_fn: activation after each hidden layer
    :param normalize_error: divide the error by the target outputs' running total variance; ``False`` gives
        the mean squared error over the outputs, unscaled
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
        normalize_error: bool = True,
    ):
        super().__init__()
        self.clip_obs = clip_obs
        self.normalize_error = normalize_error
        self.target = nn.Sequential(*create_mlp(input_dim, output_dim, list(target_net_arch), activation_fn))
        self.target.requires_grad_(False)
        self.predictor = nn.Sequential(
            *create_mlp(input_dim, output_dim, list(predictor_net_arch), activation_fn)
        )
        self.obs_rms = RunningMeanStd(shape=(input_dim,))
        # Starts at unit variance: until the first update the error is the mean over the outputs.
        self.target_rms = RunningMeanStd(shape=(output_dim,))
        # Fused: one kernel for the step's tensors, about twice as fast a fit for networks this small.
        self.optimizer = th.optim.Adam(self.predictor.parameters(), lr=learning_rate, fused=True)

    def update_normalizer(self, inputs: th.Tensor) -> None:
        """Add a batch of critic states ``(B, input_dim)`` to the input and target-output statistics."""
        self.obs_rms.update(inputs.detach().cpu().numpy())
        with th.no_grad():
            self.target_rms.update(self.target(self.normalize(inputs)).cpu().numpy())

    def normalize(self, inputs: th.Tensor) -> th.Tensor:
        """Standardize with the running statistics and clip."""
        mean = th.as_tensor(self.obs_rms.mean, dtype=inputs.dtype, device=inputs.device)
        std = th.as_tensor(np.sqrt(self.obs_rms.var + 1e-8), dtype=inputs.dtype, device=inputs.device)
        return th.clamp((inputs - mean) / std, -self.clip_obs, self.clip_obs)

    def _squared_error(self, normalized: th.Tensor, targets: th.Tensor | None = None) -> th.Tensor:
        """``mean_k (f(s)_k - g(s)_k)^2`` of normalized inputs; `targets`: ``g(s)`` if already computed."""
        targets = self.target(normalized) if targets is None else targets
        return (self.predictor(normalized) - targets).pow(2).mean(dim=-1)

    def prediction_error(self, inputs: th.Tensor) -> th.Tensor:
        """Novelty of each critic state, shape ``(B,)``, without gradient.

        ``||f(s) - g(s)||^2 / sum_k Var(g_k)`` with ``normalize_error`` (the default), else
        ``mean_k (f(s)_k - g(s)_k)^2``.
        """
        with th.no_grad():
            error = self._squared_error(self.normalize(inputs))
        if self.normalize_error:
            # mean_k (f - g)^2 / mean_k Var(g_k) = ||f - g||^2 / sum_k Var(g_k)
            error = error / float(np.mean(self.target_rms.var) + 1e-8)
        return error

    def fit(self, inputs: th.Tensor, n_epochs: int, batch_size: int) -> float:
        """Train the predictor on a batch of critic states; returns the mean loss of the last epoch."""
        normalized = self.normalize(inputs.detach())
        with th.no_grad():  # the target is frozen: its outputs are computed once, not per minibatch
            targets = self.target(normalized)
        losses: list[th.Tensor] = []
        for _ in range(n_epochs):
            losses = []
            for indices in th.randperm(len(normalized), device=normalized.device).split(batch_size):
                loss = self._squared_error(normalized[indices], targets[indices]).mean()
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                losses.append(loss.detach())
        # Leave no gradient behind: the algorithm clips the gradient norm of all the policy's parameters.
        self.optimizer.zero_grad(set_to_none=True)
        return float(th.stack(losses).mean())

    def fuse_optimizer(self) -> None:
        """Make the predictor's Adam fused again after its state was loaded: ``load_state_dict`` takes the
        saved settings, and a model saved before the fused step saved ``fused=None``."""
        for group in self.optimizer.param_groups:
            group["fused"] = True

    def get_extra_state(self) -> dict[str, th.Tensor]:
        state = {}
        for prefix, rms in (("", self.obs_rms), ("target_", self.target_rms)):
            state[f"{prefix}mean"] = th.as_tensor(rms.mean)
            state[f"{prefix}var"] = th.as_tensor(rms.var)
            state[f"{prefix}count"] = th.tensor(float(rms.count), dtype=th.float64)
        return state

    def set_extra_state(self, state: dict[str, Any]) -> None:
        # Models saved before the target statistics existed keep unit variance until their next rollout.
        for prefix, rms in (("", self.obs_rms), ("target_", self.target_rms)):
            if f"{prefix}mean" in state:
                rms.mean = state[f"{prefix}mean"].cpu().numpy().astype(np.float64)
                rms.var = state[f"{prefix}var"].cpu().numpy().astype(np.float64)
                rms.count = float(state[f"{prefix}count"])


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


def with_rnd_training(callback: MaybeCallback) -> list[BaseCallback]:
    """`callback` (none, one, or a list, as ``learn`` takes it) as a list led by an
    :class:`RNDTrainingCallback`, so that the RND predictor trains at the end of each rollout before the
    other callbacks run. SB3 builds and initializes the list once, so each callback is initialized once."""
    if callback is None:
        callback = []
    elif not isinstance(callback, list):
        callback = [callback if isinstance(callback, BaseCallback) else ConvertCallback(callback)]
    return [RNDTrainingCallback(), *callback]
