"""Tile terrains: their geometry, the robots' tiles, the terrain curriculum and the paper's terrain tests."""

from __future__ import annotations

import hashlib
from dataclasses import replace

import gymnasium
import mujoco
import numpy as np
import pytest
from stable_baselines3.common.logger import configure

import zerith_gym
from sb3_huri import HuRiPPO
from zerith_gym.core.physics import build_model
from zerith_gym.core.scenarios import SCENARIOS, Scenario
from zerith_gym.sb3.callbacks import TerrainCurriculum
from zerith_gym.terrain.ground import Terrain, TerrainSpec, tile_terrain
from zerith_gym.terrain.levels import LevelRule, TerrainLevels, next_levels
from zerith_gym.terrain.tiles import (
    LEGGED_GYM_PROPORTIONS,
    PAPER_TILE_KINDS,
    TILE_KINDS,
    TileGrid,
    legged_gym_kinds,
    tile_heights,
)
from zerith_gym.zerith1.constants import ZERITH1

SMALL = {"levels": 3, "tile_size": 6.0, "border": 2.0}
"""A small grid of every kind: 3 levels of 6-m tiles."""
STAIRS = ("stairs_up", "stairs_down")


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
    grid = TileGrid(kinds=PAPER_TILE_KINDS, **SMALL)
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


OLD_KIND_HASHES = {
    (PAPER_TILE_KINDS, 4): "c7ac048ecc54d477d0e2036c6767b33a398e6964e61595a9781a384b90666271",
    (("discrete", "slope_up", "discrete", "slope_down", "slope_up"), 7): (
        "2e6c2696801a1b597b5ee90a3e5cfec7c5da761799e834f8e05cc0f4d6545399"
    ),
}
"""sha256 of the heights of SMALL grids of the paper's kinds (kinds, seed), taken before the smooth slopes and
the stairs were added (numpy 2.4.6): those kinds' heights and random draws must not change."""


def test_the_paper_kinds_build_the_heights_they_built_before_the_new_kinds() -> None:
    for (kinds, seed), expected in OLD_KIND_HASHES.items():
        heights = tile_heights(TileGrid(kinds=kinds, **SMALL), 0.1, seed)
        assert hashlib.sha256(heights.tobytes()).hexdigest() == expected, kinds
    # the new kinds draw nothing: the paper's kinds beside them get the same tiles as without them
    mixed = TileGrid(kinds=("stairs_up", "slope_up", "smooth_slope_down", "discrete", "stairs_down"), **SMALL)
    alone = TileGrid(kinds=("slope_up", "discrete"), **SMALL)
    with_new, without = tile_heights(mixed, 0.1, 3), tile_heights(alone, 0.1, 3)
    for level in range(SMALL["levels"]):
        for column, old_column in ((1, 0), (3, 1)):
            np.testing.assert_array_equal(
                _tile_block(mixed, with_new, level, column, 0.1),
                _tile_block(alone, without, level, old_column, 0.1),
            )


def _centre_row(grid: TileGrid, heights: np.ndarray, level: int, column: int) -> np.ndarray:
    """A tile's heights along the row through its centre, from its -x edge to its centre (0.1 m cells)."""
    tile = _tile_block(grid, heights, level, column, 0.1)
    middle = round(grid.tile_size / 0.2)
    return tile[middle, : middle + 1]


