#!/usr/bin/env python3
"""Merges the runs of bench/rods/figure_9_2.sh (OUT/runs/*/stability.csv) into
OUT/stability.csv, OUT/stability_map.txt and OUT/summary.md: the stability map per method
(time step down, whipping speed across), the largest stable time step per method and speed,
the ADONIS/linear and ADONIS/impulse ratios, and the thesis result alongside.

Largest stable step h*: the largest h of the sweep such that h and every smaller step that
was run are stable (a run above a failure that happens to be stable, e.g. because its
large steps damp the whip so much that it never reaches the wall, does not count; such
cells are listed). With the contact_steps column of weft stability, a second table counts
only runs that touched the wall (h* in contact): at large steps the whip lags so far behind
the handle that it never reaches the wall, and such a run says nothing about the contact
response (map symbol o). Usage: figure_9_2.py OUT"""
import csv
import glob
import os
import sys

SYMBOL = {"stable": ".", "diverged": "D", "not_converged": "N", "excessive_strain": "S", "invalid": "?"}
NAMES = {"rods_impulse": "impulse", "rods_linear": "linear compliance", "rods_adonis": "ADONIS"}
THESIS = ("Thesis (§9.1, Figure 9.2; methods/rod-contact §14.1): about two orders of magnitude larger maximum "
          "stable time step for ADONIS; the stability regions of linear compliance and impulses largely "
          "overlap (for small-bend collisions linear compliance behaves like an unfiltered impulse). "
          "Success: 5 s simulated with axial extension never above 50 %. Sweep 5 us - 100 ms.")


