#!/usr/bin/python3
"""Summaries of the tour's experiments (scripts/tour/*.sh): tables in summary.md, the numbers
in summary.json (what tests/apps/test_tour.py asserts), and the plots through
scripts/weft_plot.py (skipped with a message when Debian's python3-matplotlib is missing).

  tour_summary.py integrators OUT   first steps on the hinge (runs.txt) and the stability maps
  tour_summary.py linear OUT        bench/bench_linear.csv of `weft bench linear`
  tour_summary.py contact OUT       stability.csv of `weft stability` on the whip (its contact_steps
                                    tell a run that met the wall from one that never reached it)
  integrators and contact also summarise work_precision/ablate.csv (`weft ablate --sweep time.dt=...`)

Standard library only. Exit status 0, or 2 when an input is missing or malformed.
"""
import csv
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PLOT = os.path.join(HERE, "..", "weft_plot.py")


sys.path.insert(0, os.path.join(HERE, ".."))
from weft_plot import InputError, read_csv  # noqa: E402  (the CSV reader and its errors of weft_plot.py)


def plot(kind, inp, out, *extra):
    """Runs weft_plot.py; returns 'written', 'skipped' (no matplotlib) or 'failed'."""
    r = subprocess.run(["/usr/bin/python3", PLOT, kind, inp, "--out", out, *extra], capture_output=True, text=True)
    if r.returncode == 0:
        return "written"
    if r.returncode == 3:
        sys.stderr.write("plot skipped: python3-matplotlib is not installed (apt-get install python3-matplotlib)\n")
        return "skipped"
    sys.stderr.write("plot failed: {}".format(r.stderr))
    return "failed"


def read_text(path, missing):
    """The file's text without trailing blanks, or `missing` when it cannot be read."""
    try:
        with open(path) as f:
            return f.read().rstrip()
    except OSError:
        return missing


