"""Opens what `touchstone fem` wrote with VTK's XML readers (the ones ParaView uses): every
.pvd's datasets must load, with the displacement and stress fields on every point and finite
values. Usage: check_vtu_opens.py <output folder>"""
import math
import pathlib
import sys
import xml.etree.ElementTree as ET

import vtk
from vtk.util.numpy_support import vtk_to_numpy

out = pathlib.Path(sys.argv[1])
pvds = sorted(out.glob("*.pvd"))
if not pvds:
    sys.exit(f"no .pvd in {out}")
checked = 0
for pvd in pvds:
    for dataset in ET.parse(pvd).getroot().iter("DataSet"):
        path = pvd.parent / dataset.get("file")
        reader = vtk.vtkXMLPUnstructuredGridReader() if path.suffix == ".pvtu" else vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(path))
        reader.Update()
        grid = reader.GetOutput()
        if grid.GetNumberOfPoints() == 0 or grid.GetNumberOfCells() == 0:
            sys.exit(f"{path}: empty grid")
        data = grid.GetPointData()
        for name in ("displacement_m", "von_mises_Pa", "stress_zz_Pa"):
            array = data.GetArray(name)
            if array is None:
                sys.exit(f"{path}: no point array '{name}'")
            values = vtk_to_numpy(array)
            if not all(math.isfinite(v) for v in values.ravel()):
                sys.exit(f"{path}: '{name}' has non-finite values")
        if data.GetArray("displacement_m").GetNumberOfComponents() != 3:
            sys.exit(f"{path}: displacement is not a 3-vector")
        checked += 1
print(f"{checked} datasets from {len(pvds)} .pvd files open in VTK with finite displacement and stress")