def main(out):
    rows = {}
    for path in sorted(glob.glob(os.path.join(out, "runs", "*", "stability.csv"))):
        with open(path) as f:
            for r in csv.DictReader(f):
                rows[(r["combo"], float(r["value"]), float(r["dt"]))] = r
    if not rows:
        print(f"no runs under {out}/runs yet")
        return 1
    combos = [c for c in NAMES if any(k[0] == c for k in rows)]
    speeds = sorted({k[1] for k in rows})
    dts = sorted({k[2] for k in rows}, reverse=True)
    fields = ["combo", "dt", "key", "value", "outcome", "steps", "steps_planned", "max_strain", "energy_change",
              "newton_mean", "newton_max", "wall_seconds", "contact_steps", "message"]
    has_contacts = all("contact_steps" in r and r["contact_steps"] != "" for r in rows.values())

    def symbol(r):
        if has_contacts and r["outcome"] == "stable" and int(r["contact_steps"]) == 0:
            return "o"
        return SYMBOL.get(r["outcome"], "?")
    with open(os.path.join(out, "stability.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for k in sorted(rows, key=lambda k: (combos.index(k[0]), k[1], -k[2])):
            w.writerow(rows[k])

    def fmt_dt(h):
        return f"{h * 1e3:g} ms" if h >= 1e-3 else f"{h * 1e6:g} us"

    lines = []
    for c in combos:
        lines.append(f"{NAMES[c]} ({c})  . stable, " + ("o stable but never in contact, " if has_contacts else "") +
                     "D diverged, N not converged, S excessive strain, - not run")
        lines.append(f"{'dt':>10} | " + " ".join(f"{s:>5g}" for s in speeds) + "   rad/s")
        for h in dts:
            cells = [symbol(rows[(c, s, h)]) if (c, s, h) in rows else "-" for s in speeds]
            lines.append(f"{fmt_dt(h):>10} | " + " ".join(f"{x:>5}" for x in cells))
        lines.append("")
    map_text = "\n".join(lines)
    with open(os.path.join(out, "stability_map.txt"), "w") as f:
        f.write(map_text)

    hstar, notes, complete, hstar_contact = {}, [], {}, {}
    for c in combos:
        for s in speeds:
            run = [h for h in sorted(dts) if (c, s, h) in rows]
            best, failed_below = None, False
            for h in run:  # ascending
                ok = rows[(c, s, h)]["outcome"] == "stable"
                if ok and not failed_below:
                    best = h
                if not ok:
                    failed_below = True
                elif failed_below:
                    notes.append(f"{NAMES[c]} at {s:g} rad/s: stable at {fmt_dt(h)} above a failure at a smaller step "
                                 f"(max strain {float(rows[(c, s, h)]['max_strain']):.3g})")
            hstar[(c, s)] = best
            complete[(c, s)] = len(run) == len(dts) and not failed_below
            if has_contacts:  # the largest h* cell that also touched the wall
                inside = [h for h in run if best is not None and h <= best and int(rows[(c, s, h)]["contact_steps"]) > 0]
                hstar_contact[(c, s)] = max(inside) if inside else None
    info = ""
    p = os.path.join(out, "sweep_info.txt")
    if os.path.exists(p):
        info = open(p).read()
    md = ["# Figure 9.2: whip-it stability sweep", "", THESIS, "", "## This run", "", "```", info.strip(), "```", "",
          "## Stability maps", "", "```", map_text, "```", "",
          "## Largest stable time step h* (every smaller step run is stable too)", "",
          "| speed [rad/s] | " + " | ".join(NAMES[c] for c in combos) + " | ADONIS / linear | ADONIS / impulse |",
          "|---|" + "---|" * (len(combos) + 2)]
    largest = max(dts)
    for s in speeds:
        cells = []
        for c in combos:
            h = hstar[(c, s)]
            cell = "none" if h is None else fmt_dt(h)
            if h is not None and h == largest:
                cell += " (whole sweep)"
            cells.append(cell)
        ratios = []
        for base in ("rods_linear", "rods_impulse"):
            a, b = hstar.get(("rods_adonis", s)), hstar.get((base, s))
            if a is None or b is None:
                ratios.append("n/a")
            else:
                r = a / b
                ratios.append(f">= {r:g}" if a == largest else f"{r:g}")
        md.append(f"| {s:g} | " + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
    md += ["", "A ratio written >= is a lower bound: ADONIS was stable up to the largest step of the sweep.", ""]
    if has_contacts:
        md += ["## h* in contact: counting only runs that touched the wall", "",
               "| speed [rad/s] | " + " | ".join(NAMES[c] for c in combos) + " | ADONIS / linear | ADONIS / impulse |",
               "|---|" + "---|" * (len(combos) + 2)]
        for s in speeds:
            cells = ["none" if hstar_contact.get((c, s)) is None else fmt_dt(hstar_contact[(c, s)]) for c in combos]
            ratios = []
            for base in ("rods_linear", "rods_impulse"):
                a, b = hstar_contact.get(("rods_adonis", s)), hstar_contact.get((base, s))
                ratios.append("n/a" if a is None or b is None else f"{a / b:g}")
            md.append(f"| {s:g} | " + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
        md.append("")
    if notes:
        md += ["## Stable cells above a failure (not counted in h*)", ""] + [f"- {n}" for n in notes] + [""]
    missing = [(c, s, h) for c in combos for s in speeds for h in dts if (c, s, h) not in rows]
    if missing:
        md += [f"## Not run (yet): {len(missing)} cells", "",
               "h* above assumes the missing smaller steps are stable; re-run figure_9_2.py when the sweep ends.", ""]
    fails = [r for r in rows.values() if r["outcome"] != "stable"]
    if fails:
        md += ["## Failures", "", "| method | speed | dt | outcome | steps | message |", "|---|---|---|---|---|---|"]
        for r in sorted(fails, key=lambda r: (r["combo"], float(r["value"]), -float(r["dt"]))):
            md.append(f"| {NAMES.get(r['combo'], r['combo'])} | {float(r['value']):g} | {fmt_dt(float(r['dt']))} | "
                      f"{r['outcome']} | {r['steps']}/{r['steps_planned']} | {r['message'][:160]} |")
        md.append("")
    total = sum(float(r["wall_seconds"]) for r in rows.values())
    md += [f"{len(rows)} runs, {total:.0f} s of wall time in the runs.", ""]
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "bench/results/rods/figure_9_2"))
