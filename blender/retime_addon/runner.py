"""Finding and running the ``retime`` program (outside Blender's Python: it needs NumPy 2, SciPy, numba)."""
import os
import shutil
import subprocess
import time
import traceback


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


def one_line(error):
    """What went wrong, for the report; a bug's traceback goes to the system console only."""
    if isinstance(error, RetimeAddonError):
        return str(error)
    traceback.print_exc()
    return f"unexpected {type(error).__name__}: {error} (details in the system console; please report it)"


class BackgroundRunOperator:
    """An operator's part that runs a job's ``retime`` to the end (``execute``: scripts) or in the background
    (``invoke`` from the panel: the status bar shows the job and the seconds, Esc cancels). The job
    (``job_type(context, operator)``) has ``launch(context)``, ``run`` (a :class:`Run`), ``doing`` (what the
    status bar says), ``finish(context)`` -> (report type, message) and ``cleanup()``; ``title`` starts the
    operator's own reports."""

    job_type = None
    title = "Retime"
    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        try:
            job = self.job_type(context, self)
        except Exception as e:
            return self._fail(one_line(e))
        try:
            wm = context.window_manager
            wm.progress_begin(0, 100)
            wm.progress_update(5)
            job.launch(context)
            while not job.run.done():
                wm.progress_update(min(90, 10 + int(job.run.elapsed)))
                time.sleep(0.05)
            wm.progress_update(95)
            level, message = job.finish(context)
        except Exception as e:
            return self._fail(one_line(e))
        finally:
            context.window_manager.progress_end()
            job.cleanup()
        self.report(level, message)
        return {"FINISHED"}

    def invoke(self, context, event):
        if context.window is None:
            return self.execute(context)
        try:
            self._job = self.job_type(context, self)
            self._job.launch(context)
        except Exception as e:
            if self._job is not None:
                self._job.cleanup()
            self._job = None
            return self._fail(one_line(e))
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._end(context)
            self.report({"WARNING"}, f"{self.title.lower()} cancelled; nothing changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not self._job.run.done():
            self._status(context)
            return {"RUNNING_MODAL"}
        try:
            level, message = self._job.finish(context)
        except Exception as e:
            self._end(context)
            return self._fail(one_line(e))
        self._end(context)
        self.report(level, message)
        return {"FINISHED"}

    def _status(self, context):
        elapsed = self._job.run.elapsed
        context.window_manager.progress_update(min(90, 10 + int(elapsed)))
        if context.workspace is not None:
            context.workspace.status_text_set(f"Retime: {self._job.doing}, {elapsed:.0f} s (Esc cancels)")

    def _end(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        self._job.cleanup()

    def _fail(self, message):
        self.report({"ERROR"}, f"{self.title}: " + " ".join(message.split()))  # one line, whatever retime printed
        return {"CANCELLED"}
