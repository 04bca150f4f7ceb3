"""Tile terrains: a grid of square tiles, one column per terrain kind and one row per difficulty level.

Legged-robot trainers lay their terrains out this way so that a curriculum can move each robot to a
harder or easier tile by changing where it starts (`zerith_gym.terrain.levels`). Every tile is built around
a spawn square at its centre (flat but for the rough slopes' bumps) and meets its neighbours at height 0
along its edges, so a robot that walks off its tile steps onto the next one instead of off a cliff. A kind
is named for what a robot that starts at the tile's centre meets, whichever way it walks:

- `slope_up`: an inverted pyramid, the robot starts at the bottom and walks up a rough slope whichever way
  it goes; the gradient grows with the level.
- `slope_down`: a pyramid, the robot starts on top and walks down a rough slope.
- `discrete`: random rectangular blocks raised or sunk by the level's step height (`+-h` or `+-h/2`).
- `platform`: a square platform of the level's height, to step down from (the paper's Table 8).
- `smooth_slope_up`, `smooth_slope_down`: `slope_up` and `slope_down` without the bumps.
- `stairs_up`: inverted pyramid stairs, the robot starts on the bottom landing (the spawn square) and climbs
  square rings of steps, `stair_width` deep and the level's stair height high, up to the tile's edge.
- `stairs_down`: pyramid stairs, the robot starts on the top landing and walks down them to the edge.

The stairs are legged_gym's pyramid stairs (Rudin et al. 2022, "Learning to walk in minutes using massively
parallel deep RL"), whose "stairs up" also sink towards the centre for the robot to climb out.
`legged_gym_kinds` lays that paper's mix of kinds over a number of columns, for `TileGrid(kinds=...)`.

Heights are in metres on the grid's vertices (rows along y, columns along x), pure numpy, and the same
for the same seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import accumulate
from numbers import Real

import numpy as np

PAPER_TILE_KINDS = ("slope_up", "slope_down", "discrete", "platform")
"""The kinds of the HuRi paper's terrain tests and training (appendix A.7, Table 8): `TileGrid`'s default."""
TILE_KINDS = (*PAPER_TILE_KINDS, "smooth_slope_up", "smooth_slope_down", "stairs_up", "stairs_down")
"""The terrain kinds a tile can have."""
STAIRS_KINDS = ("stairs_up", "stairs_down")
"""The kinds built of steps `stair_width` deep."""
LEGGED_GYM_PROPORTIONS = (
    ("smooth_slope", 0.1),
    ("rough_slope", 0.1),
    ("stairs_up", 0.35),
    ("stairs_down", 0.25),
    ("discrete", 0.2),
)
"""legged_gym's terrain mix (Rudin et al. 2022): the share of the columns of each of its terrain types."""


