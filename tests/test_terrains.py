"""Tile terrains: their geometry, the robots' tiles, the terrain curriculum and the paper's terrain tests."""

from __future__ import annotations

from dataclasses import replace

import gymnasium
import mujoco
import numpy as np
import pytest
from stable_baselines3.common.logger import configure

import zerith_gym
from sb3_huri import HuRiPPO
from zerith_gym.callbacks import TerrainCurriculum
from zerith_gym.physics import build_model
from zerith_gym.scenarios import SCENARIOS, Scenario
from zerith_gym.terrain import Terrain, TerrainSpec, tile_terrain
from zerith_gym.terrain_levels import LevelRule, TerrainLevels, next_levels
from zerith_gym.tiles import TILE_KINDS, TileGrid, tile_heights

SMALL = {"levels": 3, "tile_size": 6.0, "border": 2.0}
"""A small grid of every kind: 3 levels of 6-m tiles."""


def _tile_block(grid: TileGrid, heights: np.ndarray, level: int, column: int, resolution: float):
    per_tile, offset = round(grid.tile_size / resolution), round(grid.border / resolution)
    rows = slice(offset + column * per_tile, offset + (column + 1) * per_tile + 1)
    cols = slice(offset + level * per_tile, offset + (level + 1) * per_tile + 1)
    return heights[rows, cols]


# ----------------------------------------------------------------------------------------- geometry
def test_every_kind_builds_the_same_for_the_same_seed_and_meets_its_neighbours_at_zero() -> None:
    grid = TileGrid(kinds=TILE_KINDS, **SMALL)
    first, again, other = (tile_heights(grid, 0.1, seed) for seed in (4, 4, 5))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)  # the rough slopes' bumps and the blocks are drawn
    width, depth = grid.size
    assert first.shape == (round(depth / 0.1) + 1, round(width / 0.1) + 1)
    for column in range(len(TILE_KINDS)):
        for level in range(grid.levels):
            tile = _tile_block(grid, first, level, column, 0.1)
            assert np.all(tile[[0, -1], :] == 0.0) and np.all(tile[:, [0, -1]] == 0.0)
    border = round(grid.border / 0.1)
    assert np.all(first[:border] == 0.0) and np.all(first[:, :border] == 0.0)


def test_each_kind_has_the_shape_and_height_its_level_gives() -> None:
    grid = TileGrid(kinds=TILE_KINDS, **SMALL)
    heights = tile_heights(grid, 0.1, seed=0)
    run = (grid.tile_size - grid.spawn_size) / 2
    centre = round(grid.tile_size / 0.2)  # the middle vertex of a tile
    for level in range(grid.levels):
        gradient = grid.at_level(grid.slope, level)
        up, down, blocks, platform = (_tile_block(grid, heights, level, k, 0.1) for k in range(4))
        assert up[centre, centre] == pytest.approx(-gradient * run, abs=grid.roughness)
        assert down[centre, centre] == pytest.approx(gradient * run, abs=grid.roughness)
        step = grid.at_level(grid.step_height, level)
        allowed = np.round([-step, -step / 2, 0.0, step / 2, step], 9)
        assert set(np.round(np.unique(blocks), 9)) <= set(allowed)
        assert np.abs(blocks).max() == pytest.approx(step)
        spawn = round(grid.spawn_size / 0.2)
        assert np.all(blocks[centre - spawn : centre + spawn + 1, centre - spawn : centre + spawn + 1] == 0)
        assert platform[centre, centre] == pytest.approx(grid.at_level(grid.platform_height, level))
        assert platform.max() == platform[centre, centre] and platform[0, 0] == 0.0
    assert grid.at_level(grid.slope, 0) == grid.slope[0] and grid.at_level(grid.slope, 2) == grid.slope[1]


