"""The training campaign's queue: the long runs, in priority order, and how far each has come.

A queue file (``runs/campaign.yml``) lists entries; each trains one run folder (RL Zoo's layout, written by
``sb3_huri.runner.training``) up to a number of steps, then evaluates that checkpoint once under the
paper's protocol into its evaluation record (``study.campaign.final_evaluation``). Paths in
the file are relative to the file's own folder. The same run folder may appear in several entries (trained
to 150M, later on to 285M)::

    defaults:                  # optional; these are the defaults
      robustness_every: 5000000  # a robustness row (Table 1 on 50 robots) every this many steps
      robustness_episodes: 50
      robustness_seed: 1000
      eval_episodes: 100         # the final evaluation: robots per case, seeds eval_seed + i
      eval_seed: 2000
      episode_steps: 1000        # 20 s evaluation episodes
      analyses: [risk_levels, force_magnitude]  # measured after the final evaluation; [] for none
    entries:
      - name: robust-huri-s0     # unique
        protocol: robust         # one of PROTOCOLS (below)
        method: huri             # an RL Zoo algorithm name of sb3_huri.zoo.METHODS
        seed: 0
        run: huri/Zerith1-v0_6
        conf: ../hyperparams/huri_robust.yml
        steps: 156732992         # train until at least this many steps, then evaluate
        hyperparams: {n_envs: 256, n_steps: 64}  # optional: preset entries replaced, as rl_zoo3 -params

An entry is *done* when its run has trained that far, an evaluation written for the entry exists in
``<run>/evaluations/`` and the analyses of ``study.campaign.analyses`` hold every case
beside it. Nothing else is stored: the run folders are the campaign's state.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.runner.files import read_json
from sb3_huri.runner.record import EVALUATIONS
from sb3_huri.runner.state import RunState
from zerith_gym import GO2LIKE_ID, ZERITH1_ID

DEFAULT_QUEUE = Path("runs") / "campaign.yml"
"""The queue file the campaign's commands read unless told otherwise (relative to the working folder)."""
PROTOCOLS = ("robust", "robust-256", "paper", "terrain", "quadruped")
"""The training protocols: the project's (train at the test magnitudes), the same with 256 robots x 64 steps
per update instead of 32 x 512 (as many samples per update; a recipe that uses more cores, and whether it
learns per sample as the 32-robot one does), the paper's (train at its Table-5 ranges, test out of
distribution), the paper's terrain training (its appendix A.7), and the paper's quadruped (its appendix
A.6: `Go2Like-v0` on legged_gym's task, tested on Table 8's platforms). Entries pair and average only
within a protocol."""
ANALYSES = ("risk_levels", "force_magnitude", "advantages", "value_baseline")
"""What an entry can be measured on after its final evaluation (``campaign.analyses``)."""
PROTOCOL_ENVS = {"quadruped": GO2LIKE_ID}
"""The env a protocol trains on where it is not ``ZERITH1_ID``."""


@dataclass(frozen=True)
class QueueDefaults:
    """Evaluation settings shared by every entry of a queue."""

    robustness_every: int = 5_000_000
    robustness_episodes: int = 50
    robustness_seed: int = 1000
    eval_episodes: int = 100
    eval_seed: int = 2000
    episode_steps: int = 1000
    """Control steps of an evaluation episode (20 s, as the paper's tests), robustness rows included."""
    analyses: tuple[str, ...] = ANALYSES
    """What each entry is measured on after its final evaluation, at the evaluated checkpoint: its critic's
    risk levels per scenario, its survival over force magnitude and how far its risk distortion moves its
    advantages (``campaign.analyses``)."""


@dataclass(frozen=True)
class CampaignEntry:
    """One entry of the queue: train `run` with `method`, `seed` and the preset `conf` to `steps`."""

    name: str
    protocol: str
    method: str
    seed: int
    run: Path
    conf: Path
    steps: int
    defaults: QueueDefaults = field(default_factory=QueueDefaults)
    hyperparams: dict[str, Any] = field(default_factory=dict)
    """Preset entries replaced for this entry's run, as ``rl_zoo3 train -params`` (stored in its config)."""

    @property
    def env_id(self) -> str:
        """The env the entry trains on (its run folder's file names)."""
        return PROTOCOL_ENVS.get(self.protocol, ZERITH1_ID)

    def trained_steps(self) -> int:
        """Steps the run folder's newest checkpoint holds (0 for a run not started)."""
        return RunState.read(self.run, self.env_id).timesteps

    def evaluation(self) -> Path | None:
        """The entry's final evaluation file, ``<steps>.json``, if it was written (the other analyses' files
        beside it, ``<steps>-<analysis>.json``, are not evaluations); RunError for one that does not read."""
        for path in sorted((self.run / EVALUATIONS).glob("*.json")):
            if not path.stem.isdigit():
                continue
            record = read_json(path, "an evaluation record")
            if isinstance(record, dict) and record.get("entry") == self.name:
                return path
        return None


_REQUIRED = ("name", "protocol", "method", "seed", "run", "conf", "steps")
_OPTIONAL = ("hyperparams",)


