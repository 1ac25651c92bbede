import json, sys
v = float(sys.argv[1]); D = 0.1; T = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
phases = []
t = 0.0; s = 1
while t < T - 1e-12:
    phases.append({"velocity": [0, s * v, 0], "start": round(t, 9), "end": round(t + D, 9)})
    t += D; s = -s
y0 = -v * D / 2
scene = {
  "description": f"tension-free whip: the handle swings along y at {v} m/s",
  "combo": "rods_adonis",
  "rods": [{"name": "whip", "shape": "straight", "vertices": 30, "length": "20 cm",
            "root": [0.05, y0, 0], "direction": [1, 0, 0], "root_held": "edge",
            "motion": {"phases": phases},
            "material": {"radius": "60 um", "youngs_modulus": "1e10 dyn/cm^2", "shear_modulus": "3.4e9 dyn/cm^2",
                         "density": "1.3 g/cm^3"}}],
  "obstacles": [{"shape": "box", "name": "wall", "center": [0.15, 0.1, 0], "half_extents": [0.0025, 0.1, 0.1], "friction": 0.2}],
  "gravity": [0, 0, 0],
  "contact": {"stretch_tol": 0.01, "gs_max": 150},
  "time": {"dt": 0.001, "duration": T, "frame_rate": 50}
}
name = f"edge_v{sys.argv[1]}.json" if T == 1.0 else f"edge_v{sys.argv[1]}_{sys.argv[2]}s.json"
json.dump(scene, open(name, "w"), indent=1)
