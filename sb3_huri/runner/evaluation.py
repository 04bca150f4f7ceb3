"""Evaluating a trained Zerith-1 agent: survival, velocity tracking, gait and the critic's risk, per scenario.

A *case* is a scenario with an optional fixed command, ``scenario@vx`` (command (vx, 0, 0)) or a scenario
alone (its own command: (1, 0, 0) for the paper's test scenarios). ``evaluate`` runs one episode on each of
``episodes`` robots side by side with the deterministic policy; robot i is seeded ``seed + i``, so every
agent meets the same conditions. Metrics:

- ``survive``: share of episodes that reach the time limit without a fall;
- ``vx_err``: mean |v_x - v_x,cmd| (m/s, pelvis frame) over every step of every episode, up to a fall;
- ``vx``: mean forward velocity (m/s); ``lin_err``: mean |v_xy - v_xy,cmd|; ``yaw_err``: mean |w_z - w_z,cmd|;
- ``steps_per_s``: steps per second, a step being a foot off the ground for at least 60 ms (a walk at the
  0.7-s gait clock makes about 2.9);
- ``alternation``: share of consecutive steps made by alternate feet, not together (1 = the feet take turns);
- ``single_support``: share of the time on exactly one foot.

With ``risk=True`` the critic's view of every state is recorded too (``HuRiPPO.assess_risk``: the sorted
return quantiles, the risk parameter beta and the interquartile range): ``beta`` and ``iqr`` averaged over
every robot-step, and robot 0's trace, step by step, with the external force it felt (the paper's Fig. 5).
With ``risk_states=True`` every robot-step's assessment is kept too (``RiskStates``: the risk level, its IQR
and RND parts, the IQR and the RND novelty), for statistics over all the states an agent visits
(``study.analyses.risk_levels``).

``PROTOCOL`` is the paper's evaluation: the six disturbance scenarios of its Table 1
(survival), ``load``, ``friction``, ``load-friction`` and ``uneven`` (velocity tracking, its Fig. 4), the
terrain tests of its appendix (Tables 8 and 9: survival) and walking on the plane, with risk traces on the
plane, under sudden pushes and on uneven ground (its Fig. 5).
"""

from __future__ import annotations

import contextlib
import itertools
import random
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sb3_huri.runner.files import RunError, replaced
from zerith_gym.core.observations import layout_slices
from zerith_gym.core.randomization import DOMAIN_VECTOR_SIZE, DomainParams
from zerith_gym.core.scenarios import SCENARIOS, TEST_COMMAND
from zerith_gym.zerith1.constants import CONTROL_DT, ZERITH1

MIN_AIR_STEPS = 3
"""A foot must stay off the ground this many control steps (60 ms) for a step to count."""

TABLE1_SCENARIOS = (
    "continuous-centroid",
    "continuous-hands",
    "continuous-feet",
    "sudden-centroid",
    "sudden-hands",
    "sudden-feet",
)
"""The paper's Table 1 columns: success (no fall) under continuous and sudden forces on three body parts."""
TRACKING_SCENARIOS = ("load", "friction", "load-friction", "uneven")
"""The paper's Fig. 4 conditions (velocity tracking), and uneven ground."""
PLANE_CASE = f"nominal@{TEST_COMMAND[0]:g}"
"""Walking on the plane at the test command, no randomization and no force: the reference for the risk."""
RISK_CASES = (PLANE_CASE, "sudden-centroid", "uneven")
"""Where the critic's value distribution and beta are traced (the paper's Fig. 5: plane, push, uneven)."""
TERRAIN_SCENARIOS = ("multi-terrain", "platform-0.40", "platform-0.45")
"""The paper's terrain tests: Table 9 (rough slopes and blocks, U[0, 100] N on the centroid) and Table 8
(stepping down a 0.40 / 0.45 m platform under forces and a +-1 kg mass change)."""
PROTOCOL = (PLANE_CASE, *TABLE1_SCENARIOS, *TRACKING_SCENARIOS, *TERRAIN_SCENARIOS)
"""Every case of the evaluation, in the order it runs."""


def parse_case(case: str) -> tuple[str, tuple[float, float, float] | None]:
    """``scenario@vx`` -> (scenario, (vx, 0, 0)); ``scenario`` -> (scenario, None). ValueError if unknown."""
    name, _, vx = case.partition("@")
    if name not in SCENARIOS:
        raise ValueError(
            f"unknown scenario {name!r} in case {case!r}; valid scenarios: {', '.join(SCENARIOS)}"
        )
    return name, None if not vx else (float(vx), 0.0, 0.0)