def _entry(raw: Any, index: int, base: Path, defaults: QueueDefaults, where: Path) -> CampaignEntry:
    from sb3_huri.zoo import METHODS

    if not isinstance(raw, dict):
        raise ExperimentError(f"{where}: entry {index} is not a mapping of {', '.join(_REQUIRED)}")
    missing = [key for key in _REQUIRED if key not in raw]
    unknown = sorted(set(raw) - set(_REQUIRED) - set(_OPTIONAL))
    if missing or unknown:
        raise ExperimentError(
            f"{where}: entry {index} ({raw.get('name', '?')}): "
            + "; ".join(
                part
                for part in (
                    f"missing {', '.join(missing)}" if missing else "",
                    f"unknown {', '.join(unknown)}" if unknown else "",
                )
                if part
            )
            + f" (an entry has {', '.join(_REQUIRED)}, optionally {', '.join(_OPTIONAL)})"
        )

    def bad(key: str, what: str) -> ExperimentError:
        """The error of the entry's field `key`, naming the file, the entry and the field."""
        return ExperimentError(f"{where}: entry {raw['name']}: {key}: {what}")

    if raw["protocol"] not in PROTOCOLS:
        raise bad("protocol", f"protocol {raw['protocol']!r} is not one of {', '.join(PROTOCOLS)}")
    if raw["method"] not in METHODS:
        raise bad("method", f"unknown method {raw['method']!r}; methods: {', '.join(METHODS)}")
    seed, steps = _number(raw, "seed", int, bad), _number(raw, "steps", lambda v: int(float(v)), bad)
    if steps < 1:
        raise bad("steps", f"steps must be positive, got {steps}")
    if not isinstance(raw["conf"], str | Path):
        raise bad("conf", f"a preset file's path, got {raw['conf']!r}")
    conf = (base / raw["conf"]).resolve()
    if not conf.is_file():
        raise bad("conf", f"preset file {raw['conf']} not found (looked for {conf})")
    if not isinstance(raw["run"], str | Path):
        raise bad("run", f"a run folder's path, got {raw['run']!r}")
    hyperparams = raw.get("hyperparams") or {}
    if not isinstance(hyperparams, dict) or not all(isinstance(key, str) for key in hyperparams):
        example = "{n_envs: 256, n_steps: 64}"
        raise bad(
            "hyperparams", f"hyperparams must map preset names to values, e.g. {example}; got {hyperparams!r}"
        )
    return CampaignEntry(
        str(raw["name"]), raw["protocol"], raw["method"], seed, (base / raw["run"]).resolve(), conf, steps,
        defaults, dict(hyperparams),
    )  # fmt: skip


def _number(raw: dict[str, Any], key: str, read: Any, bad: Any) -> int:
    """The entry's field `key` read by `read` as a number; `bad(key, what)`'s error otherwise."""
    try:
        return read(raw[key])
    except (TypeError, ValueError):
        raise bad(key, f"seed and steps must be numbers, got {raw[key]!r}") from None


def load_queue(path: str | Path) -> list[CampaignEntry]:
    """The entries of the queue file at `path`, in order; ExperimentError saying what is wrong otherwise."""
    path = Path(path)
    if not path.is_file():
        raise ExperimentError(f"queue file {path} not found")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as error:
        raise ExperimentError(f"{path} is not valid YAML: {error}") from None
    if not isinstance(data, dict) or not isinstance(data.get("entries"), list):
        raise ExperimentError(f"{path}: a queue file is a mapping with a list under `entries:`")
    defaults = _defaults(data.get("defaults") or {}, path)
    entries = [_entry(raw, i, path.parent, defaults, path) for i, raw in enumerate(data["entries"])]
    names = [entry.name for entry in entries]
    duplicated = sorted({name for name in names if names.count(name) > 1})
    if duplicated:
        raise ExperimentError(f"{path}: entry names must be unique; repeated: {', '.join(duplicated)}")
    return entries


def _defaults(raw: Any, path: Path) -> QueueDefaults:
    """The queue's ``defaults:``; ExperimentError saying what is allowed otherwise."""
    known = {f.name for f in fields(QueueDefaults)}
    if not isinstance(raw, dict) or set(raw) - known:
        raise ExperimentError(f"{path}: `defaults:` takes {', '.join(sorted(known))}")
    analyses = raw.get("analyses", ANALYSES)
    if not isinstance(analyses, list | tuple) or not all(name in ANALYSES for name in analyses):
        raise ExperimentError(
            f"{path}: `defaults: analyses:` is a list of {', '.join(ANALYSES)} ([] for none), "
            f"got {analyses!r}"
        )
    try:
        numbers = {key: int(float(value)) for key, value in raw.items() if key != "analyses"}
    except (TypeError, ValueError) as error:
        raise ExperimentError(
            f"{path}: `defaults:` {', '.join(sorted(known - {'analyses'}))} are numbers ({error})"
        ) from None
    return QueueDefaults(**numbers, analyses=tuple(analyses))