def test_heights_under_the_feet_are_mujocos_ground() -> None:
    """`height_at` (rewards, the critic's samples, falls) against rays cast onto the compiled model."""
    terrain = Terrain(tile_terrain(kinds=TILE_KINDS, **SMALL), seed=2)
    model = build_model(terrain)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(0)
    half_x, half_y = terrain.half_extent
    rows, cols = terrain.heights.shape
    vertices = np.column_stack([rng.integers(0, cols, 200), rng.integers(0, rows, 200)])
    at_vertices = vertices * [2 * half_x / (cols - 1), 2 * half_y / (rows - 1)] - [half_x, half_y]
    anywhere = rng.uniform([-half_x, -half_y], [half_x, half_y], (200, 2))
    geom = np.zeros(1, np.int32)
    span = terrain.heights.max() - terrain.lowest
    for points, tolerance in ((at_vertices, 1e-6 * span + 1e-9), (anywhere, None)):
        down = np.array([0.0, 0.0, -1.0])
        cast = [mujoco.mj_ray(model, data, [x, y, 3.0], down, None, 1, -1, geom) for x, y in points]
        ray = 3.0 - np.array(cast)
        error = np.abs(ray - terrain.height_at(points))
        if tolerance is not None:  # on the vertices the two agree up to float32 data
            assert error.max() < 1e-5
        else:  # inside a cell, MuJoCo's triangles and the bilinear look-up part by less than a cell's rise
            assert np.median(error) < 1e-3 and error.max() < 0.5 * terrain.spec.tiles.step_height[1] + 0.05
    floor = model.geom("floor")
    assert floor.pos[2] < terrain.lowest  # never above a pit of the field


@pytest.mark.parametrize("workers", [0, 1])
def test_robots_start_on_their_tiles_and_stand_on_the_ground(workers: int) -> None:
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=TILE_KINDS, start_levels=3, **SMALL))
    env = zerith_gym.make_vec_env(12, seed=0, scenario=scenario, workers=workers)
    env.reset()
    grid = scenario.terrain.tiles
    expected = grid.tile_centres((np.arange(12) // 4) % 3, np.arange(12) % 4)
    for _ in range(5):
        env.step(np.zeros((12, 12)))
    np.testing.assert_array_equal(env.terrain_levels, (np.arange(12) // 4) % 3)
    robots = env.robots if workers == 0 else None
    if robots is not None:
        base = np.array([data.qpos[:3] for data in robots.sim.datas])
        assert np.abs(base[:, :2] - expected).max() < scenario.terrain.spawn_jitter + 0.05
        ground = robots.terrain.height_at(base[:, :2])
        assert np.all((base[:, 2] - ground > 0.6) & (base[:, 2] - ground < 1.1))  # standing, on its tile
    env.close()


def test_a_single_env_starts_on_the_tile_its_reset_asks_for() -> None:
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=TILE_KINDS, **SMALL))
    single = gymnasium.make("Zerith1-v0", scenario=scenario).unwrapped
    single.reset(seed=0)
    at_start = single.data.qpos[:2].copy()
    single.reset(seed=0, options={"tile": (2, 3)})
    centre = scenario.terrain.tiles.tile_centres(np.array([2]), np.array([3]))[0]
    assert np.abs(single.data.qpos[:2] - centre).max() <= scenario.terrain.spawn_jitter
    assert np.abs(at_start - centre).max() > 5.0
    for bad in ((3, 0), (0, 4), (1.5, 0), "a", (True, 0)):
        with pytest.raises(ValueError, match="tile must be"):
            single.reset(options={"tile": bad})
    single.close()


@pytest.mark.parametrize("workers", [0, 1])
def test_a_vec_env_starts_robots_on_the_tiles_its_options_ask_for(workers: int) -> None:
    """SB3's `set_options` with the single env's "tile" option, for some robots, in any worker's slice."""
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=TILE_KINDS, start_levels=1, **SMALL))
    env = zerith_gym.make_vec_env(12, seed=0, scenario=scenario, workers=workers)
    asked = {1: (2, 3), 7: (1, 0), 11: (2, 2)}  # robot 11 is in the last worker's slice
    env.set_options([{"tile": asked[i]} if i in asked else {} for i in range(12)])
    env.reset()
    env.step(np.zeros((12, 12)))
    expected = np.zeros(12, dtype=int)
    expected[list(asked)] = [level for level, _ in asked.values()]
    np.testing.assert_array_equal(env.terrain_levels, expected)
    if workers == 0:
        base = np.array([data.qpos[:2] for data in env.robots.sim.datas])
        centres = scenario.terrain.tiles.tile_centres(*np.array(list(asked.values())).T)
        assert np.abs(base[list(asked)] - centres).max() < scenario.terrain.spawn_jitter + 0.05
    env.reset()  # the options were for one reset; the robots keep their tiles (no curriculum moves them)
    env.step(np.zeros((12, 12)))
    np.testing.assert_array_equal(env.terrain_levels, expected)
    for bad in ((3, 0), (0, 4), "a"):
        env.set_options({"tile": bad})
        with pytest.raises(ValueError, match="tile must be"):
            env.reset()
    env.close()


