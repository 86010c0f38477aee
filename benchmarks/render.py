"""Rendering speed of one 31-joint CMU skeleton (16_06, 480x540 panel, 30 fps video).

Prints frames per second for drawing alone and for drawing plus H.264 encoding (PyAV, libx264 in a
background thread), by the wall clock and per CPU second (which a busy machine does not distort).
The issue's target is at least 60 frames per second on this 2-core machine.

    python3 benchmarks/render.py [--json]
"""
import argparse
import json
import os
import tempfile
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs (default 3)")
    args = ap.parse_args()

    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.viz.render import Renderer, track_from_motion
    from retime.viz.video import VideoWriter

    motion = load_motion(bundled_path("16_06.amc"))
    track = track_from_motion(motion, "original")
    t0 = time.perf_counter()
    renderer = Renderer([track], fps=30.0, panel_size=(480, 540))
    setup = time.perf_counter() - t0
    n = renderer.n_frames
    renderer.frame(0)
    draw = encode = draw_cpu = encode_cpu = 0.0
    for _ in range(args.repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        for k in range(n):
            renderer.frame(k)
        draw = max(draw, n / (time.perf_counter() - t0))
        draw_cpu = max(draw_cpu, n / (time.process_time() - c0))
        with tempfile.TemporaryDirectory() as d:
            t0, c0 = time.perf_counter(), time.process_time()
            with VideoWriter(os.path.join(d, "bench.mp4"), renderer.width, renderer.height, 30.0) as w:
                for k in range(n):
                    w.write(renderer.frame(k))
            encode = max(encode, n / (time.perf_counter() - t0))
            encode_cpu = max(encode_cpu, n / (time.process_time() - c0))
    result = {"case": "16_06 one skeleton 480x540", "joints": int(track.positions.shape[1]), "frames": n,
              "setup_s": round(setup, 4), "draw_fps": round(draw, 1), "draw_encode_fps": round(encode, 1),
              "draw_fps_per_cpu_second": round(draw_cpu, 1), "draw_encode_fps_per_cpu_second": round(encode_cpu, 1),
              "load_average": round(os.getloadavg()[0], 2), "target_fps": 60}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{result['case']}: {n} frames ({result['joints']} joints incl. end sites), setup {setup * 1000:.0f} ms")
        print(f"  draw only        {draw:7.1f} frames/s   ({draw_cpu:.1f} per CPU second)")
        print(f"  draw + encode    {encode:7.1f} frames/s   ({encode_cpu:.1f} per CPU second, encoder in a 2nd thread; "
              "target >= 60)")
        print(f"  load average     {result['load_average']:.2f} (wall-clock numbers assume an otherwise idle machine)")


if __name__ == "__main__":
    main()
