"""Build-time only: put the RL Zoo start-up hook's ``.pth`` file into regular and editable wheels.

``setup.cfg`` names the two commands below in ``cmdclass``; nothing imports this module at run time.
A ``.pth`` file must sit at the top of site-packages, and setuptools has no declarative option for that:

- ``pip install .``: ``build_py`` writes the file at the root of the wheel, next to the top-level modules;
- ``pip install -e .``: setuptools' editable wheel leaves build outputs out, so the file is added to the
  finished wheel (rewritten whole, so that its RECORD lists the file and ``pip uninstall`` removes it).

The file's name sorts after setuptools' ``__editable__.*.pth``, so in an editable install the hook module is
importable by the time the line runs.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from setuptools.command.build_py import build_py
from setuptools.command.editable_wheel import editable_wheel
from wheel.wheelfile import WheelFile

PTH_NAME = "sb3_huri_zoo_hook.pth"
PTH_LINE = "import _sb3_huri_zoo_hook\n"


class BuildPyWithZooHook(build_py):
    """``build_py`` that also writes the hook's ``.pth`` file at the root of the (non-editable) wheel."""

    def run(self) -> None:
        super().run()
        if not self.editable_mode:
            Path(self.build_lib, PTH_NAME).write_text(PTH_LINE)


class EditableWheelWithZooHook(editable_wheel):
    """``editable_wheel`` whose wheel also contains the hook's ``.pth`` file."""

    def run(self) -> None:
        super().run()
        for wheel_path in Path(self.dist_dir).glob("*.whl"):
            _add_pth_file(wheel_path)


def _add_pth_file(wheel_path: Path) -> None:
    with tempfile.TemporaryDirectory(dir=wheel_path.parent) as folder:
        rewritten = Path(folder, wheel_path.name)
        with WheelFile(wheel_path) as original:
            if PTH_NAME in original.namelist():
                return
            with WheelFile(rewritten, "w") as wheel:
                for item in original.infolist():
                    if item.filename != original.record_path:
                        wheel.writestr(item, original.read(item))
                wheel.writestr(PTH_NAME, PTH_LINE)
        rewritten.replace(wheel_path)
