"""Speed of Zerith1-v0, single and batched, against raw MuJoCo physics of the same models in the same run.

For each configuration it prints control steps per second (robot-steps/s for a batch) of

- raw physics: `mj_step(model, data, nstep=decimation)` on the env's own (randomized) models, with the
  same uniform random actions as the env run turned into joint targets, and a robot put back to its
  reset state when its pelvis drops below the fall height, so the physics does what it does in the env;
- the env: `Zerith1Env.step` (unwrapped and from `gym.make`) or `ZerithVecEnv.step` with those actions,
  resets included;

and the ratio env / raw physics. On K cores (`--physics-threads K`, default: every core) it also times raw
physics with the robots split into K groups stepped in parallel threads (MuJoCo releases the GIL in
`mj_step`), the env with its physics on K threads (`physics_threads=K`, the task logic on one), and the
env with its robots split into K slices, K - 1 stepped by worker processes and one by this process
(`workers=K-1`, task logic and physics in parallel; the default of `make_vec_env` on this machine), and
gives each of those ratios to raw physics on K threads too. With `--rollout`,
it also times raw physics through MuJoCo's threaded `mujoco.rollout` (the alternative to the loop; not
used by the env, see docs/performance.md). With `--stages`, it also splits a batch's step into its
stages (timers around the batch's methods and around each `mj_step` call), in microseconds per robot-step.

    python benchmarks/bench_env.py                          # single env, and batches of 16 and 64
    python benchmarks/bench_env.py --num-envs 32 --steps 2000 --rollout --action-scale 0.2
    python benchmarks/bench_env.py --steps 0 --num-envs 32 --stages
    python benchmarks/bench_env.py --steps 0 --num-envs 32 64 --batch-steps 12800 --rounds 6
    python benchmarks/bench_env.py --steps 0 --num-envs 256 1024 --physics-threads 16   # a 16-core machine
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import gymnasium as gym
import mujoco
import numpy as np
from mujoco import rollout

import zerith_gym
from zerith_gym.cpu import simulator
from zerith_gym.cpu.simulator import Simulator
from zerith_gym.cpu.workers import available_cores, default_workers
from zerith_gym.zerith1 import constants as robot
from zerith_gym.zerith1.task import FALL_HEIGHT


def random_actions(steps: int, num_robots: int, scale: float, seed: int = 0) -> np.ndarray:
    """Uniform actions in [-scale, scale]: 1 makes robots fall within ~30 steps, 0.2 keeps more upright."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-scale, scale, size=(steps, num_robots, robot.NUM_JOINTS)).astype(np.float32)


FULL_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def physics_states(sim: Simulator) -> np.ndarray:
    """Every robot's full physics state (num_robots, state size), to put fallen robots back."""
    size = mujoco.mj_stateSize(sim.models[0], FULL_STATE)
    states = np.empty((len(sim.models), size))
    for state, model, data in zip(states, sim.models, sim.datas, strict=True):
        mujoco.mj_getState(model, data, state, FULL_STATE)
    return states


def physics_rate(sim: Simulator, actions: np.ndarray, threads: int = 1) -> float:
    """Robot-steps/s of raw `mj_step(nstep=decimation)` over the simulator's robots, from their state.

    With `threads` > 1 the robots are split into that many groups, stepped in parallel as the env does.
    """
    pairs = list(zip(sim.models, sim.datas, strict=True))
    starts = physics_states(sim)
    targets = robot.DEFAULT_JOINT_POS + robot.ACTION_SCALE * actions.astype(np.float64)
    groups = [group.tolist() for group in np.array_split(np.arange(len(pairs)), threads)]

    def step_group(group: list[int], step_targets: np.ndarray) -> None:
        for i in group:
            model, data = pairs[i]
            data.ctrl[:] = step_targets[i]
            mujoco.mj_step(model, data, nstep=robot.DECIMATION)
            if data.qpos[2] < FALL_HEIGHT:
                mujoco.mj_setState(model, data, starts[i], FULL_STATE)

    with ThreadPoolExecutor(max(threads - 1, 1)) as pool:
        start = time.perf_counter()
        for step_targets in targets:
            others = [pool.submit(step_group, group, step_targets) for group in groups[1:]]
            step_group(groups[0], step_targets)
            for future in others:
                future.result()
        return targets.shape[0] * targets.shape[1] / (time.perf_counter() - start)


