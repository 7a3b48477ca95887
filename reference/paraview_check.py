"""Opens Rust result directories with ParaView's own XDMF reader (headless) and checks that every
field is there, with the right size and in double precision: DIR/solution.xdmf (the mesh, vertex
fields) and DIR/dual.xdmf (the dual submesh S_h, cell fields), given to ParaView as absolute paths;
for an `adapt` directory, DIR/adapt.xdmf: one time step per step-NNN, each with its own mesh, the
vertex fields and the indicator `estimator` as cell data.

Usage (from the repository root):
    /usr/bin/python3 -m reference.paraview_check RESULT_DIR [...]
"""
import os
import sys
import tomllib

import h5py
from paraview import servermanager
from paraview.simple import Xdmf3ReaderS

from .problems import of as problem_of

VTK_DOUBLE = 11


def point_fields(h5):
    """The vertex fields of the problem of a result (its solution.h5): reference/problems.py."""
    with h5py.File(h5, "r") as f:
        return problem_of(tomllib.loads(str(f.attrs["case_text"]))).fields


def read(path):
    """The one unstructured grid of an XDMF file, as ParaView reads it."""
    reader = Xdmf3ReaderS(FileName=[os.path.abspath(path)])
    reader.UpdatePipeline()
    data = servermanager.Fetch(reader)
    while not data.IsA("vtkUnstructuredGrid"):
        data = data.GetBlock(0) if data.IsA("vtkMultiBlockDataSet") else data.GetPiece(0)
    return data


def check(path):
    """Checks DIR/solution.xdmf (the mesh) and DIR/dual.xdmf (the dual submesh, when written:
    `solve --dual` or `--flux`)."""
    mesh = read(os.path.join(path, "solution.xdmf"))
    problems = []
    for name in point_fields(os.path.join(path, "solution.h5")):
        arr = mesh.GetPointData().GetArray(name)
        if arr is None:
            problems.append("point field %s missing" % name)
        elif arr.GetDataType() != VTK_DOUBLE or arr.GetNumberOfTuples() != mesh.GetNumberOfPoints():
            problems.append("point field %s: type %s, %d values"
                            % (name, arr.GetDataTypeAsString(), arr.GetNumberOfTuples()))
    if not os.path.exists(os.path.join(path, "dual.xdmf")):
        return problems
    dual = read(os.path.join(path, "dual.xdmf"))
    cells = dual.GetCellData()
    if cells.GetArray("lambda") is None:
        problems.append("dual cell field lambda missing")
    for i in range(cells.GetNumberOfArrays()):
        arr = cells.GetArray(i)
        if arr.GetDataType() != VTK_DOUBLE or arr.GetNumberOfTuples() != dual.GetNumberOfCells():
            problems.append("dual cell field %s: type %s, %d values"
                            % (arr.GetName(), arr.GetDataTypeAsString(), arr.GetNumberOfTuples()))
    if dual.GetNumberOfCells() != 6 * mesh.GetNumberOfCells():
        problems.append("dual mesh has %d cells for %d triangles" % (dual.GetNumberOfCells(), mesh.GetNumberOfCells()))
    return problems


def check_series(path):
    """Checks DIR/adapt.xdmf, the time series of an `adapt` run, step by step."""
    steps = sorted(d for d in os.listdir(path) if d.startswith("step-"))
    reader = Xdmf3ReaderS(FileName=[os.path.abspath(os.path.join(path, "adapt.xdmf"))])
    reader.UpdatePipeline()
    times = list(reader.TimestepValues)
    problems = [] if len(times) == len(steps) else ["%d time steps for %d steps" % (len(times), len(steps))]
    for t, step in zip(times, steps):
        reader.UpdatePipeline(time=t)
        data = servermanager.Fetch(reader)
        while not data.IsA("vtkUnstructuredGrid"):
            data = data.GetBlock(0) if data.IsA("vtkMultiBlockDataSet") else data.GetPiece(0)
        with h5py.File(os.path.join(path, step, "solution.h5"), "r") as f:
            own, own_eta = len(f["mesh/topology"]), f["mesh/estimator"][...]
        if data.GetNumberOfCells() != own:
            problems.append("time %g: %d cells, %s has %d" % (t, data.GetNumberOfCells(), step, own))
        eta = data.GetCellData().GetArray("estimator")
        if eta is None or eta.GetDataType() != VTK_DOUBLE or eta.GetNumberOfTuples() != data.GetNumberOfCells():
            problems.append("time %g: no double cell field estimator" % t)
        elif any(eta.GetValue(k) != own_eta[k] for k in range(len(own_eta))):
            problems.append("time %g: the indicators shown are not those of %s" % (t, step))
        first = point_fields(os.path.join(path, step, "solution.h5"))[0]
        if data.GetPointData().GetArray(first) is None:
            problems.append("time %g: no point field %s" % (t, first))
    return problems


def main(paths):
    ok = True
    for p in paths:
        problems = check_series(p) if os.path.exists(os.path.join(p, "adapt.xdmf")) else check(p)
        ok &= not problems
        print("paraview %-50s %s" % (p, "ok: all fields double" if not problems else "; ".join(problems)))
    return ok


if __name__ == "__main__":
    sys.exit(0 if main(sys.argv[1:]) else 1)
