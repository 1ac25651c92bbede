#!/usr/bin/python3
"""weft's renderer: frames of a `weft run` output directory to PNG with POV-Ray, then an
animated GIF or an MP4, alone or side by side with a second run of the same scene.

Run with the system interpreter (/usr/bin/python3): Debian's Pillow lives in
/usr/lib/python3/dist-packages, which a pyenv or virtualenv python does not see.

  weft_render.py RUN_DIR [--out DIR] [--width W] [--height H] [--frames A:B[:N]]
                 [--format gif|mp4|png] [--fps F] [--camera auto|x,y,z] [--look-at x,y,z]
                 [--side-by-side OTHER_RUN_DIR] [--labels A [B]] [--quality low|high] ...

RUN_DIR holds what `weft run` wrote: per frame k the OBJ files <name>_<kkkk>.obj (cloth
meshes, `rods` as polylines, obstacles triangulated per frame), scene.json and summary.json.
scene.json tells cloths, rods and obstacles apart; without it, the file contents do.

Tools (Debian packages): povray renders (required); ffmpeg makes GIFs (palettegen) and MP4s;
without ffmpeg, Pillow (python3-pil) makes GIFs, draws the labels and composes side-by-side
frames. Exit status: 0 done; 1 a tool failed (its message is shown); 2 bad input (the message
names it); 3 a required tool is missing (the message says what to install).
"""
import argparse
import concurrent.futures
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

EXIT_FAILED, EXIT_INPUT, EXIT_MISSING = 1, 2, 3

FRAME_FILE = re.compile(r"^(.+)_(\d{4,})\.obj$")
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "km": 1e3}
DEFAULT_ROD_RADIUS = 5e-5  # docs/scene-reference.md: rods.N.material.radius

# Colours (sRGB). Cloth: front and back of each cloth; rods: one per family.
CLOTH_COLOURS = [((0.86, 0.33, 0.27), (0.96, 0.86, 0.62)),
                 ((0.20, 0.55, 0.66), (0.93, 0.90, 0.80)),
                 ((0.55, 0.40, 0.72), (0.95, 0.88, 0.70)),
                 ((0.35, 0.62, 0.33), (0.96, 0.92, 0.78))]
ROD_COLOURS = [(0.50, 0.30, 0.16), (0.20, 0.42, 0.60), (0.70, 0.25, 0.22), (0.30, 0.55, 0.28),
               (0.62, 0.50, 0.20), (0.45, 0.32, 0.62)]
OBSTACLE_COLOUR = (0.62, 0.63, 0.65)


class InputError(Exception):
    """Bad input: exit status 2."""


class MissingTool(Exception):
    """A required program or module is not installed: exit status 3."""


class ToolFailed(Exception):
    """povray or ffmpeg failed: exit status 1."""


# ---------------------------------------------------------------------------------------------
# Reading a run directory

def length(value, what, default):
    """A length from scene.json: a number (SI) or a string "<number> <unit>"."""
    if value is None:
        return default
    if isinstance(value, (int, float)):
        return float(value)
    m = re.fullmatch(r"\s*([-+0-9.eE]+)\s*([a-z]*)\s*", str(value))
    if m and (m.group(2) in LENGTH_UNITS or not m.group(2)):
        try:
            return float(m.group(1)) * LENGTH_UNITS.get(m.group(2), 1.0)
        except ValueError:
            pass
    raise InputError("scene.json: {} = {!r} is not a length (a number in m, or e.g. \"60 um\")".format(what, value))


def read_obj(path):
    """Vertices, triangles (0-based), polylines (0-based) and the time in the header comment."""
    verts, faces, lines, time = [], [], [], None
    try:
        with open(path) as f:
            for row in f:
                if row.startswith("v "):
                    p = row.split()
                    verts.append((float(p[1]), float(p[2]), float(p[3])))
                elif row.startswith("f "):
                    idx = [int(t.split("/")[0]) - 1 for t in row.split()[1:]]
                    for k in range(1, len(idx) - 1):  # fan-triangulate polygons
                        faces.append((idx[0], idx[k], idx[k + 1]))
                elif row.startswith("l "):
                    lines.append([int(t) - 1 for t in row.split()[1:]])
                elif row.startswith("#") and time is None:
                    m = re.search(r"\bt=([-+0-9.eE]+)", row)
                    if m:
                        time = float(m.group(1))
    except OSError as e:
        raise InputError("{}: {}".format(path, e.strerror))
    except (ValueError, IndexError):
        raise InputError("{}: not a valid OBJ file".format(path))
    return verts, faces, lines, time


