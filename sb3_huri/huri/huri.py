"""HuRiPPO: adaptive risk-aware distributional PPO (HuRi) as a Stable-Baselines3 on-policy algorithm."""

from collections import defaultdict
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import FloatSchedule, explained_variance, obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv
from torch.nn import functional as F

from sb3_huri.common.energy import energy_distance
from sb3_huri.common.expectation import expectation_loss
from sb3_huri.common.learning_rate import kl_adaptive_rate, set_learning_rates
from sb3_huri.common.mirror import NormalizedMirror, env_mirrors, mirror_loss
from sb3_huri.common.observations import add_batch_axis, concatenate_observations, to_numpy
from sb3_huri.common.quantiles import interquartile_range, sorted_atoms
from sb3_huri.common.rnd import with_rnd_training
from sb3_huri.huri.buffers import HuRiDictRolloutBuffer, HuRiRolloutBuffer, HuRiRolloutBufferSamples
from sb3_huri.huri.hyperparameters import (
    RULES,
    agreeing,
    check_action_space,
    check_hyperparameters,
    completed_policy_kwargs,
    resolve_batch_size,
    warn_unless_rewards_normalized,
)
from sb3_huri.huri.methods import DEFAULT_METHOD
from sb3_huri.huri.policies import ACTOR_KEY, HuRiPolicy, MlpPolicy, MultiInputPolicy
from sb3_huri.huri.risk import RiskAssessment, RiskModel, RiskReading
from sb3_huri.huri.saves import NETWORK_DEFAULTS, fitting_optimizer_state, upgrade_saved_attributes

SelfHuRiPPO = TypeVar("SelfHuRiPPO", bound="HuRiPPO")


