#!/usr/bin/python3
"""weft's plots: PNG and SVG from matplotlib (Debian's python3-matplotlib).

Run with the system interpreter (/usr/bin/python3): Debian's matplotlib lives in
/usr/lib/python3/dist-packages, which a pyenv or virtualenv python does not see.

  weft_plot.py stability CSV [--out DIR] [--title T]
      stability map from `weft stability`'s stability.csv: one panel per combination, the
      time step down (log), the varied scene value across; cells coloured by outcome
      (stable, diverged, not converged, excessive strain, invalid).
  weft_plot.py pareto CSV [--out DIR] [--x COL] [--y COL] [--label COL] [--point COL]
      the work-precision diagram: error against run time (log-log), one curve per label
      through its rows (the sweep points, their values beside them; a legend names the
      curves), and the Pareto front over every point (no other is both faster and more accurate).
  weft_plot.py stages CSV [--out DIR] [--label COL] [--prefix P]
      time per stage: one stacked bar per row from the columns named P<stage>.
  weft_plot.py validate CSV [--out DIR]
      `weft validate`'s validate.csv: one bar per problem, its error over its tolerance
      (green: pass, red: missed), the pass line at 1.
  weft_plot.py histories JSONL [--out DIR] [--key K] [--label COL]
      convergence histories: one line per JSON record, the list under K (log y).
  weft_plot.py scaling CSV --x COL --y COL[,COL...] --group COL [--out DIR] [--title T]
      growth with problem size (log-log): one panel per y column, one line per value of the
      group column (e.g. iterations and time per solve against vertices, per linear solver).

Exit status: 0 with the files written, 3 when matplotlib is missing (the message says how to
install it), 2 on bad input (the message names the file, the row and the column).
"""
import argparse
import csv
import json
import math
import os
import sys

OUTCOMES = [  # (csv value, legend, colour, map symbol of stability_map.txt)
    ("stable", "stable", "#4daf4a", "."),
    ("stable_no_contact", "stable, never in contact", "#b8e186", "o"),
    ("diverged", "diverged", "#e41a1c", "D"),
    ("not_converged", "not converged", "#ff7f00", "N"),
    ("excessive_strain", "excessive strain", "#984ea3", "S"),
    ("invalid", "invalid", "#999999", "?"),
]


class InputError(Exception):
    pass


def load_pyplot():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        return plt
    except ImportError:
        sys.stderr.write("weft_plot: matplotlib is not available to {} - install Debian's python3-matplotlib "
                         "(apt-get install python3-matplotlib) and run with /usr/bin/python3; no plot written\n"
                         .format(sys.executable))
        sys.exit(3)


def read_csv(path, required):
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise InputError("{}: {}".format(path, e.strerror))
    if not rows:
        raise InputError("{}: no rows".format(path))
    missing = [c for c in required if c not in rows[0]]
    if missing:
        raise InputError("{}: missing column(s) {} (has: {})".format(path, ", ".join(missing), ", ".join(rows[0].keys())))
    return rows


def number(path, i, row, col, positive=False):
    try:
        v = float(row[col])
    except (TypeError, ValueError):
        raise InputError("{}: row {}: column '{}' = '{}' is not a number".format(path, i + 2, col, row[col]))
    if positive and not v > 0:
        raise InputError("{}: row {}: column '{}' = {} must be > 0 (log axis)".format(path, i + 2, col, v))
    return v


def save(fig, out, stem):
    os.makedirs(out, exist_ok=True)
    written = []
    for ext in ("png", "svg"):
        p = os.path.join(out, "{}.{}".format(stem, ext))
        fig.savefig(p, dpi=150, bbox_inches="tight")
        written.append(p)
    print("\n".join(written))


def sort_key(v):
    try:
        return (0, float(v), v)
    except ValueError:
        return (1, 0.0, v)


