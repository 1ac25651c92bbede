"""The tour's experiments (docs/tour/*.md) in quick mode: runs scripts/tour/EXPERIMENT.sh --quick
with the weft binary under test and asserts what each page claims on the numbers it wrote
(summary.json), then that the plots exist.

  test_tour.py WEFT SOURCE_DIR OUT_DIR integrators|linear|contact

Exit status: 0 when every check passes; 1 on a failed check; 77 (CTest: skipped) when the
numbers pass but the plots could not be checked because Debian's python3-matplotlib is not
installed (the scripts then skip their plots with a message).
"""
import json
import os
import subprocess
import sys
import time

weft, src, out, which = sys.argv[1:5]
script = {"integrators": "integrators.sh", "linear": "linear_solvers.sh", "contact": "contact.sh"}[which]
try:
    import matplotlib  # noqa: F401
    have_matplotlib = True
except ImportError:
    have_matplotlib = False

failures = []


def check(cond, what):
    print(("ok:     " if cond else "FAILED: ") + what)
    if not cond:
        failures.append(what)


t0 = time.time()
env = dict(os.environ, WEFT=weft)
env.pop("TOUR_QUICK", None)
r = subprocess.run(["bash", os.path.join(src, "scripts", "tour", script), "--quick", out], env=env,
                   capture_output=True, text=True)
print(r.stdout[-4000:])
print(r.stderr[-4000:], file=sys.stderr)
print("{} --quick: exit {} in {:.1f} s".format(script, r.returncode, time.time() - t0))
if r.returncode != 0:
    sys.exit(1)
with open(os.path.join(out, "summary.json")) as f:
    s = json.load(f)
images = []


def check_work_precision(combos, order_range):
    """Every combination swept over dt: error falls at every halving, order within the range."""
    wp = s.get("work_precision", {})
    check(sorted(wp) == sorted(combos), "work-precision diagram of {} ({})".format(", ".join(combos), ", ".join(sorted(wp))))
    for c in combos:
        pts = wp.get(c, {}).get("points", [])
        errs = [p["rms_error"] for p in pts]
        check(len(pts) >= 3 and all(p["ok"] for p in pts), "{}: {} swept runs, all completed".format(c, len(pts)))
        check(all(b < a for a, b in zip(errs, errs[1:])), "{}: the error falls as dt falls ({})".format(
            c, ", ".join("{:.3g}".format(e) for e in errs)))
        order = wp.get(c, {}).get("order")
        check(order is not None and order_range[0] <= order <= order_range[1],
              "{}: error order in dt {} within [{}, {}]".format(c, order, *order_range))
    return wp


if which == "integrators":
    rows = s["first_step"]
    check(len(rows) == 9, "nine first steps: three variants x three time steps ({})".format(len(rows)))
    by = {(r["variant"], r["dt_240"]): r for r in rows}
    for k in (1, 5, 10):
        ip, root, pn = by[("incremental_potential", k)], by[("root_finding", k)], by[("pure_newton", k)]
        check(ip["first_step_converged"], "dt={}/240: incremental potential converges ({} iterations)".format(k, ip["first_step_iterations"]))
        check(pn["first_step_converged"], "dt={}/240: pure Newton converges ({} iterations)".format(k, pn["first_step_iterations"]))
        check(ip["first_step_iterations"] < root["first_step_iterations"],
              "dt={}/240: minimisation needs fewer iterations than root finding ({} < {}{})".format(
                  k, ip["first_step_iterations"], root["first_step_iterations"], "" if root["first_step_converged"] else ", stopped"))
        check(pn["first_step_iterations"] < ip["first_step_iterations"],
              "dt={}/240: pure Newton needs fewer than the globalised minimisation ({} < {})".format(
                  k, pn["first_step_iterations"], ip["first_step_iterations"]))
    check(not by[("root_finding", 10)]["first_step_converged"],
          "dt=10/240: root finding stalls within the quick limit (residual {:.3g} > tolerance {:.3g})".format(
              by[("root_finding", 10)]["final_residual"], by[("root_finding", 10)]["tolerance"]))
    hinge = s["maps"]["hinge_map"]
    ip, root = hinge["cloth_ip_direct"], hinge["cloth_root_direct"]
    check(ip["cells"] == 9 and root["cells"] == 9, "hinge map: 3 x 3 cells per combination")
    check(root["stable"] < ip["stable"], "hinge map: root finding has fewer stable cells than the incremental potential ({} < {})".format(
        root["stable"], ip["stable"]))
    check("cloth_map" not in s["maps"], "--quick leaves out the cloth map")
    with open(os.path.join(out, "histories.jsonl")) as f:
        check(sum(1 for l in f if l.strip()) == 9, "histories.jsonl: one residual history per first step")
    wp = check_work_precision(["cloth_ip_direct", "cloth_root_direct"], (0.7, 1.3))  # backward Euler: first order
    if len(wp) == 2:
        pairs = zip(wp["cloth_ip_direct"]["points"], wp["cloth_root_direct"]["points"])
        check(all(abs(a["rms_error"] - b["rms_error"]) <= 0.01 * a["rms_error"] for a, b in pairs),
              "both integrators solve the same equation: their errors agree within 1 % at every dt")
    images = ["histories", os.path.join("hinge_map", "stability_map"), os.path.join("work_precision", "pareto")]

