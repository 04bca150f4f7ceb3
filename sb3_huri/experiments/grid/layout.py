"""The experiment folder: its settings, the grid of runs, each run's folder and status, written atomically.

An experiment folder ``DIR`` holds::

    DIR/experiment.json                       settings shared by every run, and the grid (method, seed)
    DIR/<method>/<env>_<seed + 1>/            one run, in RL Zoo's layout (RL Zoo's run ids start at 1)
        <env>.zip, <env>/{config,args}.yml, <env>/vecnormalize.pkl    the newest checkpoint
        <env>/state.json, <env>/rng.pt        its steps, curriculum stage, sessions and random states
        status.json                           the grid's record: trained to, resumptions, evaluated, times
        curve.csv                             the learning curve (sb3_huri.runner.curve; Fig. 3 analog)
        evaluations/<steps>.json              the evaluation record of its checkpoint (sb3_huri.runner.record)
        evaluations/<steps>-risk_<case>.npz   the critic's trace in the risk cases (the Fig. 5 analog)
    DIR/report.md, DIR/*.png                  written by ``python -m sb3_huri.experiments report DIR``

A standard task's run (``grid.standard``) has the same files but for the risk traces, its evaluation record
holding the final model's episode returns.

Every file is replaced atomically (``sb3_huri.runner.files``), so a kill at any moment leaves either the
old or the new version, never a torn one. A run's folder is the one format every training of the package
writes (``sb3_huri.runner``): a resumed run continues from its newest checkpoint, which ``state.json``
completes.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import read_json, write_json
from sb3_huri.runner.record import EvalSettings

EXPERIMENT_FILE = "experiment.json"
STATUS_FILE = "status.json"
FORMAT = "sb3-huri-experiment"
RUN_FORMAT = "sb3-huri-run"
VERSION = 1


class RunBusy(ExperimentError):
    """The run folder is locked by a live process (an earlier command still running, or another node)."""


@dataclass
class Settings:
    """What every run of an experiment shares; stored in ``experiment.json``."""

    env: str
    preset: dict[str, Any]
    """The RL Zoo preset of ``env`` (``sb3_huri.zoo.read_preset``), as read when the experiment began."""
    timesteps: int
    eval: EvalSettings = field(default_factory=EvalSettings)
    checkpoint_freq: int = 50_000
    runs: list[tuple[str, int]] = field(default_factory=list)
    """The grid: (method, seed) of every run, in the order they were asked for."""

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["runs"] = [list(run) for run in self.runs]
        return {"format": FORMAT, "version": VERSION, **data}

    @classmethod
    def from_json(cls, data: Any, path: Path) -> Settings:
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ExperimentError(
                f'{path} is not an sb3-huri experiment file (no "format": "{FORMAT}"): '
                "choose a new or empty --out folder"
            )
        if data.get("version") != VERSION:
            raise ExperimentError(f"{path} has format version {data.get('version')!r}; expected {VERSION}")
        try:
            return cls(
                env=str(data["env"]),
                preset=dict(data["preset"]),
                timesteps=int(data["timesteps"]),
                eval=EvalSettings(**data["eval"]),
                checkpoint_freq=int(data["checkpoint_freq"]),
                runs=[(str(method), int(seed)) for method, seed in data["runs"]],
            )
        except (KeyError, TypeError, ValueError) as error:
            raise ExperimentError(f"{path} is corrupt: {error!r}") from error


def experiment_file(out: Path) -> Path:
    return out / EXPERIMENT_FILE


def load_settings(out: Path) -> Settings:
    """The settings of the experiment in ``out``; ExperimentError for a missing, foreign or corrupt one."""
    path = experiment_file(out)
    if not out.is_dir():
        raise ExperimentError(f"{out} is not a folder")
    if not path.is_file():
        raise ExperimentError(
            f"{out} holds no experiment ({EXPERIMENT_FILE} missing): "
            "`python -m sb3_huri.experiments run --out DIR` creates one"
        )
    return Settings.from_json(read_json(path, "an experiment's settings"), path)


def open_experiment(out: Path, requested: Settings) -> Settings:
    """Create ``out`` for ``requested`` or continue the experiment already there, and return its settings.

    Continuing: the env and preset must be those it began with (runs of one experiment share them);
    ``timesteps`` may grow (finished runs then train on to the new total) but not shrink; the evaluation
    settings follow the command (runs evaluated otherwise are evaluated again); new (method, seed) pairs
    join the grid. A folder that is not empty and holds no experiment is refused, so that nothing of
    another program's is overwritten.
    """
    path = experiment_file(out)
    if out.exists() and not out.is_dir():
        raise ExperimentError(f"--out {out} exists and is not a folder")
    if not path.exists():
        if out.is_dir() and any(out.iterdir()):
            raise ExperimentError(
                f"{out} is not empty and holds no experiment ({EXPERIMENT_FILE} missing): "
                "choose a new or empty --out folder"
            )
        out.mkdir(parents=True, exist_ok=True)
        write_json(path, requested.to_json())
        return requested
    current = Settings.from_json(read_json(path, "an experiment's settings"), path)
    if current.env != requested.env:
        raise ExperimentError(
            f"{out} holds an experiment on {current.env}, not {requested.env}: choose another --out folder"
        )
    if current.preset != requested.preset:
        changed = sorted(
            key
            for key in set(current.preset) | set(requested.preset)
            if current.preset.get(key) != requested.preset.get(key)
        )
        raise ExperimentError(
            f"{out} was started with another preset of {current.env} (differs in: {', '.join(changed)}); "
            "runs of one experiment share their preset: choose another --out folder"
        )
    if requested.timesteps < current.timesteps:
        raise ExperimentError(
            f"{out} trains every run to {current.timesteps} steps; --timesteps {requested.timesteps} would "
            "leave runs beyond it (ask for at least as many, or use another --out folder)"
        )
    merged = Settings(
        env=current.env,
        preset=current.preset,
        timesteps=requested.timesteps,
        eval=requested.eval,
        checkpoint_freq=requested.checkpoint_freq,
        runs=list(dict.fromkeys([*current.runs, *requested.runs])),
    )
    write_json(path, merged.to_json())
    return merged


def run_folder(out: Path, env: str, method: str, seed: int) -> Path:
    """``out/<method>/<env>_<seed + 1>``: RL Zoo's layout, whose run ids start at 1 (``--exp-id``)."""
    return out / method / f"{env}_{seed + 1}"