def git_describe():
    try:
        r = subprocess.run(["git", "-C", HERE, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        dirty = subprocess.run(["git", "-C", HERE, "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True)
        return r.stdout.strip() + (" + working tree" if dirty.stdout.strip() else "")
    except OSError:
        return "?"


def write(out, md, doc):
    doc["info"] = info(out)
    doc["git"] = git_describe()
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write(md)
    sys.stdout.write(md)
    print("summary: {}/summary.md, summary.json".format(out))


def stability_counts(path):
    """{combo: {"stable": n, "cells": n}} from a stability.csv."""
    counts = {}
    for r in read_csv(path, ["combo", "outcome"]):
        c = counts.setdefault(r["combo"], {"stable": 0, "cells": 0})
        c["cells"] += 1
        c["stable"] += r["outcome"] == "stable"
    return counts


def info(out):
    return read_text(os.path.join(out, "info.txt"), "").strip()


def map_text(dir_):
    return read_text(os.path.join(dir_, "stability_map.txt"), "(no stability_map.txt)")


# ---------------------------------------------------------------------------------------------
def integrators(out):
    runs = []
    try:
        with open(os.path.join(out, "runs.txt")) as f:
            for line in f:
                if line.strip():
                    name, dt, rc, d, t0, t1 = line.split()
                    runs.append((name, float(dt), int(rc), d, float(t1) - float(t0)))
    except OSError as e:
        raise InputError("{}/runs.txt: {}".format(out, e.strerror))
    rows, hist = [], []
    for name, dt, rc, d, wall in runs:
        stats = os.path.join(d, "stats.jsonl")
        try:
            with open(stats) as f:
                steps = [json.loads(l) for l in f if l.strip()]
        except (OSError, ValueError) as e:
            raise InputError("{}: {} (weft run exited with {}; see {}.log)".format(stats, e, rc, d))
        if not steps:
            raise InputError("{}: no step recorded (weft run exited with {})".format(stats, rc))
        n = steps[0]["newton"]
        k = round(dt * 240)
        rows.append({"variant": name, "dt": dt, "dt_240": k, "first_step_iterations": n["iterations"],
                     "first_step_converged": n["status"] == "success", "first_step_stop": n.get("stop_reason", n["status"]),
                     "final_residual": n["final_residual"], "tolerance": n["tolerance"], "method": n.get("method", ""),
                     "frame_steps": len(steps), "frame_iterations": sum(s["newton"]["iterations"] for s in steps),
                     "exit_code": rc, "wall_seconds": wall})
        res = [h["residual"] for h in n.get("history", [])] + [n["final_residual"]]
        hist.append({"label": "{} dt={}/240".format(name, k), "residuals": res})
    cols = list(rows[0].keys())
    with open(os.path.join(out, "first_step.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(out, "histories.jsonl"), "w") as f:
        for h in hist:
            f.write(json.dumps(h) + "\n")
    plots = {"histories": plot("histories", os.path.join(out, "histories.jsonl"), out, "--key", "residuals")}
    maps = {}
    for grid in ("hinge_map", "cloth_map"):
        p = os.path.join(out, grid, "stability.csv")
        if os.path.exists(p):
            maps[grid] = stability_counts(p)

    variants = list(dict.fromkeys(r["variant"] for r in rows))
    dts = sorted({r["dt_240"] for r in rows})
    md = ["# Integrators on the hinge: root finding vs incremental potential\n",
          "```\n{}\n```\n".format(info(out)),
          "## Newton iterations of the first step (hinge released from a 90 degree fold)\n",
          "Same equation, same Newton direction where K is positive definite; what differs is the merit "
          "function the line search watches. `>` : the step did not converge within the iteration limit "
          "(the residual it stopped at, against the tolerance, in the second table).\n",
          "| variant | " + " | ".join("dt = {}/240 s".format(k) for k in dts) + " |",
          "|---|" + "---:|" * len(dts)]
    by = {(r["variant"], r["dt_240"]): r for r in rows}
    for v in variants:
        cells = []
        for k in dts:
            r = by.get((v, k))
            cells.append("-" if r is None else ("{}".format(r["first_step_iterations"]) if r["first_step_converged"]
                                                else "> {} (stopped)".format(r["first_step_iterations"])))
        md.append("| {} | {} |".format(v, " | ".join(cells)))
    md.append("\n| variant | dt | first step | final residual | tolerance | steps in 1/24 s | iterations in 1/24 s | wall [s] |")
    md.append("|---|---|---|---:|---:|---:|---:|---:|")
    for r in rows:
        md.append("| {} | {}/240 | {} | {:.3g} | {:.3g} | {} | {} | {:.2f} |".format(
            r["variant"], r["dt_240"], r["first_step_stop"], r["final_residual"], r["tolerance"], r["frame_steps"],
            r["frame_iterations"], r["wall_seconds"]))
    for grid, title in (("hinge_map", "hinge, Young's modulus against dt, 0.25 s"),
                        ("cloth_map", "hanging cloth 11 x 11, Young's modulus against dt, 1 s")):
        if grid not in maps:
            continue
        md.append("\n## Stability map: {} (at most 100 Newton iterations per step)\n".format(title))
        md.append("| combination | stable cells |\n|---|---:|")
        for c, n in maps[grid].items():
            md.append("| {} | {} of {} |".format(c, n["stable"], n["cells"]))
        md.append("\n```\n{}\n```".format(map_text(os.path.join(out, grid))))
    md.append("\nPlots: histories.{png,svg} (first-step residuals), hinge_map/stability_map.{png,svg}" +
              (", cloth_map/stability_map.{png,svg}" if "cloth_map" in maps else "") + ".\n")
    wp, wp_md = work_precision(out)
    md += wp_md
    doc = {"experiment": "integrators", "first_step": rows, "maps": maps, "plots": plots, "work_precision": wp}
    write(out, "\n".join(md), doc)


def work_precision(out):
    """work_precision/ablate.csv of `weft ablate --sweep time.dt=...`: per combination its points
    in order of falling dt and the least-squares order of the error in dt; ({}, []) without it."""
    path = os.path.join(out, "work_precision", "ablate.csv")
    if not os.path.exists(path):
        return {}, []
    rows = read_csv(path, ["combo", "point", "status", "rms_error", "newton_iterations", "contacts", "wall_seconds"])
    curves = {}
    for r in rows:
        key, _, value = r["point"].partition("=")
        if key != "time.dt":
            raise InputError("{}: point '{}' is not a time.dt sweep".format(path, r["point"]))
        curves.setdefault(r["combo"], []).append({
            "dt": float(value), "ok": r["status"] == "ok", "rms_error": float(r["rms_error"]),
            "newton_iterations": int(r["newton_iterations"]), "contacts": int(r["contacts"]),
            "wall_seconds": float(r["wall_seconds"])})
    doc = {}
    for c, pts in curves.items():
        pts.sort(key=lambda p: -p["dt"])
        good = [p for p in pts if p["ok"] and p["rms_error"] > 0]
        doc[c] = {"points": pts, "order": fit_exponent([p["dt"] for p in good], [p["rms_error"] for p in good])}
    combos = list(doc)
    dts = [p["dt"] for p in doc[combos[0]]["points"]]
    md = ["## Work-precision diagram (`weft ablate --sweep time.dt=...`)\n",
          "RMS vertex error against one reference run (relative to the scene's size), Newton iterations and wall "
          "time of each run; order: least-squares slope of log error against log dt.\n",
          "| combination | order | " + " | ".join("dt = {:.4g} s".format(dt) for dt in dts) + " |",
          "|---|---:|" + "---:|" * len(dts)]
    for c in combos:
        cells = ["{:.3g} ({} it., {:.2f} s{})".format(p["rms_error"], p["newton_iterations"], p["wall_seconds"],
                                                    ", {} contacts".format(p["contacts"]) if p["contacts"] else "")
                 if p["ok"] else "failed" for p in doc[c]["points"]]
        order = doc[c]["order"]
        md.append("| {} | {} | {} |".format(c, "{:.2f}".format(order) if order is not None else "-", " | ".join(cells)))
    md.append("\nPlot (written by `weft ablate`): work_precision/pareto.{png,svg}, error against run time, one curve per "
              "combination and the Pareto front.\n")
    return doc, md


# ---------------------------------------------------------------------------------------------
def fit_exponent(xs, ys):
    """Least-squares slope of log y against log x (growth y ~ x^p); None for fewer than 2 points."""
    if len(xs) < 2:
        return None
    lx, ly = [math.log(x) for x in xs], [math.log(y) for y in ys]
    mx, my = sum(lx) / len(lx), sum(ly) / len(ly)
    sxx = sum((a - mx) ** 2 for a in lx)
    return sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / sxx if sxx > 0 else None


def linear(out):
    path = os.path.join(out, "bench", "bench_linear.csv")
    rows = read_csv(path, ["vertices", "solver", "mean_iterations", "mean_setup_s", "mean_solve_s", "mean_total_s", "failures"])
    solvers = {}
    for r in rows:
        s = solvers.setdefault(r["solver"], {"vertices": [], "iterations": [], "setup_s": [], "solve_s": [], "total_s": [],
                                             "failures": 0})
        s["vertices"].append(int(r["vertices"]))
        s["iterations"].append(float(r["mean_iterations"]))
        s["setup_s"].append(float(r["mean_setup_s"]))
        s["solve_s"].append(float(r["mean_solve_s"]))
        s["total_s"].append(float(r["mean_total_s"]))
        s["failures"] += int(r["failures"])
    for s in solvers.values():
        s["iteration_growth"] = s["iterations"][-1] / s["iterations"][0]
        s["iteration_exponent"] = fit_exponent(s["vertices"], s["iterations"])
        s["time_exponent"] = fit_exponent(s["vertices"], s["total_s"])
    plots = {"scaling": plot("scaling", path, out, "--x", "vertices", "--y", "mean_iterations,mean_total_s", "--group", "solver",
                             "--title", "pinned sheet, one linearly implicit step per solve")}
    d, sa = solvers.get("diag_pcg"), solvers.get("sa_ppcg")
    md = ["# Linear solvers as the mesh grows: Diag-PCG vs SA+PPCG\n", "```\n{}\n```\n".format(info(out)),
          "`weft bench linear`, example pinned, regular tessellation; per solve (mean over the steps): CG iterations to "
          "the relative M^-1-norm residual 1e-5, and wall time (SA+PPCG: setup = building the multigrid hierarchy, "
          "every step, + solve).\n",
          "| vertices | Diag-PCG its | SA+PPCG its | Diag-PCG [ms] | SA+PPCG setup + solve [ms] | T(Diag-PCG) / T(SA+PPCG) |",
          "|---:|---:|---:|---:|---:|---:|"]
    if d and sa:
        for k, n in enumerate(d["vertices"]):
            j = sa["vertices"].index(n) if n in sa["vertices"] else None
            if j is None:
                continue
            md.append("| {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} + {:.1f} | {:.2f} |".format(
                n, d["iterations"][k], sa["iterations"][j], 1e3 * d["total_s"][k], 1e3 * sa["setup_s"][j],
                1e3 * sa["solve_s"][j], d["total_s"][k] / sa["total_s"][j]))
    md.append("\n| solver | iterations, largest / smallest mesh | iterations ~ N^p | time per solve ~ N^p | failed solves |")
    md.append("|---|---:|---:|---:|---:|")
    for name, s in solvers.items():
        md.append("| {} | {:.2f} | p = {:.2f} | p = {:.2f} | {} |".format(name, s["iteration_growth"], s["iteration_exponent"] or 0,
                                                                        s["time_exponent"] or 0, s["failures"]))
    md.append("\nPlot: scaling.{png,svg}. The full report of the benchmark: bench/report.md.\n")
    write(out, "\n".join(md), {"experiment": "linear", "solvers": solvers, "plots": plots})


# ---------------------------------------------------------------------------------------------
LABELS = {"rods_impulse": "impulse", "rods_linear": "linear compliance", "rods_adonis": "ADONIS"}


def fmt_dt(h):
    return "{:g} ms".format(h * 1e3) if h >= 1e-3 else "{:g} us".format(h * 1e6)


def largest_stable(col):
    """col: sorted [(dt, ok)]; the largest dt with every dt up to it ok (0 if the smallest fails)."""
    best = 0.0
    for dt, ok in col:
        if not ok:
            break
        best = dt
    return best


def contact(out):
    path = os.path.join(out, "stability.csv")
    rows = read_csv(path, ["combo", "dt", "value", "outcome", "steps", "steps_planned", "max_strain", "wall_seconds",
                           "contact_steps", "message"])
    combos = list(dict.fromkeys(r["combo"] for r in rows))
    speeds = sorted({r["value"] for r in rows}, key=float)
    dts = sorted({float(r["dt"]) for r in rows})
    outcome = {(r["combo"], r["value"], float(r["dt"])): r["outcome"] for r in rows}
    contacts = {(r["combo"], r["value"], float(r["dt"])): int(r["contact_steps"]) for r in rows if r["outcome"] == "stable"}
    hstar, hstar_contact, cells, failures = {}, {}, {}, []
    for c in combos:
        hstar[c], hstar_contact[c], cells[c] = {}, {}, {}
        for v in speeds:
            col = [(dt, outcome[(c, v, dt)] == "stable") for dt in dts if (c, v, dt) in outcome]
            hstar[c][v] = largest_stable(col)
            if contacts:
                # stable and in contact with the wall at least once: runs that never reach the wall say nothing
                # about the response; stop at the first one (every smaller step is then both stable and in contact)
                best = 0.0
                for dt, ok in col:
                    if not ok or contacts.get((c, v, dt), 0) <= 0:
                        break
                    best = dt
                hstar_contact[c][v] = best
            cells[c][v] = {"stable": sum(ok for _, ok in col), "cells": len(col),
                           "stable_without_contact": sum(1 for dt, ok in col if ok and contacts.get((c, v, dt), 1) == 0)}
    for r in rows:
        if r["outcome"] != "stable":
            failures.append(r)
    md = ["# Contact on the whip: impulse vs linear compliance vs ADONIS\n", "```\n{}\n```\n".format(info(out)),
          "h*: the largest step of the sweep at which the run, and the run at every smaller step of the sweep, completes "
          "without a failed step and without an edge stretched beyond 50 % (0: not even the smallest step). "
          "h* in contact: the same, counting only runs in which the rod touched the wall (at least one step with a "
          "contact): at large steps the whip may never reach the wall, and a run without contact says nothing about "
          "the contact response.\n"]
    ratios = {}
    for label, h in (("h* in contact", hstar_contact), ("h*", hstar)):
        if not any(h.values()) or not any(h[c] for c in combos):
            continue
        md.append("| {} | speed [rad/s] | ".format(label) + " | ".join(LABELS.get(c, c) for c in combos) +
                  " | ADONIS / impulse | ADONIS / linear |")
        md.append("|---|---|" + "---:|" * (len(combos) + 2))
        for v in speeds:
            a, i, l = (h.get(k, {}).get(v) for k in ("rods_adonis", "rods_impulse", "rods_linear"))
            ri = a / i if a and i else None
            rl = a / l if a and l else None
            ratios.setdefault(label, {})[v] = {"adonis_over_impulse": ri, "adonis_over_linear": rl}
            md.append("| {} | {} | {} | {} | {} |".format(label, v, " | ".join(fmt_dt(h[c][v]) if h[c][v] > 0 else "0" for c in combos),
                                                         "{:g}".format(ri) if ri else "-", "{:g}".format(rl) if rl else "-"))
        md.append("")
    md.append("Largest step of the sweep: {}; a ratio at that bound is a lower bound.\n".format(fmt_dt(dts[-1])))
    if contacts:
        md.append("Steps with a contact in each stable run ({:g} s simulated; `-` failed run):\n".format(
            int(rows[0]["steps_planned"]) * float(rows[0]["dt"])))
        md.append("| method | speed | " + " | ".join(fmt_dt(dt) for dt in reversed(dts)) + " |")
        md.append("|---|---|" + "---:|" * len(dts))
        for c in combos:
            for v in speeds:
                md.append("| {} | {} | {} |".format(LABELS.get(c, c), v, " | ".join(
                    str(contacts[(c, v, dt)]) if (c, v, dt) in contacts else "-" for dt in reversed(dts))))
        md.append("")
    strain = {c: {v: {} for v in speeds} for c in combos}
    for r in rows:
        strain[r["combo"]][r["value"]][r["dt"]] = float(r["max_strain"])
    top = speeds[-1]
    md.append("Largest edge strain |l/l0 - 1| of each run at {} rad/s, in % (a run stops at the first step above 50 %; "
              "N: the step's Newton solve failed first):\n".format(top))
    md.append("| dt | " + " | ".join(LABELS.get(c, c) for c in combos) + " |")
    md.append("|---|" + "---:|" * len(combos))
    for dt in reversed(dts):
        cells_md = []
        for c in combos:
            key = next((k for k in strain[c][top] if float(k) == dt), None)
            if key is None:
                cells_md.append("-")
            elif outcome[(c, top, dt)] == "not_converged":
                cells_md.append("N")
            else:
                cells_md.append("{:.3g}".format(100 * strain[c][top][key]))
        md.append("| {} | {} |".format(fmt_dt(dt), " | ".join(cells_md)))
    md.append("")
    md.append("## Stability maps\n\n```\n{}\n```\n".format(map_text(out)))
    md.append("## Failed runs\n\n| method | speed | dt | outcome | steps | max strain | message |\n|---|---|---|---|---|---:|---|")
    for r in failures:
        md.append("| {} | {} | {} | {} | {}/{} | {:.3g} | {} |".format(LABELS.get(r["combo"], r["combo"]), r["value"],
                                                                     fmt_dt(float(r["dt"])), r["outcome"], r["steps"],
                                                                     r["steps_planned"], float(r["max_strain"]),
                                                                     r["message"].replace("|", "/")))
    wall = sum(float(r["wall_seconds"]) for r in rows)
    md.append("\n{} runs, {:.0f} s of wall time in the runs. Plot: stability_map.{{png,svg}}.\n".format(len(rows), wall))
    wp, wp_md = work_precision(out)
    md += wp_md
    doc = {"work_precision": wp, "experiment": "contact", "hstar": hstar, "hstar_contact": hstar_contact, "cells": cells, "ratios": ratios,
           "max_strain": strain, "contacts": {"{} {} {}".format(*k): n for k, n in contacts.items()},
           "dts": dts, "speeds": speeds, "wall_seconds": wall}
    write(out, "\n".join(md), doc)


def main(argv):
    if len(argv) != 3 or argv[1] not in ("integrators", "linear", "contact"):
        sys.stderr.write(__doc__)
        return 2
    try:
        {"integrators": integrators, "linear": linear, "contact": contact}[argv[1]](argv[2])
    except InputError as e:
        sys.stderr.write("tour_summary: {}\n".format(e))
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
