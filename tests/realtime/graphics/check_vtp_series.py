"""Opens what VtkTimeSeriesWriter wrote with VTK's XML readers (the ones ParaView uses): both
.pvd collections must parse, list the same timesteps, and every dataset must load with its
arrays (finite, right component counts) and its time_s matching the collection's timestep.
Usage: check_vtp_series.py <output folder> <base name> <expected number of frames>"""
import math
import pathlib
import sys
import xml.etree.ElementTree as ET

import vtk
from vtk.util.numpy_support import vtk_to_numpy

out = pathlib.Path(sys.argv[1])
base = sys.argv[2]
expected = int(sys.argv[3])


def fail(message):
    sys.exit(f"check_vtp_series: {message}")


def read(path):
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    data = reader.GetOutput()
    if data.GetNumberOfPoints() == 0 or data.GetNumberOfCells() == 0:
        fail(f"{path}: empty or unreadable")
    return data


def array(path, attributes, name, components):
    values = attributes.GetArray(name)
    if values is None:
        fail(f"{path}: no array '{name}'")
    if values.GetNumberOfComponents() != components:
        fail(f"{path}: '{name}' has {values.GetNumberOfComponents()} components, expected {components}")
    numbers = vtk_to_numpy(values)
    if not all(math.isfinite(v) for v in numbers.ravel()):
        fail(f"{path}: '{name}' has non-finite values")
    return numbers


timesteps = {}
for part in ("organ", "tool"):
    pvd = out / f"{base}_{part}.pvd"
    try:
        root = ET.parse(pvd).getroot()
    except (OSError, ET.ParseError) as error:
        fail(f"{pvd}: {error}")
    if root.get("type") != "Collection":
        fail(f"{pvd}: not a VTK collection")
    datasets = list(root.iter("DataSet"))
    if len(datasets) != expected:
        fail(f"{pvd}: {len(datasets)} datasets, expected {expected}")
    timesteps[part] = []
    for dataset in datasets:
        path = pvd.parent / dataset.get("file")
        time = float(dataset.get("timestep"))
        timesteps[part].append(time)
        data = read(path)
        if abs(vtk_to_numpy(data.GetFieldData().GetArray("time_s"))[0] - time) > 0:
            fail(f"{path}: time_s differs from the collection's timestep {time}")
        if part == "organ":
            displacement = array(path, data.GetPointData(), "displacement_m", 3)
            magnitude = array(path, data.GetPointData(), "displacement_magnitude_m", 1)
            if abs(magnitude - (displacement**2).sum(axis=1) ** 0.5).max() > 1e-15:
                fail(f"{path}: displacement_magnitude_m is not |displacement_m|")
        else:
            force = array(path, data.GetPointData(), "force_on_hand_N", 3)
            if abs(force[1:]).max() > 0:
                fail(f"{path}: force_on_hand_N is not zero away from the tip point")
            if data.GetFieldData().GetArray("in_contact") is None:
                fail(f"{path}: no field data 'in_contact'")
    if timesteps[part] != sorted(timesteps[part]):
        fail(f"{pvd}: timesteps not increasing")
if timesteps["organ"] != timesteps["tool"]:
    fail("the organ and tool collections list different timesteps")
print(f"{2 * expected} datasets from 2 .pvd files open in VTK with finite, consistent arrays")
