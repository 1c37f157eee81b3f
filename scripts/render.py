"""Renders the DEM's XDMF (particles, tools, walls) to PNG frames with ParaView.

Run by scripts/render.sh under `xvfb-run -a pvbatch` (Debian's python3-paraview); see
docs/visualise.md. Arguments: XDMF OUT_DIR STEM EVERY WIDTH HEIGHT LAST(0|1).
Prints one line per frame and, last, `frames: N` (scripts/render.sh reads it).

The blocks are found by their order in the XDMF's first time step (particles, tool_<name>...,
walls): ParaView's Xdmf3 reader suffixes every block name with the time step index, so names
do not select the same block over time.
"""
import builtins  # pvbatch's namespace has VTK's max/min in place of Python's
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
from paraview.simple import (AnnotateTimeFilter, ColorBy, CreateRenderView, GetColorTransferFunction,
                             GetScalarBar, ProgrammableFilter, Render, SaveScreenshot, Show,
                             Xdmf3ReaderT, servermanager)
from vtk.util.numpy_support import vtk_to_numpy

xdmf, out_dir, stem = sys.argv[1], sys.argv[2], sys.argv[3]
every, width, height, last_only = int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6]), sys.argv[7] == "1"


def fail(msg):
    sys.stderr.write("render: " + msg + "\n")
    sys.exit(2)


# Which blocks are what: the grid names of the first time step.
try:
    domain = ET.parse(xdmf).getroot().find("Domain")
    collection = domain.find("Grid")
    first = collection.find("Grid")
    names = [g.get("Name") for g in first.findall("Grid")] if first is not None else []
except (ET.ParseError, AttributeError) as e:
    fail(f"{xdmf} is not an XDMF file this program reads ({e})")
if first is not None and first.get("GridType") == "Uniform" and first.find("Topology") is not None:
    fail(f"{xdmf} has one plain grid per time step (an XDMF written before tools and walls were "
         "added, or not by dem_run/dem_service): run the DEM again with this version, or open it "
         "in ParaView directly")
if collection.get("CollectionType") != "Temporal" or not names:
    fail(f"{xdmf}: expected one temporal collection of time steps with particles, tools and walls "
         "(as dem_run and dem_service write them, docs/visualise.md)")
# The HDF5 files the XDMF names must be there (the reader aborts the process otherwise).
for item in first.iter("DataItem"):
    if item.get("Format") == "HDF" and item.text and ":" in item.text:
        h5 = os.path.join(os.path.dirname(xdmf), item.text.strip().split(":", 1)[0])
        if not os.path.isfile(h5):
            fail(f"{xdmf} reads its data from {h5}, which is missing: keep the .h5 beside the .xdmf")
particles = names.index("particles") if "particles" in names else None
tools = [i for i, n in enumerate(names) if n.startswith("tool_")]
walls = names.index("walls") if "walls" in names else None

reader = Xdmf3ReaderT(FileName=[xdmf])
times = list(reader.TimestepValues)
if not times:
    fail(f"{xdmf} has no time steps (the run wrote no snapshot yet)")
if last_only:
    chosen = [len(times) - 1]
else:
    chosen = sorted(set(range(0, len(times), every)) | {len(times) - 1})


def block(index):
    f = ProgrammableFilter(Input=reader)
    f.OutputDataSetType = "vtkUnstructuredGrid"
    f.Script = (f"b = self.GetInputDataObject(0, 0).GetBlock({index})\n"
                "if b is not None: self.GetOutputDataObject(0).ShallowCopy(b)\n")
    return f


def fetch(src, t):
    src.UpdatePipeline(t)
    return servermanager.Fetch(src)


# First pass: where the tools go over the run (the camera frames their box) and how fast the
# particles are in the chosen frames (the colour range).
part = block(particles) if particles is not None else None
tool_blocks = [block(i) for i in tools]
wall_block = block(walls) if walls is not None else None
lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
speeds = []
for k in range(len(times)):  # the camera frames the tools over the whole run, whatever is drawn
    t = times[k]
    for tb in tool_blocks:
        b = fetch(tb, t).GetBounds()
        if b[0] <= b[1]:
            lo, hi = np.minimum(lo, b[0::2]), np.maximum(hi, b[1::2])
    if part is not None and k in chosen:
        d = fetch(part, t)
        v = d.GetPointData().GetArray("velocity")
        if v is not None and v.GetNumberOfTuples():
            speeds.append(np.linalg.norm(vtk_to_numpy(v), axis=1))