def plot_stability(args):
    rows = read_csv(args.csv, ["combo", "dt", "value", "outcome"])
    known = {o[0]: k for k, o in enumerate(OUTCOMES)}
    for i, r in enumerate(rows):
        number(args.csv, i, r, "dt", positive=True)
        if r["outcome"] not in known:
            raise InputError("{}: row {}: column 'outcome' = '{}' is not one of {}".format(
                args.csv, i + 2, r["outcome"], ", ".join(known)))
    # A stable run that never touched anything, when other runs did (column contact_steps,
    # written by weft stability): it did not test the contact method.
    if any(float(r.get("contact_steps") or 0) > 0 for r in rows):
        for r in rows:
            if r["outcome"] == "stable" and float(r.get("contact_steps") or 0) == 0:
                r["outcome"] = "stable_no_contact"
    plt = load_pyplot()
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    combos = list(dict.fromkeys(r["combo"] or "(scene's)" for r in rows))
    dts = sorted({float(r["dt"]) for r in rows})
    values = sorted({r["value"] for r in rows}, key=sort_key)
    key = rows[0].get("key", "") or ""
    fig, axes = plt.subplots(1, len(combos), figsize=(max(3.2, 0.45 * len(values) + 1.8) * len(combos), 0.32 * len(dts) + 1.8),
                             squeeze=False, sharey=True)
    cmap = ListedColormap([o[2] for o in OUTCOMES])
    for ax, combo in zip(axes[0], combos):
        grid = [[math.nan] * len(values) for _ in dts]
        for r in rows:
            if (r["combo"] or "(scene's)") != combo:
                continue
            grid[dts.index(float(r["dt"]))][values.index(r["value"])] = known[r["outcome"]]
        masked = [[c if c == c else -1 for c in line] for line in grid]
        import numpy as np
        data = np.ma.masked_less(np.array(masked, dtype=float), 0)
        ax.imshow(data, cmap=cmap, vmin=-0.5, vmax=len(OUTCOMES) - 0.5, aspect="auto", origin="lower", interpolation="nearest")
        ax.set_xticks(range(len(values)))
        ax.set_xticklabels(values if key else [""] * len(values), rotation=45, ha="right")
        ax.set_yticks(range(len(dts)))
        ax.set_yticklabels(["{:.3g}".format(d) for d in dts])
        ax.set_title(combo)
        ax.set_xlabel(key if key else "")
        ax.set_xticks([x - 0.5 for x in range(1, len(values))], minor=True)
        ax.set_yticks([y - 0.5 for y in range(1, len(dts))], minor=True)
        ax.grid(which="minor", color="white", linewidth=1)
        ax.tick_params(which="minor", length=0)
    axes[0][0].set_ylabel("time step [s]")
    present = sorted({known[r["outcome"]] for r in rows})
    fig.legend(handles=[Patch(color=OUTCOMES[k][2], label=OUTCOMES[k][1]) for k in present], loc="lower center",
               ncol=len(present), bbox_to_anchor=(0.5, -0.02 - 0.03 * (len(present) > 3)))
    if args.title:
        fig.suptitle(args.title)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    save(fig, args.out, "stability_map")


def pareto_front(points):
    """Indices of the points that no other point beats in both coordinates (smaller is better)."""
    front = []
    for i, (x, y) in enumerate(points):
        if not any((xo <= x and yo <= y) and (xo < x or yo < y) for j, (xo, yo) in enumerate(points) if j != i):
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def short_number(text):
    """A sweep value as written in a plot: 0.010416666666666666 -> 0.01042; other text unchanged."""
    try:
        return "{:.4g}".format(float(text))
    except ValueError:
        return text


def place_labels(fig, ax, labels):
    """Direct labels of points that do not overlap: each label tries a few offsets around its
    point and is left out (the legend and the CSV still name the point) when all of them would
    cover a label already placed."""
    fig.canvas.draw()
    to_px = ax.transData.transform
    placed = []  # boxes in pixels: (x0, y0, x1, y1)
    offsets = [(4, -10), (4, 4), (-4, 4), (-4, -10), (4, -20), (4, 14)]
    scale = fig.dpi / 72.0
    for x, y, text, colour in labels:
        px, py = to_px((x, y))
        w, h = 6 * 0.6 * len(text) * scale, 7 * scale  # 6 pt text
        for dx, dy in offsets:
            x0 = px + dx * scale - (w if dx < 0 else 0)
            y0 = py + dy * scale
            box = (x0, y0, x0 + w, y0 + h)
            if all(box[2] < b[0] or box[0] > b[2] or box[3] < b[1] or box[1] > b[3] for b in placed):
                placed.append(box)
                ax.annotate(text, (x, y), textcoords="offset points", xytext=(dx, dy), fontsize=6, color=colour,
                            ha="right" if dx < 0 else "left")
                break


