"""Train HuRi on Pendulum-v1, watch its risk parameter, evaluate, save and reload.

    python examples/huri_pendulum.py                   # about a minute on one CPU core
    python examples/huri_pendulum.py --method huri-baseline --timesteps 50000

HuRi's IQR thresholds are in units of the return, so rewards are normalized (as in the paper) with
``VecNormalize``; evaluation uses the raw reward.
"""

import argparse
import tempfile
from pathlib import Path

import torch as th
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import VecNormalize

from sb3_huri import METHODS, HuRiPPO
from sb3_huri.huri import DEFAULT_METHOD


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--method", default=DEFAULT_METHOD, choices=list(METHODS))
    parser.add_argument("--timesteps", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    # Small MLPs gain nothing from several threads, and spinning threads are slow on a busy machine.
    th.set_num_threads(1)

    env = VecNormalize(make_vec_env("Pendulum-v1", n_envs=8, seed=args.seed))
    # The paper's update (4 minibatches, 8 epochs, [512, 256, 128] ELU networks), with the rollout length,
    # discount and learning rate sized for Pendulum on a CPU.
    model = HuRiPPO(
        "MlpPolicy",
        env,
        method=args.method,
        n_steps=256,
        n_minibatches=4,
        n_epochs=8,
        gamma=0.9,
        learning_rate=1e-3,
        ent_coef=0.0,
        vf_coef=1.0,
        max_grad_norm=1.0,
        use_sde=True,
        sde_sample_freq=4,
        policy_kwargs=dict(net_arch=[512, 256, 128], activation_fn=th.nn.ELU),
        seed=args.seed,
        verbose=0,
    )
    model.learn(args.timesteps, progress_bar=True)

    buffer = model.rollout_buffer
    print(
        f"last rollout: mean beta {buffer.risk.mean():+.3f}, mean IQR {buffer.iqr.mean():.3f}, "
        f"mean RND error {buffer.rnd_error.mean():.4f}"
    )

    eval_env = VecNormalize(
        make_vec_env("Pendulum-v1", n_envs=1, seed=1000), training=False, norm_reward=False
    )
    eval_env.obs_rms = env.obs_rms
    mean_return, std_return = evaluate_policy(model, eval_env, n_eval_episodes=10, deterministic=True)
    print(f"{args.method}: return {mean_return:.1f} +- {std_return:.1f} over 10 episodes")

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "huri_pendulum.zip"
        model.save(path)
        reloaded = HuRiPPO.load(path)
        obs = eval_env.reset()
        same = (
            reloaded.predict(obs, deterministic=True)[0] == model.predict(obs, deterministic=True)[0]
        ).all()
        print(f"saved and reloaded: identical actions = {bool(same)}")


if __name__ == "__main__":
    main()
