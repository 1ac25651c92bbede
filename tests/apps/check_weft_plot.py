"""Checks scripts/weft_plot.py: every plot kind writes a real PNG and a parseable SVG, the
Pareto front is the set of non-dominated points, and bad input names the file, row and
column with exit status 2.

Run with Debian's system interpreter; exits 77 (CTest: skipped) when python3-matplotlib is
not installed. Usage: check_weft_plot.py SOURCE_DIR OUT_DIR
"""
import importlib.util
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

try:
    import matplotlib  # noqa: F401
except ImportError:
    print("python3-matplotlib is not installed: skipping (apt-get install python3-matplotlib to enable)")
    sys.exit(77)

src, out = sys.argv[1:3]
script = os.path.join(src, "scripts", "weft_plot.py")
os.makedirs(out, exist_ok=True)


def run(*args):
    return subprocess.run([sys.executable, script, *args], capture_output=True, text=True)


def check_images(stem):
    png = os.path.join(out, stem + ".png")
    with open(png, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n", png
    assert os.path.getsize(png) > 2000, png  # not an empty canvas
    root = ET.parse(os.path.join(out, stem + ".svg")).getroot()
    assert root.tag.endswith("svg"), root.tag


stab = os.path.join(out, "stability.csv")
with open(stab, "w") as f:
    f.write("combo,dt,key,value,outcome,steps,steps_planned,max_strain,energy_change,newton_mean,newton_max,wall_seconds,message\n")
    for combo, outcomes in (("rods_adonis", ["stable", "stable", "stable", "not_converged"]),
                            ("rods_linear", ["stable", "diverged", "excessive_strain", "excessive_strain"])):
        for (dt, value), o in zip([(0.001, 5), (0.001, 20), (0.01, 5), (0.01, 20)], outcomes):
            f.write('{},{},rods.0.motion.angular_velocity,"{}",{},1,1,0,0,1,1,1,""\n'.format(combo, dt, value, o))
r = run("stability", stab, "--out", out)
assert r.returncode == 0, r.stderr
check_images("stability_map")

ab = os.path.join(out, "ablate.csv")
with open(ab, "w") as f:
    f.write("combo,wall_seconds,rms_error,seconds_energy,seconds_linear_solve\n"
            "reference,10,0,2,8\nfast,1,0.1,0.5,0.5\nbalanced,2,0.01,1,1\ndominated,3,0.05,1,2\n")
r = run("pareto", ab, "--out", out)
assert r.returncode == 0, r.stderr
check_images("pareto")
r = run("stages", ab, "--out", out)
assert r.returncode == 0, r.stderr
check_images("stages")

val = os.path.join(out, "validate.csv")
with open(val, "w") as f:
    f.write("problem,quantity,unit,reference,measured,error,tolerance,error_kind,result,status,steps,seconds,source\n"
            "cantilever/theta,tip drop,m,0.416,0.42,0.01,0.05,relative,pass,ok,80,1.0,elastica\n"
            "incline/stick,slide distance,m,0,0.002,0.002,0.001,absolute,fail,ok,240,0.5,Coulomb\n"
            "membrane/uniaxial,contraction,-,0.068,0,0,0.02,relative,fail,failed at step 3 (solve): x,3,0.1,StVK\n")
r = run("validate", val, "--out", out)
assert r.returncode == 0, r.stderr
check_images("validate")

hist = os.path.join(out, "histories.jsonl")
with open(hist, "w") as f:
    f.write('{"label": "a", "residuals": [1, 0.1, 0.001]}\n{"label": "b", "residuals": [1, 0.5, 0.2, 0.01]}\n')
r = run("histories", hist, "--out", out)
assert r.returncode == 0, r.stderr
check_images("histories")

# The Pareto front: 'dominated' is slower and less accurate than 'balanced'.
spec = importlib.util.spec_from_file_location("weft_plot", script)
wp = importlib.util.module_from_spec(spec)
spec.loader.exec_module(wp)
assert wp.pareto_front([(1, 0.1), (2, 0.01), (3, 0.05)]) == [0, 1]
assert wp.pareto_front([(1, 1), (1, 1)]) == [0, 1]  # ties dominate nothing

# Bad input: the file, the row and the column are named; status 2; nothing written.
bad = os.path.join(out, "bad.csv")
with open(bad, "w") as f:
    f.write("combo,dt,key,value,outcome\nx,0.01,k,1,exploded\n")
r = run("stability", bad, "--out", os.path.join(out, "bad"))
assert r.returncode == 2 and "row 2" in r.stderr and "'outcome'" in r.stderr and "exploded" in r.stderr, r.stderr
assert not os.path.exists(os.path.join(out, "bad"))
with open(bad, "w") as f:
    f.write("combo,wall_seconds,rms_error\nx,-1,0.1\n")
r = run("pareto", bad, "--out", os.path.join(out, "bad"))
assert r.returncode == 2 and "'wall_seconds'" in r.stderr and "> 0" in r.stderr, r.stderr
print("weft_plot: all plot kinds written and checked")
