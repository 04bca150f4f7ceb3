"""Terrains: the default plane and an uneven height field, with height look-ups for rewards and the critic."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from zerith_gym.arrays import namespace

TERRAIN_KINDS = ("plane", "uneven")


@dataclass(frozen=True)
class TerrainSpec:
    """What ground the robot walks on.

    "uneven" is a square height field of uniform random cell heights in [0, max_height] (0.1 m cells, a
    flat border), laid on the ground plane; the robot starts near its -x edge so that 20 s of walking
    forward at 1 m/s stays on it.
    """

    kind: str = "plane"
    half_size: float = 15.0
    resolution: float = 0.1
    max_height: float = 0.05
    spawn_xy: tuple[float, float] = (0.0, 0.0)
    spawn_jitter: float = 0.0
    """Half width (m) of the uniform jitter added to the spawn point at each reset."""

    def __post_init__(self) -> None:
        if self.kind not in TERRAIN_KINDS:
            raise ValueError(f"terrain kind must be one of {TERRAIN_KINDS}, got {self.kind!r}")


PLANE = TerrainSpec()
UNEVEN = TerrainSpec(kind="uneven", spawn_xy=(-12.0, 0.0), spawn_jitter=1.0)


class Terrain:
    """Ground geometry of one model; `height_at` gives the ground height under world xy points."""

    def __init__(self, spec: TerrainSpec, seed: int = 0) -> None:
        self.spec = spec
        self.is_plane = spec.kind == "plane"
        self.heights = np.zeros((1, 1))
        if not self.is_plane:
            cells = round(2 * spec.half_size / spec.resolution) + 1
            normalized = np.random.default_rng(seed).random((cells, cells))
            normalized[[0, -1], :] = 0.0
            normalized[:, [0, -1]] = 0.0
            normalized /= normalized.max()  # MuJoCo normalizes height-field data to [0, 1]: do it ourselves
            self._normalized = normalized
            self.heights = normalized * spec.max_height

    @property
    def ground_geoms(self) -> tuple[str, ...]:
        """Names of the geoms the feet can stand on (their friction is randomized with the feet's)."""
        return ("floor",) if self.is_plane else ("floor", "terrain")

    def add_to(self, model_spec: mujoco.MjSpec) -> None:
        """Add the height field (if any) to a model spec whose world has a "floor" plane."""
        if self.is_plane:
            return
        rows, cols = self.heights.shape
        half = self.spec.half_size
        model_spec.add_hfield(
            name="terrain",
            size=[half, half, self.spec.max_height, 0.05],
            nrow=rows,
            ncol=cols,
            userdata=self._normalized.ravel().tolist(),
        )
        floor = model_spec.geom("floor")
        model_spec.worldbody.add_geom(
            name="terrain",
            type=mujoco.mjtGeom.mjGEOM_HFIELD,
            hfieldname="terrain",
            contype=floor.contype,
            conaffinity=floor.conaffinity,
            condim=floor.condim,
            friction=floor.friction,
            material="grid",
        )

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Ground height (m) under points `xy` (..., 2): bilinear interpolation of the height field.

        Numpy or JAX arrays (the MJX backend traces this with jax.numpy).
        """
        xp = namespace(xy)
        if self.is_plane:
            return xp.zeros(xy.shape[:-1])
        res, half = self.spec.resolution, self.spec.half_size
        last = self.heights.shape[0] - 1
        u = xp.clip((xy[..., 0] + half) / res, 0.0, last)
        v = xp.clip((xy[..., 1] + half) / res, 0.0, last)
        c0 = xp.minimum(u.astype(int), last - 1)
        r0 = xp.minimum(v.astype(int), last - 1)
        fu, fv = u - c0, v - r0
        h = self.heights if xp is np else xp.asarray(self.heights, dtype=xy.dtype)
        return (1 - fv) * ((1 - fu) * h[r0, c0] + fu * h[r0, c0 + 1]) + fv * (
            (1 - fu) * h[r0 + 1, c0] + fu * h[r0 + 1, c0 + 1]
        )