def plot_pareto(args):
    rows = read_csv(args.csv, [args.x, args.y, args.label])
    groups, skipped, failed = {}, [], []  # label -> [(x, y, point)], in the order met
    for i, r in enumerate(rows):
        name = r[args.label] + (" " + r[args.point] if r.get(args.point) else "")
        if r.get("status", "ok") != "ok":  # a failed run's partial error would flatter it
            failed.append(name)
            continue
        x = number(args.csv, i, r, args.x, positive=True)
        y = number(args.csv, i, r, args.y)
        if y <= 0:  # the reference itself (zero error) has no place on a log axis
            skipped.append(name)
            continue
        groups.setdefault(r[args.label], []).append((x, y, r.get(args.point, "")))
    if not groups:
        raise InputError("{}: no row with {} > 0".format(args.csv, args.y))
    pts = [(x, y) for g in groups.values() for x, y, _ in g]
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.8))
    # One curve per label through its points in order of run time; a legend names the curves
    # and each point carries only its sweep value, so no label lands on another's name.
    markers = "osD^v<>phX*"
    cmap = plt.get_cmap("tab10" if len(groups) <= 10 else "tab20")
    labels = []  # (x, y, text, colour): placed after the axes' limits are known
    for k, (name, g) in enumerate(groups.items()):
        g = sorted(g)
        ax.plot([p[0] for p in g], [p[1] for p in g], marker=markers[k % len(markers)], color=cmap(k % cmap.N), lw=1.2,
                ms=5, zorder=3, label=name)
        if len(g) > 1:
            labels += [(x, y, " ".join(short_number(v.split("=", 1)[-1]) for v in point.split()), cmap(k % cmap.N))
                       for x, y, point in g]
    front = pareto_front(pts)
    # Wide and pale under the curves, so that it stays visible where it follows one of them.
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "-", color="black", lw=5, alpha=0.18, zorder=1,
            solid_capstyle="round", label="Pareto front")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(args.x)
    ax.set_ylabel(args.y)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    place_labels(fig, ax, labels)
    notes = []
    keys = sorted({v.split("=", 1)[0] for g in groups.values() for _, _, p in g for v in p.split()})
    if keys:
        notes.append("swept: " + ", ".join(keys))
    if skipped:
        notes.append("not shown (zero error): " + ", ".join(skipped))
    if failed:
        notes.append("failed: " + ", ".join(failed))
    if notes:
        ax.set_title("\n".join(notes), fontsize=8)
    save(fig, args.out, "pareto")


def plot_stages(args):
    rows = read_csv(args.csv, [args.label])
    stages = [c for c in rows[0].keys() if c.startswith(args.prefix)]
    if not stages:
        raise InputError("{}: no column starts with '{}'".format(args.csv, args.prefix))
    values = [[number(args.csv, i, r, s) for s in stages] for i, r in enumerate(rows)]
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(max(6.4, 0.8 * len(rows) + 2), 4.8))
    bottom = [0.0] * len(rows)
    for k, s in enumerate(stages):
        col = [v[k] for v in values]
        ax.bar(range(len(rows)), col, bottom=bottom, label=s[len(args.prefix):])
        bottom = [b + c for b, c in zip(bottom, col)]
    ax.set_xticks(range(len(rows)))
    ax.set_xticklabels([r[args.label] for r in rows], rotation=30, ha="right")
    ax.set_ylabel("wall time [s]")
    ax.legend(fontsize=8)
    save(fig, args.out, "stages")


