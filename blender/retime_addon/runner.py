"""Finding and running the ``retime`` program (outside Blender's Python: it needs NumPy 2, SciPy, numba)."""
import os
import shutil
import subprocess
import time


class RetimeAddonError(Exception):
    """A problem the user can act on, reported in one line."""


INSTALL_HINT = "install it (pip install retime) or set its path in Preferences > Add-ons > Retime"


def retime_executable(preference_path: str) -> str:
    """The ``retime`` program: the add-on's preference, then RETIME_EXECUTABLE, then PATH."""
    import bpy

    if preference_path.strip():
        path = bpy.path.abspath(preference_path.strip())
        if not os.path.isfile(path):
            raise RetimeAddonError(f"the retime program set in the add-on's preferences, {path}, does not exist; "
                                   "fix the path or clear it to use PATH")
        return path
    given = os.environ.get("RETIME_EXECUTABLE", "").strip()
    if given:
        if not os.path.isfile(given):
            raise RetimeAddonError(f"RETIME_EXECUTABLE={given}: no such file; point it at the retime program")
        return given
    found = shutil.which("retime")
    if found is None:
        raise RetimeAddonError(f"cannot find the retime program on PATH: {INSTALL_HINT}")
    return found


class Run:
    """``retime`` running as a subprocess, its output collected in files (no pipe to fill up)."""

    def __init__(self, argv, folder):
        self.argv = [str(a) for a in argv]
        self.out_path, self.err_path = os.path.join(folder, "stdout.txt"), os.path.join(folder, "stderr.txt")
        self.started = time.monotonic()
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            try:
                self.process = subprocess.Popen(self.argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
            except OSError as e:
                raise RetimeAddonError(f"cannot run {self.argv[0]}: {e.strerror}; {INSTALL_HINT}") from None

    @property
    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def done(self) -> bool:
        return self.process.poll() is not None

    def cancel(self):
        if not self.done():
            self.process.terminate()  # retime removes its partial outputs on SIGTERM
            try:
                self.process.wait(5)
            except subprocess.TimeoutExpired:
                self.process.kill()

    def result(self, success=(0,)) -> str:
        """The program's last line of output once it succeeded (an exit code in ``success``: ``retime
        check`` exits 1 for a clip that is not physical); its one-line error otherwise."""
        code = self.process.wait()
        with open(self.out_path, errors="replace") as f:
            out = [ln.strip() for ln in f if ln.strip()]
        with open(self.err_path, errors="replace") as f:
            err = [ln.strip() for ln in f if ln.strip()]
        if code in success:
            return out[-1] if out else ""
        errors = [ln for ln in err if ": error: " in ln]
        said = errors[-1] if errors else (err[-1] if err else f"exit code {code}")
        raise RetimeAddonError(said)
