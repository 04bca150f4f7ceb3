"""Zerith1-v0: a 12-DoF Zerith-1-like humanoid learning to walk under disturbances (MuJoCo)."""

from __future__ import annotations

from zerith_gym.env import ZerithEnv
from zerith_gym.zerith1.constants import ZERITH1


class Zerith1Env(ZerithEnv):
    """Zerith-1 humanoid walking on commanded velocities, with the HuRi paper's randomization and tests.

    ## Action space
    `Box(-1, 1, (12,))`: joint-position offsets from the default stance, scaled per joint by
    `robot.ACTION_SCALE` (rad), in the order of `robot.JOINT_NAMES` (left leg then right leg: hip_yaw,
    hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll). Position actuators (PD with torque limits) track
    the targets at the physics rate; the policy runs at 50 Hz. Out-of-range actions are clipped; NaN or
    infinite ones raise `ValueError`.

    ## Observation space
    `obs_mode="dict"` (default): `Dict(policy=Box(46), critic=Box(139))`; `obs_mode="policy"`: the 46-d
    policy Box alone. Policy: base roll and pitch, base angular velocity, clock sin/cos, command, joint
    positions relative to the default stance, joint velocities, last action (noisy in training). Critic:
    the noiseless policy terms, base linear velocity and height, ground height around each foot, foot
    contacts and forces, the gait's desired contacts, the external force and the domain parameters.
    Layouts: `zerith_gym.zerith1.observations`; index tables in docs/zerith1.md.

    ## Rewards
    The terms of the paper's Table 4 (`zerith_gym.zerith1.rewards.DEFAULT_REWARD_WEIGHTS`), each weighted and
    multiplied by the control period (0.02 s). Override weights with `reward_weights={name: weight}`.
    Each term is a named function in `zerith_gym.zerith1.rewards` (`TERMS`). `info["reward_terms"]` holds each
    term's weighted value of the step (they sum to the reward), `info["episode_terms"]` each term's
    episode sum when an episode ends.

    ## Episode end
    Terminated on a fall: pelvis below 0.45 m above the ground or tilted more than 0.8 rad. Truncated at
    20 s (1000 steps), and when the simulation diverges (`info["sim_unstable"]`; the last finite
    observation is returned with reward 0).

    ## Arguments
    The task options (declared once, in `zerith_gym.options.ZerithOptions`, for every Zerith env):
    - `scenario`: a name in `zerith_gym.SCENARIOS` (default "train"), or a custom `Scenario`.
    - `obs_mode`: "dict" or "policy".
    - `command`: fixed (vx, vy, yaw rate); default: drawn during the episode (train, nominal) or
      (1, 0, 0) in the evaluation scenarios. `reset(options={"command": ...})` sets it for one episode.
      On a tile terrain, `reset(options={"tile": (level, kind column)})` starts the robot on that tile
      (default: level 0 of the first kind; a `TerrainCurriculum` moves it on from there).
    - `reward_weights`: overrides of the reward weights.
    - `terrain_seed`: seed of the height field's heights, uneven or tiles (fixed for the env's lifetime).
    - `episode_steps`: control steps before the time-out truncation (default 1000, 20 s). The env
      truncates itself (and reports `episode_terms`); beyond 1000 also raise `gym.make`'s
      `max_episode_steps`.

    and, for this env only, `render_mode`: "human" or "rgb_array" (camera following the robot);
    `width`, `height`.

    ## Info (every step)
    `fall`, `sim_unstable`, `lin_vel_error` (|v_xy - v_cmd|), `ang_vel_error` (|yaw rate - cmd|),
    `external_force` (N, world frame, on each body of the scenario's target group: its first body's where
    each body draws its own force, `ForceSchedule.per_body`), `command`,
    `reward_terms` (name -> weighted value), `terrain_level` (the tile row walked on: 0 unless the
    scenario's terrain has tiles); at an episode's end also `episode_terms`.

    ## Symmetry
    `policy_mirror` and `action_mirror` reflect the actor's observation and an action left to right
    (`zerith_gym.zerith1.symmetry`), for a symmetry loss (`HuRiPPO(mirror_coef=...)`).
    """

    metadata = {**ZerithEnv.metadata, "render_fps": round(1.0 / ZERITH1.control_dt)}
    robot = "zerith1"
