# paraview_check.py - run by pvbatch (tests/cli_paraview.sh): opens a run's XDMF sidecar
# with ParaView's readers and checks it against what h5py read from the HDF5 file.
#
#   pvbatch paraview_check.py EXPECTED.json RUN.xmf OUT.png
#
# EXPECTED.json: {"times": [...], "particles": [n per frame], "bodies": {NAME: {"centre":
# [[x, y, z] per frame], "radius": R}}}. Checks, for every frame:
#   - "XDMF Reader" (ParaView's XDMF 2 reader): the particles block has the file's particle
#     count, each body's block is a surface (triangles) whose centre (mean of its vertices)
#     is the body's position in /bodies and whose extent is the body's size;
#   - "Xdmf3 Reader": the bodies likewise (its particles block is empty: ParaView 5.11's
#     Xdmf3 reader reads no X_Y_Z geometry; the H5Part reader and the XDMF 2 reader do);
# then renders the middle frame (particles as points, the bodies as surfaces) to OUT.png and
# checks that the picture shows both: pixels of the particles' and of the body's colour.
# Prints "paraview_check: ok" and exits 0, or prints each failure and exits 1.
import json
import sys

from paraview.simple import (GetActiveViewOrCreate, Render, ResetCamera, SaveScreenshot,
                             Show, XDMFReader, Xdmf3ReaderS, ExtractBlock)
from paraview import servermanager as sm
from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet
from vtkmodules.vtkIOImage import vtkPNGReader
from vtkmodules.util.numpy_support import vtk_to_numpy
import numpy as np

exp_path, xmf, png = sys.argv[1:4]
exp = json.load(open(exp_path))
errors = []


def err(msg):
    errors.append(msg)
    print("paraview_check: FAIL: " + msg, flush=True)


def leaves(obj):
    """(name, dataset) of every leaf of a composite dataset (name None if unnamed)."""
    out = []
    it = obj.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        md = it.GetCurrentMetaData()
        name = md.Get(vtkCompositeDataSet.NAME()) if md and md.Has(vtkCompositeDataSet.NAME()) else None
        out.append((name, it.GetCurrentDataObject()))
        it.GoToNextItem()
    return out


def points(ds):
    return vtk_to_numpy(ds.GetPoints().GetData()).astype(float) if ds.GetNumberOfPoints() else np.zeros((0, 3))


def check_body(label, k, name, ds):
    b = exp["bodies"][name]
    want, R = np.array(b["centre"][k]), b["radius"]
    if ds is None or ds.GetNumberOfCells() == 0 or ds.GetNumberOfPoints() == 0:
        err("%s: frame %d: body %s has no surface" % (label, k, name))
        return
    if ds.GetCellType(0) != 5:  # VTK_TRIANGLE
        err("%s: frame %d: body %s: cell type %d, not triangles" % (label, k, name, ds.GetCellType(0)))
    p = points(ds)
    c = p.mean(axis=0)
    if np.abs(c - want).max() > 1e-3:
        err("%s: frame %d: body %s centre %s, /bodies says %s" % (label, k, name, c.tolist(), want.tolist()))
    r = np.sqrt(((p - c) ** 2).sum(1))
    if abs(r.max() - R) > 1e-3 * R + 1e-6:
        err("%s: frame %d: body %s reaches %g from its centre, radius %g" % (label, k, name, r.max(), R))


times, counts = exp["times"], exp["particles"]
body_names = sorted(exp["bodies"])

# --- the XDMF 2 reader: particles and bodies, by block name
r2 = XDMFReader(FileNames=[xmf])
ts = list(r2.TimestepValues)
if len(ts) != len(times) or any(abs(a - b) > 1e-9 for a, b in zip(ts, times)):
    err("XDMF Reader: times %s, the file's frames are at %s" % (ts[:5], times[:5]))
for k, t in enumerate(times):
    r2.UpdatePipeline(time=t)
    blocks = dict(leaves(sm.Fetch(r2)))
    ds = blocks.get("particles")
    n = ds.GetNumberOfPoints() if ds is not None else -1
    if n != counts[k]:
        err("XDMF Reader: frame %d: %d particles, the file has %d" % (k, n, counts[k]))
    for name in body_names:
        check_body("XDMF Reader", k, name, blocks.get(name))

# --- the Xdmf3 reader: the bodies (its blocks are unnamed, in the sidecar's order)
r3 = Xdmf3ReaderS(FileName=[xmf])
ts3 = list(r3.TimestepValues)
if len(ts3) != len(times):
    err("Xdmf3 Reader: %d times, the file has %d frames" % (len(ts3), len(times)))
for k, t in enumerate(times):
    r3.UpdatePipeline(time=t)
    surf = [ds for _, ds in leaves(sm.Fetch(r3)) if ds is not None and ds.GetNumberOfCells() and
            ds.GetCellType(0) == 5]
    if len(surf) != len(body_names):
        err("Xdmf3 Reader: frame %d: %d body surfaces, want %d" % (k, len(surf), len(body_names)))
        continue
    for name, ds in zip(body_names, surf):
        check_body("Xdmf3 Reader", k, name, ds)

# --- a picture of the middle frame: particles (blue points) and bodies (orange surfaces)
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [800, 500]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
view.Background = [1, 1, 1]
view.OrientationAxesVisibility = 0
view.ViewTime = times[len(times) // 2]
fluid = Show(ExtractBlock(Input=r2, Selectors=["/Root/particles"]), view)
fluid.ColorArrayName = [None, ""]
fluid.Representation = "Points"
fluid.PointSize = 6
fluid.RenderPointsAsSpheres = 1
fluid.DiffuseColor = fluid.AmbientColor = [0.1, 0.3, 0.9]
for name in body_names:
    body = Show(ExtractBlock(Input=r2, Selectors=["/Root/" + name]), view)
    body.ColorArrayName = [None, ""]
    body.Representation = "Surface"
    body.DiffuseColor = body.AmbientColor = [1.0, 0.5, 0.0]
view.CameraPosition = [0.0, -2.0, 1.2]
view.CameraFocalPoint = [0.0, 0.0, 0.25]
view.CameraViewUp = [0.0, 0.0, 1.0]
ResetCamera(view)
Render(view)
SaveScreenshot(png, view, ImageResolution=[800, 500])

reader = vtkPNGReader()
reader.SetFileName(png)
reader.Update()
img = reader.GetOutput()
w, h, _ = img.GetDimensions()
rgb = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(-1, img.GetNumberOfScalarComponents())[:, :3].astype(int)
blue = int(((rgb[:, 2] > 120) & (rgb[:, 0] < 100)).sum())
orange = int(((rgb[:, 0] > 150) & (rgb[:, 1] > 40) & (rgb[:, 1] < 170) & (rgb[:, 2] < 90)).sum())
print("paraview_check: %s: %dx%d, %d particle pixels, %d body pixels" % (png, w, h, blue, orange))
if w * h == 0:
    err("%s: empty picture" % png)
if blue < 200:
    err("%s: the particles are not visible (%d blue pixels)" % (png, blue))
if body_names and orange < 500:
    err("%s: the body is not visible (%d orange pixels)" % (png, orange))

if errors:
    print("paraview_check: %d failure(s)" % len(errors))
    sys.exit(1)
print("paraview_check: ok")
