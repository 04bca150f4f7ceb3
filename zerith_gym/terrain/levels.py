"""Which tile each robot starts on, and the terrain curriculum that moves robots between levels.

A tile terrain (`zerith_gym.terrain.tiles`) has one column per terrain kind and one row per difficulty level.
Robot `i` of an env (counted over the whole env, whichever process steps it) keeps column `i % columns` and
starts at level `(i // columns) % start_levels`. With a `LevelRule` (the `TerrainCurriculum` callback sets
one), each robot whose episode ended is moved before its next start, as legged-robot curricula do:

- up a level if it walked at least `promote_distance` from its spawn point without falling;
- down a level if it fell, or walked less than `demote_fraction` of the distance its commands asked for.

Levels stay within [0, levels - 1]. An episode cut by a diverging simulation moves no level (its robot's
position is unknown). Other terrains have one tile: every robot at level 0 of column 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zerith_gym.terrain.ground import TerrainSpec


@dataclass(frozen=True)
class LevelRule:
    """When a robot moves up or down a level at the end of an episode (see the module's docstring)."""

    promote_distance: float | None = None
    """Metres walked from the spawn point to move up; None: half a tile, the way to the tile's edge."""
    demote_fraction: float = 0.5
    """A robot that walked less than this share of its commanded distance moves down."""

    def __post_init__(self) -> None:
        if self.promote_distance is not None and not self.promote_distance > 0:
            raise ValueError(f"promote_distance must be > 0 m (or None), got {self.promote_distance!r}")
        if not 0.0 <= self.demote_fraction <= 1.0:
            raise ValueError(f"demote_fraction must be in [0, 1], got {self.demote_fraction!r}")


def next_levels(
    levels: np.ndarray,
    walked: np.ndarray,
    commanded: np.ndarray,
    fell: np.ndarray,
    promote_distance: float,
    demote_fraction: float,
    top_level: int,
) -> np.ndarray:
    """The levels after episodes that walked `walked` m of `commanded` m and fell or not, all (n,)."""
    up = (walked >= promote_distance) & ~fell
    down = fell | (walked < demote_fraction * commanded)
    return np.clip(levels + up.astype(int) - (down & ~up).astype(int), 0, top_level)


def check_tile(spec: TerrainSpec, tile: object) -> tuple[int, int]:
    """`tile` as (level, kind column) of `spec`'s grid; ValueError unless it names one (a terrain without
    tiles has one: (0, 0))."""
    levels, columns = spec.num_levels, spec.num_columns
    try:
        level, column = tile  # type: ignore[misc]
    except (TypeError, ValueError):
        level = column = None
    whole = all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in (level, column))
    if not (whole and 0 <= level < levels and 0 <= column < columns):  # type: ignore[operator]
        kinds = spec.tiles.kinds if spec.tiles is not None else (spec.kind,)
        raise ValueError(
            f"tile must be (level, kind column) with level in [0, {levels - 1}] and column in "
            f"[0, {columns - 1}] (kinds {', '.join(kinds)}), got {tile!r}"
        )
    return int(level), int(column)  # type: ignore[arg-type]


class TerrainLevels:
    """The tiles of a batch of robots (global indices `robots`, stepped every `control_dt` s) and what the
    curriculum needs to move them.

    Per control step `record` keeps each robot's position, the distance its commands asked for and
    whether its episode ended in a fall; `spawn_points` moves the robots whose episode ended (with a
    rule) and gives where their next episode starts.
    """

    def __init__(self, spec: TerrainSpec, robots: np.ndarray, control_dt: float) -> None:
        self.spec, self.control_dt = spec, control_dt
        columns = spec.num_columns
        start_levels = spec.tiles.start_levels if spec.tiles is not None else 1
        self.columns = robots % columns
        self.levels = (robots // columns) % start_levels
        self.rule: LevelRule | None = None
        n = len(robots)
        self.spawn = np.zeros((n, 2))
        self.position = np.zeros((n, 2))
        self.commanded = np.zeros(n)
        self.fell = np.zeros(n, dtype=bool)
        self.ended = np.zeros(n, dtype=bool)
        self.unstable = np.zeros(n, dtype=bool)

    def set_rule(self, rule: LevelRule | None) -> None:
        """Move robots between levels by `rule` from their next start on (None: stop moving them)."""
        if rule is not None and self.spec.tiles is None:
            raise ValueError(
                f"a terrain curriculum needs a tile terrain; this env's is {self.spec.kind!r} (use a "
                "scenario on tiles, e.g. 'terrain')"
            )
        self.rule = rule

    def place(self, index: int, tile: object) -> None:
        """Start robot `index` on `tile` (level, kind column) from its next reset, its last episode unjudged;
        a curriculum moves it on from there. ValueError unless the tile is on the grid (`check_tile`)."""
        self.levels[index], self.columns[index] = check_tile(self.spec, tile)
        self.ended[index] = False

    def spawn_points(self, ids: np.ndarray) -> np.ndarray:
        """Move robots `ids` whose episode ended by the rule (if any); the centres (len(ids), 2) of their
        tiles, where their next episodes start."""
        grid = self.spec.tiles
        if self.rule is not None and grid is not None:
            done = ids[self.ended[ids] & ~self.unstable[ids]]
            walked = np.linalg.norm(self.position[done] - self.spawn[done], axis=1)
            promote = self.rule.promote_distance
            self.levels[done] = next_levels(
                self.levels[done],
                walked,
                self.commanded[done],
                self.fell[done],
                grid.tile_size / 2 if promote is None else promote,
                self.rule.demote_fraction,
                grid.levels - 1,
            )
        points = self.spec.spawn_points(self.levels[ids], self.columns[ids])
        self.commanded[ids] = 0.0
        self.fell[ids] = self.ended[ids] = self.unstable[ids] = False
        return points

    def started(self, ids: np.ndarray, spawn: np.ndarray) -> None:
        """Robots `ids` started at world xy `spawn` (len(ids), 2), their tile's centre plus jitter."""
        self.spawn[ids] = spawn
        self.position[ids] = spawn

    def record(
        self,
        base_xy: np.ndarray,
        command: np.ndarray,
        fell: np.ndarray,
        ended: np.ndarray,
        unstable: np.ndarray,
    ) -> None:
        """After a control step: every robot's base xy (n, 2), command (n, 3), fall, episode end and diverged
        simulation (n,) each; a diverged robot's position is not read (its sensors were zeroed)."""
        self.position[~unstable] = base_xy[~unstable]
        self.unstable |= unstable
        self.commanded += np.hypot(command[:, 0], command[:, 1]) * self.control_dt
        self.fell |= fell
        self.ended |= ended