class HuRiPPO(OnPolicyAlgorithm):
    """Adaptive risk-aware distributional PPO (HuRi, "Humanoid Robots Adaptive Risk-Aware Distributional RL").

    The actor is PPO's (clipped surrogate, normalized advantages, entropy bonus). The critic predicts
    ``n_quantiles`` atoms of the return distribution, trained with the energy distance to SR(lambda) target
    atoms (eq. 4) plus an expectation loss (eq. 5). Advantages are GAE on the distorted value
    ``V_beta(s) = sum_i w_i(beta_s) theta_(i)(s)``, where each state's risk parameter ``beta_s`` is
    ``beta_IQR`` (from the interquartile range of its atoms, Algorithm 1) plus ``tanh`` of its RND novelty.
    The paper's methods are presets (``method``); every knob below overrides its preset. The risk arguments
    (``method`` to ``td_level``) make one :class:`~sb3_huri.huri.risk.RiskModel`,
    ``model.risk_model``, where they are checked; the model keeps its settings as attributes of the same
    names, which it saves. ``sb3_huri.huri.hyperparameters`` checks the others.

    Defaults: what HuRiPPO shares with SB3's ``PPO`` (rollout and minibatch sizes, epochs, learning rate,
    coefficients, networks) defaults to PPO's, so that swapping the class swaps the critic and nothing
    else; HuRi's own arguments (atoms, band, RND, SR(lambda), loss coefficients) default to the paper's.
    The paper's Table 3 (sized for thousands of GPU environments) is ``hyperparams/huri_paper.yml``.

    :param policy: ``"MlpPolicy"`` / ``"MultiInputPolicy"`` (both :class:`HuRiPolicy`, which handles ``Box``
        and ``Dict`` observations) or a :class:`HuRiPolicy` subclass
    :param env: the environment to learn from (if registered in Gymnasium, can be a str)
    :param learning_rate: learning rate, a float or a schedule of the progress remaining (from 1 to 0);
        with ``desired_kl``, the initial learning rate
    :param n_steps: steps per environment per rollout
    :param batch_size: minibatch size, as in PPO; ``None`` (default): 64, PPO's, unless ``n_minibatches``
        is given
    :param n_minibatches: minibatches per epoch, the rollout split evenly (rsl_rl's way of sizing them);
        used when ``batch_size`` is ``None``
    :param n_epochs: epochs over each rollout
    :param gamma: discount factor
    :param gae_lambda: GAE parameter
    :param clip_range: PPO clipping parameter, a float or a schedule
    :param normalize_advantage: normalize advantages per minibatch
    :param ent_coef: entropy bonus coefficient (``lambda_entropy``)
    :param vf_coef: coefficient of the critic loss (PPO's MSE, or the distributional critic's loss)
    :param max_grad_norm: gradient clipping norm
    :param use_sde: use generalized state-dependent exploration
    :param sde_sample_freq: resample the gSDE noise matrix every n steps (-1: once per rollout)
    :param target_kl: stop an update early when the approximate KL divergence exceeds ``1.5 * target_kl``
    :param desired_kl: adapt the learning rate (the actor's, with ``critic_learning_rate``) to this KL per
        minibatch within ``kl_learning_rate_bounds``, as legged-robot PPO trainers do
        (``sb3_huri.common.learning_rate``); ``None`` follows ``learning_rate``
    :param critic_learning_rate: the critic's own learning rate (a float or a schedule), so that a small
        trust-region rate of the actor does not stop the critic learning; ``None`` (default) shares
        ``learning_rate``
    :param method: the method's preset, a name of ``sb3_huri.huri.METHODS`` (the RL Zoo algorithm names);
        default ``huri``, HuRi with the IQR band as printed (``huri-percentile``: a scale-free band)
    :param n_quantiles: number of critic atoms ``N``; ``None`` takes ``policy_kwargs["n_quantiles"]`` if
        given, else 64 (ignored by ``huri-baseline``, whose critic is scalar)
    :param distortion: ``"wang"`` or ``"cvar"``; ``None`` takes the method's
    :param use_iqr: risk level from the IQR band; ``None`` takes the method's
    :param use_rnd: add ``tanh(RND error)`` to the risk level; ``None`` takes the method's
    :param wang_beta: Wang risk level when ``use_iqr`` is off (0: neutral, > 0: averse, < 0: seeking)
    :param cvar_alpha: CVaR level in ``(0, 1]`` when ``use_iqr`` is off (1: neutral)
    :param iqr_thresholds: ``(t_min, t_max)`` of the absolute band, in return units (normalize rewards)
    :param iqr_risk_levels: risk level below, within and above the band; ``None`` takes
        ``(-1, 0, 1)`` for Wang and ``(1, 1, 0.5)`` for CVaR (paper A.8)
    :param iqr_band: ``"absolute"``: ``iqr_thresholds`` are fixed (the paper's band as printed);
        ``"percentile"``: they follow the ``iqr_percentiles`` of the critic's per-state IQR over recent
        rollouts, are saved and stay fixed outside training; ``None`` takes the method's
    :param iqr_percentiles: ``(p_min, p_max)`` of the percentile band
    :param iqr_band_smoothing: weight of each new rollout in the percentile band's exponential average
    :param td_level: at which risk level a TD error of the advantages values its two states
        (``sb3_huri.common.risk_gae``): ``"state"``, each at its own (the per-state values in SB3's GAE),
        ``"step"``, both at the level of the state the step starts from; ``None`` takes the method's
    :param sr_lambda: SR(lambda) parameter of the critic targets in ``[0, 1]`` (paper: 1, Monte-Carlo)
    :param quantile_coef: weight of the energy-distance loss (``lambda_quantiles``)
    :param expectation_coef: weight of the expectation loss (``lambda_expectation``)
    :param expectation_loss: ``"distorted"``: the predicted mean against its own distorted mean (eq. 5 as
        printed, which also penalizes the spread); ``"target"``: against the target atoms' mean
        (``sb3_huri.common.expectation``)
    :param rnd_kwargs: keyword arguments of the :class:`~sb3_huri.common.rnd.RandomNetworkDistillation`;
        ``None`` takes ``policy_kwargs["rnd_kwargs"]`` if given, else its defaults (the paper's)
    :param mirror_coef: weight of a symmetry loss on the actor (``sb3_huri.common.mirror``), for an env that
        gives ``policy_mirror`` and ``action_mirror`` maps (Zerith1-v0); 0 (default): none, as in the paper
    :param stats_window_size: episodes averaged in the rollout logs
    :param tensorboard_log: tensorboard log folder (None: no logging)
    :param policy_kwargs: extra arguments of the policy (e.g. ``net_arch``, ``activation_fn``); may hold
        ``n_quantiles`` and ``rnd_kwargs``, as ``model.policy_kwargs`` does, if they agree with the above
    :param verbose: 0 silent, 1 info, 2 debug
    :param seed: random seed
    :param device: ``"cpu"``, ``"cuda"``, ``"auto"``...
    :param _init_setup_model: build the networks at construction
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": MlpPolicy,
        "MultiInputPolicy": MultiInputPolicy,
    }
    policy: HuRiPolicy
    rollout_buffer: HuRiRolloutBuffer | HuRiDictRolloutBuffer
    kl_learning_rate_bounds: ClassVar[tuple[float, float]] = (1e-6, 1e-2)
    """Range of the KL-adaptive learning rate (``desired_kl``)."""

    def __init__(
        self,
        policy: str | type[HuRiPolicy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 3e-4,
        n_steps: int = 2048,
        batch_size: int | None = None,
        n_minibatches: int | None = None,
        n_epochs: int = 10,
        gamma: float = 0.99,
        gae_lambda: float = 0.95,
        clip_range: float | Schedule = 0.2,
        normalize_advantage: bool = True,
        ent_coef: float = 0.0,
        vf_coef: float = 0.5,
        max_grad_norm: float = 0.5,
        use_sde: bool = False,
        sde_sample_freq: int = -1,
        target_kl: float | None = None,
        desired_kl: float | None = None,
        critic_learning_rate: float | Schedule | None = None,
        method: str = DEFAULT_METHOD,
        n_quantiles: int | None = None,
        distortion: str | None = None,
        use_iqr: bool | None = None,
        use_rnd: bool | None = None,
        wang_beta: float = 0.0,
        cvar_alpha: float = 0.5,
        iqr_thresholds: tuple[float, float] = (0.3, 0.7),
        iqr_risk_levels: tuple[float, float, float] | None = None,
        iqr_band: str | None = None,
        iqr_percentiles: tuple[float, float] = (30.0, 70.0),
        iqr_band_smoothing: float = 0.5,
        td_level: str | None = None,
        sr_lambda: float = 1.0,
        quantile_coef: float = 1.0,
        expectation_coef: float = 0.05,
        expectation_loss: str = "distorted",
        rnd_kwargs: dict[str, Any] | None = None,
        mirror_coef: float = 0.0,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ):
        self.method, policy_kwargs = method, dict(policy_kwargs or {})
        self._set_risk_model(RiskModel.from_arguments(
            method, n_quantiles=agreeing("n_quantiles", n_quantiles, policy_kwargs, default=None),
            distortion=distortion, use_iqr=use_iqr, use_rnd=use_rnd, wang_beta=wang_beta,
            cvar_alpha=cvar_alpha, iqr_thresholds=iqr_thresholds, iqr_risk_levels=iqr_risk_levels,
            iqr_band=iqr_band, iqr_percentiles=iqr_percentiles, iqr_band_smoothing=iqr_band_smoothing,
            td_level=td_level,
        ))  # fmt: skip
        self.iqr_band_rollouts = 0  # rollouts that moved the percentile band so far
        if not _init_setup_model:  # as `load` builds it: a model saved without them takes its method's
            for name, given in (("iqr_band", iqr_band), ("td_level", td_level)):
                if given is None:
                    delattr(self, name)
        use_rnd = self.risk_model.use_rnd
        self.rnd_kwargs = agreeing("rnd_kwargs", rnd_kwargs, policy_kwargs, default={}) if use_rnd else None
        self.sr_lambda = float(sr_lambda)
        self.quantile_coef, self.expectation_coef = quantile_coef, expectation_coef
        self.expectation_loss, self.mirror_coef = expectation_loss, mirror_coef
        self._mirrors: tuple[NormalizedMirror, NormalizedMirror] | None = None  # set by each update
        self.n_minibatches, self.desired_kl = n_minibatches, desired_kl
        self.critic_learning_rate = critic_learning_rate
        self.kl_learning_rate: float | None = None  # set by the first update with desired_kl
        self._check_settings(n_steps=n_steps, n_epochs=n_epochs, gamma=gamma, gae_lambda=gae_lambda)
        if isinstance(policy, str):
            # Both aliases name the same class: resolving it here lets "MlpPolicy" take Dict observations.
            policy = self._get_policy_from_name(policy)  # type: ignore[assignment]
        super().__init__(
            policy, env, learning_rate=learning_rate, n_steps=n_steps, gamma=gamma, gae_lambda=gae_lambda,
            ent_coef=ent_coef, vf_coef=vf_coef, max_grad_norm=max_grad_norm, use_sde=use_sde,
            sde_sample_freq=sde_sample_freq, stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log, policy_kwargs=policy_kwargs, verbose=verbose, device=device,
            seed=seed, _init_setup_model=False,
        )  # fmt: skip
        if self.env is not None:
            check_action_space(self.action_space)
            batch_size = resolve_batch_size(batch_size, self.n_minibatches, self.n_steps * self.env.num_envs)
        self.batch_size = batch_size
        self.n_epochs, self.clip_range = n_epochs, clip_range
        self.normalize_advantage, self.target_kl = normalize_advantage, target_kl
        if _init_setup_model:  # a new model (`load` builds one without, then restores the saved values)
            self.network_defaults = NETWORK_DEFAULTS
            self._setup_model()

    def _set_risk_model(self, risk_model: RiskModel) -> None:
        """Hold `risk_model`, and its settings as attributes of the same names (``distortion``, ``use_rnd``,
        ...). Those are what ``save`` writes: ``load`` restores them into a model built with the default
        arguments, and :meth:`_setup_model` rebuilds the risk model from them."""
        self.risk_model = risk_model
        self.__dict__.update(risk_model.settings())

    def _check_settings(self, **others: Any) -> None:
        """ValueError naming the first invalid hyperparameter (the attributes set so far and `others`); the
        risk settings are the risk model's to check."""
        checked = [name for name in RULES if name not in others]
        check_hyperparameters(**others, **{name: getattr(self, name) for name in checked})

    def _setup_model(self) -> None:
        # `load` has restored the saved attributes by now, an earlier version's too: under today's names.
        upgrade_saved_attributes(self.__dict__)
        # The risk settings may be a loaded model's (or given to `load`): its risk model is rebuilt from them.
        self._set_risk_model(RiskModel.from_attributes(self))
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        # At setup rather than construction, so that `load(..., custom_objects={"policy_kwargs": ...})` with
        # only network options still gets the saved model's critic and RND.
        self.policy_kwargs = completed_policy_kwargs(
            self.policy_kwargs, self.risk_model, self.rnd_kwargs,
            critic_param_group=getattr(self, "critic_learning_rate", None) is not None, method=self.method,
        )  # fmt: skip
        is_dict = isinstance(self.observation_space, spaces.Dict)
        buffer_class = HuRiDictRolloutBuffer if is_dict else HuRiRolloutBuffer
        self.rollout_buffer = buffer_class(
            self.n_steps, self.observation_space, self.action_space,  # type: ignore[arg-type]
            device=self.device, gamma=self.gamma, gae_lambda=self.gae_lambda, n_envs=self.n_envs,
            n_quantiles=self.risk_model.n_quantiles, sr_lambda=self.sr_lambda,
            td_level=self.risk_model.td_level,
        )  # fmt: skip
        self.policy = self.policy_class(  # type: ignore[assignment]
            self.observation_space, self.action_space, self.lr_schedule, use_sde=self.use_sde,
            **self.policy_kwargs,
        ).to(self.device)  # fmt: skip
        self.clip_range = FloatSchedule(self.clip_range)
        self.critic_lr_schedule = (
            None if self.critic_learning_rate is None else FloatSchedule(self.critic_learning_rate)
        )

    def _init_callback(self, callback: MaybeCallback, progress_bar: bool = False) -> BaseCallback:
        if self.policy.rnd is not None:  # the RND predictor trains first at the end of each rollout
            callback = with_rnd_training(callback)
        return super()._init_callback(callback, progress_bar)

    def _setup_learn(self, total_timesteps: int, *args: Any, **kwargs: Any) -> tuple[int, BaseCallback]:
        if self.risk_model.use_iqr and self.risk_model.iqr_band == "absolute" and self.env is not None:
            warn_unless_rewards_normalized(self.env, self.risk_model.iqr_thresholds)
        return super()._setup_learn(total_timesteps, *args, **kwargs)

    def set_parameters(
        self,
        load_path_or_dict: str | dict[str, Any],
        exact_match: bool = True,
        device: th.device | str = "auto",
    ) -> None:
        """SB3's, and a model saved with one learning rate also loads with ``critic_learning_rate``, its Adam
        state dropped (``sb3_huri.huri.saves.fitting_optimizer_state``); the RND predictor's Adam stays
        fused whatever the save holds."""
        if isinstance(load_path_or_dict, dict) and self.policy.critic_param_group:
            fitting = fitting_optimizer_state(load_path_or_dict, self.policy.optimizer)
            exact_match = exact_match and fitting is load_path_or_dict
            load_path_or_dict = fitting
        super().set_parameters(load_path_or_dict, exact_match=exact_match, device=device)
        if self.policy.rnd is not None:
            self.policy.rnd.fuse_optimizer()

    def _excluded_save_params(self) -> list[str]:
        # `_mirrors`: rebuilt by each update from the env; `risk_model`: by `_setup_model` from its settings
        return [*super()._excluded_save_params(), "_mirrors", "risk_model"]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        state_dicts, variables = super()._get_torch_save_params()
        if self.policy_kwargs.get("rnd_kwargs") is not None:
            state_dicts.append("policy.rnd.optimizer")
        return state_dicts, variables

    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: HuRiRolloutBuffer | HuRiDictRolloutBuffer,  # type: ignore[override]
        n_rollout_steps: int,
    ) -> bool:
        """Fill the buffer with ``n_rollout_steps`` steps per env, then assess every state's risk.

        Like SB3's loop, except that the critic's atoms are stored as they come and sorted at the end of
        the rollout in one batch, and that time-outs are collected and bootstrapped there in one batch too,
        because their value depends on the risk parameter of the final state.
        """
        assert self._last_obs is not None, "No previous observation was provided"
        self.policy.set_training_mode(False)
        n_steps = 0
        rollout_buffer.reset()
        if self.use_sde:
            self.policy.reset_noise(env.num_envs)
        callback.on_rollout_start()
        time_outs: list[tuple[int, int, Any]] = []  # (step, env index, final observation)

        while n_steps < n_rollout_steps:
            if self.use_sde and self.sde_sample_freq > 0 and n_steps % self.sde_sample_freq == 0:
                self.policy.reset_noise(env.num_envs)
            with th.no_grad():
                obs_tensor = obs_as_tensor(self._last_obs, self.device)  # type: ignore[arg-type]
                actions, atoms, log_probs = self.policy(obs_tensor)
            actions = actions.cpu().numpy()
            clipped_actions = actions
            if isinstance(self.action_space, spaces.Box):
                if self.policy.squash_output:
                    clipped_actions = self.policy.unscale_action(clipped_actions)
                else:
                    clipped_actions = np.clip(actions, self.action_space.low, self.action_space.high)

            new_obs, rewards, dones, infos = env.step(clipped_actions)
            self.num_timesteps += env.num_envs
            callback.update_locals(locals())
            if not callback.on_step():
                return False
            self._update_info_buffer(infos, dones)
            n_steps += 1
            if isinstance(self.action_space, spaces.Discrete):
                actions = actions.reshape(-1, 1)
            for idx in np.flatnonzero(dones):
                final_obs = infos[idx].get("terminal_observation")
                if final_obs is not None and infos[idx].get("TimeLimit.truncated", False):
                    time_outs.append((rollout_buffer.pos, int(idx), final_obs))
            rollout_buffer.add(self._last_obs, actions, rewards, self._last_episode_starts, atoms, log_probs)  # type: ignore[arg-type]
            self._last_obs = new_obs  # type: ignore[assignment]
            self._last_episode_starts = dones

        self._finish_rollout(rollout_buffer, new_obs, dones, time_outs)
        callback.update_locals(locals())
        callback.on_rollout_end()
        return True

    def _finish_rollout(
        self,
        buffer: HuRiRolloutBuffer | HuRiDictRolloutBuffer,
        last_obs: Any,
        dones: np.ndarray,
        time_outs: list[tuple[int, int, Any]],
    ) -> None:
        """Risk parameters, distorted values, advantages and critic targets for the collected rollout.

        All states (the rollout's, the next ones and the final states of truncated episodes) are assessed
        in one batch. The RND input statistics are updated with the rollout before its novelty is measured.
        """
        n_rollout = buffer.buffer_size * buffer.n_envs
        buffer.sort_atoms()
        extra_obs = [last_obs] + [add_batch_axis(obs) for _, _, obs in time_outs]
        with th.no_grad():
            extra = obs_as_tensor(concatenate_observations(extra_obs), self.device)
            rollout_atoms = th.as_tensor(buffer.atoms, device=self.device).reshape(n_rollout, -1)
            if self.risk_model.adapts_band:  # the rollout's states move the band before they are read
                self._move_band(to_numpy(interquartile_range(rollout_atoms)))
            outputs = th.cat((rollout_atoms, self.policy.predict_values(extra)))
            critic_inputs = None
            if self.policy.rnd is not None:
                rollout_obs = obs_as_tensor(buffer.flat_observations(), self.device)
                rollout_inputs = self.policy.critic_features(rollout_obs)
                self.policy.rnd.update_normalizer(rollout_inputs)
                critic_inputs = th.cat((rollout_inputs, self.policy.critic_features(extra)))
            assessed = self._assess(outputs, critic_inputs)

        rollout = RiskReading(*(to_numpy(tensor[:n_rollout]) for tensor in assessed))
        shape, n_last = (buffer.buffer_size, buffer.n_envs), buffer.n_envs
        buffer.set_risk(
            rollout.weights.reshape(*shape, -1),
            rollout.risk.reshape(shape),
            rollout.iqr.reshape(shape),
            rollout.rnd_error.reshape(shape),
            last_weights=to_numpy(assessed.weights[n_rollout : n_rollout + n_last]),
        )
        if time_outs:
            steps, envs = np.array([t[0] for t in time_outs]), np.array([t[1] for t in time_outs])
            first = n_rollout + n_last
            buffer.set_time_out_bootstrap(
                steps, envs, to_numpy(assessed.atoms[first:]), to_numpy(assessed.value[first:]),
                weights=to_numpy(assessed.weights[first:]),
            )  # fmt: skip
        buffer.compute_returns_and_advantage(
            last_values=assessed.value[n_rollout : n_rollout + n_last],
            dones=dones,
            last_atoms=to_numpy(assessed.atoms[n_rollout : n_rollout + n_last]),
        )
        if self.risk_model.distributional:
            for key, value in self.risk_model.rollout_metrics(rollout).items():
                self.logger.record(key, value)

    def _move_band(self, iqr: np.ndarray) -> None:
        """Move the percentile band's thresholds with a rollout's per-state IQRs (saved as
        ``iqr_thresholds``; ``RiskModel.with_band_from``)."""
        self._set_risk_model(self.risk_model.with_band_from(iqr, first=self.iqr_band_rollouts == 0))
        self.iqr_band_rollouts += 1

    def assess_risk(self, observation: np.ndarray | dict[str, np.ndarray]) -> RiskAssessment:
        """Return distribution, risk parameter and distorted value the critic gives to observations.

        For analysis, e.g. tracking ``beta`` and the value distribution along an episode (paper Fig. 5).
        Observations are taken as the policy sees them (normalized already when training used
        ``VecNormalize``). As with ``predict``, a batch gives one row per observation, and a single
        observation unbatched results: atoms of shape ``(n_quantiles,)`` and scalars.
        """
        obs_tensor, vectorized = self.policy.obs_to_tensor(observation)
        with th.no_grad():
            critic_inputs = self.policy.critic_features(obs_tensor) if self.policy.rnd is not None else None
            assessed = self._assess(self.policy.predict_values(obs_tensor), critic_inputs)
        arrays = (to_numpy(getattr(assessed, name)) for name in RiskAssessment._fields)
        return RiskAssessment(*(array if vectorized else array[0] for array in arrays))

    def _assess(self, outputs: th.Tensor, critic_inputs: th.Tensor | None) -> RiskReading:
        """The risk model's reading of critic outputs ``(B, n_quantiles)`` (:meth:`RiskModel.assess`), with
        the RND novelty of the critic's flat inputs ``(B, features)`` (``None`` without RND)."""
        rnd = self.policy.rnd
        rnd_error = (
            rnd.prediction_error(critic_inputs) if rnd is not None and critic_inputs is not None else None
        )
        return self.risk_model.assess(outputs, rnd_error)

    def train(self) -> None:
        """One PPO update on the collected rollout (paper eq. 12).

        ``loss = surrogate + vf_coef * critic_loss - ent_coef * entropy`` (see :meth:`_critic_loss`).
        With ``desired_kl`` the learning rate adapts to each minibatch's approximate KL before its step.
        """
        self.policy.set_training_mode(True)
        progress = self._current_progress_remaining
        if self.desired_kl is None:
            self._set_learning_rates(self.lr_schedule(progress))
        else:  # starts from the schedule's value, then carries over from update to update
            self._set_kl_learning_rate(self.kl_learning_rate or self.lr_schedule(progress))
        clip_range = self.clip_range(progress)  # type: ignore[operator]
        self._mirrors = self.mirror_maps() if self.mirror_coef > 0 else None
        logs: dict[str, list[float]] = defaultdict(list)
        approx_kl_divs: list[float] = []
        actor_rates: list[float] = []  # the rate of each minibatch's step (desired_kl)
        continue_training = True

        for epoch in range(self.n_epochs):
            approx_kl_divs = []
            for data in self.rollout_buffer.get(self.batch_size):
                loss, approx_kl_div = self._minibatch_loss(data, clip_range, logs)
                approx_kl_divs.append(approx_kl_div)
                if self.target_kl is not None and approx_kl_div > 1.5 * self.target_kl:
                    continue_training = False
                    if self.verbose >= 1:
                        print(f"Early stopping at step {epoch} due to reaching max kl: {approx_kl_div:.2f}")
                    break
                if self.desired_kl is not None:
                    self._adapt_learning_rate(approx_kl_div)
                    actor_rates.append(self.kl_learning_rate)

                self.policy.optimizer.zero_grad()
                loss.backward()
                th.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()

            self._n_updates += 1
            if not continue_training:
                break

        for name, key in (
            ("entropy", "entropy_loss"),
            ("pg", "policy_gradient_loss"),
            ("value", "value_loss"),
        ):
            self.logger.record(f"train/{key}", np.mean(logs[name]))
        if self._mirrors is not None:
            self.logger.record("train/mirror_loss", np.mean(logs["mirror"]))
        if self.risk_model.distributional:
            self.logger.record("train/quantile_loss", np.mean(logs["quantile"]))
            self.logger.record("train/expectation_loss", np.mean(logs["expectation"]))
        self.logger.record("train/approx_kl", np.mean(approx_kl_divs))
        self.logger.record("train/clip_fraction", np.mean(logs["clip"]))
        self.logger.record("train/loss", loss.item())
        values, returns = self.rollout_buffer.values.flatten(), self.rollout_buffer.returns.flatten()
        self.logger.record("train/explained_variance", explained_variance(values, returns))
        if hasattr(self.policy, "log_std"):
            self.logger.record("train/std", th.exp(self.policy.log_std).mean().item())
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)
        if self.desired_kl is not None:
            # The rate rises and falls within an update (the KL is ~0 at its first minibatch): its mean.
            self.logger.record("train/learning_rate", float(np.mean(actor_rates or [self.kl_learning_rate])))
        if self.critic_lr_schedule is not None:
            self.logger.record("train/critic_learning_rate", self.critic_lr_schedule(progress))

    def _minibatch_loss(
        self, data: HuRiRolloutBufferSamples, clip_range: float, logs: dict[str, list]
    ) -> tuple[th.Tensor, float]:
        """PPO's loss on a minibatch (clipped surrogate, critic loss, entropy bonus) and its approximate KL
        from the rollout's policy (before this minibatch's step); the parts are appended to `logs`."""
        actions = data.actions
        if isinstance(self.action_space, spaces.Discrete):
            actions = data.actions.long().flatten()
        outputs, log_prob, entropy = self.policy.evaluate_actions(data.observations, actions)

        advantages = data.advantages
        if self.normalize_advantage and len(advantages) > 1:
            advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        log_ratio = log_prob - data.old_log_prob
        ratio = th.exp(log_ratio)
        policy_loss = -th.min(
            advantages * ratio, advantages * th.clamp(ratio, 1 - clip_range, 1 + clip_range)
        ).mean()
        value_loss = self._critic_loss(outputs, data, logs)
        entropy_loss = -th.mean(-log_prob) if entropy is None else -th.mean(entropy)
        loss = policy_loss + self.ent_coef * entropy_loss + self.vf_coef * value_loss
        if self._mirrors is not None:
            observations = data.observations
            actor_observations = observations[ACTOR_KEY] if isinstance(observations, dict) else observations
            symmetry = mirror_loss(self.policy.actor_mean, actor_observations, *self._mirrors)
            loss = loss + self.mirror_coef * symmetry
            logs["mirror"].append(symmetry.item())

        logs["pg"].append(policy_loss.item())
        logs["value"].append(value_loss.item())
        logs["entropy"].append(entropy_loss.item())
        logs["clip"].append(th.mean((th.abs(ratio - 1) > clip_range).float()).item())
        with th.no_grad():
            approx_kl_div = th.mean((ratio - 1) - log_ratio).item()
        return loss, approx_kl_div

    def _critic_loss(
        self, outputs: th.Tensor, data: HuRiRolloutBufferSamples, logs: dict[str, list]
    ) -> th.Tensor:
        """The critic's loss on a minibatch: PPO's MSE for a scalar critic, and for a quantile critic
        ``quantile_coef * energy_distance(atoms, SR(lambda) targets) + expectation_coef * expectation loss``
        (eqs. 4, 5; ``expectation_loss`` picks the reading of eq. 5, see ``sb3_huri.common.expectation``).
        """
        if not self.risk_model.distributional:
            return F.mse_loss(data.returns, outputs.flatten())
        atoms = sorted_atoms(outputs)
        quantile_loss = energy_distance(atoms, data.target_atoms, presorted=True).mean()  # targets: sorted
        mean_loss = expectation_loss(atoms, data.target_atoms, data.distortion_weights, self.expectation_loss)
        logs["quantile"].append(quantile_loss.item())
        logs["expectation"].append(mean_loss.item())
        return self.quantile_coef * quantile_loss + self.expectation_coef * mean_loss

    def _adapt_learning_rate(self, approx_kl: float) -> None:
        """KL-adaptive step: a smaller learning rate when the policy moved too far, larger when too little
        (:func:`~sb3_huri.common.learning_rate.kl_adaptive_rate`)."""
        assert self.desired_kl is not None and self.kl_learning_rate is not None
        desired, bounds = self.desired_kl, self.kl_learning_rate_bounds
        self._set_kl_learning_rate(kl_adaptive_rate(self.kl_learning_rate, approx_kl, desired, bounds))

    def _set_kl_learning_rate(self, learning_rate: float) -> None:
        self.kl_learning_rate = learning_rate
        self._set_learning_rates(learning_rate)

    def _set_learning_rates(self, learning_rate: float) -> None:
        """Set the optimizer's rate: ``learning_rate`` everywhere, or on the actor with the critic's own."""
        self.logger.record("train/learning_rate", learning_rate)
        schedule = self.critic_lr_schedule
        critic_rate = None if schedule is None else schedule(self._current_progress_remaining)
        set_learning_rates(self.policy.optimizer, learning_rate, critic_rate)

    @classmethod
    def load(cls: type[SelfHuRiPPO], path: Any, env: GymEnv | None = None, **kwargs: Any) -> SelfHuRiPPO:
        """SB3's ``load``. Hyperparameters passed in `kwargs` replace the saved ones (as in SB3, and as
        ``rl_zoo3 train -i`` continues a trained agent with its preset's); they are checked as the
        constructor checks them, and a ValueError names the first invalid one. A model saved by an earlier
        version loads with its settings under today's names (``sb3_huri.huri.saves``)."""
        model = super().load(path, env, **kwargs)
        model._check_settings()
        return model

    def mirror_maps(self) -> tuple[NormalizedMirror, NormalizedMirror]:
        """The env's mirror of the actor's observation, in the units the normalizer gives the actor (its
        statistics now), and its mirror of the action; ValueError if the env has none."""
        normalizer = self.get_vec_normalize_env()
        return env_mirrors(self.env, self.observation_space, normalizer, ACTOR_KEY, self.device)

    def learn(
        self: SelfHuRiPPO,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 1,
        tb_log_name: str = "HuRiPPO",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfHuRiPPO:
        return super().learn(
            total_timesteps=total_timesteps,
            callback=callback,
            log_interval=log_interval,
            tb_log_name=tb_log_name,
            reset_num_timesteps=reset_num_timesteps,
            progress_bar=progress_bar,
        )
