"""Opens a node-cloud .vtu (write_node_cloud_vtu) with VTK's XML reader, the one ParaView uses,
and checks what it got: the number of points, one VTK_VERTEX cell per point, the named point
arrays with one tuple per point and finite values, and optionally the first value of an array
(exact: the writer promises a bit-for-bit round trip). Exits non-zero on the first mismatch.
Usage: check_node_cloud_vtu.py <file.vtu> <number of points> <array>[=<first value>] ..."""
import math
import sys

import vtk
from vtk.util.numpy_support import vtk_to_numpy

if len(sys.argv) < 3:
    sys.exit(__doc__)
path, expected_points = sys.argv[1], int(sys.argv[2])

reader = vtk.vtkXMLUnstructuredGridReader()
reader.SetFileName(path)
reader.Update()
# A malformed array is dropped with an error message but no exception: count the errors too.
if reader.GetErrorCode() != 0:
    sys.exit(f"{path}: VTK reader error code {reader.GetErrorCode()}")
grid = reader.GetOutput()
if grid.GetNumberOfPoints() != expected_points:
    sys.exit(f"{path}: {grid.GetNumberOfPoints()} points, expected {expected_points}")
if grid.GetNumberOfCells() != expected_points:
    sys.exit(f"{path}: {grid.GetNumberOfCells()} cells, expected one per point ({expected_points})")
for cell in range(grid.GetNumberOfCells()):
    if grid.GetCellType(cell) != vtk.VTK_VERTEX:
        sys.exit(f"{path}: cell {cell} has type {grid.GetCellType(cell)}, not VTK_VERTEX")

data = grid.GetPointData()
for spec in sys.argv[3:]:
    name, _, first = spec.partition("=")
    array = data.GetArray(name)
    if array is None:
        names = [data.GetArrayName(k) for k in range(data.GetNumberOfArrays())]
        sys.exit(f"{path}: no point array '{name}' (has {names})")
    if array.GetNumberOfTuples() != expected_points:
        sys.exit(f"{path}: '{name}' has {array.GetNumberOfTuples()} tuples, expected {expected_points}")
    values = vtk_to_numpy(array).ravel()
    if not all(math.isfinite(float(v)) for v in values):
        sys.exit(f"{path}: '{name}' has non-finite values")
    if first and float(values[0]) != float(first):
        sys.exit(f"{path}: '{name}' starts with {float(values[0])!r}, expected {float(first)!r}")
print(f"{path}: {expected_points} points open in VTK with {len(sys.argv) - 3} arrays as expected")