if not np.all(np.isfinite(lo)):  # no tools: frame the particles of the first chosen frame
    if part is None:
        fail(f"{xdmf} has neither particles nor tools to show")
    b = fetch(part, times[chosen[0]]).GetBounds()
    lo, hi = np.array(b[0::2]), np.array(b[1::2])
speeds = np.concatenate(speeds) if speeds else np.zeros(1)
# The 99.5th percentile: a few flying grains do not wash out the pile's colours.
vmax = float(np.percentile(speeds, 99.5)) if speeds.size else 1.0
vmax = vmax if vmax > 1e-6 else builtins.max(float(speeds.max()), 1e-3)  # a soil at rest

view = CreateRenderView()
view.ViewSize = [width, height]
view.Background = [1.0, 1.0, 1.0]
try:  # ParaView 5.10+: the palette's background is used unless told otherwise
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
view.OrientationAxesVisibility = 1

if part is not None:
    pd = Show(part, view)
    pd.SetRepresentationType("Point Gaussian")
    pd.ShaderPreset = "Sphere"
    pd.ScaleByArray = 1
    pd.SetScaleArray = ["POINTS", "radius"]
    pd.UseScaleFunction = 0
    pd.GaussianRadius = 1.0
    ColorBy(pd, ("POINTS", "velocity", "Magnitude"))
    lut = GetColorTransferFunction("velocity")
    lut.ApplyPreset("Turbo", True) or lut.ApplyPreset("Jet", True)
    lut.RescaleTransferFunction(0.0, vmax)
    lut.AutomaticRescaleRangeMode = "Never"
    bar = GetScalarBar(lut, view)
    bar.Title = "speed (m/s)"
    bar.ComponentTitle = ""
    bar.AutomaticLabelFormat = 0
    bar.LabelFormat = bar.RangeLabelFormat = "%-#.3g"
    bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.1]
    bar.Visibility = 1
for tb in tool_blocks:
    td = Show(tb, view)
    td.ColorArrayName = ["POINTS", ""]
    td.AmbientColor = td.DiffuseColor = [0.62, 0.64, 0.70]
    td.Specular = 0.3
if wall_block is not None:
    wd = Show(wall_block, view)
    wd.ColorArrayName = ["POINTS", ""]
    wd.AmbientColor = wd.DiffuseColor = [0.75, 0.72, 0.66]
    wd.Opacity = 0.3  # the side walls stand between the camera and the soil
label = AnnotateTimeFilter(Input=reader, Format="t = {time:.3f} s")
ld = Show(label, view)
ld.FontSize = builtins.max(12, height // 30)
ld.Color = [0.1, 0.1, 0.1]
ld.WindowLocation = "Upper Left Corner"

# Camera: the tools' box over the run (padded), seen from the side (-y), a little from the
# front (+x) and above.
centre = 0.5 * (lo + hi)
radius = 0.5 * float(np.linalg.norm(hi - lo))
radius = builtins.max(radius * 1.15, 1e-3)
direction = np.array([0.3, -1.0, 0.75])
direction /= np.linalg.norm(direction)
view.CameraViewAngle = 30.0
distance = radius / math.sin(math.radians(view.CameraViewAngle / 2))
view.CameraFocalPoint = centre.tolist()
view.CameraPosition = (centre + distance * direction).tolist()
view.CameraViewUp = [0.0, 0.0, 1.0]
view.CenterOfRotation = centre.tolist()

os.makedirs(out_dir, exist_ok=True)
for n, k in enumerate(chosen):
    view.ViewTime = times[k]
    Render(view)
    name = os.path.join(out_dir, f"{stem}_last.png" if last_only else f"{stem}_{n:05d}.png")
    SaveScreenshot(name, view, ImageResolution=[width, height])
    print(f"frame {n}: t = {times[k]:.6g} s (snapshot {k}) -> {name}", flush=True)
print(f"frames: {len(chosen)}", flush=True)
