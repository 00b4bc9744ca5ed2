"""Reads otmpm's VTK output without VTK (run with Debian's /usr/bin/python3):
the .vtu frames with meshio (Debian's python3-meshio; its version 5 has no
.vtp reader) and the .vtp frames with a small independent decoder of VTK's
raw appended format. Every frame's points and point data must equal the HDF5
result file's frame bit for bit, and the .pvd must list every frame with its time.

    python3 vtk_files_check.py RESULT.h5...
"""
import os
import re
import sys
import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np

TYPES = {"Float64": np.float64, "Float32": np.float32, "Int64": np.int64, "UInt8": np.uint8}


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def read_vtp(path):
    """Points, vertex connectivity and point data of a raw-appended .vtp file."""
    raw = open(path, "rb").read()
    start = raw.index(b"<AppendedData")
    data = raw[raw.index(b"_", start) + 1:]
    root = ET.fromstring(raw[:start] + b"</VTKFile>")
    if root.get("type") != "PolyData" or root.get("header_type") != "UInt64":
        fail(f"{path}: not a PolyData file with UInt64 headers")
    order = "<" if root.get("byte_order") == "LittleEndian" else ">"

    def array(element):
        offset = int(element.get("offset"))
        n = int(np.frombuffer(data, dtype=order + "u8", count=1, offset=offset)[0])
        dtype = np.dtype(TYPES[element.get("type")]).newbyteorder(order)
        values = np.frombuffer(data, dtype=dtype, count=n // dtype.itemsize, offset=offset + 8)
        return values.reshape(-1, int(element.get("NumberOfComponents", "1")))

    piece = root.find("PolyData/Piece")
    points = array(piece.find("Points/DataArray"))
    verts = {a.get("Name"): array(a) for a in piece.find("Verts")}
    point_data = {a.get("Name"): array(a) for a in piece.find("PointData")}
    return points, verts, point_data


def frame_of(path, index):
    with h5py.File(path, "r") as f:
        g = f["frames"][f"{index:06d}"]
        return float(g.attrs["time"]), {k: g[k][:] for k in g if k != "x3"}, len(f["frames"])


def check(path):
    stem = path[: -len(".h5")]
    pvd = ET.parse(stem + ".pvd").getroot()
    entries = pvd.findall("Collection/DataSet")
    _, _, frames = frame_of(path, 0)
    if len(entries) != frames:
        fail(f"{stem}.pvd lists {len(entries)} frames, the HDF5 file has {frames}")
    for index, entry in enumerate(entries):
        time, fields, _ = frame_of(path, index)
        if float(entry.get("timestep")) != time:
            fail(f"{stem}.pvd: frame {index} at t = {entry.get('timestep')}, the HDF5 file says {time}")
        file = os.path.join(os.path.dirname(stem + ".pvd"), entry.get("file"))
        x = fields.pop("x")
        n, d = x.shape
        if file.endswith(".vtu"):
            mesh = meshio.read(file)
            points, point_data = mesh.points, mesh.point_data
            cells = sum(len(c.data) for c in mesh.cells if c.type == "vertex")
            reader = "meshio"
        else:
            points, verts, point_data = read_vtp(file)
            cells = len(verts["offsets"])
            if not np.array_equal(verts["connectivity"].ravel(), np.arange(n)):
                fail(f"{file}: vertex connectivity is not 0 .. {n - 1}")
            reader = "vtp decoder"
        if points.shape != (n, 3) or not np.array_equal(points[:, :d], x) or np.any(points[:, d:] != 0):
            fail(f"{file} ({reader}): points differ from x of the HDF5 frame")
        if cells != n:
            fail(f"{file} ({reader}): {cells} vertex cells for {n} particles")
        if set(point_data) != set(fields):
            fail(f"{file} ({reader}): point data {sorted(point_data)} != fields {sorted(fields)}")
        for name, values in fields.items():
            got = np.asarray(point_data[name]).reshape(n, -1)
            if not np.array_equal(got, values.reshape(n, -1)):
                fail(f"{file} ({reader}): field {name} differs from the HDF5 frame")
    print(f"ok: {os.path.basename(stem)}.pvd: {frames} frames read with {reader}, equal to the HDF5 file bit for bit")


for result in sys.argv[1:]:
    check(result)