@pytest.mark.parametrize(
    ("stair_width", "stair_height", "steps", "tread_cells"),
    [(0.31, (0.05, 0.2), 6, (3, 4)), (0.5, (0.1, 0.3), 4, (5,))],  # 0.5 m: every riser on a vertex line
)
def test_stairs_climb_whole_steps_from_the_centre_to_the_edge(
    stair_width: float, stair_height: tuple[float, float], steps: int, tread_cells: tuple[int, ...]
) -> None:
    grid = TileGrid(kinds=STAIRS, stair_width=stair_width, stair_height=stair_height, **SMALL)
    heights = tile_heights(grid, 0.1, seed=0)
    assert grid.stair_steps == steps  # the landing's step: those that fit in the 2 m from the edge in SMALL
    spawn, middle = round(grid.spawn_size / 0.2), round(grid.tile_size / 0.2)
    for level in range(grid.levels):
        rise = grid.at_level(stair_height, level)
        assert rise == pytest.approx(stair_height[0] + (stair_height[1] - stair_height[0]) * level / 2)
        for column, sign in ((0, -1.0), (1, 1.0)):  # up: sunk towards the centre; down: raised
            tile = _tile_block(grid, heights, level, column, 0.1)
            assert np.all(tile[[0, -1], :] == 0.0) and np.all(tile[:, [0, -1]] == 0.0)
            landing = tile[middle - spawn : middle + spawn + 1, middle - spawn : middle + spawn + 1]
            assert np.all(landing == sign * steps * rise)  # the spawn square: flat, the last step
            index = sign * tile / rise  # the step each vertex is on
            np.testing.assert_allclose(index, np.round(index), atol=1e-9)
            assert np.round(index).min() == 0 and np.round(index).max() == steps
            row = np.round(sign * _centre_row(grid, heights, level, column) / rise).astype(int)
            assert set(np.diff(row)) == {0, 1}  # from the edge inwards: one step at a time, never down
            starts = np.flatnonzero(np.diff(row)) + 1  # first vertex (0.1 m cells) of steps 1 .. steps
            np.testing.assert_array_equal(row[starts], np.arange(1, steps + 1))
            distance = starts * 0.1
            edges = np.arange(1, steps + 1) * stair_width
            assert np.all((distance >= edges - 1e-9) & (distance < edges + 0.1 - 1e-9))
            assert set(np.diff(starts)) <= set(tread_cells)
            np.testing.assert_array_equal(tile, tile.T)  # square rings: the same whichever way it walks


def test_smooth_slopes_are_the_rough_slopes_without_bumps() -> None:
    kinds = ("smooth_slope_up", "smooth_slope_down", "slope_up", "slope_down")
    grid = TileGrid(kinds=kinds, **SMALL)
    heights = tile_heights(grid, 0.1, seed=1)
    spawn, middle = round(grid.spawn_size / 0.2), round(grid.tile_size / 0.2)
    for level in range(grid.levels):
        gradient = grid.at_level(grid.slope, level)
        up, down, rough_up, rough_down = (_tile_block(grid, heights, level, k, 0.1) for k in range(4))
        np.testing.assert_array_equal(up, -down)
        assert np.all(down[[0, -1], :] == 0.0) and np.all(down[:, [0, -1]] == 0.0)
        assert np.all(
            down[middle - spawn : middle + spawn + 1, middle - spawn : middle + spawn + 1] == down.max()
        )
        assert down.max() == pytest.approx(gradient * grid.run, abs=1e-12)
        run_cells = round(grid.run / 0.1)
        np.testing.assert_allclose(np.diff(down[middle, : run_cells + 1]), gradient * 0.1, atol=1e-12)
        np.testing.assert_array_equal(down, down.T)
        assert (
            np.abs(up - rough_up).max() <= grid.roughness
            and np.abs(down - rough_down).max() <= grid.roughness
        )
        if level > 0:
            assert np.all(np.diff(down[middle, : middle + 1]) >= 0)  # no bumps: never down towards the top


def test_repeated_kinds_give_repeated_columns() -> None:
    grid = TileGrid(kinds=("stairs_down", "discrete", "stairs_down", "discrete"), **SMALL)
    heights = tile_heights(grid, 0.1, seed=0)
    for level in range(grid.levels):
        stairs, blocks, stairs_again, blocks_again = (
            _tile_block(grid, heights, level, k, 0.1) for k in range(4)
        )
        np.testing.assert_array_equal(stairs, stairs_again)  # no random draws
        assert not np.array_equal(blocks, blocks_again)  # drawn again for each tile


def test_legged_gym_kinds_lay_out_its_mix_by_its_proportions() -> None:
    assert legged_gym_kinds() == (
        "smooth_slope_up", "smooth_slope_down", "slope_down", "slope_down", *("stairs_up",) * 7,
        *("stairs_down",) * 5, *("discrete",) * 4,
    )  # fmt: skip
    kind_of_type = {
        "smooth_slope": ("smooth_slope_up", "smooth_slope_down"),
        "rough_slope": ("slope_down",),
        "stairs_up": ("stairs_up",),
        "stairs_down": ("stairs_down",),
        "discrete": ("discrete",),
    }
    assert sum(share for _, share in LEGGED_GYM_PROPORTIONS) == pytest.approx(1.0)
    for columns in range(1, 101):
        kinds = legged_gym_kinds(columns)
        assert len(kinds) == columns and set(kinds) <= set(TILE_KINDS)
        for name, share in LEGGED_GYM_PROPORTIONS:
            count = sum(kind in kind_of_type[name] for kind in kinds)
            if columns % 20 == 0:
                assert count == round(share * columns), (columns, name)
            else:
                assert abs(count - share * columns) < 1.0, (columns, name)
        if columns % 20 == 0:
            assert kinds.count("smooth_slope_up") == kinds.count("smooth_slope_down")
    spec = tile_terrain(kinds=legged_gym_kinds(), levels=2, tile_size=6.0, border=2.0)
    heights = Terrain(spec, seed=0).heights
    assert spec.num_columns == 20 and np.isfinite(heights).all()
    assert heights.min() < 0 < heights.max()  # stairs and slopes up sink, stairs and slopes down rise


