"""Render each tile-terrain kind at its lowest, middle and top level, with a robot on the top level.

    MUJOCO_GL=egl python examples/render_terrains.py --out docs/media
    MUJOCO_GL=egl python examples/render_terrains.py --robot go2like --out docs/media

writes `terrain-<kind>.png` per kind (the pictures of docs/zerith1.md; left to right: level 0, the middle
level, the top level, with the default `TileGrid` ranges) or, for the quadruped, `go2like-<kind>.png`: the
top level of legged_gym's ranges (the `quadruped-rough` scenario's) seen from close by (docs/go2like.md).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import matplotlib.pyplot as plt
import mujoco
import numpy as np

from zerith_gym.core.physics import build_model
from zerith_gym.core.scenarios import QUADRUPED_ROUGH
from zerith_gym.robots import ROBOT_TASKS
from zerith_gym.terrain.ground import Terrain, tile_terrain
from zerith_gym.terrain.tiles import TILE_KINDS

VIEWS = {"zerith1": (17.0, 90.0, -38.0), "go2like": (4.0, 135.0, -30.0)}
"""Per robot: the camera's distance (m), azimuth and elevation (degrees)."""


def render_kind(kind: str, robot_name: str, width: int, height: int) -> np.ndarray:
    """An image (height, width, 3) of three tiles of `kind` (levels low to high) and a robot on the last."""
    robot = ROBOT_TASKS[robot_name].robot
    if robot_name == "zerith1":
        spec = tile_terrain(kinds=(kind,), levels=3, border=1.0)
    else:
        grid = dataclasses.replace(
            QUADRUPED_ROUGH.terrain.tiles, kinds=(kind,), levels=3, start_levels=1, border=1.0
        )
        spec = dataclasses.replace(QUADRUPED_ROUGH.terrain, tiles=grid)
    terrain = Terrain(spec, seed=0)
    model = build_model(terrain, robot)
    data = mujoco.MjData(model)
    top = spec.tiles.tile_centres(np.array([2]), np.array([0]))[0]
    data.qpos[:2] = top
    data.qpos[2] = terrain.height_at(top[None])[0] + robot.standing_height + 0.05
    data.qpos[3] = 1.0
    data.qpos[7:] = robot.default_joint_pos
    mujoco.mj_forward(model, data)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [0.0, 0.0, 0.0] if robot_name == "zerith1" else data.qpos[:3]
    camera.distance, camera.azimuth, camera.elevation = VIEWS[robot_name]
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.update_scene(data, camera)
        return renderer.render()


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("--out", type=Path, default=Path("docs/media"), help="folder of the images")
    parser.add_argument("--robot", choices=list(ROBOT_TASKS), default="zerith1")
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--height", type=int, default=400)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    prefix = "terrain" if args.robot == "zerith1" else args.robot
    for kind in TILE_KINDS:
        path = args.out / f"{prefix}-{kind}.png"
        plt.imsave(path, render_kind(kind, args.robot, args.width, args.height))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