class Part:
    """One output name of a run: a cloth, the rods or an obstacle."""

    def __init__(self, name, kind, index=0, shape=None, radii=None):
        self.name, self.kind, self.index, self.shape = name, kind, index, shape
        self.radii = radii or []  # rods: radius of each rod [m]
        self.families = []        # rods: family index of each rod


class Run:
    """A `weft run` output directory: its frames, parts, scene and summary."""

    def __init__(self, path):
        self.path = path
        if not os.path.isdir(path):
            raise InputError("{}: no such directory (expected the output directory of `weft run`)".format(path))
        self.scene = self._json("scene.json")
        self.summary = self._json("summary.json")
        self.files = {}  # frame -> {name: path}
        for entry in os.listdir(path):
            m = FRAME_FILE.match(entry)
            if m:
                self.files.setdefault(int(m.group(2)), {})[m.group(1)] = os.path.join(path, entry)
        if not self.files:
            raise InputError("{}: no frames (no <name>_<kkkk>.obj files; was output.obj false?)".format(path))
        self.frames = sorted(self.files)
        self.parts = self._classify()

    def _json(self, name):
        p = os.path.join(self.path, name)
        if not os.path.exists(p):
            return None
        try:
            with open(p) as f:
                return json.load(f)
        except (OSError, ValueError) as e:
            raise InputError("{}: cannot read: {}".format(p, e))

    def _classify(self):
        names = sorted({n for files in self.files.values() for n in files})
        known = {}
        s = self.scene or {}
        cloths = s.get("cloths") or []
        for c, spec in enumerate(cloths):
            n = spec.get("name", "cloth")
            known[n if len(cloths) == 1 else "{}{}".format(n, c)] = Part(n, "cloth", c)
        for o, spec in enumerate(s.get("obstacles") or []):
            n = "{}{}".format(spec.get("name", "obstacle"), o)
            known[n] = Part(n, "obstacle", o, shape=spec.get("shape"))
        rods = s.get("rods") or []
        if rods:
            part = Part("rods", "rods")
            for fam, spec in enumerate(rods):
                r = length((spec.get("material") or {}).get("radius"), "rods.{}.material.radius".format(fam),
                           DEFAULT_ROD_RADIUS)
                count = int(spec.get("count", 1))
                part.radii += [r] * count
                part.families += [fam] * count
            known["rods"] = part
        parts = {}
        for n in names:
            parts[n] = known.get(n) or self._guess(n, sum(p.kind == "cloth" for p in parts.values()))
        return parts

    def _guess(self, name, cloth_index):
        """No scene.json entry: tell the part by its content (first frame that has it)."""
        frame = next(k for k in self.frames if name in self.files[k])
        verts, faces, lines, _ = read_obj(self.files[frame][name])
        if lines:
            return Part(name, "rods")
        if (len(verts), len(faces)) == (4, 2):
            return Part(name, "obstacle", shape="plane")
        if (len(verts), len(faces)) == (8, 12):
            return Part(name, "obstacle", shape="box")
        if (len(verts), len(faces)) == (266, 528):  # obstacle_mesh's 24 x 12 sphere
            return Part(name, "obstacle", shape="sphere")
        return Part(name, "cloth", cloth_index)

    def label(self):
        for doc in (self.summary, self.scene):
            if doc and doc.get("combo"):
                return str(doc["combo"])
        return os.path.basename(os.path.normpath(self.path))

    def frame_rate(self):
        """Frames per simulated second in the directory: time.frame_rate / output.every."""
        s = self.scene or {}
        rate = (s.get("time") or {}).get("frame_rate", 24)
        if isinstance(rate, str):  # "24 Hz", "24 1/s"
            m = re.match(r"\s*([-+0-9.eE]+)", rate)
            rate = m.group(1) if m else 24
        try:
            rate, every = float(rate), int((s.get("output") or {}).get("every", 1))
        except (TypeError, ValueError):
            return 24.0
        return rate / max(every, 1) if rate > 0 else 24.0


def select_frames(frames, spec):
    """`A:B` (inclusive; either end may be left out), `A:B:N` (every N-th of those) or `K`."""
    if spec is None:
        return list(frames)
    parts = spec.split(":")
    try:
        if len(parts) == 1:
            k = int(parts[0])
            chosen = [k] if k in frames else []
        elif len(parts) in (2, 3):
            a = int(parts[0]) if parts[0] else frames[0]
            b = int(parts[1]) if parts[1] else frames[-1]
            n = int(parts[2]) if len(parts) == 3 and parts[2] else 1
            if n < 1:
                raise ValueError
            chosen = [k for k in frames if a <= k <= b][::n]
        else:
            raise ValueError
    except ValueError:
        raise InputError("--frames {}: expected A:B, A:B:N (every N-th) or a frame number K, e.g. 0:48, ::5, 12".format(spec))
    if not chosen:
        raise InputError("--frames {}: selects no frame (the run has frames {}..{})".format(spec, frames[0], frames[-1]))
    return chosen


