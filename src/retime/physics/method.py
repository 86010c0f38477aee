"""Physics-based retiming behind the contract of :mod:`retime.method`."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import RetimeError
from ..method import Report, Request, Result, settings_record
from .constants import MAX_GRAVITY, G

NAME = "physics"
MASS_FACTORS = (1e-3, 1e3)


@dataclass(frozen=True)
class Settings:
    """Physics' options (see :func:`retime.physics.api.physics_warp` for each)."""

    gravity: tuple | None = None  # m/s^2 in the file's own axes (None: 9.81 down its up axis)
    gravity_scale: float | None = None  # or: standard gravity times this, down the up axis
    mass_factors: dict = field(default_factory=dict)  # {segment name: factor}
    objective: str = "match"  # match the original's torques, or "minimize" them
    body: object = None  # a body file path or model (None: anthropometric, 70 kg)
    contacts: object = None  # a contact CSV path or (F, 4) states (None: detected)
    friction: float | None = None
    torque_scale: float = 1.0
    optimizer: str = "newton"  # L-BFGS polished by banded Newton; or "lbfgs", "gd" (the paper's), "slsqp"
    start: str = "global"  # or "uniform" (the paper's)
    alpha: float = 10.0
    beta: float = 0.1
    gamma: float = 0.03
    knot_spacing: float = 0.05
    samples_per_frame: int = 4
    max_iter: int = 3000
    progress: bool = False  # the compile notice and progress bars on stderr


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


def solve(motion, request: Request) -> Result:
    from .api import physics_warp

    s = request.settings_or(Settings)
    if motion.n_frames < 4:
        raise RetimeError(f"physics needs at least 4 frames, the motion has {motion.n_frames}")
    result = physics_warp(motion, duration=request.output_duration(motion), gravity=file_gravity(motion, s),
                          mass_factors=check_masses(motion, s.mass_factors), objective=s.objective,
                          keytimes=request.keytimes, body=s.body, contacts=s.contacts, friction=s.friction,
                          torque_scale=s.torque_scale, alpha=s.alpha, beta=s.beta, method=s.optimizer,
                          knot_spacing=s.knot_spacing, samples_per_frame=s.samples_per_frame, max_iter=s.max_iter,
                          progress=s.progress, gamma=s.gamma, start=s.start)
    summary = result.report["summary"]
    summary["method"] = NAME
    summary["notes"] = list(summary.get("conform_notes", []))
    summary["settings"] = settings_record(s, leave_out=("body", "contacts"))
    t = summary["timings"]
    t["method"] = round(float(sum(v for k, v in t.items() if k != "compile")) - t.get("compile", 0.0), 4)
    info = result.info
    solver = {"optimizer": info.method, "objective": info.objective, "iterations": info.iterations,
              "evaluations": info.evaluations, "converged": bool(info.converged),
              "constraint_violation": info.constraint_violation, "seconds": info.seconds,
              "stopped": info.message, "kkt_residual": info.kkt_residual,
              "lbfgs_objective": info.lbfgs_objective, "newton_iterations": info.newton_iterations}
    return Result(result.curve, Report(summary, result.report["frames"]), info=solver, detail=result)
