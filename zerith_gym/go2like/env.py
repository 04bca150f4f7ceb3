"""Go2Like-v0: a 12-DoF Go2-like quadruped learning legged_gym's walking task (MuJoCo)."""

from __future__ import annotations

from zerith_gym.env import ZerithEnv
from zerith_gym.go2like.constants import GO2LIKE


class Go2LikeEnv(ZerithEnv):
    """The Go2-like quadruped (`zerith_gym/go2like/go2like.xml`) walking on commanded velocities, with
    legged_gym's task (`zerith_gym.go2like.task`), on the step, physics, scenarios and tools Zerith-1 uses.

    ## Action space
    `Box(-1, 1, (12,))`: joint-position offsets of 0.25 rad per unit from legged_gym's default pose, in the
    order of `go2like.constants.JOINT_NAMES` (legs FL, FR, RL, RR, each hip, thigh, calf). PD actuators
    (kp 20, kd 0.5, torque limits 23.7 / 23.7 / 45.43 Nm) track the targets at 200 Hz; the policy runs at
    50 Hz. Out-of-range actions are clipped; NaN or infinite ones raise `ValueError`.

    ## Observation space
    `obs_mode="dict"` (default): `Dict(policy=Box(235), critic=Box(313))`; `obs_mode="policy"`: the policy
    Box alone. Policy: base linear and angular velocity, projected gravity, command, joint positions
    relative to the default pose, joint velocities, last action, and the trunk's height above 187 ground
    points around it (noisy in training). Critic: the noiseless policy entries, trunk height, foot contacts
    and forces, the external force and the domain parameters (`zerith_gym.go2like.task`).

    ## Rewards
    legged_gym's terms with its Go2 scales (`go2like.task.DEFAULT_REWARD_WEIGHTS`), each times 0.02 s;
    the step's reward is their sum clipped at 0 (legged_gym's `only_positive_rewards`). Override weights
    with `reward_weights={name: weight}`; `info["reward_terms"]` holds each weighted term before the clip.

    ## Episode end
    Terminated when the trunk touches the ground; truncated at 20 s (1000 steps) or when the simulation
    diverges (`info["sim_unstable"]`).

    ## Arguments
    Those of `Zerith1Env` (`zerith_gym.options.ZerithOptions`); the default scenario is "quadruped-train"
    (legged_gym's randomization, pushes and commands on flat ground). Any scenario whose forces act on the
    centroid or the feet applies; forces on hands are rejected (the robot has none). The mirror attributes
    are None: the symmetry loss is Zerith-1's.
    """

    metadata = {**ZerithEnv.metadata, "render_fps": round(1.0 / GO2LIKE.control_dt)}
    robot = "go2like"
