#!/usr/bin/env python3
"""`mpirun -n 2 weft run` against `weft run`: a cloth simulation whose Newton systems PETSc
solves across two ranks writes, from rank 0 alone, the frames of the one-process run within
the linear tolerance; a solver that runs on one process is refused under mpirun.

Usage: mpirun_weft.py MPIEXEC NUMPROC_FLAG WEFT SOURCE_DIR (CTest passes them).
"""
import glob
import json
import os
import subprocess
import sys
import tempfile


def obj_vertices(path):
    with open(path) as f:
        return [tuple(float(c) for c in line.split()[1:4]) for line in f if line.startswith("v ")]


def run(cmd, env):
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    return r.returncode, r.stdout + r.stderr


def main():
    mpiexec, np_flag, weft, source = sys.argv[1:5]
    scene = os.path.join(source, "scenes", "hanging_cloth.json")
    common = ["cloths.0.mesh.resolution=[15,15]", "time.duration=0.1", "output.vtp=false", "-q"]
    failures = []

    def check(ok, what):
        print(("ok      " if ok else "FAILED  ") + what)
        if not ok:
            failures.append(what)

    with tempfile.TemporaryDirectory(prefix="weft_mpirun_") as tmp:
        env = dict(os.environ, TMPDIR=tmp)
        one, two, refused = (os.path.join(tmp, d) for d in ("one", "two", "refused"))
        code, out = run([weft, "run", scene, "linear.solver=petsc_gamg", *common, "-o", one], env)
        check(code == 0, f"one process runs (exit {code}): {out[-400:]}")
        code, out = run([mpiexec, np_flag, "2", weft, "run", scene, "linear.solver=petsc_gamg", *common, "-o", two], env)
        check(code == 0, f"two ranks run (exit {code}): {out[-400:]}")
        if failures:
            return 1
        s1 = json.load(open(os.path.join(one, "summary.json")))
        s2 = json.load(open(os.path.join(two, "summary.json")))
        check(s1["ranks"] == 1 and s2["ranks"] == 2, f"the summaries say 1 and 2 ranks ({s1['ranks']}, {s2['ranks']})")
        check(s1["combo"] == s2["combo"] == "cloth_ip_petsc_gamg", f"both ran cloth_ip_petsc_gamg ({s2['combo']})")
        check(s1["status"] == s2["status"] == "completed" and s1["steps"] == s2["steps"] > 0,
              f"both completed the same {s1['steps']} steps")
        frames1 = sorted(os.path.basename(p) for p in glob.glob(os.path.join(one, "*.obj")))
        frames2 = sorted(os.path.basename(p) for p in glob.glob(os.path.join(two, "*.obj")))
        check(len(frames1) >= 2 and frames1 == frames2, f"the same frames ({len(frames1)} and {len(frames2)})")
        first = obj_vertices(os.path.join(one, frames1[0]))
        a = obj_vertices(os.path.join(one, frames1[-1]))
        b = obj_vertices(os.path.join(two, frames2[-1]))
        motion = max(abs(p - q) for u, v in zip(a, first) for p, q in zip(u, v))
        diff = max(abs(p - q) for u, v in zip(a, b) for p, q in zip(u, v))
        print(f"        last frame {frames1[-1]}: motion {motion:.3e} m, two ranks against one {diff:.3e} m")
        check(motion > 1e-2, "the cloth moved (the comparison says something)")
        check(len(a) == len(b) and diff <= 1e-3 * motion, "two ranks end within 1e-3 of the motion of one")
        check(not glob.glob(os.path.join(tmp, "weft_rank*")), "the other rank left nothing behind")
        # A solver that runs on one process is refused before anything is written.
        code, out = run([mpiexec, np_flag, "2", weft, "run", scene, *common, "-o", refused], env)
        check(code != 0 and "linear.solver = petsc_gamg" in out, f"sa_ppcg under mpirun is refused (exit {code})")
        check(not os.path.exists(refused), "the refused run wrote nothing")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
