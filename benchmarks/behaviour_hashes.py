"""Fingerprints of what the code computes: env transitions and short trainings, hashed, to check a change
that must not alter behaviour (a refactor, a speed-up) against the fingerprints taken before it.

- `env/<scenario>`: 8 robots seeded 0-7 stepped 200 times with the same uniform random actions; the hash of
  every policy and critic observation, reward, termination and truncation (float bytes, in order).
- `train/<method>`: the robust recipe (`hyperparams/huri_robust.yml`) shrunk to 8 robots x 32 steps per
  rollout, trained for 3 rollouts from seed 0 on one thread; the hash of the policy's parameters after.
- `standard/<method>`: the `Walker2d-v5` preset of `hyperparams/huri.yml` (SB3's PPO settings: one env,
  minibatches of 64, 10 epochs) shrunk to 256 steps per rollout, 3 rollouts from seed 0 on one thread.

    python benchmarks/behaviour_hashes.py                                     # print them
    python benchmarks/behaviour_hashes.py --write benchmarks/behaviour_hashes.json
    python benchmarks/behaviour_hashes.py --check benchmarks/behaviour_hashes.json  # exit 1 on a change

The hashes are exact: they hold on one machine and one set of package versions (the file records both);
on another, compare two checkouts there rather than against the file.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ("train", "robust", "sudden-feet", "terrain")
METHODS = ("huri", "huri-baseline", "huri-neutral")


def env_hash(scenario: str, robots: int = 8, steps: int = 200) -> str:
    """The hash of `steps` transitions of `robots` robots in `scenario` under fixed random actions."""
    import zerith_gym

    digest = hashlib.sha256()
    env = zerith_gym.make_vec_env(robots, seed=0, workers=0, scenario=scenario)
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (steps, robots, 12)).astype(np.float32)
    try:
        obs = env.reset()
        for action in actions:
            for key in ("policy", "critic"):
                digest.update(np.ascontiguousarray(obs[key]).tobytes())
            obs, rewards, dones, infos = env.step(action)
            truncated = np.array([info.get("TimeLimit.truncated", False) for info in infos])
            for array in (rewards, dones, truncated):
                digest.update(np.ascontiguousarray(array).tobytes())
    finally:
        env.close()
    return digest.hexdigest()[:16]


def training_hash(method: str, rollouts: int = 3) -> str:
    """The hash of the policy's parameters after a few rollouts of the shrunk robust recipe."""
    import torch as th
    from rl_zoo3.utils import get_callback_list
    from stable_baselines3.common.callbacks import CallbackList

    from sb3_huri.runner.build import preset_env, preset_model
    from sb3_huri.zoo import read_preset

    th.set_num_threads(1)
    preset = read_preset("Zerith1-v0", ROOT / "hyperparams" / "huri_robust.yml")
    preset.update(n_envs=8, n_steps=32)
    env = preset_env(preset, seed=0, workers=0)
    try:
        model = preset_model(preset, env, method=method, seed=0, device="cpu")
        model.learn(rollouts * 8 * 32, callback=CallbackList(get_callback_list(preset)))
    finally:
        env.close()
    return _parameters_hash(model)


def standard_hash(method: str, rollouts: int = 3, n_steps: int = 256) -> str:
    """The hash of the policy's parameters after a few rollouts of the shrunk `Walker2d-v5` preset."""
    import torch as th

    from sb3_huri.experiments.grid.standard import make_env
    from sb3_huri.runner.build import preset_model, preset_normalized
    from sb3_huri.zoo import read_preset

    th.set_num_threads(1)
    preset = read_preset("Walker2d-v5", ROOT / "hyperparams" / "huri.yml")
    preset.update(n_steps=n_steps)
    env = preset_normalized(make_env("Walker2d-v5", preset, seed=0), preset)
    try:
        model = preset_model(preset, env, method=method, seed=0, device="cpu")
        model.learn(rollouts * n_steps)
    finally:
        env.close()
    return _parameters_hash(model)


def _parameters_hash(model: Any) -> str:
    """The hash of the policy's parameters and buffers (the RND's statistics among them)."""
    digest = hashlib.sha256()
    _hash_state(digest, model.policy.state_dict())
    return digest.hexdigest()[:16]


def _hash_state(digest: hashlib._Hash, state: dict) -> None:
    """Every tensor of a (nested) state dict, by sorted name, into `digest`."""
    for name, value in sorted(state.items()):
        digest.update(name.encode())
        if isinstance(value, dict):
            _hash_state(digest, value)
        elif hasattr(value, "detach"):
            digest.update(value.detach().cpu().numpy().tobytes())
        else:
            digest.update(repr(value).encode())


def fingerprints() -> dict[str, str]:
    return {
        **{f"env/{scenario}": env_hash(scenario) for scenario in SCENARIOS},
        **{f"train/{method}": training_hash(method) for method in METHODS},
        **{f"standard/{method}": standard_hash(method) for method in METHODS},
    }


def versions() -> dict[str, str]:
    """The machine and the package versions the hashes hold for."""
    from importlib.metadata import version

    packages = ("numpy", "torch", "mujoco", "gymnasium", "stable_baselines3")
    return {"machine": f"{platform.machine()} {platform.python_version()}"} | {
        p: version(p) for p in packages
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--write", type=Path, default=None, help="write the fingerprints to this JSON file")
    parser.add_argument("--check", type=Path, default=None, help="compare with a file --write wrote")
    args = parser.parse_args()
    found = fingerprints()
    for key, value in found.items():
        print(f"{key:24} {value}")
    if args.write is not None:
        args.write.write_text(json.dumps({"versions": versions(), "hashes": found}, indent=1) + "\n")
    if args.check is not None:
        reference = json.loads(args.check.read_text())
        if reference["versions"] != versions():
            print(f"note: {args.check} was written with {reference['versions']}, this is {versions()}")
        changed = [key for key, value in reference["hashes"].items() if found.get(key) != value]
        print("changed: " + ", ".join(changed) if changed else "every fingerprint is the same")
        sys.exit(1 if changed else 0)


if __name__ == "__main__":
    main()
