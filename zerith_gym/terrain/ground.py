"""Terrains: the default plane, an uneven height field and tile grids (`zerith_gym.terrain.tiles`), with
height look-ups for rewards and the critic and the robots' spawn points."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from zerith_gym.core.arrays import namespace
from zerith_gym.terrain.tiles import STAIRS_KINDS, TileGrid, tile_heights

TERRAIN_KINDS = ("plane", "uneven", "tiles")
HFIELD_SOLREF = (0.01, 1.0)
"""Contact time constant and damping ratio of height fields (the plane keeps MuJoCo's (0.02, 1)).

MuJoCo collides a height field as a union of triangular prisms. Where a 1-cm sole sphere sinks a few
millimetres at a seam between two prisms, the neighbouring prism's side face gives a contact with a sideways
normal, which trips a walking robot: the shipped HuRi agent walking at 0.5 m/s falls on a flat height field
at step 91 and walks on the plane. Stiffer contacts (mixed with the soles' 0.02: 0.015) keep the soles
shallower and cut those contacts by 7x (docs/zerith1.md, "Terrains")."""


@dataclass(frozen=True)
class TerrainSpec:
    """What ground the robot walks on.

    "uneven" is a square height field of uniform random cell heights in [0, max_height] (0.1 m cells, a
    flat border), laid on the ground plane; the robot starts near its -x edge so that 20 s of walking
    forward at 1 m/s stays on it. "tiles" is the grid of terrain kinds and levels that `tiles` describes
    (`zerith_gym.terrain.tiles.TileGrid`, `resolution` m cells); each robot starts at the centre of its tile.
    """

    kind: str = "plane"
    half_size: float = 15.0
    resolution: float = 0.1
    max_height: float = 0.05
    spawn_xy: tuple[float, float] = (0.0, 0.0)
    spawn_jitter: float = 0.0
    """Half width (m) of the uniform jitter added to the spawn point at each reset."""
    tiles: TileGrid | None = None
    """The tile grid of a "tiles" terrain."""

    def __post_init__(self) -> None:
        if self.kind not in TERRAIN_KINDS:
            raise ValueError(f"terrain kind must be one of {TERRAIN_KINDS}, got {self.kind!r}")
        if (self.kind == "tiles") != isinstance(self.tiles, TileGrid):
            raise ValueError('a "tiles" terrain needs a TileGrid as `tiles`, and only it has one')
        if not self.resolution > 0 or self.spawn_jitter < 0:
            raise ValueError("the terrain's resolution must be > 0 and its spawn_jitter >= 0")
        if self.tiles is not None:
            for name in ("tile_size", "border"):
                cells = getattr(self.tiles, name) / self.resolution
                if abs(cells - round(cells)) > 1e-9:
                    raise ValueError(
                        f"the tiles' {name} ({getattr(self.tiles, name)} m) must be a whole number of cells "
                        f"of the terrain's resolution ({self.resolution} m), so that tiles start on vertices"
                    )
            stairs = any(kind in STAIRS_KINDS for kind in self.tiles.kinds)
            if stairs and self.tiles.stair_width < 2 * self.resolution - 1e-9:
                raise ValueError(
                    f"the tiles' stair_width ({self.tiles.stair_width} m) must be at least two cells of the "
                    f"terrain's resolution ({self.resolution} m), so that every step has a flat cell"
                )

    @property
    def num_levels(self) -> int:
        """Difficulty levels (rows of tiles; 1 unless "tiles")."""
        return self.tiles.levels if self.tiles is not None else 1

    @property
    def num_columns(self) -> int:
        """Terrain kinds side by side (columns of tiles; 1 unless "tiles")."""
        return len(self.tiles.kinds) if self.tiles is not None else 1

    def spawn_points(self, levels: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """Where robots on tiles (level, column) start, world xy (n, 2): `spawn_xy` unless "tiles"."""
        if self.tiles is None:
            return np.broadcast_to(np.asarray(self.spawn_xy, dtype=float), (len(levels), 2))
        return self.tiles.tile_centres(levels, columns)


PLANE = TerrainSpec()
UNEVEN = TerrainSpec(kind="uneven", spawn_xy=(-12.0, 0.0), spawn_jitter=1.0)


def tile_terrain(**grid: object) -> TerrainSpec:
    """A "tiles" terrain of the `TileGrid` with these fields (0.1 m cells, 0.3 m spawn jitter)."""
    return TerrainSpec(kind="tiles", tiles=TileGrid(**grid), spawn_jitter=0.3)  # type: ignore[arg-type]


class Terrain:
    """Ground geometry of one model; `height_at` gives the ground height under world xy points."""

    def __init__(self, spec: TerrainSpec, seed: int = 0) -> None:
        self.spec = spec
        self.is_plane = spec.kind == "plane"
        self.heights = np.zeros((1, 1))
        """Heights (m) on the height field's vertices, rows along y, columns along x."""
        self.half_extent = (spec.half_size, spec.half_size)
        """Half the height field's extent (m) along x and y; it is centred on the origin."""
        if spec.kind == "uneven":
            cells = round(2 * spec.half_size / spec.resolution) + 1
            heights = np.random.default_rng(seed).random((cells, cells))
            heights[[0, -1], :] = 0.0
            heights[:, [0, -1]] = 0.0
            self.heights = heights / heights.max() * spec.max_height
            self._field = heights / heights.max()  # MuJoCo's [0, 1] data of the height field
        elif spec.tiles is not None:
            self.heights = tile_heights(spec.tiles, spec.resolution, seed)
            width, depth = spec.tiles.size
            self.half_extent = (width / 2, depth / 2)
            span = max(float(self.heights.max() - self.heights.min()), 1e-6)
            self._field = (self.heights - self.heights.min()) / span
        self.lowest = float(self.heights.min())
        """The lowest ground (m): the floor plane lies there, under the height field."""

    @property
    def ground_geoms(self) -> tuple[str, ...]:
        """Names of the geoms the feet can stand on (their friction is randomized with the feet's)."""
        return ("floor",) if self.is_plane else ("floor", "terrain")

    def add_to(self, model_spec: mujoco.MjSpec) -> None:
        """Add the height field (if any) to a model spec whose world has a "floor" plane.

        MuJoCo scales height-field data in [0, 1] by the field's elevation range and raises it by the
        geom's height: the field's geom sits at the lowest ground, the floor plane there too (uneven) or
        5 cm lower (tiles), never above a pit of the field.
        """
        if self.is_plane:
            return
        rows, cols = self.heights.shape
        elevation = max(float(self.heights.max()) - self.lowest, 1e-6)  # the span of `_field`
        model_spec.add_hfield(
            name="terrain",
            size=[*self.half_extent, elevation, 0.05],
            nrow=rows,
            ncol=cols,
            userdata=self._field.ravel().tolist(),
        )
        material = "grid"
        if self.spec.tiles is not None:  # plain, so that shading shows the slopes and blocks
            material = "tiles"
            model_spec.add_material(name=material, rgba=[0.62, 0.56, 0.47, 1.0], specular=0.1)
        floor = model_spec.geom("floor")
        below = self.lowest - (0.05 if self.spec.tiles is not None else 0.0)  # tiles: no shared surface
        floor.pos = [floor.pos[0], floor.pos[1], min(float(floor.pos[2]), below)]
        model_spec.worldbody.add_geom(
            name="terrain",
            type=mujoco.mjtGeom.mjGEOM_HFIELD,
            hfieldname="terrain",
            pos=[0.0, 0.0, self.lowest],
            contype=floor.contype,
            conaffinity=floor.conaffinity,
            condim=floor.condim,
            friction=floor.friction,
            solref=list(HFIELD_SOLREF),
            material=material,
        )

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Ground height (m) under points `xy` (..., 2): bilinear interpolation of the height field.

        Numpy or JAX arrays (the MJX backend traces this with jax.numpy).
        """
        xp = namespace(xy)
        if self.is_plane:
            return xp.zeros(xy.shape[:-1])
        rows, cols = self.heights.shape
        (half_x, half_y), last_col, last_row = self.half_extent, cols - 1, rows - 1
        u = xp.clip((xy[..., 0] + half_x) / (2 * half_x / last_col), 0.0, last_col)  # / the vertex spacing
        v = xp.clip((xy[..., 1] + half_y) / (2 * half_y / last_row), 0.0, last_row)
        c0 = xp.minimum(u.astype(int), last_col - 1)
        r0 = xp.minimum(v.astype(int), last_row - 1)
        fu, fv = u - c0, v - r0
        h = self.heights if xp is np else xp.asarray(self.heights, dtype=xy.dtype)
        return (1 - fv) * ((1 - fu) * h[r0, c0] + fu * h[r0, c0 + 1]) + fv * (
            (1 - fu) * h[r0 + 1, c0] + fu * h[r0 + 1, c0 + 1]
        )
