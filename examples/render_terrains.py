"""Render each tile-terrain kind at its lowest, middle and top level, with a Zerith-1 on the top level.

    MUJOCO_GL=egl python examples/render_terrains.py --out docs/media

writes `terrain-<kind>.png` per kind (the pictures of docs/zerith1.md). The levels use the default
`TileGrid` ranges; left to right: level 0, the middle level, the top level.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib.pyplot as plt
import mujoco
import numpy as np

from zerith_gym import robot
from zerith_gym.physics import build_model
from zerith_gym.terrain import Terrain, tile_terrain
from zerith_gym.tiles import TILE_KINDS


def render_kind(kind: str, width: int, height: int) -> np.ndarray:
    """An image (height, width, 3) of three tiles of `kind` (levels low to high) and a robot on the last."""
    spec = tile_terrain(kinds=(kind,), levels=3, border=1.0)
    terrain = Terrain(spec, seed=0)
    model = build_model(terrain)
    data = mujoco.MjData(model)
    top = spec.tiles.tile_centres(np.array([2]), np.array([0]))[0]
    data.qpos[:2] = top
    data.qpos[2] = terrain.height_at(top[None])[0] + robot.STANDING_HEIGHT + 0.05
    data.qpos[3] = 1.0
    data.qpos[7:] = robot.DEFAULT_JOINT_POS
    mujoco.mj_forward(model, data)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [0.0, 0.0, 0.0]
    camera.distance, camera.azimuth, camera.elevation = 17.0, 90.0, -38.0
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.update_scene(data, camera)
        return renderer.render()


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("--out", type=Path, default=Path("docs/media"), help="folder of the images")
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--height", type=int, default=400)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for kind in TILE_KINDS:
        path = args.out / f"terrain-{kind}.png"
        plt.imsave(path, render_kind(kind, args.width, args.height))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