def test_robots_start_on_the_new_kinds_and_stand_on_the_ground() -> None:
    kinds = ("smooth_slope_up", "smooth_slope_down", *STAIRS)
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=kinds, start_levels=3, **SMALL))
    env = zerith_gym.make_vec_env(12, seed=0, scenario=scenario, workers=0)
    env.reset()
    for _ in range(5):
        env.step(np.zeros((12, 12)))
    base = np.array([data.qpos[:3] for data in env.robots.sim.datas])
    expected = scenario.terrain.tiles.tile_centres((np.arange(12) // 4) % 3, np.arange(12) % 4)
    assert np.abs(base[:, :2] - expected).max() < scenario.terrain.spawn_jitter + 0.05
    ground = env.robots.terrain.height_at(base[:, :2])
    assert np.all((base[:, 2] - ground > 0.6) & (base[:, 2] - ground < 1.1))
    np.testing.assert_array_equal(ground, env.robots.terrain.height_at(expected))  # on the flat spawn square
    columns, levels = np.arange(12) % 4, (np.arange(12) // 4) % 3
    tilted = (levels > 0) | (columns >= 2)  # all but the level-0 slopes (gradient 0)
    assert np.all(ground[tilted & (columns % 2 == 0)] < 0) and np.all(ground[tilted & (columns % 2 == 1)] > 0)
    env.close()


def test_heights_under_the_feet_are_mujocos_ground() -> None:
    """`height_at` (rewards, the critic's samples, falls) against rays cast onto the compiled model."""
    terrain = Terrain(tile_terrain(kinds=TILE_KINDS, **SMALL), seed=2)
    model = build_model(terrain, ZERITH1)
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
            rise = max(terrain.spec.tiles.step_height[1], terrain.spec.tiles.stair_height[1])
            assert np.median(error) < 1e-3 and error.max() < 0.5 * rise + 0.05  # a block's or a step's edge
    floor = model.geom("floor")
    assert floor.pos[2] < terrain.lowest  # never above a pit of the field


@pytest.mark.parametrize("workers", [0, 1])
def test_robots_start_on_their_tiles_and_stand_on_the_ground(workers: int) -> None:
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=PAPER_TILE_KINDS, start_levels=3, **SMALL))
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
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=PAPER_TILE_KINDS, **SMALL))
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
    scenario = Scenario("tiles", terrain=tile_terrain(kinds=PAPER_TILE_KINDS, start_levels=1, **SMALL))
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
    tiles = TerrainLevels(spec, np.arange(8), ZERITH1.control_dt)
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
    tiles = TerrainLevels(spec, np.arange(4), ZERITH1.control_dt)
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
        (lambda: TileGrid(stair_width=0.0), r"stair_width must be in \(0, 3\] m"),
        (lambda: TileGrid(stair_width=3.1), r"stair_width must be in \(0, 3\] m"),
        (lambda: TileGrid(tile_size=6.0, stair_width=float("nan")), r"stair_width must be in \(0, 2\] m"),
        (lambda: TileGrid(stair_height=(0.2, 0.1)), "stair_height must be a range"),
        (lambda: TileGrid(stair_height=(-0.05, 0.1)), "stair_height must be a range"),
        (lambda: TileGrid(stair_height=(0.05, float("inf"))), "stair_height must be a range"),
        (lambda: TileGrid(stair_height=0.1), "stair_height must be a range"),
        (lambda: tile_terrain(kinds=("stairs_up",), stair_width=0.15), "at least two cells"),
        (lambda: legged_gym_kinds(0), "columns must be a positive integer"),
        (lambda: LevelRule(demote_fraction=1.5), "demote_fraction"),
        (lambda: LevelRule(promote_distance=0.0), "promote_distance"),
    ],
)
def test_bad_terrain_options_are_refused(make, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_narrow_stairs_are_refused_only_where_there_are_stairs() -> None:
    assert tile_terrain(stair_width=0.15).tiles.stair_width == 0.15  # no stairs: not a step to fit in cells
    assert TerrainSpec(kind="tiles", tiles=TileGrid(kinds=STAIRS, stair_width=0.15), resolution=0.05)


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