# ---------------------------------------------------------------------------------------------
# Geometry

def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(a):
    return math.sqrt(dot(a, a))


def unit(a):
    n = norm(a)
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else (0.0, 0.0, 1.0)


def vertex_normals(verts, faces):
    """Area-weighted vertex normals (the face normals' sum, as the faces are oriented)."""
    acc = [[0.0, 0.0, 0.0] for _ in verts]
    for a, b, c in faces:
        n = cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))
        for i in (a, b, c):
            acc[i][0] += n[0]
            acc[i][1] += n[1]
            acc[i][2] += n[2]
    return [unit(n) for n in acc]


class Box:
    def __init__(self):
        self.lo, self.hi = [math.inf] * 3, [-math.inf] * 3

    def add(self, pts, pad=0.0):
        for p in pts:
            for i in range(3):
                self.lo[i] = min(self.lo[i], p[i] - pad)
                self.hi[i] = max(self.hi[i], p[i] + pad)

    def empty(self):
        return self.lo[0] > self.hi[0]

    def center(self):
        return tuple(0.5 * (a + b) for a, b in zip(self.lo, self.hi))

    def size(self):
        return max(norm(sub(self.hi, self.lo)), 1e-6)

    def corners(self):
        return [(x, y, z) for x in (self.lo[0], self.hi[0]) for y in (self.lo[1], self.hi[1]) for z in (self.lo[2], self.hi[2])]


def nice_length(x):
    """The 1-2-5 length nearest below x (checker squares that read as a scale)."""
    e = math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * 10 ** e <= x:
            return m * 10 ** e
    return 10 ** e


def pov(p):
    """A simulation point (right-handed, z up) as a POV-Ray vector (left-handed, y up)."""
    return "<{:.7g},{:.7g},{:.7g}>".format(p[0], p[2], p[1])


def srgb(c):
    return "srgb <{:.3f},{:.3f},{:.3f}>".format(*c)


class Camera:
    """Perspective camera in simulation coordinates, fitted to a bounding box."""

    def __init__(self, box, args, ground_z):
        self.width, self.height = args.width, args.height
        self.fov = 40.0  # horizontal, degrees
        tan_h = math.tan(math.radians(self.fov) / 2)
        tan_v = tan_h * self.height / self.width
        self.target = args.look_at or box.center()
        if args.camera is not None:
            self.location = args.camera
        else:
            az, el = math.radians(args.azimuth), math.radians(max(-89.0, min(89.0, args.elevation)))
            view = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))  # target -> camera
            right = unit(cross((0.0, 0.0, 1.0), view))  # image axes (their signs do not matter here)
            up = cross(view, right)
            # smallest distance at which every corner of the box is inside the frustum
            d = 0.0
            for p in box.corners():
                q = sub(p, self.target)
                depth = dot(q, view)
                d = max(d, depth + abs(dot(q, right)) / tan_h, depth + abs(dot(q, up)) / tan_v)
            d = 1.08 * max(d, 1e-3)
            self.location = tuple(self.target[i] + d * view[i] for i in range(3))
        self.distance = norm(sub(self.location, self.target))
        # world size of one pixel at the target: the minimum visible rod radius is measured in it
        self.pixel = 2 * self.distance * tan_h / self.width
        self.ground_z = ground_z

    def pov(self):
        d = sub(self.target, self.location)
        sky = " sky <0,0,1>" if math.hypot(d[0], d[1]) < 1e-6 * norm(d) else ""  # looking straight down or up
        return ("camera {{ perspective location {} look_at {} right x*{:.6g} up y angle {}{} }}\n"
                .format(pov(self.location), pov(self.target), self.width / self.height, self.fov, sky))


# ---------------------------------------------------------------------------------------------
# POV-Ray scene of one frame

