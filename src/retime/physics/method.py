"""Physics-based retiming behind the contract of :mod:`retime.method`.

:class:`Settings` is where physics' options and their defaults are written, once (the reasons for the
defaults are in :mod:`retime.physics.api`): the command line's options and help, the editor's controls,
batch and the Blender panel read them from here, and :func:`retime.physics.physics_warp` takes the same
names as keywords."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from ..errors import RetimeError
from ..method import Report, Request, Result, settings_record
from .constants import DEFAULT_SMOOTHING, MAX_GRAVITY, G

NAME = "physics"
MASS_FACTORS = (1e-3, 1e3)
OBJECTIVES = ("match", "minimize")
STARTS = ("global", "uniform")
#: the timing spline's optimizers (:mod:`retime.physics.timing.optimize`)
OPTIMIZER_NAMES = ("newton", "lbfgs", "gd", "slsqp")
#: fields of the objective's inner workings, kept out of the report's settings record (which lists
#: what a user chooses)
INNER = ("metric", "excess", "penalty", "delta", "w_min", "w_max", "smoothing")


@dataclass(frozen=True)
class Settings:
    """Physics' options (checked when made: every front end gets the same one-line errors)."""

    gravity: tuple | None = None  # m/s^2 in the file's own axes (None: 9.81 down its up axis)
    gravity_scale: float | None = None  # or: standard gravity times this, down the up axis
    mass_factors: dict = field(default_factory=dict)  # {segment name: factor}
    objective: str = "match"  # match the original's torques, or "minimize" them
    body: object = None  # a body file path or model (None: anthropometric, 70 kg)
    contacts: object = None  # a contact CSV path or (F, 4) states (None: detected)
    friction: float | None = None  # friction coefficient (None: the body's, 0.5)
    torque_scale: float = 1.0  # all torque limits times this
    optimizer: str = "newton"  # L-BFGS polished by banded Newton; or "lbfgs", "gd" (the paper's), "slsqp"
    start: str = "global"  # or "uniform" (the paper's)
    alpha: float = 10.0  # weight of the feasibility penalty (Eq. 14's alpha)
    beta: float = 0.1  # weight of the torque term
    gamma: float = 0.03  # pull of the playback speed towards 1
    knot_spacing: float = 0.05  # the timing spline's control points, seconds of source time apart
    samples_per_frame: int = 4  # objective samples per source frame
    max_iter: int = 3000
    progress: bool = False  # the compile notice and progress bars on stderr
    metric: str = "residual"  # distance to a region in body weights of residual force ("plane": Eq. 14's)
    excess: bool = True  # torques measured from what any timing could reach
    penalty: str = "l1"  # exact penalty of the distance ("l2": Eq. 14's square)
    delta: float = 1e-3  # smoothing of the l1 penalty near the region
    w_min: float = 0.02  # slowest playback speed the spline may take
    w_max: float = 12.0  # fastest (raised for a short requested duration)
    smoothing: float = DEFAULT_SMOOTHING  # Gaussian low-pass of the path for the dynamics (s)

    def __post_init__(self):
        if self.objective not in OBJECTIVES:
            raise RetimeError(f"unknown objective {self.objective!r} (use 'match' or 'minimize')")
        if self.start not in STARTS:
            raise RetimeError(f"unknown start {self.start!r} (use 'global' or 'uniform')")
        if self.optimizer not in OPTIMIZER_NAMES:
            raise RetimeError(f"unknown optimizer {self.optimizer!r}: use one of {', '.join(OPTIMIZER_NAMES)}")


def file_gravity(motion, settings: Settings):
    """Gravity in the file's axes from the settings (None: standard, down the detected up)."""
    if settings.gravity is not None and settings.gravity_scale is not None:
        raise RetimeError("give a gravity vector or a gravity scale, not both")
    if settings.gravity_scale is not None:
        g = float(settings.gravity_scale)
        if not (0 < g * G <= MAX_GRAVITY):
            raise RetimeError(f"gravity scale must be above 0 and at most {MAX_GRAVITY / G:.0f}, "
                              f"got {g:g}")
        from ..motion.frame import up_vector

        return tuple(-G * g * up_vector(motion.skeleton.up))
    return settings.gravity


