"""A run's bookkeeping while it trains: checkpoints between rollouts, its curve and its status file.

Kept apart from ``training`` so that reading a run's files (the report) does not import torch.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from sb3_huri.experiments.layout import RunStatus, write_status
from sb3_huri.experiments.run_files import checkpoint_paths, prune_checkpoints, replace_file
from sb3_huri.zoo.checkpoints import CurveWriter


class RunBookkeeping(CurveWriter):
    """A checkpoint between rollouts every ``checkpoint_freq`` steps; after every rollout, the curve's row
    (``sb3_huri.zoo.curve``, as every training of the package writes it) and the status (steps and
    training seconds, counting the seconds of earlier sessions)."""

    def __init__(
        self, folder: Path, status: RunStatus, checkpoint_freq: int, curriculum: Any | None = None
    ) -> None:
        super().__init__(folder, curriculum)
        self.status, self.checkpoint_freq = status, checkpoint_freq
        self._began, self._seconds_before = time.time(), status.train_seconds

    @property
    def wall_s(self) -> float:
        """Training seconds of the run, this session's included."""
        return self._seconds_before + time.time() - self._began

    def checkpoint(self, model: Any) -> None:
        """Model and normalizer to temporary files, renamed, then named in the status (the commit)."""
        steps = model.num_timesteps
        model_path, stats_path = checkpoint_paths(self.folder, steps)
        model_path.parent.mkdir(exist_ok=True)
        replace_file(model.save, model_path)
        vec_normalize = model.get_vec_normalize_env()
        if vec_normalize is not None:
            replace_file(vec_normalize.save, stats_path)
        self.status.checkpoint, self.status.steps, self.status.train_seconds = steps, steps, self.wall_s
        write_status(self.folder, self.status)
        prune_checkpoints(self.folder, keep=steps)

    def _on_rollout_start(self) -> None:
        if self.model.num_timesteps - (self.status.checkpoint or 0) >= self.checkpoint_freq:
            self.checkpoint(self.model)

    def _on_rollout_end(self) -> None:
        super()._on_rollout_end()
        self.status.steps, self.status.train_seconds = self.model.num_timesteps, self.wall_s
        write_status(self.folder, self.status)