class Scene:
    """What every frame of the render shares: camera, lights, ground, textures."""

    def __init__(self, runs, frames, args):
        self.args = args
        box, plane = Box(), None
        self.uv = {}  # (run path, cloth name) -> texture coordinates of each vertex
        for run in runs:
            for k in frames:
                for name, path in run.files[k].items():
                    part = run.parts[name]
                    verts, faces, _, _ = read_obj(path)
                    if part.kind == "obstacle" and part.shape == "plane":
                        plane = plane or (verts, faces)
                        continue
                    box.add(verts)
            for name, part in run.parts.items():
                if part.kind == "cloth":
                    k0 = next(k for k in run.frames if name in run.files[k])
                    self.uv[(run.path, name)] = self._uv_frame(read_obj(run.files[k0][name])[0])
        if box.empty():  # only planes: frame a unit box at the first one
            box.add([(-0.5, -0.5, 0.0), (0.5, 0.5, 0.5)])
        self.box = box
        size = box.size()
        self.ground_z = box.lo[2] - 0.04 * size
        self.camera = Camera(box, args, self.ground_z)
        self.square = nice_length(size / 6)
        self.has_plane = plane is not None

    @staticmethod
    def _uv_frame(verts):
        """Texture coordinates of a cloth: its first frame's vertices on the plane of its two
        longest bounding-box axes, in checker squares (about 8 along the longest)."""
        b = Box()
        b.add(verts)
        ext = [b.hi[i] - b.lo[i] for i in range(3)]
        a0, a1 = sorted(range(3), key=lambda i: -ext[i])[:2]
        sq = nice_length(max(ext[a0], 1e-6) / 8)
        return [((v[a0] - b.lo[a0]) / sq, (v[a1] - b.lo[a1]) / sq) for v in verts]

    def header(self):
        a, cam = self.args, self.camera
        size = self.box.size()
        c = self.box.center()
        # key light up-left behind the camera, fill light on the other side (no shadows)
        view = unit(sub(cam.location, cam.target))
        side = unit(cross((0.0, 0.0, 1.0), view))
        key = tuple(c[i] + 3 * size * (0.7 * view[i] + 0.5 * side[i]) + (3 * size if i == 2 else 0) for i in range(3))
        fill = tuple(c[i] + 3 * size * (0.8 * view[i] - 0.8 * side[i]) + (1 * size if i == 2 else 0) for i in range(3))
        out = ["#version 3.7;\n",
               "global_settings { assumed_gamma 1.0 max_trace_level 6 }\n",
               cam.pov(),
               "sky_sphere { pigment { gradient y color_map { [0 srgb <0.96,0.97,0.98>] [0.5 srgb <0.80,0.86,0.93>] "
               "[1 srgb <0.62,0.72,0.86>] } } }\n"]
        if a.quality == "high":
            s = 0.6 * size
            out.append("light_source {{ {} color rgb 1.05 area_light <{:.5g},0,0>, <0,0,{:.5g}>, 5, 5 adaptive 1 jitter "
                       "circular orient }}\n".format(pov(key), s, s))
        else:
            out.append("light_source {{ {} color rgb 1.05 }}\n".format(pov(key)))
        out.append("light_source {{ {} color rgb 0.35 shadowless }}\n".format(pov(fill)))
        out.append("#declare T_obstacle = texture {{ pigment {{ color {} }} finish {{ ambient 0.04 diffuse 0.8 "
                   "specular 0.15 roughness 0.04 }} }}\n".format(srgb(OBSTACLE_COLOUR)))
        for i, (front, back) in enumerate(CLOTH_COLOURS):
            lighter = tuple(min(1.0, 0.85 * x + 0.15) for x in front)
            # uv_mapping evaluates at <u,v,0>, a checker cell boundary in z: move the pattern off it
            pattern = ("checker color {} color {} translate 0.5*z".format(srgb(front), srgb(lighter)) if a.checker
                       else "color {}".format(srgb(front)))
            out.append("#declare T_cloth_front{} = texture {{ uv_mapping pigment {{ {} }} finish {{ ambient 0.05 "
                       "diffuse 0.8 specular 0.05 roughness 0.1 }} }}\n".format(i, pattern))
            out.append("#declare T_cloth_back{} = texture {{ pigment {{ color {} }} finish {{ ambient 0.05 "
                       "diffuse 0.8 }} }}\n".format(i, srgb(back)))
        for i, col in enumerate(ROD_COLOURS):
            out.append("#declare T_rod{} = texture {{ pigment {{ color {} }} finish {{ ambient 0.05 diffuse 0.75 "
                       "specular 0.35 roughness 0.02 }} }}\n".format(i, srgb(col)))
        if not self.has_plane and a.ground:
            out.append(self._plane((0.0, 0.0, 1.0), (0.0, 0.0, self.ground_z)))
        return "".join(out)

    def _plane(self, normal, point):
        n = unit(normal)
        return ("plane {{ {}, {:.7g} texture {{ pigment {{ checker color srgb <0.84,0.84,0.82> color srgb <0.76,0.76,0.75> "
                "scale {:.5g} }} finish {{ ambient 0.05 diffuse 0.8 }} }} }}\n"
                .format(pov(n), dot(n, point), self.square))

    def frame(self, run, k):
        """The .pov text of frame k of a run, and the simulated time read from its files."""
        out, time = [self.header()], None
        for name in sorted(run.files[k]):
            part = run.parts[name]
            verts, faces, lines, t = read_obj(run.files[k][name])
            time = time if t is None else t
            if part.kind == "cloth":
                out.append(self._cloth(run, name, part, verts, faces))
            elif part.kind == "rods":
                out.append(self._rods(part, verts, lines))
            elif part.shape == "plane" and faces:
                out.append(self._plane(cross(sub(verts[faces[0][1]], verts[faces[0][0]]),
                                             sub(verts[faces[0][2]], verts[faces[0][0]])), verts[0]))
            elif part.shape == "sphere" and verts:
                c = tuple(sum(v[i] for v in verts) / len(verts) for i in range(3))
                r = max(norm(sub(v, c)) for v in verts)
                out.append("sphere {{ {}, {:.7g} texture {{ T_obstacle }} }}\n".format(pov(c), r))
            elif faces:
                out.append(self._mesh(verts, faces, None, None, "texture { T_obstacle }"))
        return "".join(out), time

    def _cloth(self, run, name, part, verts, faces):
        if not faces:
            return ""
        uv = self.uv[(run.path, name)]
        uv = uv if len(uv) == len(verts) else None  # a cloth mesh changed size: no pattern
        i = part.index % len(CLOTH_COLOURS)
        return self._mesh(verts, faces, vertex_normals(verts, faces), uv,
                          "texture {{ T_cloth_front{0} }} interior_texture {{ T_cloth_back{0} }}".format(i))

    @staticmethod
    def _mesh(verts, faces, normals, uv, textures):
        out = ["mesh2 {\nvertex_vectors { ", str(len(verts))]
        out += [",\n" + pov(v) for v in verts]
        if normals:
            out += ["}\nnormal_vectors { ", str(len(normals))]
            out += [",\n" + pov(n) for n in normals]
        if uv:
            out += ["}\nuv_vectors { ", str(len(uv))]
            out += [",\n<{:.6g},{:.6g}>".format(*t) for t in uv]
        out += ["}\nface_indices { ", str(len(faces))]
        out += [",\n<{},{},{}>".format(*f) for f in faces]
        out.append("}\n" + textures + "\n}\n")
        return "".join(out)

    def _rods(self, part, verts, lines):
        floor = self.args.min_radius_px * self.camera.pixel
        out = []
        for r, line in enumerate(lines):
            radius = max(part.radii[r] if r < len(part.radii) else DEFAULT_ROD_RADIUS, floor)
            family = part.families[r] if r < len(part.families) else 0
            pts = [verts[i] for i in line]
            body = ["sphere {{ {}, {:.6g} }}\n".format(pov(pts[0]), radius)]
            for p, q in zip(pts, pts[1:]):
                if norm(sub(q, p)) > 1e-9 * radius:
                    body.append("cylinder {{ {}, {}, {:.6g} open }}\nsphere {{ {}, {:.6g} }}\n"
                                .format(pov(p), pov(q), radius, pov(q), radius))
            out.append("union {{\n{}texture {{ T_rod{} }}\n}}\n".format("".join(body), family % len(ROD_COLOURS)))
        return "".join(out)