def rollout_rate(sim: Simulator, actions: np.ndarray, nthread: int) -> float:
    """Robot-steps/s of raw physics through `mujoco.rollout`: one call per control step, state carried."""
    model = sim.models[0]
    states = physics_states(sim)
    starts = states.copy()
    targets = robot.DEFAULT_JOINT_POS + robot.ACTION_SCALE * actions.astype(np.float64)
    out_state = np.empty((len(sim.models), robot.DECIMATION, states.shape[1]))
    out_sensor = np.empty((len(sim.models), robot.DECIMATION, model.nsensordata))
    datas = [mujoco.MjData(model) for _ in range(max(nthread, 1))]
    qpos_z = 1 + 2  # time, then qpos: the base height
    with rollout.Rollout(nthread=nthread) as pool:
        start = time.perf_counter()
        for step_targets in targets:
            control = np.repeat(step_targets[:, None], robot.DECIMATION, axis=1)
            pool.rollout(sim.models, datas, states, control, state=out_state, sensordata=out_sensor)
            states[:] = out_state[:, -1]
            fallen = states[:, qpos_z] < FALL_HEIGHT
            states[fallen] = starts[fallen]
        return targets.shape[0] * targets.shape[1] / (time.perf_counter() - start)


def single_env_rate(env: gym.Env, actions: np.ndarray) -> float:
    """Control steps/s of `env.step` with the given actions, resetting at episode ends."""
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return len(actions) / (time.perf_counter() - start)


def vec_env_rate(env: zerith_gym.ZerithVecEnv, actions: np.ndarray) -> float:
    """Robot-steps/s of `VecEnv.step` with the given actions (automatic resets)."""
    start = time.perf_counter()
    for step_actions in actions:
        env.step(step_actions)
    return actions.shape[0] * actions.shape[1] / (time.perf_counter() - start)


MJ_STEP_STAGE = "  of which mj_step itself"


def stage_times(env: zerith_gym.ZerithVecEnv, actions: np.ndarray) -> dict[str, float]:
    """Microseconds per robot-step in each stage of `ZerithVecEnv.step`, from timers around its parts.

    The timers wrap methods of this env's batch (and `mj_step` as the simulator module calls it) while
    it runs, then are removed; each adds well under a microsecond per call.
    """
    batch, mj_step = env.robots, mujoco.mj_step
    parts = {
        "task before physics": (batch.task, "before_physics"),
        "simulator step (all of it)": (batch.sim, "step"),
        "task after physics": (batch.task, "after_physics"),
        "reset: task (draws, state)": (batch.task, "reset"),
        "reset: simulator (models, placement)": (batch.sim, "reset"),
        "reset: first observations": (batch.task, "observe"),
    }
    order = list(parts)
    order.insert(order.index("simulator step (all of it)") + 1, MJ_STEP_STAGE)
    totals = dict.fromkeys(order, 0.0)

    def timed(function: Callable, stage: str) -> Callable:
        def run(*args, **kwargs):
            start = time.perf_counter()
            result = function(*args, **kwargs)
            totals[stage] += time.perf_counter() - start
            return result

        return run

    for stage, (owner, name) in parts.items():
        setattr(owner, name, timed(getattr(owner, name), stage))
    simulator.mujoco = SimpleNamespace(mj_step=timed(mj_step, MJ_STEP_STAGE))
    try:
        start = time.perf_counter()
        for step_actions in actions:
            env.step(step_actions)
        total = time.perf_counter() - start
    finally:
        simulator.mujoco = mujoco
        for owner, name in parts.values():
            delattr(owner, name)
    totals["VecEnv bookkeeping (the rest)"] = total - sum(totals[stage] for stage in parts)
    totals["total"] = total
    return {stage: 1e6 * value / actions.shape[0] / actions.shape[1] for stage, value in totals.items()}


def report_stages(num: int, env: zerith_gym.ZerithVecEnv, actions: np.ndarray, rounds: int) -> None:
    """Print the median time of each stage of a batch's step, and of raw physics, taking turns."""
    rows = defaultdict(list)
    for chunk in np.array_split(actions, rounds):
        for stage, us in stage_times(env, chunk).items():
            rows[stage].append(us)
        rows["raw mj_step loop (same actions)"].append(1e6 / physics_rate(env.robots.sim, chunk))
    print(f"batch of {num}: microseconds per robot-step by stage (median of rounds)")
    for stage, values in rows.items():
        print(f"  {stage:40s} {np.median(values):7.1f}")


