"""The build step that compiles the simulator's kernels into the package (see ``gridsim.jit``):
``pip install .`` then installs them with it, and a user's first environment starts at once
instead of compiling for about 30 s. Best effort: if compiling fails, the package installs
without them (the kernels are then compiled at first use, with a notice)."""

import os
import subprocess
import sys

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyAndCompile(build_py):
    """``build_py``, then ``python -m gridsim compile`` on the built package (not for editable
    installs: their kernels compile in the source tree at first use)."""

    def run(self) -> None:
        super().run()
        if self.editable_mode or os.environ.get("GRIDSIM_SKIP_COMPILE"):
            return
        # the built package first, then what this build sees (pip's isolated build
        # environment, which holds the dependencies, is on sys.path, not in site-packages)
        path = [os.path.abspath(self.build_lib), *(p for p in sys.path if p)]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(path)}
        try:
            subprocess.run([sys.executable, "-m", "gridsim", "compile"], env=env, check=True,
                           cwd=self.build_lib, timeout=900)  # fmt: skip
        except (OSError, subprocess.SubprocessError) as exc:
            print(f"gridsim: the kernels were not compiled ahead ({exc}); they will be at "
                  "first use", file=sys.stderr)  # fmt: skip


setup(cmdclass={"build_py": BuildPyAndCompile})
