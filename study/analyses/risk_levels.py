"""The risk levels a HuRi agent's critic sets on the states it visits, scenario by scenario.

HuRi's risk level per state is ``beta = beta_IQR + beta_RND`` (docs/huri.md, "The algorithm", item 2):
``beta_IQR`` is the risk below / within / above the IQR band of the critic's return quantiles (Wang: -1, 0,
+1), ``beta_RND = tanh`` of the normalized RND novelty of the critic's input. ``measure_risk_levels`` runs one
agent (a run folder of the campaign: RL Zoo's layout, model and ``VecNormalize`` statistics) with the
deterministic policy on a few robots per case (robot i seeded ``seed + i``: the same robots for every agent),
one 20-s episode each, and reads every state a robot visits before its episode ends with
``HuRiPPO.assess_risk`` (``sb3_huri.runner.evaluation.evaluate(risk_states=True)``). Per case:

- ``below``, ``within``, ``above``: shares of the visited states whose IQR is below ``t_min``, in
  ``[t_min, t_max]`` or above ``t_max`` of the agent's own band (its thresholds as saved: fixed for the
  absolute band, frozen outside training for the percentile band);
- ``beta``, ``beta_iqr``, ``beta_rnd``: means of the risk level and its two parts (CVaR: ``alpha``);
  ``beta_rnd_p90``: the 90th percentile of ``beta_RND``; ``beta_rnd_above_half``: the share of states where
  ``beta_RND > 0.5``; ``rnd_error``: the mean normalized RND error;
- ``iqr_median``; ``survive``: the share of robots without a fall; ``robot_steps``: the states read;
- ``falls``: the robots that fell; ``before_fall_states``, ``beta_before_fall``, ``above_before_fall``: the
  states of a robot's last second before its fall (``FALL_WINDOW_STEPS``), their mean risk level and share
  above the band, and ``beta_elsewhere``, ``above_elsewhere`` the same over the case's other states (None
  where there are none): whether the critic turns averse where a fall follows.

The cases: the plane at the test speed (``nominal@1``), the paper's Fig. 5 conditions (``ROLE_CASES``: for
Zerith-1 sudden 150-200 N pushes on the centroid and uneven ground; for the quadruped Table 8's 0.40-m
platform under a centroid force and legged_gym's rough terrain), the agent's own training scenario (its
``config.yml`` names it) at 1 m/s and with the commands it trained on (the states most familiar to its RND),
and the plane at 0.5 m/s (a speed every training scenario commands, beside the 1 m/s the paper's protocol
never trains at).

The results go to ``<run>/evaluations/<steps>-risk_levels.json``, after each case (atomically): a later call
with the same settings skips the cases done. The file holds no ``entry`` key, the key by which the campaign
tells its final evaluations (``<steps>.json``, in the same folder) apart. ``study.scripts.risk_levels`` is the
command line; the results page's risk-levels section reads the files.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.evaluation import PLANE_CASE, RiskStates, evaluate, parse_case
from sb3_huri.runner.files import read_json, resumed_record, write_json
from sb3_huri.runner.record import EVALUATIONS
from zerith_gym import GO2LIKE_ID, ZERITH1_ID
from zerith_gym.core.scenarios import TEST_COMMAND

RISK_LEVELS_SUFFIX = "-risk_levels.json"
"""A checkpoint's risk levels are in its run's ``evaluations/`` folder, in ``<steps>-risk_levels.json``."""
ENV_IDS = (ZERITH1_ID, GO2LIKE_ID)
"""The envs whose run folders this reads (the robot is the env's)."""
ROLES = ("plane", "push", "uneven")
"""The paper's Fig. 5 conditions, in the order its risk level rises: the plane, a push, uneven ground."""
ROLE_CASES = {
    "zerith1": {"plane": PLANE_CASE, "push": "sudden-centroid", "uneven": "uneven"},
    "go2like": {"plane": PLANE_CASE, "push": "platform-0.40", "uneven": "quadruped-rough@1"},
}
"""Each robot's case for each role: the quadruped has no uneven-ground scenario of Zerith-1's nor its pushes
(150-200 N on a 15-kg trunk), so its push is Table 8's platform under U[0, 100] N and its uneven ground
legged_gym's rough terrain, at 1 m/s."""
TRAINING_SPEED_CASE = "nominal@0.5"
"""The plane at 0.5 m/s: a speed every training scenario commands (1 m/s lies beyond the paper's training
range, vx up to 0.7 m/s), the reference for the novelty of the test command."""
DEFAULT_ROBOTS = 5
DEFAULT_SEED = 2000
"""The first robots of the campaign's final evaluation (``eval_seed``)."""
FALL_WINDOW_STEPS = 50
"""The states "before a fall": a robot's last 50 control steps (1 s) up to the step it fell at."""
FALL_KEYS = ("falls", "before_fall_states", "beta_before_fall", "above_before_fall", "beta_elsewhere",
             "above_elsewhere")  # fmt: skip
"""What ``fall_statistics`` adds to a case (a file measured before it lacks them: measured again)."""
RND_HIGH = 0.5
"""``beta_rnd_above_half`` counts the states whose ``beta_RND`` exceeds this."""


def risk_levels_path(run: Path, steps: int) -> Path:
    """The risk-levels file of the run's checkpoint at ``steps``."""
    return run / EVALUATIONS / f"{steps}{RISK_LEVELS_SUFFIX}"


def risk_levels_files(run: Path) -> dict[int, Path]:
    """Every risk-levels file of a run folder, by the steps of the checkpoint it measured."""
    found = {}
    for path in (run / EVALUATIONS).glob(f"*{RISK_LEVELS_SUFFIX}"):
        steps = path.name[: -len(RISK_LEVELS_SUFFIX)]
        if steps.isdigit():
            found[int(steps)] = path
    return dict(sorted(found.items()))


def run_env_id(run: Path) -> str:
    """The env a run folder trained on: its ``args.yml``'s ``env``, else the one whose model it holds."""
    for env_id in ENV_IDS:
        args = run / env_id / "args.yml"
        named = (yaml.safe_load(args.read_text()) or {}).get("env") if args.is_file() else None
        if named in ENV_IDS:
            return str(named)
    held = [env_id for env_id in ENV_IDS if (run / f"{env_id}.zip").is_file()]
    if not held:
        raise ExperimentError(f"{run} holds no model of {' or '.join(ENV_IDS)} (<env_id>.zip)")
    return held[0]


def training_scenario(run: Path, env_id: str) -> str:
    """The scenario the run trained in: its preset's ``env_kwargs.scenario``, else the robot's default."""
    from zerith_gym import robot_of
    from zerith_gym.robots import locomotion_task

    path = run / env_id / "config.yml"
    config = yaml.safe_load(path.read_text()) if path.is_file() else None
    if isinstance(config, list):  # RL Zoo writes an ordered mapping as a list of pairs
        config = dict(config)
    scenario = ((config or {}).get("env_kwargs") or {}).get("scenario")
    return str(scenario) if scenario else locomotion_task(robot_of(env_id)).default_scenario


def default_cases(robot: str, scenario: str) -> list[str]:
    """The cases an agent of ``robot`` trained in ``scenario`` is measured on: the roles' cases, its training
    scenario at the test speed (unless a role's case already is) and with its own commands, and the plane at
    the training speed."""
    cases = list(ROLE_CASES[robot].values())
    at_test_speed = f"{scenario}@{TEST_COMMAND[0]:g}"
    return [*cases, *([at_test_speed] if at_test_speed not in cases else []), scenario, TRAINING_SPEED_CASE]


def case_statistics(states: RiskStates, thresholds: Sequence[float]) -> dict[str, float]:
    """The statistics of one case's visited states (see the module docstring) against the band
    ``(t_min, t_max)``, compared in the IQR's own precision as ``RiskModel.assess`` compares them."""
    iqr = np.asarray(states.iqr)
    t_min, t_max = np.asarray(thresholds, dtype=iqr.dtype)
    below, above = iqr < t_min, iqr > t_max
    beta_rnd = np.asarray(states.risk_rnd, dtype=np.float64)
    return {
        "robot_steps": len(iqr),
        "below": float(below.mean()),
        "within": float((~below & ~above).mean()),
        "above": float(above.mean()),
        "beta": float(np.mean(states.risk, dtype=np.float64)),
        "beta_iqr": float(np.mean(states.risk_iqr, dtype=np.float64)),
        "beta_rnd": float(beta_rnd.mean()),
        "beta_rnd_p90": float(np.quantile(beta_rnd, 0.9)),
        "beta_rnd_above_half": float((beta_rnd > RND_HIGH).mean()),
        "rnd_error": float(np.mean(states.rnd_error, dtype=np.float64)),
        "iqr_median": float(np.median(iqr)),
    }


def fall_statistics(states: RiskStates, fall_step: np.ndarray, thresholds: Sequence[float]) -> dict[str, Any]:
    """The risk levels of the states within ``FALL_WINDOW_STEPS`` before a robot's fall (``fall_step``: each
    robot's, NaN where none) against the case's other states: the module docstring's ``FALL_KEYS``."""
    iqr, fall_step = np.asarray(states.iqr), np.asarray(fall_step, dtype=float)
    to_fall = fall_step[states.robot] - states.step
    before = to_fall < FALL_WINDOW_STEPS  # NaN (no fall) compares False
    above = iqr > np.asarray(thresholds, dtype=iqr.dtype)[1]
    risk = np.asarray(states.risk, dtype=np.float64)

    def mean(values: np.ndarray, where: np.ndarray) -> float | None:
        return float(values[where].mean()) if where.any() else None

    return {
        "falls": int(np.count_nonzero(~np.isnan(fall_step))),
        "before_fall_states": int(before.sum()),
        "beta_before_fall": mean(risk, before),
        "above_before_fall": mean(above, before),
        "beta_elsewhere": mean(risk, ~before),
        "above_elsewhere": mean(above, ~before),
    }


def measured_cases(record: dict[str, Any]) -> set[str]:
    """The cases of a risk-levels record that hold every statistic, those before a fall included."""
    return {case for case, values in record["cases"].items() if all(key in values for key in FALL_KEYS)}


def choose_checkpoint(run: Path, env_id: str, steps: int | None = None) -> tuple[int, Path, Path | None, str]:
    """The checkpoint to measure: (steps, model file, normalizer file, why this one).

    ``steps`` None: the one the run's newest final evaluation (``evaluations/<steps>.json``) used if the run
    still holds it, else the run's newest model. ``steps`` given: the first saved model at or after it, as
    the campaign picks an entry's (``final_evaluation.find_checkpoint``). ExperimentError if there is none.
    """
    from sb3_huri.runner.folder import saved_models

    found = saved_models(run, env_id)
    if not found:
        raise ExperimentError(f"{run} holds no complete model of {env_id}")
    if steps is not None:
        later = [step for step in found if step >= steps]
        if not later:
            held = ", ".join(f"{step:,}" for step in found)
            raise ExperimentError(f"{run} holds no model at or after {steps:,} steps (models held: {held})")
        return min(later), *found[min(later)], f"the first model at or after {steps:,} steps"
    evaluated = sorted(int(p.stem) for p in (run / EVALUATIONS).glob("*.json") if p.stem.isdigit())
    if evaluated and evaluated[-1] in found:
        return evaluated[-1], *found[evaluated[-1]], "the checkpoint of its final evaluation"
    newest = max(found)
    why = "its newest model" + (
        f"; its final evaluation's checkpoint, {evaluated[-1]:,} steps, is not kept" if evaluated else ""
    )
    return newest, *found[newest], why


CHECKOUT_SPREAD_S = 1.0
"""A run's save writes its normalizer before ``state.json``; a git checkout writes them the other way round,
milliseconds apart. A normalizer newer than the state by more than this is a later save's, a rollout on."""


def load_measured(run: Path, env_id: str, steps: int, model_file: Path, normalizer_file: Path | None) -> Any:
    """Model and normalizer of the checkpoint at ``steps``. The run's newest model may be replaced while it is
    read (a run still training): ExperimentError unless the model holds ``steps`` steps and the run's
    state still names that step, with statistics saved no later than it."""
    from sb3_huri.runner.folder import load_checkpoint

    model, normalizer = load_checkpoint(model_file, normalizer_file)
    if model_file == run / f"{env_id}.zip":
        state = run / env_id / "state.json"
        held = int(read_json(state, "the run's training state")["timesteps"])
        stats_later = (
            normalizer_file is not None
            and normalizer_file.stat().st_mtime > state.stat().st_mtime + CHECKOUT_SPREAD_S
        )
        if model.num_timesteps != steps or held != steps or stats_later:
            raise ExperimentError(f"{run} saved a new checkpoint while it was read; measure it again")
    return model, normalizer


def band_of(model: Any) -> dict[str, Any]:
    """How the model reads its IQR band: reading, thresholds, the risk levels, distortion and RND."""
    risk = model.risk_model
    return {
        "reading": risk.iqr_band,
        "thresholds": [float(value) for value in risk.iqr_thresholds],
        "levels": [float(value) for value in risk.iqr_risk_levels],
        "distortion": risk.distortion,
        "use_iqr": risk.use_iqr,
        "use_rnd": risk.use_rnd,
    }


def measure_risk_levels(
    run: Path,
    *,
    steps: int | None = None,
    cases: Sequence[str] | None = None,
    robots: int = DEFAULT_ROBOTS,
    seed: int = DEFAULT_SEED,
    episode_steps: int | None = None,
    deadline: float | None = None,
) -> Path:
    """Measure the agent of ``run`` case by case (see the module docstring); return its file's path.

    ``steps``: the checkpoint (``choose_checkpoint``); ``cases``: ``scenario@vx`` or ``scenario`` (default:
    ``default_cases``); ``robots`` episodes per case, robot i seeded ``seed + i``; ``episode_steps``: the time
    limit (default the env's, 20 s); ``deadline`` (``time.time()``): start no case after it. Cases already in
    the file with the same settings are skipped; a file of other settings is refused (ExperimentError)
    rather than overwritten.
    """
    from zerith_gym import robot_of

    run = Path(run)
    env_id = run_env_id(run)
    robot, scenario = robot_of(env_id), training_scenario(run, env_id)
    wanted = list(cases) if cases is not None else default_cases(robot, scenario)
    for case in wanted:
        parse_case(case)  # unknown scenarios fail before the model is loaded
    steps, model_file, normalizer_file, why = choose_checkpoint(run, env_id, steps)
    model, normalizer = load_measured(run, env_id, steps, model_file, normalizer_file)
    if not getattr(model, "risk_model", None) or not model.risk_model.distributional:
        raise ExperimentError(f"{run}: its model has no quantile critic, hence no risk level to measure")
    path = risk_levels_path(run, steps)
    record = _record(run, env_id, robot, scenario, model, model_file, steps, robots, seed, episode_steps)
    record = _resumed(path, record)
    print(f"{run}: {steps:,} steps ({why}), {record['band']['reading']} band {record['band']['thresholds']}")
    done = measured_cases(record)
    for case in wanted:
        if case in done:
            continue
        if deadline is not None and time.time() >= deadline:
            break
        began = time.time()
        name, command = parse_case(case)
        result = evaluate(
            model, normalizer, name, command, robots, seed, episode_steps=episode_steps, workers=0,
            risk_states=True, robot=robot, per_robot=True,
        )  # fmt: skip
        thresholds = record["band"]["thresholds"]
        statistics = case_statistics(result["states"], thresholds)
        falls = fall_statistics(result["states"], result["fall_step"], thresholds)
        record["cases"][case] = {**statistics, **falls, "survive": result["survive"]}
        record["eval_s"] += time.time() - began
        path.parent.mkdir(parents=True, exist_ok=True)
        write_json(path, record)
        print(f"  {case_line(case, record['cases'][case])} ({time.time() - began:.0f} s)", flush=True)
    return path


def _record(
    run: Path,
    env_id: str,
    robot: str,
    scenario: str,
    model: Any,
    model_file: Path,
    steps: int,
    robots: int,
    seed: int,
    episode_steps: int | None,
) -> dict[str, Any]:
    """A new file's contents: what was measured and how, and no case yet."""
    from zerith_gym.core.task import EPISODE_STEPS

    return {
        "env_id": env_id,
        "robot": robot,
        "method": getattr(model, "method", None),
        "steps": steps,
        "model": str(model_file.relative_to(run)) if model_file.is_relative_to(run) else str(model_file),
        "training_scenario": scenario,
        "band": band_of(model),
        "roles": dict(ROLE_CASES[robot]),
        "settings": {"robots": robots, "seed": seed, "episode_steps": episode_steps or EPISODE_STEPS},
        "eval_s": 0.0,
        "cases": {},
    }


RESUMED_KEYS = ("env_id", "steps", "band", "settings")
"""What a file's measurements must share with a new call's for the call to add to them: the checkpoint (its
steps and band, whichever file holds it: the run's newest model, then a kept checkpoint once the run trained
on) and the settings."""


def _resumed(path: Path, record: dict[str, Any]) -> dict[str, Any]:
    """``record`` with the cases and time of the file at ``path`` when it measured the same checkpoint the
    same way; ExperimentError if it measured it otherwise."""
    return resumed_record(path, record, RESUMED_KEYS, "cases", "an agent's risk levels")


LINE_COLUMNS = (
    ("below", "below"),
    ("within", "within"),
    ("above", "above"),
    ("beta", "beta"),
    ("beta_iqr", "b_IQR"),
    ("beta_rnd", "b_RND"),
    ("beta_rnd_p90", "RND_p90"),
    ("beta_rnd_above_half", "RND>0.5"),
    ("iqr_median", "IQR_med"),
    ("above_before_fall", "ab<fall"),
    ("above_elsewhere", "ab_else"),
    ("survive", "survive"),
)
"""The printed columns of a case: statistic and header."""


def case_line(case: str, statistics: dict[str, Any]) -> str:
    """One case's statistics as a fixed-width line (``header_line``'s columns)."""
    values = (statistics.get(key) for key, _ in LINE_COLUMNS)
    cells = (f"{math.nan if value is None else value:>8.3f}" for value in values)
    return f"{case:<24}" + " ".join(cells) + f" {statistics.get('robot_steps', 0):>8}"


def header_line() -> str:
    """The header of ``case_line``'s columns."""
    return f"{'case':<24}" + " ".join(f"{name:>8}" for _, name in LINE_COLUMNS) + f" {'states':>8}"


def risk_levels_text(path: Path) -> str:
    """A risk-levels file as text: what was measured, then a line per case."""
    data = read_json(path, "an agent's risk levels")
    band = data["band"]
    lines = [
        f"{path}: {data['method']} at {data['steps']:,} steps, {band['reading']} band "
        f"[{band['thresholds'][0]:.3f}, {band['thresholds'][1]:.3f}], {data['settings']['robots']} robots "
        f"(seed {data['settings']['seed']}), {data['eval_s']:.0f} s",
        header_line(),
        *(case_line(case, statistics) for case, statistics in data["cases"].items()),
    ]
    return "\n".join(lines)
