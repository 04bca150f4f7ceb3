"""Zerith-1 (or the quadruped, `--env Go2Like-v0`) on MJX: raw physics, the env, and HuRiPPO against SB3
PPO, on JAX's default device.

Meant for a GPU machine (`pip install -e ".[mjx]"` and JAX's CUDA build); it also runs with JAX on the
CPU, slowly, to check the pipeline. Printed, per number of robots:

- `still`, `moving`: control steps/s of raw MJX physics of the env's own model (4 sub-steps, `jax.vmap` +
  `jit`, no task), with the solver settings asked for, every robot standing at its default targets or
  moving to random ones as the env's random actions move it (MJX's solver iterates until the whole
  batch has converged: moving robots cost several times standing ones);
- `env`: env steps/s of `make_vec_env(n, backend="mjx")` under random actions: physics, the task, the
  in-step resets and the numpy hand-off with SB3's info dicts;
- `ppo`, `huri`: env steps/s of the whole training loop (collection and updates, after a warm-up
  iteration) with the env's preset in `hyperparams/huri.yml` or `--conf-file` (`--nets` and `--n-steps`
  override its networks and rollout length), the policy on torch's CUDA device where there is one;
  `huri/ppo`: HuRiPPO's wall time per env step relative to SB3 PPO's.

With `--profile`, a torch profiler table of one HuRiPPO update (energy distance, sorting, RND) follows.
With `--split`, where the env's step time goes: the jitted step alone on the device (physics, task and the
in-step resets, no transfer), the reset of every robot alone (what a step costs more when any episode
ended), and the rest of the env's step (transfers, the VecEnv's bookkeeping, SB3's info dicts), in ms.

On a GPU the first compile of the env's functions takes minutes (over 165 s at 4096 robots on an H100);
`JAX_COMPILATION_CACHE_DIR` keeps them for the next process on that machine.

    python benchmarks/bench_mjx.py --num-envs 4096 16384 --iterations 3
    python benchmarks/bench_mjx.py --num-envs 16384 --solver 4 8 --profile
    python benchmarks/bench_mjx.py --conf-file hyperparams/huri_robust.yml --n-steps 32  # the robust recipe
    python benchmarks/bench_mjx.py --num-envs 64 --iterations 1 --skip-training     # JAX on the CPU

Set `XLA_PYTHON_CLIENT_PREALLOCATE=false` when torch shares the GPU with JAX (the script does).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

import jax
import jax.numpy as jnp
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from sb3_huri.zoo import algorithm_kwargs, normalize_kwargs, read_preset
from zerith_gym import robot_of
from zerith_gym.core.physics import RANDOMIZED_FIELDS
from zerith_gym.core.spec import RobotSpec
from zerith_gym.mjx import MjxPhysics, SolverSettings
from zerith_gym.robots import locomotion_task
from zerith_gym.terrain.ground import PLANE, Terrain


def raw_rates(num_envs: int, solver: SolverSettings, steps: int, robot: RobotSpec) -> tuple[float, float]:
    """Control steps/s of raw MJX physics of the nominal model, no task, with one compiled step: every
    robot standing at the default joint targets, then moving, with targets drawn each step as the env's
    random actions draw them (default + action scale x U[-0.3, 0.3]). MJX's solver iterates until every
    robot of the batch has converged, so moving robots cost several times standing ones."""
    physics = MjxPhysics(Terrain(PLANE), solver, robot)
    model = physics.model
    fields = {  # the nominal model's fields, batched as the env batches them
        name: jnp.broadcast_to(jnp.asarray(getattr(model, name)), (num_envs, *getattr(model, name).shape))
        for name in RANDOMIZED_FIELDS
    }
    qpos = jnp.broadcast_to(jnp.asarray(np.r_[0, 0, 0, 1, 0, 0, 0, robot.default_joint_pos]), (num_envs, 19))
    start = jax.jit(jax.vmap(physics.reset))(fields, qpos)
    lags = jnp.zeros((num_envs, robot.decimation), jnp.int32)
    no_force = (jnp.zeros((num_envs, 3)), jnp.zeros(num_envs, jnp.int32), jnp.zeros((num_envs, 2)))
    step = jax.jit(jax.vmap(physics.control_step))
    offsets = np.random.default_rng(0).uniform(-0.3, 0.3, (steps + 1, num_envs, 1, robot.num_joints))
    rates = []
    for spread in (0.0, 1.0):
        targets = jnp.asarray(
            np.broadcast_to(
                robot.default_joint_pos + spread * robot.action_scale * offsets, (steps + 1, num_envs, 3, 12)
            ),
            jnp.float32,
        )
        data, _ = step(fields, start, targets[0], lags, *no_force)  # compiles on the first pass
        jax.block_until_ready(data)
        began = time.perf_counter()
        for t in range(steps):
            data, _ = step(fields, data, targets[t + 1], lags, *no_force)
        jax.block_until_ready(data)
        rates.append(steps * num_envs / (time.perf_counter() - began))
    return rates[0], rates[1]


def env_rate(
    num_envs: int, solver: SolverSettings, steps: int, env_kwargs: dict, split: bool = False
) -> tuple[float, dict[str, float] | None]:
    """Env steps/s of the MJX VecEnv under random actions (after the compiling first step), and with
    `split` the step's parts (`split_step`)."""
    env = zerith_gym.make_vec_env(
        num_envs, seed=0, backend="mjx", solver_iterations=solver.iterations,
        ls_iterations=solver.ls_iterations, **env_kwargs,
    )  # fmt: skip
    env.reset()
    actions = np.random.default_rng(0).uniform(-0.3, 0.3, (steps + 1, num_envs, 12))
    env.step(actions[0])
    start = time.perf_counter()
    for t in range(steps):
        env.step(actions[t + 1])
    rate = steps * num_envs / (time.perf_counter() - start)
    parts = split_step(env, steps) if split else None
    env.close()
    return rate, parts


