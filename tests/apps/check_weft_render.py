"""Checks scripts/weft_render.py on tiny runs: PNG frames of the right size that are not blank,
the GIF's frame count, a rod scene (polylines), side by side (twice as wide), and exit status
2 with a message naming the problem on bad input.

Run with Debian's system interpreter; exits 77 (CTest: skipped) when povray is not installed
(the bad-input checks run before that). Usage: check_weft_render.py WEFT_BINARY SOURCE_DIR OUT_DIR
"""
import importlib.util
import os
import shutil
import struct
import subprocess
import sys
import time

weft, source, out = sys.argv[1:4]
script = os.path.join(source, "scripts", "weft_render.py")
started = time.monotonic()
os.makedirs(out, exist_ok=True)


def render(*args, expect=0, env=None):
    p = subprocess.run(["/usr/bin/python3", script] + [str(a) for a in args] + ["--quiet"], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, universal_newlines=True, env=env)
    assert p.returncode == expect, "weft_render.py {}: exit {} (expected {})\n{}{}".format(
        " ".join(map(str, args)), p.returncode, expect, p.stdout, p.stderr)
    return p.stderr


def weft_run(scene, name, *overrides):
    d = os.path.join(out, name)
    subprocess.run([weft, "run", os.path.join(source, "scenes", scene), "--out", d, "--quiet"] + list(overrides),
                   check=True)
    return d


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path + ": not a PNG"
    return struct.unpack(">II", head[16:24])


def variance(path):
    from PIL import Image
    im = Image.open(path).convert("L")
    px = list(im.getdata())
    mean = sum(px) / len(px)
    return sum((p - mean) ** 2 for p in px) / len(px)


have_pil = importlib.util.find_spec("PIL") is not None  # Debian's python3-pil: pixel checks, GIF frame count

# A tiny cloth: 9 x 7 vertices, frames 0..3 at 24 frames/s.
cloth = weft_run("hanging_cloth.json", "cloth", "cloths.0.mesh.resolution=[9,7]", "time.duration=0.125")
small = ["--width", 160, "--height", 120, "--quality", "low"]

# Bad input: exit 2 and a message naming what is wrong (no povray needed).
err = render(os.path.join(out, "no_such_dir"), *small, expect=2)
assert "no_such_dir" in err and "no such directory" in err, err
empty = os.path.join(out, "empty")
os.makedirs(empty, exist_ok=True)
err = render(empty, *small, expect=2)
assert "no frames" in err, err
err = render(cloth, "--frames", "50:60", *small, expect=2)
assert "selects no frame" in err, err
err = render(cloth, "--frames", "x", *small, expect=2)
assert "--frames x" in err, err
short = weft_run("hanging_cloth.json", "cloth_short", "cloths.0.mesh.resolution=[9,7]", "time.duration=0.05")
err = render(cloth, "--side-by-side", short, *small, expect=2)
assert "--side-by-side" in err and "frames" in err, err
# povray missing: exit 3, saying how to install it
err = render(cloth, *small, expect=3, env={"PATH": empty})
assert "apt-get install povray" in err, err

if not shutil.which("povray"):
    print("povray is not installed: skipping the renders (apt-get install povray to enable)")
    sys.exit(77)

# Cloth: 3 frames (0..2) as PNG, and a GIF when ffmpeg or Pillow can make one.
fmt = "gif" if (have_pil or shutil.which("ffmpeg")) else "png"
render(cloth, "--out", os.path.join(out, "cloth_render"), "--frames", "0:2", "--format", fmt, *small)
frames = sorted(f for f in os.listdir(os.path.join(out, "cloth_render")) if f.endswith(".png"))
assert frames == ["frame_00000.png", "frame_00001.png", "frame_00002.png"], frames
for f in frames:
    path = os.path.join(out, "cloth_render", f)
    assert png_size(path) == (160, 120), (f, png_size(path))
    if have_pil:
        assert variance(path) > 20, f + ": blank image"
if fmt == "gif" and have_pil:
    from PIL import Image
    gif = Image.open(os.path.join(out, "cloth_render", "render.gif"))
    assert gif.size == (160, 120) and gif.n_frames == 3, (gif.size, gif.n_frames)
elif fmt == "gif":
    assert os.path.getsize(os.path.join(out, "cloth_render", "render.gif")) > 0

# MP4 (ffmpeg only): an H.264 file of the 3 frames; without ffmpeg, exit 3 before rendering.
if shutil.which("ffmpeg"):
    render(cloth, "--out", os.path.join(out, "cloth_mp4"), "--frames", "0:2", "--format", "mp4", *small)
    with open(os.path.join(out, "cloth_mp4", "render.mp4"), "rb") as f:
        assert f.read(12)[4:8] == b"ftyp", "render.mp4: not an MP4 file"
else:
    err = render(cloth, "--out", os.path.join(out, "cloth_mp4"), "--format", "mp4", *small, expect=3)
    assert "apt-get install ffmpeg" in err, err

# Rods: the whip (one polyline and a box), frames 0..2 at 50 frames/s. The 60 um rod is far
# below a pixel: drawn at least 1 pixel in radius (the default) it covers pixels that the true
# radius (--min-radius-px 0) leaves to the background.
whip = weft_run("whip.json", "whip", "time.duration=0.04")
render(whip, "--out", os.path.join(out, "whip_render"), "--format", "png", "--frames", "2", "--no-overlay", *small)
path = os.path.join(out, "whip_render", "frame_00002.png")
assert png_size(path) == (160, 120)
if have_pil:
    from PIL import Image, ImageChops
    assert variance(path) > 20, path + ": blank image"
    render(whip, "--out", os.path.join(out, "whip_thin"), "--format", "png", "--frames", "2", "--no-overlay",
           "--min-radius-px", 0, *small)
    diff = ImageChops.difference(Image.open(path).convert("L"),
                                 Image.open(os.path.join(out, "whip_thin", "frame_00002.png")).convert("L"))
    changed = sum(1 for p in diff.getdata() if p > 30)
    assert changed >= 20, "the rod covers only {} pixels".format(changed)

# Side by side: the same scene under another combination, same frames: twice as wide.
if have_pil or shutil.which("ffmpeg"):
    whip2 = weft_run("whip.json", "whip_impulse", "time.duration=0.04", "combo=rods_impulse")
    sbs = os.path.join(out, "sbs_render")
    render(whip, "--side-by-side", whip2, "--out", sbs, "--format", "png", "--frames", "1:2", *small)
    for k in (1, 2):
        path = os.path.join(sbs, "frame_{:05d}.png".format(k))
        assert png_size(path) == (320, 120), (path, png_size(path))
        if have_pil:
            assert variance(path) > 20, path + ": blank image"

print("weft render checks passed in {:.1f} s".format(time.monotonic() - started))
