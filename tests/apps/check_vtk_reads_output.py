"""Checks that VTK's own XML reader (the one ParaView uses) reads weft's frames.

Run with Debian's system interpreter; exits 77 (CTest: skipped) when python3-vtk9 is not
installed. Usage: check_vtk_reads_output.py WEFT_BINARY SCENE OUT_DIR
"""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

try:
    import vtk
except ImportError:
    print("python3-vtk9 is not installed: skipping (apt-get install python3-vtk9 to enable)")
    sys.exit(77)

weft, scene, out = sys.argv[1:4]
subprocess.run([weft, "run", scene, "--out", out, "--quiet", "cloths.0.mesh.resolution=[9,7]", "time.duration=0.25"],
               check=True)
collection = ET.parse(os.path.join(out, "frames.pvd")).getroot().find("Collection")
datasets = collection.findall("DataSet")
assert len(datasets) == 7, len(datasets)  # frames 0..6 at 24 frames/s
for d in datasets:
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(os.path.join(out, d.get("file")))
    reader.Update()
    assert reader.GetErrorCode() == 0, d.get("file")
    poly = reader.GetOutput()
    assert poly.GetNumberOfPoints() == 63, poly.GetNumberOfPoints()
    assert poly.GetNumberOfPolys() == 96, poly.GetNumberOfPolys()
    assert poly.GetPointData().GetArray("velocity").GetNumberOfComponents() == 3
print(f"VTK read {len(datasets)} frames listed in frames.pvd")