def split_step(env, steps: int) -> dict[str, float]:
    """ms per step of the env's jitted step alone, of the reset of every robot alone, and of the whole
    VecEnv step, each after a compiling first call (random actions, the env already reset)."""
    robots = env.robots
    rng = np.random.default_rng(1)
    actions = jnp.asarray(rng.uniform(-0.3, 0.3, (env.num_envs, 12)), robots.state.task.actions.dtype)

    def timed(call) -> float:
        jax.block_until_ready(call())
        start = time.perf_counter()
        for _ in range(steps):
            result = call()
        jax.block_until_ready(result)
        return 1e3 * (time.perf_counter() - start) / steps

    state = robots.state
    step_ms = timed(lambda: robots._step(state, actions, robots.arrays))
    overrides = jnp.full((env.num_envs, 3), jnp.nan, actions.dtype)
    reset_ms = timed(lambda: robots._reset(jax.random.key(0), robots.arrays, overrides))
    numpy_actions = np.asarray(actions)
    env_ms = timed(lambda: env.step(numpy_actions))
    return {"jitted step": step_ms, "reset all": reset_ms, "env step": env_ms}


def build(algo: str, preset: dict, env, net: list[int] | None, device: str):
    kwargs = algorithm_kwargs(preset)
    if net:
        kwargs["policy_kwargs"] = dict(kwargs.get("policy_kwargs") or {}, net_arch=net)
    if algo == "ppo":
        kwargs["batch_size"] = env.num_envs * kwargs["n_steps"] // kwargs.pop("n_minibatches")
        for name in ("n_quantiles", "sr_lambda", "expectation_coef", "quantile_coef", "desired_kl",
                     "critic_learning_rate"):  # fmt: skip
            kwargs.pop(name, None)
        return PPO("MultiInputPolicy", env, seed=0, device=device, **kwargs)
    return HuRiPPO("MultiInputPolicy", env, seed=0, device=device, **kwargs)


