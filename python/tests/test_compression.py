"""output.compression: otmpm.results reads a compressed result file (frame
datasets chunked with HDF5's shuffle + deflate filters, read through h5py)
into the same arrays as the uncompressed file of the same run."""
import h5py
import numpy as np

import otmpm
from conftest import example, run_cli


def test_compressed_file_reads_as_the_uncompressed_one(tmp_path):
    sets = ["simulation.t_end=4e-6", "output.every=1e-6", 'output.fields=["x", "v", "stress", "strain", "F"]']
    layouts = {"double": [], "single": ["output.precision=single", "output.symmetric_tensors=true"]}
    for layout, extra in layouts.items():
        files = {}
        for level in (0, 6):
            out = tmp_path / f"{layout}_{level}.h5"
            args = ["run", example("dyka_3d.toml"), "--out", out, "--quiet"]
            for s in sets + extra + [f"output.compression={level}"]:
                args += ["--set", s]
            done = run_cli(*args)
            assert done.returncode == 0, done.stderr
            files[level] = out
        with h5py.File(files[6], "r") as f, h5py.File(files[0], "r") as g:
            for name in ("x", "v", "stress", "strain", "F"):
                packed, plain = f["frames/000002"][name], g["frames/000002"][name]
                assert packed.compression == "gzip" and packed.compression_opts == 6 and packed.shuffle
                assert packed.chunks is not None and packed.chunks[1] == packed.shape[1]
                assert plain.compression is None and plain.chunks is None
        with otmpm.results.open(files[0]) as plain, otmpm.results.open(files[6]) as packed:
            assert len(packed.frames) == len(plain.frames) == 5
            assert np.array_equal(packed.times, plain.times)
            for field in ("x", "v", "stress", "strain", "F"):
                a, b = plain.field(field), packed.field(field)
                assert a.dtype == b.dtype == (np.float32 if layout == "single" else np.float64)
                assert a.shape == b.shape and np.array_equal(a, b)
            assert np.any(plain.field("stress") != 0)  # a loaded bar: not a comparison of zeros
            for key in plain.energy:
                assert np.array_equal(plain.energy[key], packed.energy[key])
