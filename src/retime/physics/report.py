"""Per-output-frame report of a physics retiming (what the CLI writes with ``--report``).

For every output frame: the source time it shows, playback speed p' and acceleration p'', the contact
state of the source frame (the nearest one), the distance of (p'', p'^2) to that frame's feasible
region in the (p'', p'^2) plane, the residual wrench (in body weights, the relaxation's weighted L1
measure, found by an LP) that the timing needs beyond the region's bounds, whether it lies in the
region -- ``in_region``: that residual is at most ``tol`` = 1% of body weight (0 means strictly
inside) -- and the norm of the actuated joint torques (N m) under the fan contact model. The summary holds ``feasible_fraction`` (share of output frames in
their region) and, per contact phase (stance / flight), its source and output span and mean speed;
:func:`~retime.physics.api.physics_warp` adds ``least_duration`` (the fastest physical timing's duration,
:mod:`retime.physics.fastest`; null when none passes the clip) and ``bind_pose_frames``.
"""
from __future__ import annotations

import json

import numpy as np

from ..io_util import atomic_write
from .forces import FanModel
from .objective import actuated_mask
from .frame_region import residual_at

IN_REGION_TOL = 1e-2  # body weights of residual wrench beyond the region (about 7 N for 70 kg)


def _phases(contact_any, times):
    """Runs of equal contact state: [(in_contact, first, last)] over sample indices."""
    runs = []
    start = 0
    for i in range(1, len(contact_any) + 1):
        if i == len(contact_any) or contact_any[i] != contact_any[start]:
            runs.append((bool(contact_any[start]), start, i - 1))
            start = i
    return runs


def build_report(spline, pd, regions, fps, tol=IN_REGION_TOL, info=None, extra=None) -> dict:
    T = spline.duration
    n_out = int(round(T * fps)) + 1
    t = np.minimum(np.arange(n_out) / fps, T)
    s = spline(t)
    pdot = spline.speed(t)
    pddot = spline.accel(t)
    times = np.asarray(pd.times, dtype=float)
    idx = np.clip(np.rint(np.interp(s, times, np.arange(len(times)))).astype(int), 0, len(times) - 1)
    act = actuated_mask(pd)
    contact = np.asarray(pd.contact, dtype=bool)
    names = list(getattr(pd, "contact_names", [])) or [f"contact{k}" for k in range(contact.shape[1])]
    frames = []
    inside = np.zeros(n_out, dtype=bool)
    fans = {}
    dist = regions.distances(idx, pddot, pdot ** 2)
    for k in range(n_out):
        i = int(idx[k])
        u, v = float(pddot[k]), float(pdot[k] ** 2)
        d = float(dist[k])
        if i not in fans:
            fans[i] = FanModel(regions.polygon(i), regions.polygon_lam(i), regions.center[i], regions.center_lam[i])
        lam = fans[i].lam((u, v))
        tau = pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ lam
        res = 0.0 if d <= 1e-9 else residual_at(pd, regions, i, u, v)
        inside[k] = res <= tol
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
            "distance": round(float(d), 6),
            "residual": round(float(res), 5),
            "torque_norm": round(float(np.linalg.norm(tau[act])), 3),
            "relaxation": round(float(regions.relaxation[i]), 4),
            "source_residual": round(float(regions.source_residual[i]), 4),
        })
    phases = []
    for in_contact, a, b in _phases(contact.any(axis=1), times):
        s0, s1 = times[a], times[min(b + 1, len(times) - 1)]
        t0, t1 = spline.inverse(np.array([s0, s1]))
        if s1 <= s0 or t1 <= t0:  # a one-sample phase at the clip's end has no span to play
            continue
        phases.append({
            "state": "stance" if in_contact else "flight",
            "source_start": round(float(s0), 6), "source_end": round(float(s1), 6),
            "output_start": round(float(t0), 6), "output_end": round(float(t1), 6),
            "speed": round(float((s1 - s0) / (t1 - t0)), 4),
        })
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
                                "constraint_violation": info.constraint_violation, "converged": info.converged}
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


def write_report(report: dict, path) -> None:
    text = json.dumps(finite(report), indent=1, allow_nan=False)  # before the file is opened
    with atomic_write(path, "w") as f:
        f.write(text + "\n")
