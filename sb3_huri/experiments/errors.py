"""The error every command of ``python -m sb3_huri.experiments`` prints without a traceback."""

from sb3_huri.runner.files import RunError


class ExperimentError(RunError):
    """A problem with the command, its queue or its output folder that the user has to resolve."""
