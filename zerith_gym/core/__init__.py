"""The step every robot shares, and what it is made of: the robot spec, the task kernel, commands,
disturbances, randomization, physics, scenarios, spaces, infos and the robots contract. It imports no robot:
what a robot is comes in as its `RobotSpec` and `LocomotionTask`."""