def plot_validate(args):
    rows = read_csv(args.csv, ["problem", "error", "tolerance", "result"])
    ratios = []
    for i, r in enumerate(rows):
        tol = number(args.csv, i, r, "tolerance", positive=True)
        ratios.append(number(args.csv, i, r, "error") / tol if r.get("status", "ok") == "ok" else float("nan"))
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 0.32 * len(rows) + 1.4))
    y = list(range(len(rows)))[::-1]
    colours = ["tab:green" if r["result"] == "pass" else "tab:red" for r in rows]
    ax.barh(y, [v if v == v else 0 for v in ratios], color=colours)
    for yi, v in zip(y, ratios):
        if v != v:
            ax.text(0.02, yi, "run failed", va="center", fontsize=8, color="tab:red")
    ax.axvline(1.0, color="black", lw=1, ls="--")
    ax.set_yticks(y)
    ax.set_yticklabels([r["problem"] for r in rows], fontsize=8)
    ax.set_xlabel("error / tolerance (pass below 1)")
    save(fig, args.out, "validate")


def plot_histories(args):
    records = []
    try:
        with open(args.jsonl) as f:
            for n, line in enumerate(f, 1):
                if line.strip():
                    try:
                        records.append(json.loads(line))
                    except json.JSONDecodeError as e:
                        raise InputError("{}: line {}: {}".format(args.jsonl, n, e))
    except OSError as e:
        raise InputError("{}: {}".format(args.jsonl, e.strerror))
    series = [(r.get(args.label, str(i)), r[args.key]) for i, r in enumerate(records) if isinstance(r.get(args.key), list) and r[args.key]]
    if not series:
        raise InputError("{}: no record has a non-empty list under '{}'".format(args.jsonl, args.key))
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for name, hist in series:
        ax.semilogy(range(len(hist)), [max(abs(float(h)), 1e-300) for h in hist], label=str(name))
    ax.set_xlabel("iteration")
    ax.set_ylabel(args.key)
    ax.grid(True, which="both", alpha=0.3)
    if len(series) <= 12:
        ax.legend(fontsize=8)
    save(fig, args.out, "histories")


def plot_scaling(args):
    ys = [c for c in args.y.split(",") if c]
    rows = read_csv(args.csv, [args.x, args.group] + ys)
    groups = list(dict.fromkeys(r[args.group] for r in rows))
    data = {g: [] for g in groups}
    for i, r in enumerate(rows):
        data[r[args.group]].append([number(args.csv, i, r, args.x, positive=True)] +
                                   [number(args.csv, i, r, c, positive=True) for c in ys])
    plt = load_pyplot()
    fig, axes = plt.subplots(1, len(ys), figsize=(5.2 * len(ys), 4.2), squeeze=False)
    for k, (ax, col) in enumerate(zip(axes[0], ys)):
        for g in groups:
            pts = sorted(data[g])
            ax.loglog([p[0] for p in pts], [p[k + 1] for p in pts], "o-", label=g)
        ax.set_xlabel(args.x)
        ax.set_ylabel(col)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    if args.title:
        fig.suptitle(args.title)
    fig.tight_layout()
    save(fig, args.out, "scaling")


def main(argv=None):
    p = argparse.ArgumentParser(prog="weft_plot.py", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    # kind, help, plot function, input argument, options: a default or add_argument's keywords
    kinds = [
        ("stability", "stability map from stability.csv", plot_stability, "csv", {"title": ""}),
        ("pareto", "error against run time, one curve per label through its sweep points, with the Pareto front", plot_pareto, "csv",
         {"x": "wall_seconds", "y": "rms_error", "label": "combo", "point": "point"}),
        ("stages", "time per stage, stacked", plot_stages, "csv", {"label": "combo", "prefix": "seconds_"}),
        ("validate", "each problem's error against its tolerance, from validate.csv", plot_validate, "csv", {}),
        ("histories", "convergence histories", plot_histories, "jsonl", {"key": "residuals", "label": "label"}),
        ("scaling", "growth with problem size, one line per group (log-log)", plot_scaling, "csv",
         {"x": {"required": True},
          "y": {"required": True, "help": "one column or several, comma-separated (one panel each)"},
          "group": {"required": True}, "title": ""}),
    ]
    for name, text, fn, inp, options in kinds:
        s = sub.add_parser(name, help=text)
        s.add_argument(inp)
        s.add_argument("--out", default=".")
        for key, spec in options.items():
            s.add_argument("--" + key, **(spec if isinstance(spec, dict) else {"default": spec}))
        s.set_defaults(fn=fn)
    args = p.parse_args(argv)
    try:
        args.fn(args)
    except InputError as e:
        sys.stderr.write("weft_plot: {}\n".format(e))
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
