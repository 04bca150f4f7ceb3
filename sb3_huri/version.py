"""Package version, single source for setup.cfg and ``sb3_huri.__version__``."""

__version__ = "0.2.0"
