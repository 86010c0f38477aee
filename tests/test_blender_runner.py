"""The add-on's background run (``runner.BackgroundRunOperator``, shared by Retime and Check) driven as
Blender drives it from the panel: invoke, timer events while retime runs, then finish, Esc or a failure.
Headless Blender has no window, so the Blender tests only reach ``execute``; this plays the modal path
with stand-ins for the context, the window manager and the job (runner.py needs no bpy to import)."""
import importlib.util
from pathlib import Path
from types import SimpleNamespace

import pytest

RUNNER = Path(__file__).resolve().parents[1] / "blender" / "retime_addon" / "runner.py"


@pytest.fixture(scope="module")
def runner():
    spec = importlib.util.spec_from_file_location("retime_addon_runner", RUNNER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class WindowManager:
    def __init__(self):
        self.timers, self.handlers, self.progress = [], [], []

    def event_timer_add(self, step, window=None):
        self.timers.append(step)
        return step

    def event_timer_remove(self, timer):
        self.timers.remove(timer)

    def modal_handler_add(self, op):
        self.handlers.append(op)

    def progress_begin(self, a, b):
        self.progress.append("begin")

    def progress_update(self, v):
        self.progress.append(v)

    def progress_end(self):
        self.progress.append("end")


class Workspace:
    def __init__(self):
        self.status = []

    def status_text_set(self, text):
        self.status.append(text)


def context():
    return SimpleNamespace(window=object(), window_manager=WindowManager(), workspace=Workspace())


def make_operator(runner, finish=None, fail_in_init=None):
    class Run:
        elapsed = 3.2
        finished = False

        def done(self):
            return self.finished

    class Job:
        made = []

        def __init__(self, context, op):
            if fail_in_init:
                raise fail_in_init
            self.run, self.cleaned, self.launched = None, 0, False
            Job.made.append(self)

        doing = "checking 'jump'"

        def launch(self, context):
            self.run, self.launched = Run(), True

        def finish(self, context):
            return finish() if finish else ({"WARNING"}, "Check 'jump': NOT physical")

        def cleanup(self):
            self.cleaned += 1

    class Operator(runner.BackgroundRunOperator):
        job_type = Job
        title = "Retime check"

        def __init__(self):
            self.reports = []

        def report(self, level, message):
            self.reports.append((level, message))

    return Operator(), Job


def timer():
    return SimpleNamespace(type="TIMER")


def test_invoke_runs_in_the_background_and_finishes_on_a_timer(runner):
    op, Job = make_operator(runner)
    ctx = context()
    assert op.invoke(ctx, None) == {"RUNNING_MODAL"}
    job = Job.made[-1]
    assert job.launched and ctx.window_manager.handlers == [op] and ctx.window_manager.timers == [0.2]
    assert ctx.workspace.status[-1] == "Retime: checking 'jump', 3 s (Esc cancels)"
    assert op.modal(ctx, SimpleNamespace(type="MOUSEMOVE")) == {"PASS_THROUGH"}
    assert op.modal(ctx, timer()) == {"RUNNING_MODAL"} and not op.reports  # retime still running
    job.run.finished = True
    assert op.modal(ctx, timer()) == {"FINISHED"}
    assert op.reports == [({"WARNING"}, "Check 'jump': NOT physical")]
    assert job.cleaned == 1 and ctx.window_manager.timers == [] and ctx.workspace.status[-1] is None
    assert ctx.window_manager.progress[0] == "begin" and ctx.window_manager.progress[-1] == "end"


def test_esc_cancels_and_cleans_up(runner):
    op, Job = make_operator(runner)
    ctx = context()
    op.invoke(ctx, None)
    assert op.modal(ctx, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    assert op.reports == [({"WARNING"}, "retime check cancelled; nothing changed")]
    assert Job.made[-1].cleaned == 1 and ctx.window_manager.timers == []


def test_a_failure_is_one_error_line(runner):
    def finish():
        raise runner.RetimeAddonError("retime check: error: a.bvh: line 3:\n  not a number")

    op, Job = make_operator(runner, finish=finish)
    ctx = context()
    op.invoke(ctx, None)
    Job.made[-1].run.finished = True
    assert op.modal(ctx, timer()) == {"CANCELLED"}
    assert op.reports == [({"ERROR"}, "Retime check: retime check: error: a.bvh: line 3: not a number")]
    assert Job.made[-1].cleaned == 1


def test_a_job_that_cannot_start_reports_and_leaves_nothing_running(runner):
    op, _ = make_operator(runner, fail_in_init=runner.RetimeAddonError("no active object: select the armature"))
    ctx = context()
    assert op.invoke(ctx, None) == {"CANCELLED"}
    assert op.reports == [({"ERROR"}, "Retime check: no active object: select the armature")]
    assert ctx.window_manager.handlers == [] and ctx.window_manager.timers == []


def test_without_a_window_it_runs_to_the_end(runner):
    op, Job = make_operator(runner)
    ctx = context()
    ctx.window = None
    Job.launch = lambda self, context: setattr(self, "run", SimpleNamespace(done=lambda: True, elapsed=0.0))
    assert op.invoke(ctx, None) == {"FINISHED"}
    assert op.reports == [({"WARNING"}, "Check 'jump': NOT physical")] and Job.made[-1].cleaned == 1
