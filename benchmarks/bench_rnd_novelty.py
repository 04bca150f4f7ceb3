"""RND novelty of a trained HuRi agent per scenario (the paper's Fig. 5B: beta rises in unseen conditions).

Runs the saved agent (deterministic actions, its ``VecNormalize`` statistics frozen) in each scenario and
reports, over all visited states, the mean RND error, ``beta_RND = tanh(error)``, the IQR part of ``beta``
and the whole ``beta``, as ``HuRiPPO.assess_risk`` computes them. The agent's RND is read-only here.

    python benchmarks/bench_rnd_novelty.py --run trained_agents/huri/Zerith1-v0_1 --calibrate train:0.375

A model saved before the RND error was normalized by the target network's output variance has no such
statistics (its error is the unscaled mean over the outputs): ``--calibrate SCENARIO:SCALE`` first measures
that variance on one rollout of the training scenario at the curriculum scale the run had reached, the
states its RND statistics would have been tracking.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch as th
import yaml
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecNormalize

import zerith_gym
from sb3_huri import HuRiPPO
from zerith_gym.core.scenarios import get_scenario, scaled_scenario

ENV_ID = "Zerith1-v0"
DEFAULT_SCENARIOS = ["nominal", "uneven", "sudden-centroid", "continuous-centroid", "friction", "load"]


def make_env(run: Path, scenario_name: str, scale: float, n_envs: int, seed: int) -> VecNormalize:
    args_file = run / ENV_ID / "args.yml"
    env_kwargs = (
        dict(yaml.safe_load(args_file.read_text()).get("env_kwargs") or {}) if args_file.is_file() else {}
    )
    env_kwargs.pop("scenario", None)
    env_kwargs.pop("reward_weights", None)  # rewards play no part here
    scenario = get_scenario(scenario_name)
    if scale < 1.0:
        scenario = scaled_scenario(scenario, scale)
    env = VecNormalize.load(
        str(run / ENV_ID / "vecnormalize.pkl"), zerith_gym.make_vec_env(n_envs, seed=seed, scenario=scenario)
    )
    env.training = False
    return env


def calibrate_target_statistics(model: HuRiPPO, env: VecNormalize, steps: int) -> None:
    """Measure the RND target's output variance on ``steps`` steps of ``env`` (replacing the saved one)."""
    rnd = model.policy.rnd
    obs, features = env.reset(), []
    for _ in range(steps):
        with th.no_grad():
            features.append(model.policy.critic_features(obs_as_tensor(obs, model.device)))
        obs, *_ = env.step(model.predict(obs, deterministic=True)[0])
    with th.no_grad():
        outputs = rnd.target(rnd.normalize(th.cat(features))).cpu().numpy()
    rnd.target_rms.mean, rnd.target_rms.var, rnd.target_rms.count = (
        outputs.mean(0),
        outputs.var(0),
        len(outputs),
    )


def assess_scenario(model: HuRiPPO, env: VecNormalize, steps: int) -> dict[str, float]:
    obs = env.reset()
    errors, risks, falls = [], [], 0
    for _ in range(steps):
        assessment = model.assess_risk(obs)
        errors.append(assessment.rnd_error)
        risks.append(assessment.risk)
        obs, _, _, infos = env.step(model.predict(obs, deterministic=True)[0])
        falls += sum(bool(info.get("fall")) for info in infos)
    error, risk = np.concatenate(errors), np.concatenate(risks)
    beta_rnd = np.tanh(error)
    return {
        "rnd_error": float(error.mean()),
        "beta_rnd": float(beta_rnd.mean()),
        "beta_rnd_p90": float(np.quantile(beta_rnd, 0.9)),
        "beta_iqr": float((risk - beta_rnd).mean()),
        "beta": float(risk.mean()),
        "falls": falls,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--run", type=Path, required=True, help="RL Zoo run folder (model and vecnormalize.pkl)"
    )
    parser.add_argument("--scenarios", nargs="*", default=DEFAULT_SCENARIOS)
    parser.add_argument("--calibrate", default=None, help="SCENARIO:SCALE to measure the target variance on")
    parser.add_argument("--n-envs", type=int, default=16)
    parser.add_argument("--steps", type=int, default=300, help="steps per env and scenario")
    parser.add_argument("--seed", type=int, default=100)
    args = parser.parse_args()
    th.set_num_threads(1)
    model = HuRiPPO.load(args.run / f"{ENV_ID}.zip", device="cpu")
    assert model.policy.rnd is not None, "the model has no RND"
    if args.calibrate:
        name, scale = args.calibrate.split(":")
        calibrate_target_statistics(model, make_env(args.run, name, float(scale), 32, args.seed), 64)
    print(f"RND target output variance (sum): {float(np.sum(model.policy.rnd.target_rms.var)):.4f}")
    print("| scenario | RND error | beta_RND mean | beta_RND p90 | beta_IQR mean | beta mean | falls |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        row = assess_scenario(model, make_env(args.run, name, 1.0, args.n_envs, args.seed), args.steps)
        print(
            f"| {name} | {row['rnd_error']:.4f} | {row['beta_rnd']:.3f} | {row['beta_rnd_p90']:.3f} | "
            f"{row['beta_iqr']:.3f} | {row['beta']:.3f} | {row['falls']} |",
            flush=True,
        )
        print(json.dumps({"scenario": name, **row}), flush=True)


if __name__ == "__main__":
    main()