# ------------------------------------------------------------------------------------- curriculum
def test_level_moves_follow_the_rule() -> None:
    levels = np.array([0, 1, 2, 2, 1, 0, 1])
    walked = np.array([5.0, 5.0, 5.0, 0.1, 5.0, 0.0, 2.5])
    commanded = np.array([10.0, 10.0, 10.0, 10.0, 10.0, 0.0, 4.0])
    fell = np.array([False, False, False, False, True, True, False])
    moved = next_levels(levels, walked, commanded, fell, 4.0, 0.5, top_level=2)
    # promoted, promoted, at the top, fell short, fell, fell at level 0, neither
    np.testing.assert_array_equal(moved, [1, 2, 2, 1, 0, 0, 1])


def test_levels_move_only_for_ended_episodes_and_only_with_a_rule() -> None:
    spec = tile_terrain(levels=5, start_levels=5)
    tiles = TerrainLevels(spec, np.arange(8))
    start = tiles.levels.copy()
    ids = np.arange(8)
    tiles.started(ids, tiles.spawn_points(ids))
    far = tiles.spawn + np.array([5.0, 0.0])
    for _ in range(10):
        tiles.record(
            far, np.tile([1.0, 0.0, 0.0], (8, 1)), np.zeros(8, bool), np.zeros(8, bool), np.zeros(8, bool)
        )
    tiles.spawn_points(ids)  # no rule yet
    np.testing.assert_array_equal(tiles.levels, start)
    tiles.set_rule(LevelRule())
    tiles.started(ids, tiles.spawn)
    ended, steady = np.arange(8) < 4, np.zeros(8, bool)
    tiles.record(tiles.spawn + np.array([5.0, 0.0]), np.zeros((8, 3)), np.zeros(8, bool), ended, steady)
    centres = tiles.spawn_points(ids)
    np.testing.assert_array_equal(tiles.levels, np.minimum(start + (ids < 4), 4))  # 5 m > half a tile
    np.testing.assert_allclose(centres, spec.tiles.tile_centres(tiles.levels, tiles.columns))


def test_an_episode_cut_by_a_diverging_simulation_moves_no_level() -> None:
    spec = tile_terrain(levels=5, start_levels=5)
    tiles = TerrainLevels(spec, np.arange(4))
    ids = np.arange(4)
    tiles.set_rule(LevelRule())
    tiles.started(ids, tiles.spawn_points(ids))
    start = tiles.levels.copy()
    walked = tiles.spawn + np.array([5.0, 0.0])  # far enough to move up
    unstable = np.array([False, True, False, True])
    sensed = np.where(unstable[:, None], 0.0, walked)  # a diverged robot's sensors read zeros
    tiles.record(sensed, np.zeros((4, 3)), np.zeros(4, bool), np.ones(4, bool), unstable)
    tiles.spawn_points(ids)
    np.testing.assert_array_equal(tiles.levels, np.minimum(start + ~unstable, 4))


