"""Rollout buffers that keep, per step, the critic's atoms and the risk parameter HuRi derives from them."""

from collections.abc import Generator
from typing import Any, NamedTuple

import numpy as np
import torch as th
from stable_baselines3.common.buffers import DictRolloutBuffer, RolloutBuffer
from stable_baselines3.common.type_aliases import TensorDict

from sb3_huri.common.risk_gae import TD_LEVELS, risk_gae
from sb3_huri.common.sr_lambda import sr_lambda_targets


class HuRiRolloutBufferSamples(NamedTuple):
    """A minibatch: SB3's rollout samples plus the critic's targets and the distortion of each state."""

    observations: th.Tensor | TensorDict
    actions: th.Tensor
    old_values: th.Tensor
    old_log_prob: th.Tensor
    advantages: th.Tensor
    returns: th.Tensor
    target_atoms: th.Tensor
    distortion_weights: th.Tensor


class _RiskAwareRolloutMixin:
    """What HuRi adds to SB3's rollout buffers.

    Per step it stores the critic atoms (``atoms``), which the algorithm sorts once the rollout is complete
    (:meth:`sort_atoms`); it then sets the distortion weights ``w(beta_s)`` of each state and its
    diagnostics (``risk``, ``iqr``, ``rnd_error``) with :meth:`set_risk`, and the atoms and distorted value
    of the final state of each truncated episode with :meth:`set_time_out_bootstrap`.
    :meth:`compute_returns_and_advantage` then computes GAE on the distorted values
    ``V_beta(s) = sum_i w_i(beta_s) theta_(i)(s)`` and the SR(lambda) target atoms of the quantile loss.
    ``td_level`` says at which level a TD error values its two states
    (``sb3_huri.common.risk_gae``): ``"state"``, each at its own (SB3's GAE on the per-state values), or
    ``"step"``, both at the level of the state the step starts from; :meth:`advantages_under` gives the
    rollout's advantages under either.
    """

    buffer_size: int
    n_envs: int
    gamma: float
    pos: int
    generator_ready: bool

    def __init__(
        self,
        *args: Any,
        n_quantiles: int = 64,
        sr_lambda: float = 1.0,
        td_level: str = "state",
        **kwargs: Any,
    ):
        if td_level not in TD_LEVELS:
            raise ValueError(f"Unknown td_level {td_level!r}: expected one of {list(TD_LEVELS)}")
        self.n_quantiles = n_quantiles
        self.sr_lambda = sr_lambda
        self.td_level = td_level
        super().__init__(*args, **kwargs)

    def reset(self) -> None:
        shape, atom_shape = (self.buffer_size, self.n_envs), (self.buffer_size, self.n_envs, self.n_quantiles)
        self.atoms = np.zeros(atom_shape, dtype=np.float32)
        self.distortion_weights = np.full(atom_shape, 1.0 / self.n_quantiles, dtype=np.float32)
        self.target_atoms = np.zeros(atom_shape, dtype=np.float32)
        self.bootstrap_atoms = np.zeros(atom_shape, dtype=np.float32)
        self.bootstrap_values = np.zeros(shape, dtype=np.float32)
        self.bootstrap_weights = np.zeros(atom_shape, dtype=np.float32)
        self.has_time_outs = False
        # The state after the rollout, set with the risk and by `compute_returns_and_advantage`.
        self.last_atoms = np.zeros((self.n_envs, self.n_quantiles), dtype=np.float32)
        self.last_weights = np.full((self.n_envs, self.n_quantiles), 1.0 / self.n_quantiles, dtype=np.float32)
        self.last_dones = np.zeros(self.n_envs, dtype=np.float32)
        self.advantages_computed = False
        self.risk = np.zeros(shape, dtype=np.float32)
        self.iqr = np.zeros(shape, dtype=np.float32)
        self.rnd_error = np.zeros(shape, dtype=np.float32)
        self._unset_values = th.zeros(self.n_envs)  # stored by SB3's `add`; replaced once the risk is known
        self._tensors: dict[str, Any] | None = None  # the minibatches' source, made by the first `get`
        super().reset()  # type: ignore[misc]

    def add(  # type: ignore[override]
        self,
        obs: Any,
        action: np.ndarray,
        reward: np.ndarray,
        episode_start: np.ndarray,
        atoms: th.Tensor,
        log_prob: th.Tensor,
    ) -> None:
        """Store a step; ``atoms`` are the critic's atoms ``(n_envs, n_quantiles)``, in any order.

        The value of the step is set later from the sorted atoms and the state's risk parameter.
        """
        self.atoms[self.pos] = atoms.cpu().numpy()
        super().add(obs, action, reward, episode_start, self._unset_values, log_prob)  # type: ignore[misc]

    def sort_atoms(self) -> None:
        """Sort each stored state's atoms in increasing order (once per rollout, rather than per step)."""
        self.atoms.sort(axis=-1)  # numpy's: many times faster than torch's on the CPU for short rows

    def flat_observations(self) -> np.ndarray | dict[str, np.ndarray]:
        """The stored observations with time and env axes merged (row ``t * n_envs + e``).

        Only available before ``get()``, which reorders the buffer.
        """
        assert not self.generator_ready, "observations are only available in time-major order before get()"
        observations = self.observations  # type: ignore[attr-defined]
        if isinstance(observations, dict):
            return {key: obs.reshape(-1, *obs.shape[2:]) for key, obs in observations.items()}
        return observations.reshape(-1, *observations.shape[2:])

    def set_risk(
        self,
        weights: np.ndarray,
        risk: np.ndarray,
        iqr: np.ndarray,
        rnd_error: np.ndarray,
        last_weights: np.ndarray | None = None,
    ) -> None:
        """Set each state's distortion weights ``(T, E, N)`` and its risk parameter, IQR and RND error, and
        the weights of the state after the rollout ``(E, N)`` (neutral if not given)."""
        self.distortion_weights[:] = weights
        self.risk[:], self.iqr[:], self.rnd_error[:] = risk, iqr, rnd_error
        if last_weights is not None:
            self.last_weights[:] = last_weights

    def set_time_out_bootstrap(
        self,
        steps: np.ndarray,
        envs: np.ndarray,
        atoms: np.ndarray,
        values: np.ndarray,
        weights: np.ndarray | None = None,
    ) -> None:
        """Record the sorted atoms, distorted value and (if given) distortion weights of the last states of
        episodes cut at ``steps``."""
        self.bootstrap_atoms[steps, envs] = atoms
        self.bootstrap_values[steps, envs] = values
        if weights is not None:
            self.bootstrap_weights[steps, envs] = weights
        self.has_time_outs = len(steps) > 0

    def compute_returns_and_advantage(  # type: ignore[override]
        self, last_values: th.Tensor, dones: np.ndarray, last_atoms: np.ndarray | None = None
    ) -> None:
        """GAE on the distorted values (under ``td_level``) and SR(lambda) target atoms.

        :param last_values: distorted value ``V_beta`` of the state after the rollout, per env
        :param dones: whether each env's last step ended its episode
        :param last_atoms: sorted atoms of the state after the rollout ``(n_envs, n_quantiles)``;
            only needed for a distributional critic (``n_quantiles > 1``)
        """
        self.values = np.einsum("ten,ten->te", self.distortion_weights, self.atoms).astype(np.float32)
        self.last_dones = np.asarray(dones, dtype=np.float32)
        if last_atoms is not None:
            self.last_atoms = np.asarray(last_atoms, dtype=np.float32)
        self.advantages_computed = True
        rewards = self.rewards
        if self.td_level == "step":
            assert last_atoms is not None, "each step's own level needs the atoms of the last state"
            self.advantages = self.advantages_under("step")
            self.returns = self.advantages + self.values
        else:
            # A truncated episode bootstraps from its last state's value, as in SB3's PPO (the step is done).
            self.rewards = rewards + self.gamma * self.bootstrap_values
            super().compute_returns_and_advantage(last_values, dones)  # type: ignore[misc]
            self.rewards = rewards
        if self.n_quantiles > 1:
            assert last_atoms is not None, "a quantile critic needs the atoms of the last state"
            # Sorted once here, so that every epoch's energy distance skips the sort of its targets.
            self.target_atoms = sr_lambda_targets(
                rewards,
                self.atoms,
                self.episode_starts,  # type: ignore[attr-defined]
                last_atoms,
                dones.astype(np.float32),
                self.gamma,
                self.sr_lambda,
                self.bootstrap_atoms if self.has_time_outs else None,
                # SB3 seeds numpy's global generator: draw the mixing generator's seed from it.
                rng=np.random.default_rng(np.random.randint(2**31)),  # noqa: NPY002
            )
            self.target_atoms.sort(axis=-1)

    def advantages_under(self, td_level: str) -> np.ndarray:
        """The rollout's advantages ``(T, E)`` had its TD errors been read under ``td_level``
        (``sb3_huri.common.risk_gae``), from its atoms, rewards and each state's weights, the buffer left
        as it is. Available once the rollout's advantages are computed, until ``get()`` reorders the buffer.
        """
        assert not self.generator_ready, "the rollout's time order is only available before get()"
        assert self.advantages_computed, "the rollout's last state is set by compute_returns_and_advantage"
        time_outs = self.has_time_outs
        return risk_gae(
            self.rewards, self.atoms, self.distortion_weights, self.episode_starts,  # type: ignore[attr-defined]
            self.last_atoms, self.last_weights, self.last_dones, self.gamma, self.gae_lambda,  # type: ignore[attr-defined]
            td_level,
            bootstrap_atoms=self.bootstrap_atoms if time_outs else None,
            bootstrap_weights=self.bootstrap_weights if time_outs else None,
        )  # fmt: skip

    def get(self, batch_size: int | None = None) -> Generator[HuRiRolloutBufferSamples, None, None]:  # type: ignore[override]
        if not self.generator_ready:
            for name in ("target_atoms", "distortion_weights"):
                self.__dict__[name] = self.swap_and_flatten(self.__dict__[name])  # type: ignore[attr-defined]
        yield from super().get(batch_size)  # type: ignore[misc]

    def _get_samples(self, batch_inds: np.ndarray, env: Any = None) -> HuRiRolloutBufferSamples:
        """SB3's samples and HuRi's, indexed from the rollout's tensors (:meth:`_sample_tensors`) rather
        than converted from numpy minibatch by minibatch."""
        index = th.as_tensor(batch_inds, device=self.device)  # type: ignore[attr-defined]
        tensors = self._sample_tensors()
        observations = tensors.pop("observations")

        def rows(tensor: th.Tensor) -> th.Tensor:  # `index_select`: 2-3x faster than `tensor[index]` here
            return th.index_select(tensor, 0, index)

        return HuRiRolloutBufferSamples(
            observations={key: rows(obs) for key, obs in observations.items()}
            if isinstance(observations, dict)
            else rows(observations),
            **{name: rows(tensor) for name, tensor in tensors.items()},
        )

    def _sample_tensors(self) -> dict[str, Any]:
        """Every field a minibatch takes, flattened as ``get`` left it, as a tensor on the buffer's device:
        made once per rollout (on the CPU they share the arrays' memory) and sliced by each minibatch."""
        if self._tensors is None:
            device = self.device  # type: ignore[attr-defined]

            def tensor(array: np.ndarray) -> th.Tensor:
                return th.as_tensor(array, device=device)

            observations = self.observations  # type: ignore[attr-defined]
            self._tensors = dict(
                observations={key: tensor(obs) for key, obs in observations.items()}
                if isinstance(observations, dict)
                else tensor(observations),
                # float32 as SB3's samples (a MultiBinary action would not convert)
                actions=tensor(self.actions.astype(np.float32, copy=False)),  # type: ignore[attr-defined]
                old_values=tensor(self.values.reshape(-1)),
                old_log_prob=tensor(self.log_probs.reshape(-1)),  # type: ignore[attr-defined]
                advantages=tensor(self.advantages.reshape(-1)),
                returns=tensor(self.returns.reshape(-1)),
                target_atoms=tensor(self.target_atoms),
                distortion_weights=tensor(self.distortion_weights),
            )
        return dict(self._tensors)


class HuRiRolloutBuffer(_RiskAwareRolloutMixin, RolloutBuffer):
    """HuRi's rollout buffer for ``Box`` (and other non-``Dict``) observations.

    :param n_quantiles: number of critic atoms (1 for a scalar critic)
    :param sr_lambda: SR(lambda) mixing parameter of the critic targets
    :param td_level: ``"state"`` or ``"step"``, the levels a TD error values its states at
    """


class HuRiDictRolloutBuffer(_RiskAwareRolloutMixin, DictRolloutBuffer):
    """HuRi's rollout buffer for ``Dict`` observations.

    :param n_quantiles: number of critic atoms (1 for a scalar critic)
    :param sr_lambda: SR(lambda) mixing parameter of the critic targets
    :param td_level: ``"state"`` or ``"step"``, the levels a TD error values its states at
    """