@dataclass(frozen=True)
class TileGrid:
    """The layout and difficulty of a tile terrain.

    Tile (level l, kind k) spans x in [l, l + 1) * tile_size and y in [k, k + 1) * tile_size from the grid's
    corner, inside a flat border of `border` metres. A range (lo, hi) gives the value at level 0 and at the
    top level, linear in between. `kinds` may repeat a kind (a mix such as `legged_gym_kinds()`).
    """

    kinds: tuple[str, ...] = PAPER_TILE_KINDS
    levels: int = 10
    tile_size: float = 8.0
    """Side (m) of a tile."""
    border: float = 20.0
    """Flat ground (m) around the grid, so that robots on the outer tiles stay on the terrain for 20 s."""
    slope: tuple[float, float] = (0.0, 0.3)
    """Gradient (rise over run) of the slopes, rough and smooth (0.3: 17 degrees)."""
    roughness: float = 0.02
    """Half width (m) of the uniform random bumps on the rough slopes' vertices."""
    step_height: tuple[float, float] = (0.03, 0.15)
    """Height (m) of the `discrete` blocks."""
    platform_height: tuple[float, float] = (0.05, 0.45)
    """Height (m) of the `platform` to step down from."""
    spawn_size: float = 2.0
    """Side (m) of the flat square at a tile's centre where robots start (slopes, blocks and stairs)."""
    platform_size: float = 3.0
    """Side (m) of the `platform`."""
    start_levels: int = 1
    """Robots start spread over levels [0, start_levels) (before a curriculum moves them)."""
    stair_height: tuple[float, float] = (0.05, 0.2)
    """Rise (m) of each step of `stairs_up` and `stairs_down`: from legged_gym's lowest step (0.05 m) to
    0.2 m, steep building stairs for a robot of Zerith-1's size. legged_gym's quadruped climbs
    0.05 + 0.18 x level / levels m: (0.05, 0.05 + 0.18 * (levels - 1) / levels) here."""
    stair_width: float = 0.31
    """Depth (m) of each step of the stairs (legged_gym's). A vertex is on step floor(distance to the tile's
    edge / stair_width), so the risers fall between vertices: at 0.1 m cells a 0.31 m step has three vertices
    (one step in ten four), and MuJoCo joins two steps by a slope across the cell between them."""

    def __post_init__(self) -> None:
        if not self.kinds or any(kind not in TILE_KINDS for kind in self.kinds):
            raise ValueError(f"tile kinds must be a non-empty tuple of {TILE_KINDS}, got {self.kinds!r}")
        for name in ("levels", "start_levels"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if self.start_levels > self.levels:
            raise ValueError(f"start_levels ({self.start_levels}) cannot exceed levels ({self.levels})")
        if not self.tile_size > max(self.spawn_size, self.platform_size):
            raise ValueError(
                f"tile_size ({self.tile_size!r} m) must exceed spawn_size ({self.spawn_size}) and "
                f"platform_size ({self.platform_size})"
            )
        if not (self.border >= 0 and self.roughness >= 0 and self.spawn_size > 0 and self.platform_size > 0):
            raise ValueError("border and roughness must be >= 0, spawn_size and platform_size > 0")
        for name in ("slope", "step_height", "platform_height"):
            low, high = getattr(self, name)
            if not 0 <= low <= high:
                raise ValueError(f"{name} must be a range (lo, hi) with 0 <= lo <= hi, got {(low, high)!r}")
        self._check_stairs()

    def _check_stairs(self) -> None:
        """ValueError unless `stair_height` is a range of finite metres and at least one step `stair_width`
        deep fits between a tile's edge and its spawn square."""
        heights = tuple(self.stair_height) if isinstance(self.stair_height, tuple | list) else ()
        if not (len(heights) == 2 and all(_finite(h) for h in heights) and 0 <= heights[0] <= heights[1]):
            raise ValueError(
                f"stair_height must be a range (lo, hi) of metres with 0 <= lo <= hi, both finite, "
                f"got {self.stair_height!r}"
            )
        run = self.run
        if not (_finite(self.stair_width) and 0 < self.stair_width <= run):
            raise ValueError(
                f"stair_width must be in (0, {run:g}] m, so that at least one step fits between a tile's "
                f"edge and its spawn square ((tile_size - spawn_size) / 2), got {self.stair_width!r}"
            )

    @property
    def size(self) -> tuple[float, float]:
        """Extent (m) of the whole terrain along x and y, border included."""
        return (
            self.levels * self.tile_size + 2 * self.border,
            len(self.kinds) * self.tile_size + 2 * self.border,
        )

    @property
    def run(self) -> float:
        """Distance (m) from a tile's edge to its spawn square: the run of its slopes and stairs."""
        return (self.tile_size - self.spawn_size) / 2

    @property
    def stair_steps(self) -> int:
        """Number of steps of the stairs from a tile's edge (step 0, at height 0) to its centre's landing
        (step `stair_steps`, which covers the spawn square)."""
        return math.floor(self.run / self.stair_width + _ON_THE_LINE)

    def at_level(self, value_range: tuple[float, float], level: int) -> float:
        """The value of a (lo, hi) range at `level`."""
        low, high = value_range
        return low + (high - low) * level / max(self.levels - 1, 1)

    def tile_centres(self, levels: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """World xy (n, 2) of the centres of tiles (level, kind column); the terrain is centred on 0."""
        width, depth = self.size
        x = self.border + (np.asarray(levels) + 0.5) * self.tile_size - width / 2
        y = self.border + (np.asarray(columns) + 0.5) * self.tile_size - depth / 2
        return np.stack([x, y], axis=-1)


def legged_gym_kinds(columns: int = 20) -> tuple[str, ...]:
    """The kinds of `columns` columns of tiles in legged_gym's mix (`LEGGED_GYM_PROPORTIONS`), for
    `TileGrid(kinds=...)`.

    Column j gets the type whose cumulative share first exceeds j / columns + 0.001, as legged_gym's
    terrain curriculum assigns them, so the columns of a type sit side by side in the order above. Up to
    999 columns each type gets its share to within one column, exactly with a multiple of 20 (20: 2 smooth
    slopes, 2 rough ones, 7 stairs up, 5 stairs down, 4 discrete); with fewer than 20 some get none. As in
    legged_gym, the first half of the smooth slopes go up and the others down, and the rough slopes all go
    down (`slope_down`).
    """
    if not isinstance(columns, int) or isinstance(columns, bool) or columns < 1:
        raise ValueError(f"columns must be a positive integer, got {columns!r}")
    smooth, rough, up, down, _ = accumulate(share for _, share in LEGGED_GYM_PROPORTIONS)
    kinds = []
    for column in range(columns):
        choice = column / columns + 0.001
        if choice < smooth:
            kinds.append("smooth_slope_up" if choice < smooth / 2 else "smooth_slope_down")
        elif choice < rough:
            kinds.append("slope_down")
        elif choice < up:
            kinds.append("stairs_up")
        elif choice < down:
            kinds.append("stairs_down")
        else:
            kinds.append("discrete")
    return tuple(kinds)


def tile_heights(grid: TileGrid, resolution: float, seed: int) -> np.ndarray:
    """Heights (m) on the vertices of the whole terrain (rows along y, columns along x), at `resolution`."""
    width, depth = grid.size
    heights = np.zeros((round(depth / resolution) + 1, round(width / resolution) + 1))
    rng = np.random.default_rng(seed)
    per_tile = round(grid.tile_size / resolution)
    offset = round(grid.border / resolution)
    local = np.arange(per_tile + 1) * grid.tile_size / per_tile
    x, y = np.meshgrid(local, local)  # a tile's vertices, edges included
    for column, kind in enumerate(grid.kinds):
        for level in range(grid.levels):
            tile = _TILE_BUILDERS[kind](grid, level, x, y, rng)
            rows = slice(offset + column * per_tile, offset + (column + 1) * per_tile + 1)
            cols = slice(offset + level * per_tile, offset + (level + 1) * per_tile + 1)
            heights[rows, cols] = tile
    return heights


_ON_THE_LINE = 1e-9
"""Steps (of `stair_width`) added before rounding down, so that a vertex on a riser's line, a whole number of
steps from the edge up to float error, belongs to the step it starts."""


def _finite(value: object) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)


def _edge_distance(grid: TileGrid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    size = grid.tile_size
    return np.minimum(np.minimum(x, size - x), np.minimum(y, size - y))


def _in_centre(x: np.ndarray, y: np.ndarray, tile_size: float, side: float) -> np.ndarray:
    half = side / 2
    centre = tile_size / 2
    return (np.abs(x - centre) <= half) & (np.abs(y - centre) <= half)


def _pyramid_rise(grid: TileGrid, level: int, edge: np.ndarray) -> np.ndarray:
    """Height rising from 0 at the tile's edges (`edge`: the distance to them) to gradient x run at the
    spawn square, flat across it."""
    return np.minimum(edge, grid.run) * grid.at_level(grid.slope, level)


def _rough_pyramid(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The pyramid's rise and uniform random bumps of +-roughness, 0 on the tile's edges."""
    edge = _edge_distance(grid, x, y)
    rise = _pyramid_rise(grid, level, edge)
    bumps = rng.uniform(-grid.roughness, grid.roughness, x.shape)
    return rise, np.where(edge == 0, 0.0, bumps)  # the edges stay at 0 to meet the neighbours


def _slope_up(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    rise, bumps = _rough_pyramid(grid, level, x, y, rng)
    return bumps - rise


def _slope_down(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    rise, bumps = _rough_pyramid(grid, level, x, y, rng)
    return bumps + rise


def _smooth_slope_up(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """An inverted pyramid without bumps; draws nothing from `rng`."""
    return 0.0 - _pyramid_rise(grid, level, _edge_distance(grid, x, y))  # 0.0 - : edges at +0.0, not -0.0


def _smooth_slope_down(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A pyramid without bumps; draws nothing from `rng`."""
    return _pyramid_rise(grid, level, _edge_distance(grid, x, y))


def _stair_rise(grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Pyramid stairs: step k = floor(edge distance / stair_width), at most `stair_steps` (the landing over
    the spawn square), raised k x the level's stair height."""
    steps = np.floor(_edge_distance(grid, x, y) / grid.stair_width + _ON_THE_LINE)
    return np.minimum(steps, grid.stair_steps) * grid.at_level(grid.stair_height, level)


def _stairs_up(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Stairs sinking towards the centre, climbed from the spawn square; draws nothing from `rng`."""
    return 0.0 - _stair_rise(grid, level, x, y)


def _stairs_down(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Stairs rising towards the centre, walked down from the spawn square; draws nothing from `rng`."""
    return _stair_rise(grid, level, x, y)


def _discrete(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Random blocks 0.4-1.2 m wide, each raised or sunk by the step height or half of it."""
    h = grid.at_level(grid.step_height, level)
    heights = np.zeros_like(x)
    blocks = round(0.4 * grid.tile_size**2)  # about a quarter of the tile covered, overlapping
    corners = rng.uniform(0.0, grid.tile_size, (blocks, 2))
    sides = rng.uniform(0.4, 1.2, (blocks, 2))
    levels = rng.choice(np.array([-1.0, -0.5, 0.5, 1.0]) * h, blocks)
    for (cx, cy), (sx, sy), value in zip(corners, sides, levels, strict=True):
        heights[(x >= cx) & (x <= cx + sx) & (y >= cy) & (y <= cy + sy)] = value
    heights[_in_centre(x, y, grid.tile_size, grid.spawn_size) | (_edge_distance(grid, x, y) == 0)] = 0.0
    return heights


def _platform(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A flat square platform at the level's height on flat ground."""
    return np.where(
        _in_centre(x, y, grid.tile_size, grid.platform_size), grid.at_level(grid.platform_height, level), 0.0
    )


_TILE_BUILDERS = {
    "slope_up": _slope_up,
    "slope_down": _slope_down,
    "discrete": _discrete,
    "platform": _platform,
    "smooth_slope_up": _smooth_slope_up,
    "smooth_slope_down": _smooth_slope_down,
    "stairs_up": _stairs_up,
    "stairs_down": _stairs_down,
}
