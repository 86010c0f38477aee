"""Per-output-frame report of a physics retiming (what the CLI writes with ``--report``).

For every output frame: the source time it shows, playback speed p' and acceleration p'', the contact
state of the source frame (the nearest one), the distance of (p'', p'^2) to that frame's feasible
region in the (p'', p'^2) plane, the residual wrench (in body weights, the relaxation's weighted L1
measure, found by an LP) that the timing needs beyond the region's bounds, whether it lies in the
region -- ``in_region``: that residual is at most ``tol`` = 1% of body weight (0 means strictly
inside) -- and the norm of the actuated joint torques (N m) under the fan contact model. The summary holds ``feasible_fraction`` (share of output frames in
their region) and, per contact phase (stance / flight), its source and output span and mean speed;
:func:`~retime.physics.api.physics_warp` adds ``least_duration`` (the fastest physical timing's duration,
:mod:`retime.physics.timing.fastest`; null when none passes the clip) and ``bind_pose_frames``.
"""
from __future__ import annotations

import json

import numpy as np

from ..io_util import atomic_write
from ..phases import contact_phases
from .regions.feasibility import IN_REGION_TOL, feasibility, output_times
from .regions.forces import FanModel
from .timing.objective import actuated_mask


def build_report(spline, pd, regions, fps, tol=IN_REGION_TOL, info=None, extra=None) -> dict:
    T = spline.duration
    t = output_times(T, fps)
    n_out = len(t)
    s = spline(t)
    pdot = spline.speed(t)
    pddot = spline.accel(t)
    feas = feasibility(pd, regions, s, pdot, pddot, tol)
    times = np.asarray(pd.times, dtype=float)
    act = actuated_mask(pd)
    contact = np.asarray(pd.contact, dtype=bool)
    names = list(getattr(pd, "contact_names", [])) or [f"contact{k}" for k in range(contact.shape[1])]
    frames = []
    inside = feas.inside
    fans = {}
    for k in range(n_out):
        i = int(feas.frames[k])
        u, v = float(pddot[k]), float(pdot[k] ** 2)
        if i not in fans:
            fans[i] = FanModel(regions.polygon(i), regions.polygon_lam(i), regions.center[i], regions.center_lam[i])
        lam = fans[i].lam((u, v))
        tau = pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ lam
        frames.append({
            "frame": k,
            "output_time": round(float(t[k]), 6),
            "source_time": round(float(s[k]), 6),
            "source_frame": i,
            "speed": round(float(pdot[k]), 6),
            "p_ddot": round(u, 6),
            "p_dot2": round(v, 6),
            "contact": [nm for nm, c in zip(names, contact[i]) if c],
            "in_region": bool(inside[k]),
            "distance": round(float(feas.distance[k]), 6),
            "residual": round(float(feas.residual[k]), 5),
            "torque_norm": round(float(np.linalg.norm(tau[act])), 3),
            "relaxation": round(float(regions.relaxation[i]), 4),
            "source_residual": round(float(regions.source_residual[i]), 4),
        })
    phases = contact_phases(contact, times, spline.inverse)
    summary = {
        "feasible_fraction": round(float(inside.mean()), 4),
        "in_region_tolerance": tol,
        "output_frames": n_out,
        "duration": round(float(T), 6),
        "source_duration": round(float(spline.S), 6),
        "mean_speed": round(float(spline.S / T), 4),
        "implausible_source_frames": int(np.sum(regions.implausible)),
        "relaxed_source_frames": int(np.sum(regions.relaxed)),
        "mean_source_residual": round(float(np.mean(regions.source_residual)), 4),
        "phases": phases,
    }
    if info is not None:
        summary["optimizer"] = {"method": info.method, "objective": info.objective, "iterations": info.iterations,
                                "evaluations": info.evaluations, "seconds": round(info.seconds, 4),
                                "constraint_violation": info.constraint_violation, "converged": info.converged,
                                "stopped": info.message, "kkt_residual": info.kkt_residual,
                                "lbfgs_objective": info.lbfgs_objective, "newton_iterations": info.newton_iterations}
    if extra:
        summary.update(extra)
    return {"summary": summary, "frames": frames}


def flight_speeds(report) -> list[float]:
    return [p["speed"] for p in report["summary"]["phases"] if p["state"] == "flight"]


def finite(value):
    """The report with every NaN or infinity as null: JSON has no such numbers."""
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


REGION_DIGITS = 4  # significant digits of a stored region's vertices: a plot's precision, a fifth of the bytes


def region_polygons(regions, digits=REGION_DIGITS) -> list:
    """Each source frame's feasible region, [[p'', p'^2], ...], to ``digits`` significant digits: what
    ``retime plot --regions`` draws (about 180 bytes a frame)."""
    return [[[float(f"{v:.{digits}g}") for v in vertex] for vertex in np.asarray(regions.polygon(i), dtype=float)]
            for i in range(regions.n_frames)]


def write_report(report: dict, path, regions=None) -> None:
    """Write the report as JSON, atomically; with ``regions``, each source frame's region beside the frames."""
    if regions is not None:
        report = {**report, "regions": region_polygons(regions)}
    text = json.dumps(finite(report), indent=1, allow_nan=False)  # before the file is opened
    with atomic_write(path, "w") as f:
        f.write(text + "\n")
