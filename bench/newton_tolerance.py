#!/usr/bin/env python3
"""Newton stopping rules against the time-discretisation error, on the contact scenes.

For each case (a scene and overrides), runs `weft run` once per setting over the same
simulated time and compares the cloth positions at the last frame with those of a tightly
converged run ("tight": relative residual 1e-6, no step test). The run at dt / 2 with the
1e-2 m/s velocity tolerance measures the backward Euler error the tolerance should stay below.
Prints one CSV row per case and setting: Newton iterations per step, seconds per step, the
RMS and largest vertex deviation from the tight run, and the run's contact check.

    python3 bench/newton_tolerance.py WEFT OUT_DIR [--cases shrunk|stack] > results.csv
"""
import argparse
import glob
import json
import os
import subprocess
import sys

import numpy as np

STACK9 = [f"cloths.{i}.mesh.resolution=[9,9]" for i in range(8)]
CASES = {
    "shrunk": [
        ("dropVertical_13", "scenes/drop_vertical.json", ["cloths.0.mesh.resolution=[13,13]"], 0.75),
        ("dropHorizontal_15", "scenes/drop_horizontal.json", ["cloths.0.mesh.resolution=[15,15]"], 0.75),
        ("twisted_21x9", "scenes/twisted_sheet.json", ["cloths.0.mesh.resolution=[21,9]"], 1.0),
        ("sheet_stack_8x9", "scenes/sheet_stack.json", STACK9, 0.5),
        ("drape_11", "scenes/drape_sphere.json", ["cloths.0.mesh.resolution=[11,11]"], 1.0),
    ],
    # the 40k-vertex stack over its first 14 steps (the fall and the first landings)
    "stack": [("sheet_stack_8x71", "scenes/sheet_stack.json", [], 14 / 240)],
}
SETTINGS = [
    ("tight", ["integrator.relative_tolerance=1e-6", "integrator.step_tolerance=0", "integrator.velocity_tolerance=0"]),
    ("step_1um", ["integrator.step_tolerance=1e-6", "integrator.velocity_tolerance=0"]),
    ("velocity_1e-2", ["integrator.step_tolerance=0", "integrator.velocity_tolerance=0.01"]),
    ("velocity_2.4e-2", ["integrator.step_tolerance=0", "integrator.velocity_tolerance=0.024"]),
    ("dt_half", ["integrator.step_tolerance=0", "integrator.velocity_tolerance=0.01", "@half"]),
]


def positions(out):
    """The cloth vertices of the last frame, cloth after cloth."""
    cloths = json.load(open(os.path.join(out, "scene.json")))["cloths"]
    P = []
    for i, c in enumerate(cloths):
        name = c.get("name", "cloth")
        frames = sorted(glob.glob(os.path.join(out, f"{name}{i}_*.obj"))) or \
            sorted(glob.glob(os.path.join(out, f"{name}_*.obj")))
        P += [[float(x) for x in l.split()[1:4]] for l in open(frames[-1]) if l.startswith("v ")]
    return np.array(P)


def run(weft, scene, overrides, duration, dt, out):
    args = [weft, "--threads", "2", "run", scene, "-q", "-o", out, f"time.duration={duration!r}",
            f"time.frame_rate={1 / duration!r}"]
    args += [o for o in overrides if o != "@half"]
    if "@half" in overrides:
        args.append(f"time.dt={dt / 2!r}")
    subprocess.run(args, check=False, stdout=subprocess.DEVNULL)
    summary = json.load(open(os.path.join(out, "summary.json")))
    steps = [json.loads(l) for l in open(os.path.join(out, "stats.jsonl"))]
    return summary, steps


def main():
    p = argparse.ArgumentParser()
    p.add_argument("weft")
    p.add_argument("out")
    p.add_argument("--cases", default="shrunk", choices=sorted(CASES))
    a = p.parse_args()
    print("case,setting,steps,newton_per_step,max_newton,seconds_per_step,rms_deviation_m,max_deviation_m,"
          "cloth_intersection_frames,obstacle_crossing_frames,status")
    for name, scene, base, duration in CASES[a.cases]:
        dt = 1 / 240
        ref = None
        for setting, overrides in SETTINGS:
            out = os.path.join(a.out, name, setting)
            s, steps = run(a.weft, scene, base + overrides, duration, dt, out)
            if ref is None and s["status"] != "completed":  # too tight to converge: one decade looser
                setting, overrides = "tight_1e-5", [o.replace("=1e-6", "=1e-5") for o in overrides]
                out = os.path.join(a.out, name, setting)
                s, steps = run(a.weft, scene, base + overrides, duration, dt, out)
            P = positions(out)
            if ref is None:
                ref = P
            d = np.linalg.norm(P - ref, axis=1) if P.shape == ref.shape else np.full(1, np.nan)
            newton = [r["newton"]["iterations"] for r in steps if "newton" in r]
            c = s.get("contact_check", {})
            print(f"{name},{setting},{len(newton)},{np.mean(newton):.3f},{max(newton)},{s['seconds_per_step']:.4f},"
                  f"{np.sqrt(np.mean(d ** 2)):.3e},{d.max():.3e},{c.get('frames_with_cloth_intersections')},"
                  f"{c.get('frames_with_obstacle_crossings')},{s['status']}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