elif which == "linear":
    d, sa = s["solvers"]["diag_pcg"], s["solvers"]["sa_ppcg"]
    check(d["vertices"] == [441, 1681] and sa["vertices"] == [441, 1681], "two sizes: 441 and 1681 vertices")
    check(d["failures"] == 0 and sa["failures"] == 0, "no failed solve")
    for k, n in enumerate(d["vertices"]):
        check(sa["iterations"][k] < d["iterations"][k], "{} vertices: SA+PPCG needs fewer iterations than Diag-PCG ({} < {})".format(
            n, sa["iterations"][k], d["iterations"][k]))
    check(sa["iteration_growth"] < d["iteration_growth"], "SA+PPCG iterations grow less than Diag-PCG's ({:.2f}x < {:.2f}x)".format(
        sa["iteration_growth"], d["iteration_growth"]))
    check(d["iteration_growth"] > 1.5, "Diag-PCG iterations grow with the mesh ({:.2f}x for 3.8x the vertices)".format(d["iteration_growth"]))
    images = ["scaling"]

else:
    h, hc = s["hstar"], s["hstar_contact"]
    imp, lin, ado = hc["rods_impulse"]["20"], hc["rods_linear"]["20"], hc["rods_adonis"]["20"]
    check(imp > 0, "impulses are stable at the smallest step (h* in contact = {} s): the comparison is not vacuous".format(imp))
    check(ado > imp, "20 rad/s: ADONIS's largest stable step in contact exceeds impulses' ({} s > {} s)".format(ado, imp))
    check(ado > lin, "20 rad/s: ADONIS's largest stable step in contact exceeds linear compliance's ({} s > {} s)".format(ado, lin))
    check(h["rods_adonis"]["20"] >= ado, "h* counting every run is at least h* in contact")
    contacts = s["contacts"]
    check(contacts.get("rods_adonis 20 {}".format(ado), 0) > 0, "ADONIS's run at its h* touched the wall")
    check(contacts.get("rods_adonis 20 0.05", 1) == 0, "at 50 ms the whip never reaches the wall: a stable run without contact (docs/tour/contact.md says so)")
    strain = s["max_strain"]
    adonis_contact = [float(dt) for dt in strain["rods_adonis"]["20"] if contacts.get("rods_adonis 20 {}".format(float(dt)), 0) > 0]
    worst = max(strain["rods_adonis"]["20"][dt] for dt in strain["rods_adonis"]["20"] if float(dt) in adonis_contact)
    check(worst < 0.0101, "ADONIS keeps every edge within its 1 % stretch tolerance in the runs with contact ({:.3g} %)".format(100 * worst))
    check(strain["rods_impulse"]["20"]["0.002"] > 0.5, "impulses overstretch the whip at 2 ms ({:.3g} %)".format(
        100 * strain["rods_impulse"]["20"]["0.002"]))
    wp = check_work_precision(["rods_impulse", "rods_linear", "rods_adonis"], (0.4, 1.5))
    for c, d in wp.items():
        check(all(p["contacts"] > 0 for p in d["points"]), "{}: every swept run touches the wall ({} contacts)".format(
            c, ", ".join(str(p["contacts"]) for p in d["points"])))
    images = ["stability_map", os.path.join("work_precision", "pareto")]

if have_matplotlib:
    for stem in images:
        for ext in ("png", "svg"):
            p = os.path.join(out, stem + "." + ext)
            check(os.path.exists(p) and os.path.getsize(p) > 2000, "plot {} written".format(p))
if failures:
    print("{} check(s) failed".format(len(failures)))
    sys.exit(1)
if not have_matplotlib:
    print("python3-matplotlib is not installed: the numbers pass, the plots were not checked (skipping; "
          "apt-get install python3-matplotlib to enable)")
    sys.exit(77)
