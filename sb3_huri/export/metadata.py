"""What a controller needs besides the graph: the robot's observation layout, joints, gains and timing.

Read from the robot's declarations (`zerith_gym.robots`: its `RobotSpec` and `LocomotionTask`), so that
every robot of `zerith_gym` exports with its own; empty for other environments.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def training_scenario_of(run: Path, env_id: str) -> str | None:
    """The scenario a run folder's `args.yml` names (RL Zoo's layout), None if it names none."""
    import yaml

    args_file = run / env_id / "args.yml"
    try:
        saved = yaml.safe_load(args_file.read_text()) if args_file.is_file() else None
    except yaml.YAMLError:  # RL Zoo's own args.yml is an OrderedDict with a Python tag
        saved = None
    env_kwargs = (saved or {}).get("env_kwargs") if isinstance(saved, dict) else None
    scenario = (env_kwargs or {}).get("scenario")
    return None if scenario is None else str(scenario)


def deployment_metadata(env_id: str, input_size: int, training_scenario: str | None = None) -> dict[str, Any]:
    """What a controller needs to build the observation and apply the action, for `env_id`'s robot
    trained in `training_scenario` (whose command ranges it reports; None: the robot's default).

    Empty for environments other than this package's robots (the graph itself is still complete).
    """
    import gymnasium as gym

    from zerith_gym import ROBOT_ENTRY_POINTS

    robot_name = ROBOT_ENTRY_POINTS.get(str(gym.spec(env_id).entry_point))
    if robot_name is None:
        return {}
    from zerith_gym.core.observations import layout_slices
    from zerith_gym.core.scenarios import SCENARIOS
    from zerith_gym.robots import locomotion_task

    task = locomotion_task(robot_name)
    robot = task.robot
    if input_size != task.policy_size:
        raise ValueError(
            f"{env_id}'s policy observation has {task.policy_size} values, the actor reads {input_size}"
        )
    slices = layout_slices(task.policy_layout)
    commands = SCENARIOS[training_scenario or task.default_scenario].command_ranges
    return {
        "robot": robot.display_name,
        "mjcf": f"zerith_gym/{robot.asset_path.parent.name}/{robot.asset_path.name}",
        "observation_layout": [
            {
                "name": name,
                "start": slices[name].start,
                "size": size,
                "description": task.deployment_notes.get(name, "see the env's documentation"),
            }
            for name, size in task.policy_layout
        ],
        "joint_names": list(robot.joint_names),
        "default_joint_pos": robot.default_joint_pos.tolist(),
        "action_scale": robot.action_scale.tolist(),
        "joint_target": "default_joint_pos + action_scale * action (rad), per joint in joint_names order, "
        "tracked by joint PD controllers (kp, kd) with torque limits",
        "kp": robot.kp.tolist(),
        "kd": robot.kd.tolist(),
        "torque_limit": robot.torque_limit.tolist(),
        "control_dt": robot.control_dt,
        "control_frequency_hz": round(1.0 / robot.control_dt),
        "physics_dt_training": robot.physics_dt,
        **task.deployment_extras,
        "command_ranges_training": {
            "vx": list(commands.vx),
            "vy": list(commands.vy),
            "yaw_rate": list(commands.yaw_rate),
        },
    }
