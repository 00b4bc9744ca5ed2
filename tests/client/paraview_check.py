"""Opens otmpm result files in ParaView (run with pvpython) and checks what
a user sees: for each result file, its XDMF sidecar through both XDMF readers
(Xdmf3ReaderS, the recommended one, and the legacy XDMFReader) and its .pvd
collection (PVDReader) must give one time step per frame of the HDF5 file and,
at the last time step, one point and one vertex cell per particle and every
particle field as point data, with the values of the HDF5 file bit for bit
(read with h5py, so also for compressed files), and the points equal to x.

    pvpython paraview_check.py RESULT.h5...

Prints one line per file and reader; exits 1 on the first mismatch.
"""
import os
import sys

import h5py
import numpy as np
from paraview import servermanager
from paraview.simple import PVDReader, XDMFReader, Xdmf3ReaderS
from vtk.util.numpy_support import vtk_to_numpy


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def expected(path):
    """Times, particle count and fields (name -> values at the last frame) of a result file."""
    with h5py.File(path, "r") as f:
        names = sorted(f["frames"])
        times = [float(f["frames"][n].attrs["time"]) for n in names]
        last = f["frames"][names[-1]]
        fields = {k: last[k][:] for k in last if k not in ("x", "x3")}
        # A symmetric tensor stored by its components (output.symmetric_tensors) must
        # reach ParaView with exactly those (the legacy reader: as the full tensor).
        symmetric = {}
        for k in fields:
            if "components" in last[k].attrs:
                names = last[k].attrs["components"]
                symmetric[k] = (names.decode() if isinstance(names, bytes) else names).split()
                if fields[k].shape[1] != len(symmetric[k]):
                    fail(f"{path}: field {k} has {fields[k].shape[1]} columns for components {symmetric[k]}")
        # The points: the coordinates (the zero-padded copy x3 of a 1D x), read
        # through h5py like every field, whatever the storage (output.compression).
        fields[" points"] = last["x3" if "x3" in last else "x"][:]
        return times, last["x"].shape[0], int(f.attrs["dimension"]), fields, symmetric


def fetch(reader, time):
    """The dataset a reader produces at `time`, as a flat vtkDataSet."""
    reader.UpdatePipeline(time)
    data = servermanager.Fetch(reader)
    if data.IsA("vtkMultiBlockDataSet"):
        data = data.GetBlock(0)
    return data


def full_tensor(values, components, dimension):
    """Rows of a symmetric tensor's components (names like "xy") as row-major D*D rows."""
    axes = "xyz"
    full = np.empty((values.shape[0], dimension * dimension), dtype=values.dtype)
    for c, comp in enumerate(components):
        i, j = axes.index(comp[0]), axes.index(comp[1])
        full[:, i * dimension + j] = full[:, j * dimension + i] = values[:, c]
    return full


def check(path, name, reader, times, particles, dimension, fields, symmetric):
    got_times = list(reader.TimestepValues) if hasattr(reader.TimestepValues, "__len__") else [reader.TimestepValues]
    if len(got_times) != len(times) or not np.allclose(got_times, times, rtol=1e-12, atol=0):
        fail(f"{path} {name}: time steps {got_times} != frames at {times}")
    data = fetch(reader, times[-1])
    if data.GetNumberOfPoints() != particles or data.GetNumberOfCells() != particles:
        fail(f"{path} {name}: {data.GetNumberOfPoints()} points, {data.GetNumberOfCells()} cells; "
             f"expected {particles} of each (one vertex per particle)")
    point_data = data.GetPointData()
    got = {point_data.GetArrayName(i) for i in range(point_data.GetNumberOfArrays())}
    if got != set(fields) - {" points"}:
        fail(f"{path} {name}: point data {sorted(got)} != fields {sorted(fields)}")
    for field, values in fields.items():
        source = data.GetPoints().GetData() if field == " points" else point_data.GetArray(field)
        array = vtk_to_numpy(source).reshape(particles, -1)
        if name == "XDMFReader" and len(symmetric.get(field, ())) == 6 and array.shape[1] == 9:
            # The legacy reader expands an XDMF Tensor6 to the full 3 x 3 tensor (a 2D
            # stress "xx xy yy zz" is a 4-column Matrix: it arrives as stored).
            values = full_tensor(values, symmetric[field], dimension)
        cols = values.shape[1]
        # The legacy reader pads a D-component vector to 3 components with zeros (every reader the points).
        padded = (name == "XDMFReader" or field == " points") and cols == dimension and array.shape[1] == 3
        if array.shape[1] != cols and not padded:
            fail(f"{path} {name}: field {field} has {array.shape[1]} components, the HDF5 file {cols}")
        if array.dtype != values.dtype and field != " points":  # (points: any width holding the same values)
            fail(f"{path} {name}: field {field} is {array.dtype}, the HDF5 file {values.dtype}")
        if not np.array_equal(array[:, :cols], values) or np.any(array[:, cols:] != 0):
            fail(f"{path} {name}: field {field} differs from the HDF5 file")
    shapes = ", ".join(f"{k}: {point_data.GetArray(k).GetNumberOfComponents()} x {v.dtype}"
                       for k, v in sorted(fields.items()) if k != " points")
    print(f"ok: {os.path.basename(path)} {name}: {len(times)} time steps, {particles} points and vertex cells, "
          f"point data {shapes}")


def main():
    for path in sys.argv[1:]:
        times, particles, dimension, fields, symmetric = expected(path)
        stem = path[: -len(".h5")]
        check(path, "Xdmf3ReaderS", Xdmf3ReaderS(FileName=[stem + ".xdmf"]), times, particles, dimension, fields,
              symmetric)
        check(path, "XDMFReader", XDMFReader(FileNames=[stem + ".xdmf"]), times, particles, dimension, fields,
              symmetric)
        check(path, "PVDReader", PVDReader(FileName=stem + ".pvd"), times, particles, dimension, fields, symmetric)


main()