def gait_measures(contact: np.ndarray, min_air_steps: int = MIN_AIR_STEPS) -> tuple[float, float, float]:
    """Steps per second, share of consecutive steps taken in turn by the two feet, single-support share.

    ``contact`` is (steps, 2) booleans of one episode; a step is a foot leaving the ground for at least
    ``min_air_steps`` control steps (shorter losses of contact are chatter, not steps).
    """
    starts = []
    for foot in range(2):
        air = np.concatenate([[False], ~contact[:, foot], [False]]).astype(np.int8)
        edges = np.diff(air)
        lift, land = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        real = lift[land - lift >= min_air_steps]
        starts.append(real)
    # A step alternates when the other foot stepped exactly once since this foot's previous step, and
    # not together with it (which would be a two-footed hop).
    turns = []
    for own, other in ((starts[0], starts[1]), (starts[1], starts[0])):
        for previous, current in itertools.pairwise(own):
            between = other[(other > previous) & (other < current)]
            together = np.abs(other - current).min(initial=min_air_steps) < min_air_steps
            turns.append(len(between) == 1 and not together)
    alternation = float(np.mean(turns)) if turns else 0.0
    steps = sum(len(own) for own in starts)
    rate = steps / (len(contact) * CONTROL_DT) if len(contact) else 0.0
    single = float(np.mean(contact.sum(axis=1) == 1)) if len(contact) else 0.0
    return rate, alternation, single


class HoldStance:
    """A policy that holds the default stance (the zero action, whatever it observes): what the PD
    controllers alone do, the reference a trained agent should beat."""

    def predict(self, obs: dict[str, np.ndarray], deterministic: bool = True) -> tuple[np.ndarray, None]:
        robots = len(next(iter(obs.values())))
        return np.zeros((robots, ZERITH1.num_joints), dtype=np.float32), None


@dataclass
class RiskTrace:
    """The critic's view along robot 0's episode (NaN after it ended), and averages over every robot-step."""

    beta: np.ndarray
    """(steps,) risk parameter of each state (Wang's beta; CVaR's alpha; 0 for a scalar critic)."""
    iqr: np.ndarray
    """(steps,) interquartile range of the return quantiles."""
    atoms: np.ndarray
    """(steps, n_quantiles) the sorted return quantiles (units of the normalized return when training
    normalized rewards)."""
    force: np.ndarray
    """(steps,) magnitude of the external force (N) in the state."""
    beta_mean: float
    iqr_mean: float

    def arrays(self) -> dict[str, np.ndarray]:
        """The trace as named arrays (for ``np.savez``)."""
        return {"beta": self.beta, "iqr": self.iqr, "atoms": self.atoms, "force": self.force}


RISK_STATE_FIELDS = ("risk", "risk_iqr", "risk_rnd", "iqr", "rnd_error")
"""The fields of ``HuRiPPO.assess_risk``'s reading that ``RiskStates`` keeps for every robot-step."""


@dataclass
class RiskStates:
    """The critic's view of every state a rollout visited: one entry per robot-step, step by step, of every
    robot still in its episode (up to a fall or the time limit), flattened to arrays of shape
    (robot-steps,) in the critic's precision (float32), the precision ``RiskModel.assess`` compares the IQR
    with its band in; ``robot`` and ``step`` say whose state each entry is and when."""

    risk: np.ndarray
    """Risk level (Wang's beta; CVaR's alpha): ``risk_iqr + risk_rnd`` (CVaR: clipped to 1)."""
    risk_iqr: np.ndarray
    """The IQR band's part of the risk level (the fixed level without ``use_iqr``)."""
    risk_rnd: np.ndarray
    """``tanh(rnd_error)`` (0 without RND)."""
    iqr: np.ndarray
    """Interquartile range of the critic's return quantiles."""
    rnd_error: np.ndarray
    """RND novelty of the critic input (0 without RND)."""
    robot: np.ndarray | None = None
    """The robot (episode) index of each state."""
    step: np.ndarray | None = None
    """The control step of each state within its episode."""