# ---------------------------------------------------------------------------------------------
# Rendering, overlays, animation

def povray_command(args, pov_name, png_name):
    cmd = ["povray", "+I" + pov_name, "+O" + png_name, "+W{}".format(args.width), "+H{}".format(args.height),
           "-D", "+FN", "-V", "-GD", "-GR", "-GS", "+WT1"]
    if args.quality == "high":
        cmd += ["+Q9", "+A0.1", "+AM2", "+R3"]
    else:
        cmd += ["+Q4", "-A"]
    return cmd


def render_frame(scene, run, k, out_dir, args):
    """Write frame k's .pov next to its PNG and render it; returns (png path, time)."""
    text, time = scene.frame(run, k)
    stem = "frame_{:05d}".format(k)
    pov_name, png_name = stem + ".pov", stem + ".png"
    with open(os.path.join(out_dir, pov_name), "w") as f:
        f.write(text)
    # povray's default I/O policy lets it read and write the current directory: run it there
    p = subprocess.run(povray_command(args, pov_name, png_name), cwd=out_dir, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, universal_newlines=True)
    png = os.path.join(out_dir, png_name)
    if p.returncode != 0 or not os.path.exists(png):
        tail = "\n".join(l for l in p.stdout.splitlines() if "povray.conf" not in l)[-2000:]
        raise ToolFailed("povray failed on {} (exit {}):\n{}".format(os.path.join(out_dir, pov_name), p.returncode, tail))
    if not args.keep_pov:
        os.remove(os.path.join(out_dir, pov_name))
    return png, time


