"""Zerith-1, the humanoid of `Zerith1-v0`: its constants and MJCF, the paper's task (observations, Table-4
rewards, gait clock), its mirror symmetry and its env class."""