class _RiskRecorder:
    """What ``_rollout`` gathers of the critic's view, step by step: robot 0's trace, the sums over every
    robot-step and, with ``states``, each robot-step's assessment (``RiskStates``)."""

    def __init__(self, states: bool) -> None:
        self.trace: dict[str, list[Any]] = {"beta": [], "iqr": [], "atoms": [], "force": []}
        self.sums = np.zeros(3)  # beta, iqr, robot-steps
        self.states: dict[str, list[np.ndarray]] | None = (
            {name: [] for name in (*RISK_STATE_FIELDS, "robot", "step")} if states else None
        )

    def record(self, assessed: Any, alive: np.ndarray, force: float) -> None:
        """One step: the model's reading ``assessed`` of every robot's state, the robots still in their
        episode and the external force robot 0 felt (N)."""
        self.sums += (assessed.risk[alive].sum(), assessed.iqr[alive].sum(), alive.sum())
        first = alive[0]
        self.trace["beta"].append(assessed.risk[0] if first else np.nan)
        self.trace["iqr"].append(assessed.iqr[0] if first else np.nan)
        self.trace["atoms"].append(assessed.atoms[0] if first else np.full_like(assessed.atoms[0], np.nan))
        self.trace["force"].append(force if first else np.nan)
        if self.states is not None:
            for name in RISK_STATE_FIELDS:
                self.states[name].append(np.asarray(getattr(assessed, name))[alive])
            self.states["robot"].append(np.flatnonzero(alive))
            self.states["step"].append(np.full(int(alive.sum()), len(self.trace["beta"]) - 1))

    def results(self) -> dict[str, Any]:
        """``beta`` and ``iqr`` (means over every robot-step), ``trace`` and, if kept, ``states``."""
        beta_mean, iqr_mean = (self.sums[:2] / self.sums[2]).tolist()
        arrays = (np.array(self.trace[key], dtype=float) for key in ("beta", "iqr", "atoms", "force"))
        result: dict[str, Any] = {
            "beta": beta_mean,
            "iqr": iqr_mean,
            "trace": RiskTrace(*arrays, beta_mean, iqr_mean),
        }
        if self.states is not None:
            result["states"] = RiskStates(
                **{name: np.concatenate(values) for name, values in self.states.items()}
            )
        return result


@contextlib.contextmanager
def random_states_kept() -> Iterator[None]:
    """Restore the global random states of Python, NumPy and torch (CPU and CUDA) on leaving: an evaluation
    inside a training process leaves what the training draws next unchanged."""
    import torch as th

    python, numpy, torch = random.getstate(), np.random.get_state(), th.get_rng_state()  # noqa: NPY002
    cuda = th.cuda.get_rng_state_all() if th.cuda.is_available() else None
    try:
        yield
    finally:
        random.setstate(python)
        np.random.set_state(numpy)  # noqa: NPY002
        th.set_rng_state(torch)
        if cuda is not None:
            th.cuda.set_rng_state_all(cuda)


def evaluate(
    model: Any,
    normalizer: Any | None,
    scenario: str,
    command: tuple[float, float, float] | None,
    episodes: int,
    seed: int,
    *,
    episode_steps: int | None = None,
    workers: int | None = None,
    risk: bool = False,
    risk_states: bool = False,
    per_robot: bool = False,
    backend_options: Mapping[str, Any] | None = None,
    robot: str = "zerith1",
) -> dict[str, Any]:
    """Run one episode on each of ``episodes`` robots and summarize them (see the module docstring).

    ``normalizer``: the run's ``VecNormalize`` (observations are normalized as in training) or None.
    ``episode_steps``: the time limit (default: the env's, 20 s); ``workers``: processes stepping the
    robots (``zerith_gym.make_vec_env``; default one per core). With ``risk`` the result also holds
    ``beta`` and ``iqr`` (means over every robot-step) and ``trace``, a ``RiskTrace``; ``risk_states``
    implies ``risk`` and adds ``states``, a ``RiskStates`` of every robot-step. With ``per_robot``
    it holds each robot's ``fall_step`` too: (episodes,) the control step at which it fell, NaN where none
    fell; and ``domain``: the ``DomainParams`` it was drawn (physical units), to tell which conditions fell.
    ``backend_options``: more ``make_vec_env`` arguments, e.g. ``{"backend": "mjx", "solver_iterations": 4}``.
    ``robot``: the robot the model drives ("zerith1", "go2like").
    """
    import zerith_gym

    options: dict[str, Any] = {"scenario": scenario, "command": command, "robot": robot}
    if episode_steps is not None:
        options["episode_steps"] = episode_steps
    env = zerith_gym.make_vec_env(episodes, seed=seed, workers=workers, **options, **(backend_options or {}))
    try:
        recorder = _RiskRecorder(risk_states) if risk or risk_states else None
        result = _rollout(model, normalizer, env, episodes, recorder)
    finally:
        env.close()
    if not per_robot:
        del result["fall_step"], result["domain"]
    return result