def interleaved(
    measures: dict[str, Callable[[np.ndarray], float]],
    actions: np.ndarray,
    rounds: int,
    references: dict[str, str] | None = None,
) -> dict:
    """Median rate of each measure over `rounds` rounds, the measures taking turns within a round.

    The machine is shared: taking turns exposes every measure to the same load, and the median of the
    per-round ratios to the first measure (raw physics) is the figure that varies least between runs.
    `references` names, for some measures, a second measure to give the median per-round ratio to.
    """
    chunks = np.array_split(actions, rounds)
    rates = {name: [] for name in measures}
    for chunk in chunks:
        for name, measure in measures.items():
            rates[name].append(measure(chunk))
    rates = {name: np.array(values) for name, values in rates.items()}
    reference = rates[next(iter(measures))]
    results = {}
    for name, values in rates.items():
        other = (references or {}).get(name)
        second = (other, float(np.median(values / rates[other]))) if other else None
        results[name] = (float(np.median(values)), float(np.median(values / reference)), second)
    return results


def report(title: str, results: dict) -> None:
    print(f"{title:44s} steps/s   ratio to raw physics (median of rounds)")
    for name, (rate, ratio, second) in results.items():
        extra = f"   ({second[1]:.2f} of {second[0]})" if second else ""
        print(f"  {name:42s} {rate:9.0f}   {ratio:.2f}{extra}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10000, help="control steps of the single env")
    parser.add_argument("--num-envs", type=int, nargs="*", default=[16, 64], help="batch sizes")
    parser.add_argument("--batch-steps", type=int, default=40000, help="robot-steps per batch size")
    parser.add_argument("--rounds", type=int, default=10, help="rounds of turns between the measures")
    parser.add_argument("--scenario", default="train")
    parser.add_argument("--action-scale", type=float, default=1.0, help="actions uniform in +-this")
    parser.add_argument("--rollout", action="store_true", help="also time raw physics via mujoco.rollout")
    parser.add_argument("--stages", action="store_true", help="also split a batch's step into its stages")
    parser.add_argument(
        "--physics-threads",
        type=int,
        default=available_cores(),
        help="cores for raw physics threads, env physics threads and env workers (default: all)",
    )
    args = parser.parse_args()
    print(
        f"scenario {args.scenario}, actions uniform in +-{args.action_scale}, "
        f"physics dt {robot.PHYSICS_DT} s x {robot.DECIMATION} per control step"
    )

    if args.steps > 0:
        wrapped = gym.make("Zerith1-v0", scenario=args.scenario)
        env = wrapped.unwrapped
        actions = random_actions(args.steps, 1, args.action_scale)[:, 0]
        wrapped.reset(seed=0)
        single_env_rate(wrapped, actions[:500])  # warm-up
        measures = {
            f"raw mj_step(nstep={robot.DECIMATION})": lambda a: physics_rate(env.robots.sim, a[:, None]),
            "Zerith1Env.step (unwrapped)": lambda a: single_env_rate(env, a),
            "gym.make env.step (wrapped)": lambda a: single_env_rate(wrapped, a),
        }
        wrapped.reset(seed=0)
        report("single env", interleaved(measures, actions, args.rounds))

    cores = args.physics_threads
    for num in args.num_envs:
        venv = zerith_gym.make_vec_env(num, seed=0, scenario=args.scenario, workers=0)
        venv.reset()
        actions = random_actions(max(args.batch_steps // num, args.rounds), num, args.action_scale)
        vec_env_rate(venv, actions[:10])  # warm-up
        measures = {
            "raw mj_step loop": lambda a, v=venv: physics_rate(v.robots.sim, a),
            "ZerithVecEnv.step, in-process": lambda a, v=venv: vec_env_rate(v, a),
        }
        references = {}
        if cores > 1:
            raw_name = f"raw mj_step loop, {cores} threads"
            measures[raw_name] = lambda a, v=venv, k=cores: physics_rate(v.robots.sim, a, k)
            workers = min(cores, num) - 1  # with this process stepping a slice too: one slice per core
            variants = {
                f"ZerithVecEnv.step, {cores} physics threads": dict(workers=0, physics_threads=cores),
                f"ZerithVecEnv.step, {workers} workers + this process": dict(workers=workers),
            }
            default = default_workers(num)
            if default not in (0, workers):
                variants[f"ZerithVecEnv.step, default ({default} workers)"] = {}
            for name, kwargs in variants.items():
                other = zerith_gym.make_vec_env(num, seed=0, scenario=args.scenario, **kwargs)
                other.reset()
                vec_env_rate(other, actions[:10])
                measures[name] = lambda a, v=other: vec_env_rate(v, a)
                references[name] = raw_name
        if args.rollout:
            for nthread in (0, 2):
                measures[f"raw mujoco.rollout nthread={nthread}"] = lambda a, v=venv, k=nthread: rollout_rate(
                    v.robots.sim, a, k
                )
        report(f"batch of {num} (robot-steps/s)", interleaved(measures, actions, args.rounds, references))
        if args.stages:
            report_stages(num, venv, actions, args.rounds)


if __name__ == "__main__":
    main()