def check_masses(motion, mass_factors: dict) -> dict | None:
    names = motion.skeleton.names
    for name, f in mass_factors.items():
        if name not in names:
            raise RetimeError(f"mass {name}={f:g}: no segment named {name!r}; segments: {', '.join(names)}")
        if not (MASS_FACTORS[0] <= float(f) <= MASS_FACTORS[1]):
            raise RetimeError(f"mass {name}={f:g}: the factor must be from {MASS_FACTORS[0]:g} to {MASS_FACTORS[1]:g}")
    return dict(mass_factors) or None


def solve(motion, request: Request, terms=None, region_options=None) -> Result:
    """The contract's solve; ``terms`` (:class:`retime.physics.model.dynamics.DynamicsTerms` of this motion)
    and ``region_options`` let a caller reuse the dynamics or tune the regions' LPs."""
    from .api import physics_result

    s = request.settings_or(Settings)
    if motion.n_frames < 4:
        raise RetimeError(f"physics needs at least 4 frames, the motion has {motion.n_frames}")
    result = physics_result(motion, s, request, terms=terms, region_options=region_options)
    summary = result.report["summary"]
    summary["method"] = NAME
    summary["notes"] = list(summary.get("conform_notes", []))
    summary["settings"] = settings_record(s, leave_out=("body", "contacts") + INNER)
    t = summary["timings"]
    t["method"] = round(float(sum(v for k, v in t.items() if k != "compile")) - t.get("compile", 0.0), 4)
    info = result.info
    solver = {"optimizer": info.method, "objective": info.objective, "iterations": info.iterations,
              "evaluations": info.evaluations, "converged": bool(info.converged),
              "constraint_violation": info.constraint_violation, "seconds": info.seconds,
              "stopped": info.message, "kkt_residual": info.kkt_residual,
              "lbfgs_objective": info.lbfgs_objective, "newton_iterations": info.newton_iterations}
    return Result(result.curve, Report(summary, result.report["frames"]), info=solver, detail=result)


@dataclass(frozen=True)
class Shared:
    """A motion's dynamics, feasible regions and baked objective under one setting: what every live
    session of that motion and setting shares (computed once, read only by the sessions)."""

    settings: Settings
    terms: object  # :class:`.model.dynamics.DynamicsTerms`
    dynamics: object  # the :class:`.model.dynamics.PathDynamics` under the setting's gravity and masses
    regions: object  # :class:`.regions.RegionSet`
    objective: object  # :class:`.timing.objective.BakedObjective`


def _same_physics(a: Settings, b: Settings) -> bool:
    """Whether two settings give the same dynamics, regions and objective (progress aside)."""
    return replace(a, progress=False) == replace(b, progress=False)


def session(motion, request: Request, shared: Shared | None = None, cancel=None):
    """A live retiming of ``motion`` (McCann et al. §3.6): the timing spline's control points move,
    lock, appear and go, and :meth:`reconverge` warm-starts from the current solution (a
    :class:`.timing.optimize.RetimingSession`). ``shared``: what an earlier session of this motion
    computed (its ``.shared``): all of it is reused under the same settings, its body dynamics
    under others. ``cancel``: asked while the regions are computed; True stops with
    :class:`.regions.Cancelled`."""
    from .api import LiveSession, conformed_gravity, make_problem, prepare

    s = request.settings_or(Settings)
    if motion.n_frames < 4:
        raise RetimeError(f"physics needs at least 4 frames, the motion has {motion.n_frames}")
    if shared is None or not _same_physics(shared.settings, s):
        gravity = conformed_gravity(motion, file_gravity(motion, s))
        check_masses(motion, s.mass_factors)
        terms, pd, regions, obj = prepare(motion, gravity, s, terms=None if shared is None else shared.terms,
                                          cancel=cancel)
        shared = Shared(s, terms, pd, regions, obj)
    problem = make_problem(shared.objective, motion.duration, request.output_duration(motion), request.keytimes,
                           s.knot_spacing, s.w_min, s.w_max, start=s.start)

    return LiveSession(problem, shared, optimizer=s.optimizer, fps=motion.fps)


def write_report(result: Result, path) -> None:
    """The report of ``retime physics --report``: summary, per-frame records and each source frame's
    feasible region (what ``retime plot --regions`` draws)."""
    from .report import write_report as write_json

    write_json(result.detail.report, path, regions=result.detail.regions)