def _rollout(
    model: Any, normalizer: Any | None, env: Any, episodes: int, recorder: _RiskRecorder | None
) -> dict[str, Any]:
    task = env.options.task  # the robot's critic layout and scales
    in_units, blocks = task.critic_in_units, layout_slices(task.critic_layout)
    obs = env.reset()
    domain = in_units(obs["critic"])[:, -DOMAIN_VECTOR_SIZE:]  # every task's critic ends with them
    horizon = env.options.episode_steps
    vx_cmd = np.array([info["command"][0] for info in env.reset_infos])
    alive = np.ones(episodes, dtype=bool)
    fall_step = np.full(episodes, np.nan)
    vx = np.full((horizon, episodes), np.nan)
    lin_err, yaw_err = np.full_like(vx, np.nan), np.full_like(vx, np.nan)
    feet = blocks["foot_contact"].stop - blocks["foot_contact"].start
    contact = np.zeros((horizon, episodes, feet), dtype=bool)
    for t in range(horizon):
        policy_obs = normalizer.normalize_obs(obs) if normalizer is not None else obs
        if recorder is not None:
            force = np.linalg.norm(in_units(obs["critic"][0])[blocks["external_force"]])
            recorder.record(model.assess_risk(policy_obs), alive, force)
        action, _ = model.predict(policy_obs, deterministic=True)
        obs, _, dones, infos = env.step(action)
        critic = np.stack(
            [
                info.get("terminal_observation", obs)["critic"] if d else obs["critic"][i]
                for i, (info, d) in enumerate(zip(infos, dones, strict=True))
            ]
        )
        vx[t, alive] = in_units(critic[alive])[:, blocks["base_linear_velocity"]][:, 0]
        contact[t, alive] = critic[alive, blocks["foot_contact"]] > 0.5
        lin_err[t, alive] = [infos[i]["lin_vel_error"] for i in np.flatnonzero(alive)]
        yaw_err[t, alive] = [infos[i]["ang_vel_error"] for i in np.flatnonzero(alive)]
        fall_step[alive & np.array([info["fall"] for info in infos])] = t
        alive &= ~dones
        if not alive.any():
            break
    if feet == 2:
        gait = np.array([gait_measures(contact[~np.isnan(vx[:, i]), i]) for i in range(episodes)])
    else:  # the step counts are a biped's
        gait = np.full((episodes, 3), np.nan)
    result: dict[str, Any] = {
        "survive": float(np.mean(np.isnan(fall_step))),
        "vx_err": float(np.nanmean(np.abs(vx - vx_cmd))),
        "vx": float(np.nanmean(vx)),
        "lin_err": float(np.nanmean(lin_err)),
        "yaw_err": float(np.nanmean(yaw_err)),
        "steps_per_s": float(gait[:, 0].mean()),
        "alternation": float(gait[:, 1].mean()),
        "single_support": float(gait[:, 2].mean()),
        "fall_step": fall_step,
        "domain": DomainParams.from_vector(domain),
    }
    if recorder is not None:
        result.update(recorder.results())
    return result


def risk_file(folder: Path, case: str, prefix: str = "") -> Path:
    """Where the risk trace of ``case`` is kept in a run folder (``risk_nominal-1.npz`` for ``nominal@1``;
    ``<prefix>risk_nominal-1.npz`` to tell the traces of several evaluations apart)."""
    return folder / f"{prefix}risk_{case.replace('@', '-')}.npz"


def write_trace(target: Path, trace: RiskTrace) -> None:
    """Save ``trace``'s arrays at ``target`` (``.npz``) through a temporary file: no torn file on a kill."""
    with replaced(target) as temporary, open(temporary, "wb") as file:
        np.savez(file, **trace.arrays())


def read_trace(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a risk trace file (``write_trace``); RunError if it is corrupt."""
    try:
        with np.load(path) as arrays:
            return {key: arrays[key] for key in arrays.files}
    except (OSError, ValueError) as error:
        raise RunError(f"{path} is corrupt ({error}); delete it to evaluate anew") from error
