"""The per-robot info dicts of a step, built lazily from the step's arrays.

SB3's VecEnv API hands out one info mapping per robot and step. At thousands of robots, filling thousands of
dicts every step costs more than a GPU's physics step, while most readers look at a key or two of the
robots whose episode ended. So `step_infos` returns a `StepInfos` list of `RobotInfo` mappings that read
the step's arrays only when a key is read, and keep what is written (`terminal_observation`, `episode`,
...) in a small dict of their own. Readers that go over every robot can use `StepInfos.step`, the arrays
themselves (`RewardTermsLogger` does).

The arrays of a `BatchStep` are never written after the step returns them, so a `RobotInfo` read later
still gives the step's values.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator, Mapping, MutableMapping, Sequence
from itertools import repeat
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from zerith_gym.core.contract import BatchStep

_COMPUTED = ("fall", "sim_unstable", "lin_vel_error", "ang_vel_error", "external_force", "command",
             "reward_terms", "terrain_level", "TimeLimit.truncated")  # fmt: skip
"""The keys every robot's info has each step (documented in `Zerith1Env`)."""


class TermValues(Mapping[str, float]):
    """Term name -> value, read from one row (K,) of a terms array (columns `names`): what
    `info["reward_terms"]` holds.

    A read-only mapping over the row, so that building one per robot and step costs next to nothing;
    `dict(values)` makes a plain dict. The row is never written after it is handed out.
    """

    __slots__ = ("_names", "_row")

    def __init__(self, row: np.ndarray, names: tuple[str, ...]) -> None:
        self._row, self._names = row, names

    def __getitem__(self, name: str) -> float:
        if name not in self._names:
            raise KeyError(name)
        return float(self._row[self._names.index(name)])

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __repr__(self) -> str:
        return repr(dict(zip(self._names, self._row.tolist(), strict=True)))


_COMPUTED_KEYS = frozenset(_COMPUTED)


class RobotInfo(MutableMapping[str, Any]):
    """Robot `index`'s info for `step`: the step's values read on access, plus the keys written to it."""

    __slots__ = ("_index", "_step", "_written")

    def __init__(self, step: BatchStep, index: int) -> None:
        self._step, self._index = step, index
        self._written: dict[str, Any] | None = None

    def __getitem__(self, key: str) -> Any:
        if self._written is not None and key in self._written:
            return self._written[key]
        out, i = self._step.out, self._index
        if key == "fall":
            return bool(out.fall[i])
        if key == "sim_unstable":
            return bool(out.sim_unstable[i])
        if key == "lin_vel_error":
            return float(out.lin_vel_error[i])
        if key == "ang_vel_error":
            return float(out.ang_vel_error[i])
        if key == "external_force":
            return self._step.force[i].copy()
        if key == "command":
            return self._step.command[i].copy()
        if key == "reward_terms":
            return TermValues(out.terms[i], self._step.reward_names)
        if key == "terrain_level":
            return int(self._step.terrain_level[i])
        if key == "TimeLimit.truncated":
            return False  # the env writes True where a time limit ended the episode
        raise KeyError(key)

    def __setitem__(self, key: str, value: Any) -> None:
        if self._written is None:
            self._written = {}
        self._written[key] = value

    def __delitem__(self, key: str) -> None:
        if key in _COMPUTED_KEYS:
            raise KeyError(f"{key!r} is computed from the step and cannot be deleted")
        if self._written is None or key not in self._written:
            raise KeyError(key)
        del self._written[key]

    def __iter__(self) -> Iterator[str]:
        yield from _COMPUTED
        if self._written is not None:
            yield from (key for key in self._written if key not in _COMPUTED)

    def __len__(self) -> int:
        extra = 0 if self._written is None else sum(key not in _COMPUTED for key in self._written)
        return len(_COMPUTED) + extra

    def __contains__(self, key: object) -> bool:
        return key in _COMPUTED_KEYS or (self._written is not None and key in self._written)

    def get(self, key: str, default: Any = None) -> Any:
        """The value of `key`, or `default` (without raising: SB3 asks every robot for "episode")."""
        if (self._written is not None and key in self._written) or key in _COMPUTED_KEYS:
            return self[key]
        return default

    def copy(self) -> dict[str, Any]:
        """A plain dict of every key, as `dict.copy` gives (readers that copy infos expect one)."""
        return dict(self)

    def __repr__(self) -> str:
        return repr(dict(self))


class StepInfos(list):
    """The infos of one step of n robots (a list of `RobotInfo`), with the step's arrays as `step`."""

    def __init__(self, step: BatchStep) -> None:
        # Thousands of new objects at once would set off the garbage collector's full passes over every
        # object of the process (torch's included) several times per step: held off while they are made.
        collecting = gc.isenabled()
        gc.disable()
        try:
            super().__init__(map(RobotInfo, repeat(step), range(len(step.out.reward))))
        finally:
            if collecting:
                gc.enable()
        self.step = step


def step_infos(step: BatchStep) -> StepInfos:
    """The info mapping of every robot for `step` (keys documented in `Zerith1Env`)."""
    return StepInfos(step)


def ended_falls(dones: np.ndarray, infos: Sequence[Mapping[str, Any]]) -> list[bool]:
    """For each robot whose episode ended in a step (`dones`), whether it ended in a fall; an info without
    a `fall` key (another env's) counts as no fall."""
    return [bool(infos[i].get("fall", False)) for i in np.flatnonzero(dones)]
