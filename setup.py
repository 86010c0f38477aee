"""The setuptools build, plus one step: after the package files are in place, retime's numba
kernels are compiled into numba's cache beside them (``python -m retime.precompile``), so that an
installed retime (``pip install -e .`` or a wheel) starts without a minute in the compiler.
``RETIME_PRECOMPILE=0`` skips the step; if it fails, the kernels compile on first use as before."""
import os
import subprocess
import sys

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyAndKernels(build_py):
    def run(self):
        super().run()
        if os.environ.get("RETIME_PRECOMPILE", "1") == "0":
            return
        # editable: the sources themselves; a wheel: the copies it is made of
        root = os.path.abspath("src" if getattr(self, "editable_mode", False) else self.build_lib)
        paths = [root] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]  # keep pip's build env
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(paths), PYTHONDONTWRITEBYTECODE="1")
        print("retime: compiling the numba kernels into the package's cache (RETIME_PRECOMPILE=0 skips this)",
              file=sys.stderr, flush=True)
        if subprocess.run([sys.executable, "-m", "retime.precompile"], env=env, cwd=root).returncode:
            print("retime: precompiling failed; the kernels will compile on first use", file=sys.stderr)


setup(cmdclass={"build_py": BuildPyAndKernels})
