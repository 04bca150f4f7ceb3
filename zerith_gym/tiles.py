"""Tile terrains: a grid of square tiles, one column per terrain kind and one row per difficulty level.

Legged-robot trainers lay their terrains out this way so that a curriculum can move each robot to a
harder or easier tile by changing where it starts (`zerith_gym.terrain_levels`). Every tile is built around
a spawn square at its centre (flat but for the slopes' bumps) and meets its neighbours at height 0 along its
edges, so a robot that
walks off its tile steps onto the next one instead of off a cliff. The kinds:

- `slope_up`: an inverted pyramid, the robot starts at the bottom and walks up a rough slope whichever way
  it goes; the gradient grows with the level.
- `slope_down`: a pyramid, the robot starts on top and walks down a rough slope.
- `discrete`: random rectangular blocks raised or sunk by the level's step height (`+-h` or `+-h/2`).
- `platform`: a square platform of the level's height, to step down from (the paper's Table 8).

Heights are in metres on the grid's vertices (rows along y, columns along x), pure numpy, and the same
for the same seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TILE_KINDS = ("slope_up", "slope_down", "discrete", "platform")
"""The terrain kinds a tile can have."""


@dataclass(frozen=True)
class TileGrid:
    """The layout and difficulty of a tile terrain.

    Tile (level l, kind k) spans x in [l, l + 1) * tile_size and y in [k, k + 1) * tile_size from the grid's
    corner, inside a flat border of `border` metres. A range (lo, hi) gives the value at level 0 and at the
    top level, linear in between.
    """

    kinds: tuple[str, ...] = ("slope_up", "slope_down", "discrete", "platform")
    levels: int = 10
    tile_size: float = 8.0
    """Side (m) of a tile."""
    border: float = 20.0
    """Flat ground (m) around the grid, so that robots on the outer tiles stay on the terrain for 20 s."""
    slope: tuple[float, float] = (0.0, 0.3)
    """Gradient (rise over run) of `slope_up` and `slope_down` (0.3: 17 degrees)."""
    roughness: float = 0.02
    """Half width (m) of the uniform random bumps on the slopes' vertices."""
    step_height: tuple[float, float] = (0.03, 0.15)
    """Height (m) of the `discrete` blocks."""
    platform_height: tuple[float, float] = (0.05, 0.45)
    """Height (m) of the `platform` to step down from."""
    spawn_size: float = 2.0
    """Side (m) of the flat square at a tile's centre where robots start (slopes and blocks)."""
    platform_size: float = 3.0
    """Side (m) of the `platform`."""
    start_levels: int = 1
    """Robots start spread over levels [0, start_levels) (before a curriculum moves them)."""

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

    @property
    def size(self) -> tuple[float, float]:
        """Extent (m) of the whole terrain along x and y, border included."""
        return (
            self.levels * self.tile_size + 2 * self.border,
            len(self.kinds) * self.tile_size + 2 * self.border,
        )

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


def _edge_distance(grid: TileGrid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    size = grid.tile_size
    return np.minimum(np.minimum(x, size - x), np.minimum(y, size - y))


def _in_centre(x: np.ndarray, y: np.ndarray, tile_size: float, side: float) -> np.ndarray:
    half = side / 2
    centre = tile_size / 2
    return (np.abs(x - centre) <= half) & (np.abs(y - centre) <= half)


def _rough_pyramid(
    grid: TileGrid, level: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Height rising from 0 at the tile's edges to gradient x run at the spawn square, with bumps."""
    run = (grid.tile_size - grid.spawn_size) / 2
    edge = _edge_distance(grid, x, y)
    rise = np.minimum(edge, run) * grid.at_level(grid.slope, level)
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
}