def clear_frames(out_dir):
    """Remove what an earlier render left (only files this script writes)."""
    pattern = re.compile(r"^frame_\d{5,}\.(png|pov)$|^render\.(gif|mp4)$")
    for entry in os.listdir(out_dir):
        if pattern.match(entry):
            os.remove(os.path.join(out_dir, entry))


def render_run(scene, run, frames, out_dir, args, tag=""):
    os.makedirs(out_dir, exist_ok=True)
    clear_frames(out_dir)
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = {pool.submit(render_frame, scene, run, k, out_dir, args): k for k in frames}
        for n, fut in enumerate(concurrent.futures.as_completed(futures), 1):
            try:
                results[futures[fut]] = fut.result()
            except BaseException:
                for f in futures:  # stop at the first failure: render no more frames
                    f.cancel()
                raise
            if not args.quiet and (sys.stderr.isatty() or n == len(frames)):
                sys.stderr.write("\rweft render: {}{} of {} frames rendered".format(tag, n, len(frames)))
                sys.stderr.write("\n" if n == len(frames) else "")
                sys.stderr.flush()
    return [results[k] for k in frames]


def load_pil():
    try:
        from PIL import Image, ImageDraw, ImageFont
        return Image, ImageDraw, ImageFont
    except ImportError:
        return None


def font(pil, height):
    _, _, ImageFont = pil
    size = max(10, height // 20)
    for name in ("DejaVuSans.ttf", "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"):
        try:
            return ImageFont.truetype(name, size)
        except OSError:
            pass
    return ImageFont.load_default()


def draw_text(draw, xy, text, fnt):
    x, y = xy
    for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1)):  # a light halo keeps it readable on any colour
        draw.text((x + dx, y + dy), text, fill=(255, 255, 255), font=fnt)
    draw.text((x, y), text, fill=(20, 20, 20), font=fnt)


