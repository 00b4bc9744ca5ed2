"""Reads otmpm's VTK output without VTK (run with Debian's /usr/bin/python3):
the .vtu frames with meshio (Debian's python3-meshio; its version 5 has no
.vtp reader) and the .vtp frames with a small independent decoder of VTK's
raw appended format. Every frame's points and point data must equal the HDF5
result file's frame bit for bit, and the .pvd must list every frame with its time.
A distributed run's frames are .pvtp / .pvtu files naming one piece per rank:
the pieces, read in their order, must give the frame.

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


def read_serial(file, n):
    """Points, vertex cells, point data and the reader of one .vtu / .vtp file of n particles."""
    if file.endswith(".vtu"):
        mesh = meshio.read(file)
        cells = sum(len(c.data) for c in mesh.cells if c.type == "vertex")
        return mesh.points, cells, dict(mesh.point_data), "meshio"
    points, verts, point_data = read_vtp(file)
    if not np.array_equal(verts["connectivity"].ravel(), np.arange(n)):
        fail(f"{file}: vertex connectivity is not 0 .. {n - 1}")
    return points, len(verts["offsets"]), point_data, "vtp decoder"


def read_frame(file, n):
    """read_serial of a frame file, or of the pieces a .pvtp / .pvtu names, joined in order."""
    if not file.endswith((".pvtp", ".pvtu")):
        return read_serial(file, n)
    root = ET.parse(file).getroot()
    sources = [os.path.join(os.path.dirname(file), p.get("Source")) for p in root.iter("Piece")]
    if not sources:
        fail(f"{file}: names no piece")
    pieces = []
    for source in sources:
        count = int(re.search(rb'NumberOfPoints="(\d+)"', open(source, "rb").read(4096)).group(1))
        pieces.append(read_serial(source, count))
    points = np.concatenate([p[0] for p in pieces])
    point_data = {k: np.concatenate([np.asarray(p[2][k]).reshape(len(p[0]), -1) for p in pieces]) for k in pieces[0][2]}
    return points, sum(p[1] for p in pieces), point_data, pieces[0][3] + f" ({len(pieces)} pieces)"


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
        points, cells, point_data, reader = read_frame(file, n)
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