def train_rate(algo: str, preset: dict, env, net: list[int] | None, iterations: int, device: str) -> float:
    """Env steps/s of `iterations` training iterations after a warm-up one."""
    model = build(algo, preset, env, net, device)
    per_iteration = env.num_envs * model.n_steps
    model.learn(per_iteration)
    start = time.perf_counter()
    model.learn(iterations * per_iteration, reset_num_timesteps=False)
    return iterations * per_iteration / (time.perf_counter() - start), model


def profile_update(model) -> str:
    """A torch profiler table of one HuRiPPO update on the last rollout."""
    from torch.profiler import ProfilerActivity, profile

    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if torch.cuda.is_available() else [])
    with profile(activities=activities) as prof:
        model.train()
        if torch.cuda.is_available():
            torch.cuda.synchronize()
    sort = "cuda_time_total" if torch.cuda.is_available() else "cpu_time_total"
    return prof.key_averages().table(sort_by=sort, row_limit=20)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--env", default="Zerith1-v0", choices=["Zerith1-v0", "Go2Like-v0"])
    parser.add_argument("--num-envs", type=int, nargs="+", default=[4096, 16384])
    parser.add_argument("--solver", type=int, nargs=2, default=None, metavar=("ITERATIONS", "LS_ITERATIONS"))
    parser.add_argument("--iterations", type=int, default=3, help="timed training iterations")
    parser.add_argument("--steps", type=int, default=20, help="timed steps of raw physics and of the env")
    parser.add_argument("--nets", type=int, nargs="+", default=None, help="default: the preset's")
    parser.add_argument("--n-steps", type=int, default=None, help="rollout length (default: the preset's)")
    parser.add_argument("--conf-file", default=None, help="hyperparameter file (default: the packaged one)")
    parser.add_argument("--skip-training", action="store_true")
    parser.add_argument("--profile", action="store_true", help="profile one HuRiPPO update")
    parser.add_argument("--split", action="store_true", help="where the env's step time goes (ms)")
    args = parser.parse_args()
    solver = SolverSettings(*(args.solver or (None, None)))
    device = "cuda" if torch.cuda.is_available() else "cpu"
    preset = read_preset(args.env, args.conf_file)
    if args.n_steps:
        preset["n_steps"] = args.n_steps
    robot = robot_of(args.env)
    env_kwargs = {**(preset.get("env_kwargs") or {}), "robot": robot}
    print(
        f"JAX device: {jax.devices()[0]}, torch device: {device}, solver {args.solver or 'of the MJCF'}, "
        f"{args.conf_file or 'huri.yml'}: {args.env}, n_steps {preset['n_steps']}, "
        f"nets {args.nets or 'preset'}"
    )
    print(f"{'robots':>7} {'still':>9} {'moving':>9} {'env':>9} {'ppo':>9} {'huri':>9} {'huri/ppo':>9}")
    for n in args.num_envs:
        still, raw = raw_rates(n, solver, args.steps, locomotion_task(robot).robot)
        env, split = env_rate(n, solver, args.steps, env_kwargs, args.split)
        row = f"{n:>7} {still:>9.0f} {raw:>9.0f} {env:>9.0f}"
        if split:
            print(f"{n:>7} robots, ms per step: " + ", ".join(f"{k} {v:.2f}" for k, v in split.items()))
            print(f"{'':>7} moving robots' physics alone: {1e3 * n / raw:.2f} ms per control step")
        if not args.skip_training:
            venv = VecNormalize(
                zerith_gym.make_vec_env(
                    n, seed=0, backend="mjx", solver_iterations=solver.iterations,
                    ls_iterations=solver.ls_iterations, **env_kwargs,
                ),
                gamma=preset.get("gamma", 0.99), **(normalize_kwargs(preset) or {}),
            )  # fmt: skip
            ppo, _ = train_rate("ppo", preset, venv, args.nets, args.iterations, device)
            huri, model = train_rate("huri", preset, venv, args.nets, args.iterations, device)
            row += f" {ppo:>9.0f} {huri:>9.0f} {ppo / huri:>9.2f}"
            if args.profile:
                print(profile_update(model))
            venv.close()
        print(row, flush=True)


if __name__ == "__main__":
    main()
