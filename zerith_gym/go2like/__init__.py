"""The Go2-like quadruped of `Go2Like-v0`: its constants and MJCF, legged_gym's task and its env class."""
