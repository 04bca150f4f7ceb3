"""Where the runs execute: a local process pool (default) or Ray tasks spread over a cluster.

Both take ``job.RunJob`` jobs and hand back ``job.RunOutcome`` results as runs finish; the caller
(``driver``) submits at most ``parallel`` runs at a time and follows their progress in the folder.

- ``LocalBackend``: ``concurrent.futures.ProcessPoolExecutor`` (spawned processes, so that no torch or
  MuJoCo state is forked). Each pool process dies with the command (``PR_SET_PDEATHSIG`` on Linux), so a
  killed command leaves no orphan run writing its folder; Ctrl-C interrupts the runs, whose last
  checkpoints the next command continues from.
- ``RayBackend``: the same function as Ray tasks, each reserving ``cpus`` CPUs; Ray places them on the
  cluster's machines (``ray.init()`` connects to ``RAY_ADDRESS``, or to ``--ray-address``; without
  either it starts a local Ray instance). The output folder must be shared, at the same path, by every
  machine (NFS or the like). A task whose machine is lost is retried by Ray and continues from the run's
  last checkpoint.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
import signal
import sys
from collections.abc import Iterable
from typing import Any, Protocol

from sb3_huri.experiments.errors import ExperimentError
from sb3_huri.experiments.grid.job import RunJob, RunOutcome, execute_run

TASK_RETRIES = 3
"""Ray retries of a run whose worker or machine died (it continues from its last checkpoint)."""


class Backend(Protocol):
    """Runs ``RunJob`` jobs somewhere and reports them as they finish."""

    def submit(self, task: RunJob) -> Any:
        """Start ``task``; returns a handle."""

    def wait(self, handles: Iterable[Any], timeout: float) -> list[Any]:
        """The handles among ``handles`` that finished within ``timeout`` seconds (maybe none)."""

    def result(self, handle: Any) -> RunOutcome:
        """The outcome of a finished handle (re-raises what the job raised)."""

    def stop(self, handles: Iterable[Any]) -> None:
        """Interrupt the started jobs ``handles`` and release the resources (after Ctrl-C)."""

    def close(self) -> None:
        """Release the resources after every job finished."""


def _die_with_parent() -> None:
    """Pool process initializer: get SIGTERM when the command's process ends, however it ends (Linux)."""
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
            if os.getppid() == 1:  # the parent died before the call
                os._exit(1)


ONE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Math libraries' thread counts set to 1 for the pool's processes (unless the user set them): numpy's
OpenBLAS otherwise starts a thread per core in every run, which spins beside the run's own work (two runs on
two cores trained at half their speed)."""


class LocalBackend:
    """A pool of ``parallel`` processes on this machine (each process one thread of math libraries)."""

    def __init__(self, parallel: int) -> None:
        self._environment = {name: os.environ.get(name) for name in ONE_THREAD}
        for name in ONE_THREAD:  # the spawned processes inherit this environment
            os.environ.setdefault(name, "1")
        self.pool = cf.ProcessPoolExecutor(
            max_workers=parallel, mp_context=mp.get_context("spawn"), initializer=_die_with_parent
        )

    def _restore_environment(self) -> None:
        for name, value in self._environment.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value

    def submit(self, task: RunJob) -> cf.Future:
        return self.pool.submit(execute_run, task)

    def wait(self, handles: Iterable[cf.Future], timeout: float) -> list[cf.Future]:
        done, _ = cf.wait(list(handles), timeout=timeout, return_when=cf.FIRST_COMPLETED)
        return list(done)

    def result(self, handle: cf.Future) -> RunOutcome:
        return handle.result()

    def stop(self, handles: Iterable[cf.Future]) -> None:
        # Interrupt the runs (a Ctrl-C in a terminal reaches them already; a SIGINT sent to this process
        # alone does not), then wait for them to close their envs. The pool has no public handle on its
        # processes before Python 3.14.
        for process in list(getattr(self.pool, "_processes", {}).values()):
            with contextlib.suppress(OSError, ValueError):
                os.kill(process.pid, signal.SIGINT)
        self.pool.shutdown(wait=True, cancel_futures=True)
        self._restore_environment()

    def close(self) -> None:
        self.pool.shutdown(wait=True)
        self._restore_environment()


class RayBackend:
    """Ray tasks reserving ``cpus`` CPUs each, on the cluster ``ray.init`` connects to."""

    def __init__(self, cpus: int, address: str | None = None) -> None:
        try:
            import ray
        except ImportError as error:
            raise ExperimentError(
                'the ray backend needs Ray: pip install "sb3-huri[experiments]" (or "ray>=2.9")'
            ) from error
        self.ray = ray
        self.started = not ray.is_initialized()
        if self.started:
            ray.init(address=address)
        self.remote = ray.remote(num_cpus=cpus, max_retries=TASK_RETRIES)(execute_run)

    def submit(self, task: RunJob) -> Any:
        return self.remote.remote(task)

    def wait(self, handles: Iterable[Any], timeout: float) -> list[Any]:
        handles = list(handles)
        if not handles:
            return []
        done, _ = self.ray.wait(handles, num_returns=1, timeout=timeout)
        return list(done)

    def result(self, handle: Any) -> RunOutcome:
        return self.ray.get(handle)

    def stop(self, handles: Iterable[Any]) -> None:
        for handle in handles:  # the runs keep their last checkpoints
            with contextlib.suppress(Exception):
                self.ray.cancel(handle, force=True)
        self.close()

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()
