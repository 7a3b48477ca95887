"""Opens Rust result directories with ParaView's own XDMF reader (headless) and checks that every
field is there, with the right size and in double precision: DIR/solution.xdmf (the mesh, vertex
fields) and DIR/dual.xdmf (the dual submesh S_h, cell fields), given to ParaView as absolute paths.

Usage (from the repository root):
    /usr/bin/python3 -m reference.paraview_check RESULT_DIR [...]
"""
import os
import sys

from paraview import servermanager
from paraview.simple import Xdmf3ReaderS

POINT_FIELDS = ("u1", "u2", "gap", "lambda", "lambda2", "contact")
VTK_DOUBLE = 11


def read(path):
    """The one unstructured grid of an XDMF file, as ParaView reads it."""
    reader = Xdmf3ReaderS(FileName=[os.path.abspath(path)])
    reader.UpdatePipeline()
    data = servermanager.Fetch(reader)
    while not data.IsA("vtkUnstructuredGrid"):
        data = data.GetBlock(0) if data.IsA("vtkMultiBlockDataSet") else data.GetPiece(0)
    return data


def check(path):
    """Checks DIR/solution.xdmf (the mesh) and DIR/dual.xdmf (the dual submesh)."""
    mesh = read(os.path.join(path, "solution.xdmf"))
    dual = read(os.path.join(path, "dual.xdmf"))
    problems = []
    for name in POINT_FIELDS:
        arr = mesh.GetPointData().GetArray(name)
        if arr is None:
            problems.append("point field %s missing" % name)
        elif arr.GetDataType() != VTK_DOUBLE or arr.GetNumberOfTuples() != mesh.GetNumberOfPoints():
            problems.append("point field %s: type %s, %d values"
                            % (name, arr.GetDataTypeAsString(), arr.GetNumberOfTuples()))
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


def main(paths):
    ok = True
    for p in paths:
        problems = check(p)
        ok &= not problems
        print("paraview %-50s %s" % (p, "ok: all fields double" if not problems else "; ".join(problems)))
    return ok


if __name__ == "__main__":
    sys.exit(0 if main(sys.argv[1:]) else 1)