@dataclass
class RunStatus:
    """A run's progress, in ``status.json``: what a resumed command continues from."""

    method: str
    seed: int
    env: str
    checkpoint: int | None = None
    """Steps of the newest checkpoint when the status was written (``<env>/state.json`` has the latest)."""
    steps: int = 0
    """Steps trained so far (ahead of the checkpoint while training runs)."""
    trained_to: int | None = None
    """The total the run was last trained to completion for (None while it trains)."""
    evaluated: dict[str, Any] | None = None
    """The evaluation settings of the finished evaluation (None until it is done)."""
    eval_done: int = 0
    eval_cases: int = 0
    train_seconds: float = 0.0
    eval_seconds: float = 0.0
    resumed_from: list[int] = field(default_factory=list)
    """Checkpoint steps each resumption started from."""
    state: str = "pending"
    """pending, training, evaluating, done or failed (for the progress display)."""
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {"format": RUN_FORMAT, "version": VERSION, **asdict(self)}


def read_status(folder: Path, method: str, seed: int, env: str) -> RunStatus:
    """The status of the run in ``folder`` (a fresh one when the folder has none yet).

    ExperimentError for a corrupt or foreign status, or one of another run (method, seed or env differ).
    """
    path = folder / STATUS_FILE
    if not path.exists():
        return RunStatus(method, seed, env)
    data = read_json(path, "a run's status")
    if not isinstance(data, dict) or data.get("format") != RUN_FORMAT:
        raise ExperimentError(f"{path} is not an sb3-huri run status; move the folder {folder} away")
    try:
        fields = {k: v for k, v in data.items() if k not in ("format", "version")}
        status = RunStatus(**fields)
    except TypeError as error:
        raise ExperimentError(f"{path} is corrupt: {error}; delete {folder} to train the run anew") from error
    if (status.method, status.seed, status.env) != (method, seed, env):
        raise ExperimentError(
            f"{path} belongs to {status.method} seed {status.seed} on {status.env}, "
            f"not {method} seed {seed} on {env}"
        )
    return status


