"""RL Zoo integration: HuRi's methods as ``rl_zoo3`` algorithms, its Optuna sampler and its presets.

After ``pip install sb3-huri`` a start-up hook (``_sb3_huri_zoo_hook``) calls the ``register_*`` and ``use_*``
functions below as soon as RL Zoo has imported the module each one needs, so RL Zoo's own commands work::

    rl_zoo3 train --algo huri --env Zerith1-v0 -conf hyperparams/huri.yml

``register()`` does all of it at once, for scripts and for the hook-free wrapper ``python -m sb3_huri.zoo``.

Each method of the paper's comparison is its own RL Zoo algorithm of the same name (``METHODS``: the algorithm
``huri-cvar0.5`` is ``HuRiPPO(method="huri-cvar0.5")``), so that RL Zoo's log folders
(``logs/<algo>/<env>_<run>``), ``enjoy --algo`` and ``plots.all_plots -a`` tell the methods apart with no
extra flag, while all of them read the same presets.
"""

from __future__ import annotations

import functools
import os
from typing import Any

from sb3_huri.huri import methods as _methods
from sb3_huri.zoo.presets import PRESETS_FILE, algorithm_kwargs, normalize_kwargs, read_preset

__all__ = [
    "METHODS",
    "PRESETS_FILE",
    "algorithm_kwargs",
    "method_class",
    "normalize_kwargs",
    "read_preset",
    "register",
]

METHODS: tuple[str, ...] = tuple(_methods.METHODS)
"""The methods, each an RL Zoo algorithm of its name (``HuRiPPO``'s ``method``, ``sb3_huri.huri.methods``)."""


def register() -> None:
    """Register every HuRi method, ``Zerith1-v0``, the sampler and the presets with RL Zoo (idempotent)."""
    register_algorithms()
    register_environments()
    register_samplers()
    use_packaged_hyperparameters()
    use_batched_zerith_env()


def register_algorithms() -> None:
    """Add the methods of ``METHODS`` to ``rl_zoo3.ALGOS``."""
    from rl_zoo3.utils import ALGOS

    for method in METHODS:
        ALGOS.setdefault(method, method_class(method))


def register_environments() -> None:
    """Register ``Zerith1-v0`` with Gymnasium, which RL Zoo checks ``--env`` against."""
    import zerith_gym  # noqa: F401


def register_samplers() -> None:
    """Make ``rl_zoo3 train --algo <method> --optimize`` (and ``--trial-id``) use the HuRi search space."""
    from rl_zoo3.hyperparams_opt import HYPERPARAMS_CONVERTER, HYPERPARAMS_SAMPLER

    from sb3_huri.zoo.sampler import convert_huri_params, sample_huri_params

    for name in METHODS:
        HYPERPARAMS_SAMPLER.setdefault(name, sample_huri_params)
        HYPERPARAMS_CONVERTER.setdefault(name, convert_huri_params)


def use_packaged_hyperparameters() -> None:
    """Without ``-conf``, let ``rl_zoo3 train --algo <method>`` read the presets shipped with the package.

    RL Zoo's default is ``hyperparams/<algo>.yml`` inside its own package, which does not exist for HuRi; any
    ``-conf`` given on the command line is left as it is.
    """
    from rl_zoo3.exp_manager import ExperimentManager

    init = ExperimentManager.__init__
    if getattr(init, "_uses_huri_presets", False):
        return

    @functools.wraps(init)
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        init(self, *args, **kwargs)
        if kwargs.get("config") is None and self.algo in METHODS and not os.path.isfile(self.config):
            self.config = str(PRESETS_FILE)

    __init__._uses_huri_presets = True  # type: ignore[attr-defined]
    ExperimentManager.__init__ = __init__  # type: ignore[method-assign]


def use_batched_zerith_env() -> None:
    """Let ``rl_zoo3 train`` step Zerith robots with ``zerith_gym.make_vec_env`` (a slice of robots per
    core) instead of RL Zoo's ``DummyVecEnv`` of one env per robot: several times faster, same transitions.

    It applies to envs registered with an entry point of ``zerith_gym.ROBOT_ENTRY_POINTS`` (``Zerith1-v0``,
    ``Go2Like-v0``), with RL Zoo's default ``--vec-env
    dummy`` and no ``env_wrapper``, ``vec_env_wrapper`` or ``frame_stack``; anything else takes RL Zoo's own
    path. Robot i is seeded ``seed + i`` as RL Zoo seeds env i, episodes go to one ``0.monitor.csv`` in the
    run folder (RL Zoo's plots read it), and ``VecNormalize`` is applied as RL Zoo applies it.
    """
    from rl_zoo3.exp_manager import ExperimentManager

    create_envs = ExperimentManager.create_envs
    if getattr(create_envs, "_batched_zerith", False):
        return

    @functools.wraps(create_envs)
    def batched_create_envs(self, n_envs: int, eval_env: bool = False, no_log: bool = False) -> Any:
        import warnings

        import gymnasium as gym
        from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

        import zerith_gym
        from zerith_gym import ROBOT_ENTRY_POINTS

        plain = self.env_wrapper is None and self.vec_env_wrapper is None and self.frame_stack is None
        spec = gym.spec(self.env_name.gym_id)
        if not (plain and self.vec_env_class is DummyVecEnv and spec.entry_point in ROBOT_ENTRY_POINTS):
            return create_envs(self, n_envs, eval_env, no_log)
        env_kwargs = {
            **(spec.kwargs or {}),
            **((self.eval_env_kwargs if eval_env else self.env_kwargs) or {}),
            "robot": ROBOT_ENTRY_POINTS[spec.entry_point],
        }
        env = zerith_gym.make_vec_env(n_envs, seed=self.seed, **env_kwargs)
        log_dir = None if eval_env or no_log else self.save_path
        # Training and evaluation envs get the same wrappers (SB3 syncs their normalizers wrapper by wrapper).
        with warnings.catch_warnings():  # the env's own episode statistics are the same as VecMonitor's
            warnings.filterwarnings("ignore", message=".*already wrapped with a `Monitor`")
            env = VecMonitor(env, log_dir and os.path.join(log_dir, "0"), **self.monitor_kwargs)
        return self._maybe_normalize(env, eval_env)

    batched_create_envs._batched_zerith = True  # type: ignore[attr-defined]
    ExperimentManager.create_envs = batched_create_envs  # type: ignore[method-assign]


@functools.cache
def method_class(method: str) -> type:
    """``HuRiPPO`` with its ``method`` fixed: the class RL Zoo builds for the algorithm `method` (the default
    method, ``huri``, is ``HuRiPPO`` itself); ValueError for a name not in ``METHODS``."""
    from sb3_huri import HuRiPPO
    from sb3_huri.huri.methods import DEFAULT_METHOD

    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}: expected one of {list(METHODS)}")
    if method == DEFAULT_METHOD:
        return HuRiPPO

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        if kwargs.setdefault("method", method) != method:
            raise ValueError(
                f"method={kwargs['method']!r} conflicts with the algorithm {method}, which is HuRiPPO(method="
                f"{method!r}): drop `method` from the hyperparameters or use --algo {DEFAULT_METHOD}"
            )
        HuRiPPO.__init__(self, *args, **kwargs)

    return type(
        f"HuRiPPO[{method}]",
        (HuRiPPO,),
        {"__init__": __init__, "__module__": __name__, "__doc__": f"HuRiPPO(method={method!r})."},
    )