@pytest.mark.parametrize("workers", [0, 1])
def test_robots_that_fall_short_move_down_in_the_env(workers: int) -> None:
    scenario = replace(SCENARIOS["terrain"], randomization=SCENARIOS["nominal"].randomization)
    env = zerith_gym.make_vec_env(
        6, seed=1, scenario=scenario, command=(0.8, 0.0, 0.0), episode_steps=10, workers=workers
    )
    env.reset()
    env.set_level_rule(LevelRule())
    before = (np.arange(6) // 3) % 3
    for _ in range(10):  # standing still for 10 steps, asked for 0.16 m: short of half of it
        env.step(np.zeros((6, 12)))
    env.step(np.zeros((6, 12)))
    np.testing.assert_array_equal(env.terrain_levels, np.maximum(before - 1, 0))
    env.close()


def test_terrain_curriculum_trains_and_logs_the_level(tmp_path) -> None:
    env = zerith_gym.make_vec_env(8, seed=0, scenario="terrain", workers=0)
    model = HuRiPPO("MultiInputPolicy", env, n_steps=32, batch_size=128, n_epochs=1, seed=0)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(512, callback=TerrainCurriculum())
    header = (tmp_path / "progress.csv").read_text().splitlines()[0].split(",")
    assert "terrain/level" in header and "terrain/max_level_share" in header
    assert env.robots.task.tiles.rule is None  # released at the end of training
    env.close()


def test_terrain_curriculum_warns_when_every_env_is_robot_0() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env as sb3_vec_env

    env = sb3_vec_env("Zerith1-v0", n_envs=2, env_kwargs={"scenario": "terrain", "obs_mode": "policy"})
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=32, n_epochs=1)
    with pytest.warns(UserWarning, match="same tile"):
        model.learn(32, callback=TerrainCurriculum())


# --------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: TileGrid(kinds=("lava",)), "tile kinds must be"),
        (lambda: TileGrid(levels=0), "levels must be a positive integer"),
        (lambda: TileGrid(levels=2, start_levels=3), "cannot exceed levels"),
        (lambda: TileGrid(tile_size=2.0), "tile_size"),
        (lambda: TileGrid(slope=(0.3, 0.1)), "slope must be a range"),
        (lambda: TerrainSpec(kind="tiles"), "needs a TileGrid"),
        (lambda: tile_terrain(tile_size=8.05), "whole number of cells"),
        (lambda: tile_terrain(border=0.25), "whole number of cells"),
        (lambda: TerrainSpec(kind="plane", tiles=TileGrid()), "needs a TileGrid"),
        (lambda: LevelRule(demote_fraction=1.5), "demote_fraction"),
        (lambda: LevelRule(promote_distance=0.0), "promote_distance"),
    ],
)
def test_bad_terrain_options_are_refused(make, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_a_terrain_curriculum_needs_tiles() -> None:
    env = zerith_gym.make_vec_env(2, seed=0, scenario="nominal", workers=0)
    with pytest.raises(ValueError, match="needs a tile terrain"):
        env.set_level_rule(LevelRule())
    env.close()


# ------------------------------------------------------------------------------- the paper's tests
def test_the_platform_scenarios_start_on_the_platform_and_step_down_onto_the_ground() -> None:
    for name, height in (("platform-0.40", 0.40), ("platform-0.45", 0.45)):
        env = zerith_gym.make_vec_env(2, seed=0, scenario=name, workers=0)
        env.reset()
        terrain = env.robots.terrain
        base = np.array([data.qpos[:2] for data in env.robots.sim.datas])
        assert np.all(terrain.height_at(base) == pytest.approx(height))
        ahead = base + np.array([terrain.spec.tiles.platform_size / 2 + 0.5, 0.0])  # forward, off the edge
        assert np.all(terrain.height_at(ahead) == 0.0)
        env.close()