def write_status(folder: Path, status: RunStatus) -> None:
    write_json(folder / STATUS_FILE, status.to_json())


@contextlib.contextmanager
def run_lock(folder: Path) -> Iterator[None]:
    """Hold the run's lock while training or evaluating it (RunBusy if a live process holds it).

    The runner's lock (``sb3_huri.runner.lock.hold_run`` on ``<run>/.lock``), which the trainer inside
    takes again (in one process the holds nest): the OS releases it when its holder dies, however it dies,
    so a killed command never leaves a stale lock, and it keeps a second command (or a task Ray retried
    elsewhere while the first still runs) from writing the same run at once.
    """
    from sb3_huri.runner.lock import RunBusy as Held
    from sb3_huri.runner.lock import hold_run

    with contextlib.ExitStack() as held:
        try:
            held.enter_context(hold_run(folder))
        except Held as error:
            raise RunBusy(str(error)) from error
        yield


def validate_grid(env: str, methods: Sequence[str], seeds: Sequence[int]) -> list[tuple[str, int]]:
    """Every (method, seed) of the grid; ExperimentError for an unknown method or env, or an empty grid."""
    from sb3_huri.zoo import METHODS

    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ExperimentError(f"unknown method(s) {', '.join(unknown)}; methods: {', '.join(METHODS)}")
    check_env(env)
    if not methods or not seeds:
        raise ExperimentError("the grid is empty: give at least one method and one seed")
    if any(seed < 0 for seed in seeds):
        raise ExperimentError(f"seeds must be non-negative, got {list(seeds)}")
    return [(m, s) for m in dict.fromkeys(methods) for s in dict.fromkeys(seeds)]


def check_env(env: str) -> None:
    """ExperimentError unless ``env`` is a Zerith env (trained on its batched VecEnv, evaluated on the
    paper's protocol) or a standard Gymnasium env (``is_standard``)."""
    env_kind(env)


def env_kind(env: str) -> str:
    """``"zerith"`` for a registered Zerith-1 env, ``"standard"`` for any other registered Gymnasium env that
    is not a robot of ``zerith_gym`` (``HalfCheetah-v5``, ``Walker2d-v5``: ``grid.standard``);
    ExperimentError for an unregistered env or another robot (its protocol is not the grid's)."""
    import gymnasium as gym

    import zerith_gym  # noqa: F401  (registers the Zerith envs)
    from zerith_gym import ROBOT_ENTRY_POINTS, ZERITH1_ENTRY_POINT

    zerith = [spec.id for spec in gym.registry.values() if spec.entry_point == ZERITH1_ENTRY_POINT]
    if env in zerith:
        return "zerith"
    if env not in gym.registry:
        raise ExperimentError(
            f"unknown env {env!r}: the experiments train a Zerith env ({', '.join(zerith)}) or a registered "
            "Gymnasium env (e.g. Walker2d-v5)"
        )
    if gym.spec(env).entry_point in ROBOT_ENTRY_POINTS:
        raise ExperimentError(
            f"{env} is not evaluated by the grid: its Zerith protocol is Zerith1-v0's ({', '.join(zerith)}); "
            "the campaign evaluates it (docs/campaign.md)"
        )
    return "standard"


def is_standard(env: str) -> bool:
    """Whether the grid trains ``env`` as a standard task (``grid.standard``) rather than a Zerith env."""
    return env_kind(env) == "standard"


def shown_path(path: Path) -> str:
    """`path` as a report names it: relative to the working folder when inside it (a report committed with
    its runs then names them as a clone sees them), else absolute."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path.resolve())