def overlay(pil, png, label, time, out_path=None):
    Image, ImageDraw, _ = pil
    im = Image.open(png).convert("RGB")
    d = ImageDraw.Draw(im)
    fnt = font(pil, im.height)
    pad = max(3, im.height // 60)
    if label:
        draw_text(d, (pad, pad), label, fnt)
    if time is not None:
        draw_text(d, (pad, im.height - pad - fnt.getbbox("0")[3] - 2), "t = {:.3f} s".format(time), fnt)
    im.save(out_path or png)


def compose(pil, left, right, labels, time, out_path):
    Image, ImageDraw, _ = pil
    a, b = Image.open(left).convert("RGB"), Image.open(right).convert("RGB")
    im = Image.new("RGB", (a.width + b.width, max(a.height, b.height)), (255, 255, 255))
    im.paste(a, (0, 0))
    im.paste(b, (a.width, 0))
    d = ImageDraw.Draw(im)
    d.line([(a.width, 0), (a.width, im.height)], fill=(60, 60, 60), width=1)
    fnt = font(pil, im.height)
    pad = max(3, im.height // 60)
    for x, label in ((0, labels[0]), (a.width, labels[1])):
        if label:
            draw_text(d, (x + pad + 1, pad), label, fnt)
    if time is not None:
        draw_text(d, (pad, im.height - pad - fnt.getbbox("0")[3] - 2), "t = {:.3f} s".format(time), fnt)
    im.save(out_path)


def compose_ffmpeg(left, right, out_path):
    p = subprocess.run(["ffmpeg", "-y", "-loglevel", "error", "-i", left, "-i", right, "-filter_complex", "hstack", out_path],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    if p.returncode != 0:
        raise ToolFailed("ffmpeg hstack failed on {} and {}:\n{}".format(left, right, p.stdout[-2000:]))


def sequence_dir(pngs):
    """A temporary directory of numbered links to the frames, for ffmpeg's image2 input."""
    tmp = tempfile.mkdtemp(prefix="weft_render_")
    for i, p in enumerate(pngs):
        os.symlink(os.path.abspath(p), os.path.join(tmp, "{:06d}.png".format(i)))
    return tmp


def check_tools(args, pil):
    """Fail before rendering when a tool the options need is missing."""
    if not shutil.which("povray"):
        raise MissingTool("povray is not installed: apt-get install povray")
    ffmpeg = shutil.which("ffmpeg")
    if args.format == "mp4" and not ffmpeg:
        raise MissingTool("--format mp4 needs ffmpeg, which is not installed: apt-get install ffmpeg "
                          "(or use --format gif or png)")
    if args.format == "gif" and not ffmpeg and not pil:
        raise MissingTool("--format gif needs ffmpeg or Pillow, neither is installed: apt-get install ffmpeg, or "
                          "apt-get install python3-pil and run with /usr/bin/python3 (or use --format png)")
    if args.side_by_side and not pil and not ffmpeg:
        raise MissingTool("--side-by-side needs Pillow or ffmpeg to compose frames: apt-get install python3-pil "
                          "(and run with /usr/bin/python3) or apt-get install ffmpeg")


def animate(pngs, fmt, fps, path, pil):
    """render.gif (ffmpeg with a palette made for the frames, else Pillow) or render.mp4 (ffmpeg, H.264)."""
    if shutil.which("ffmpeg"):
        tmp = sequence_dir(pngs)
        try:
            src = ["ffmpeg", "-y", "-loglevel", "error", "-framerate", "{:g}".format(fps), "-i",
                   os.path.join(tmp, "%06d.png")]
            if fmt == "gif":
                cmd = src + ["-vf", "split[a][b];[a]palettegen=stats_mode=diff[p];[b][p]paletteuse=dither=bayer:bayer_scale=3",
                             "-loop", "0", path]
            else:
                cmd = src + ["-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2", "-c:v", "libx264", "-pix_fmt", "yuv420p",
                             "-crf", "20", "-movflags", "+faststart", path]
            p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
            if p.returncode != 0:
                raise ToolFailed("ffmpeg failed writing {}:\n{}".format(path, p.stdout[-2000:]))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return
    Image = pil[0]
    frames = [Image.open(p).convert("RGB").quantize(colors=255, method=Image.MEDIANCUT) for p in pngs]
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=max(20, int(round(1000 / fps))), loop=0)


# ---------------------------------------------------------------------------------------------
# Command line

def vector(text):
    try:
        v = tuple(float(t) for t in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3:
        raise argparse.ArgumentTypeError("'{}' is not x,y,z (three numbers in metres)".format(text))
    return v


def camera_arg(text):
    return None if text == "auto" else vector(text)


def positive_int(text):
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise argparse.ArgumentTypeError("'{}' is not a positive integer".format(text))
    return v


def positive_float(text):
    try:
        v = float(text)
    except ValueError:
        v = 0.0
    if not v > 0:
        raise argparse.ArgumentTypeError("'{}' is not a positive number".format(text))
    return v


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog="weft render",
        description="Render the frames of a `weft run` output directory with POV-Ray (PNG), then an animated GIF or "
                    "an MP4; with --side-by-side, two runs of the same scene next to each other, same camera.",
        epilog="Hair is thin: a 37 um hair is a tiny fraction of a pixel at most framings, so rods are drawn at least "
               "--min-radius-px pixels in radius (default 1, measured at the look-at distance); --min-radius-px 0 draws "
               "the true radius. Coordinates are the simulation's (metres, z up). Needs povray (apt-get install "
               "povray); GIF: ffmpeg or python3-pil; MP4: ffmpeg; labels and side by side: python3-pil (or ffmpeg, "
               "without labels). Exit status: 0 done, 1 a tool failed, 2 bad input, 3 a required tool is missing. "
               "See docs/render.md.")
    p.add_argument("run_dir", metavar="RUN_DIR", help="output directory of `weft run`")
    p.add_argument("--out", metavar="DIR", help="where frames and the animation go (default: RUN_DIR/render, or "
                   "RUN_DIR/render_vs_<OTHER> with --side-by-side)")
    p.add_argument("--width", type=positive_int, default=640, help="image width in pixels (default 640)")
    p.add_argument("--height", type=positive_int, default=480, help="image height in pixels (default 480)")
    p.add_argument("--frames", metavar="A:B[:N]", help="frames A to B inclusive (frame numbers of the file names; "
                   "either end may be left out), every N-th of them with :N (e.g. ::5), or one frame K (default: all)")
    p.add_argument("--format", choices=("gif", "mp4", "png"), default="gif",
                   help="gif (default) or mp4: the PNG frames plus render.gif / render.mp4; png: the frames only")
    p.add_argument("--fps", type=positive_float, help="frames per second of the animation (default: real time "
                   "from scene.json's time.frame_rate, output.every and the :N of --frames, within 1..50)")
    p.add_argument("--camera", type=camera_arg, default=None, metavar="auto|x,y,z",
                   help="camera position; auto (default) frames the bounding box of all rendered frames, the same "
                        "for every frame and for both sides of --side-by-side")
    p.add_argument("--look-at", type=vector, metavar="x,y,z", help="point the camera looks at (default: centre of "
                   "the bounding box)")
    p.add_argument("--azimuth", type=float, default=-60.0, help="auto camera: direction from the look-at point, "
                   "degrees counter-clockwise from +x about z (default -60)")
    p.add_argument("--elevation", type=float, default=30.0, help="auto camera: degrees above the xy plane "
                   "(default 30)")
    p.add_argument("--side-by-side", metavar="OTHER_RUN_DIR", help="a second run of the same scene, drawn on the "
                   "right; both must have the same frames")
    p.add_argument("--labels", nargs="+", metavar="LABEL", help="label(s) drawn on the frames (default with "
                   "--side-by-side: each run's combination from summary.json, else its directory name)")
    p.add_argument("--quality", choices=("low", "high"), default="high", help="high (default): antialiasing, "
                   "soft shadows; low: fast previews and tests")
    p.add_argument("--min-radius-px", type=float, default=1.0, metavar="P",
                   help="draw rods at least P pixels in radius, so thin hair stays visible (default 1; 0: true "
                        "radius)")
    p.add_argument("--no-ground", dest="ground", action="store_false",
                   help="no checkered ground under the scene (drawn unless the scene has a plane obstacle)")
    p.add_argument("--no-checker", dest="checker", action="store_false", help="plain cloth (default: a checker "
                   "laid on the cloth's first frame, which shows stretch and shear)")
    p.add_argument("--no-overlay", dest="overlay", action="store_false", help="no time stamp or labels on the frames")
    p.add_argument("--jobs", type=positive_int, default=2, help="povray processes at once, one thread each "
                   "(default 2)")
    p.add_argument("--keep-pov", action="store_true", help="keep each frame's .pov next to its PNG")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    args = p.parse_args(argv)
    if args.labels and len(args.labels) > 2:
        p.error("--labels takes one label, or two with --side-by-side")
    return args


def main(argv):
    args = parse_args(argv)
    run = Run(args.run_dir)
    other = Run(args.side_by_side) if args.side_by_side else None
    frames = select_frames(run.frames, args.frames)
    if other:
        missing = [k for k in frames if k not in other.files]
        if missing or (args.frames is None and other.frames != run.frames):
            raise InputError("--side-by-side: {} has {} frames ({}..{}), {} has {} ({}..{}); select common frames "
                             "with --frames A:B".format(run.path, len(run.frames), run.frames[0], run.frames[-1],
                                                        other.path, len(other.frames), other.frames[0],
                                                        other.frames[-1]))
    if args.labels and len(args.labels) == 2 and not other:
        raise InputError("--labels: two labels need --side-by-side")
    pil = load_pil()
    check_tools(args, pil)

    if args.out:
        out = args.out
    elif other:
        out = os.path.join(run.path, "render_vs_" + os.path.basename(os.path.normpath(other.path)))
    else:
        out = os.path.join(run.path, "render")
    os.makedirs(out, exist_ok=True)
    step = 1
    if args.frames and args.frames.count(":") == 2 and args.frames.split(":")[2]:
        step = int(args.frames.split(":")[2])
    fps = args.fps or min(50.0, max(1.0, run.frame_rate() / step))

    scene = Scene([run] + ([other] if other else []), frames, args)
    if not other:
        rendered = render_run(scene, run, frames, out, args)
        pngs = [png for png, _ in rendered]
        if args.overlay and pil:
            label = args.labels[0] if args.labels else None
            for png, time in rendered:
                overlay(pil, png, label, time)
    else:
        labels = args.labels or [run.label(), other.label()]
        if len(labels) == 1:
            labels = [labels[0], other.label()]
        if labels[0] == labels[1] and not args.labels:
            labels = [os.path.basename(os.path.normpath(r.path)) for r in (run, other)]
        left = render_run(scene, run, frames, os.path.join(out, "left"), args, "left: ")
        right = render_run(scene, other, frames, os.path.join(out, "right"), args, "right: ")
        clear_frames(out)
        pngs = []
        for k, (lpng, time), (rpng, _) in zip(frames, left, right):
            path = os.path.join(out, "frame_{:05d}.png".format(k))
            if pil:
                compose(pil, lpng, rpng, labels if args.overlay else (None, None), time if args.overlay else None, path)
            else:
                compose_ffmpeg(lpng, rpng, path)
            pngs.append(path)
    result = out
    if args.format != "png":
        result = os.path.join(out, "render." + args.format)
        animate(pngs, args.format, fps, result, pil)
    if not args.quiet:
        print("weft render: {} frames in {}{}".format(len(pngs), out, "" if args.format == "png" else ", " + result))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except InputError as e:
        sys.stderr.write("weft render: error: {}\n".format(e))
        sys.exit(EXIT_INPUT)
    except MissingTool as e:
        sys.stderr.write("weft render: {}\n".format(e))
        sys.exit(EXIT_MISSING)
    except ToolFailed as e:
        sys.stderr.write("weft render: {}\n".format(e))
        sys.exit(EXIT_FAILED)
    except KeyboardInterrupt:
        sys.exit(130)
