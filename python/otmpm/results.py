"""otmpm.results: reading a result file (docs/user-guide.md, "The result file").

    with otmpm.results.open("dyka.h5") as r:
        print(r.status, r.attrs["steps"], r.errors)
        v = r.field("v")            # (frames, particles, D)
        A = r.probes["A"]           # time, x, v, stress
        E = r.energy                # time, kinetic, strain, external_work, reaction_work

Works on any otmpm result file, written by `otmpm run`, `otmpm pair`,
`otmpm study` or the Python package. Uses h5py (Debian: python3-h5py).
"""
import collections.abc
import os
import tomllib
import warnings

import numpy as np

#: Fields stored as D*D components per particle (row-major), returned as (n, D, D).
TENSOR_FIELDS = ("stress", "strain", "F")
#: Fields with one value per particle, returned as (n,).
SCALAR_FIELDS = ("volume", "mass", "density", "stress_zz")
#: 2D: plane strain's out-of-plane stress sigma_zz, (n,): the dataset of that
#: name (output.fields) or the "zz" column of a symmetric 2D stress.
OUT_OF_PLANE_STRESS = "stress_zz"


def _value(v):
    """An HDF5 attribute as a Python value: bytes -> str, NumPy scalars -> int/float."""
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def link_names(group):
    """The names in an HDF5 group, sorted. h5py's own iteration (`for name in
    group`, `sorted(group)`, `group.items()`) asks libhdf5 for the links in
    increasing name order, which crashes the interpreter (SIGSEGV inside
    libhdf5) on a group whose link table a killed run left half-written (its
    stored link count is one more than the links it holds); walking the
    name index in its native order does not. The links found are returned,
    with a RuntimeWarning naming the file and group when the stored count
    differs: a killed run's frames up to the one it was writing stay readable.
    OSError naming the file and group when HDF5 cannot list it (a damaged file)."""
    import h5py

    names = []
    try:
        group.id.links.iterate(names.append, idx_type=h5py.h5.INDEX_NAME, order=h5py.h5.ITER_NATIVE)
    except RuntimeError as e:  # h5py's error for a failed iteration, e.g. a metadata checksum mismatch
        raise OSError(f"{group.file.filename}: cannot list group {group.name}: {e} (the file is damaged)") from e
    if len(names) != len(group):  # len(): the stored count (H5Gget_info)
        warnings.warn(f"{group.file.filename}: group {group.name} records {len(group)} links but holds "
                      f"{len(names)} (a damaged file, e.g. left by a killed run): reading the {len(names)} found",
                      RuntimeWarning, stacklevel=2)
    return sorted(n.decode() for n in names)


def attribute_names(obj):
    """The names of the attributes of an HDF5 object, sorted, listed as
    link_names lists links (h5py's `attrs` iteration sorts a table libhdf5
    builds from the stored count, which crashes on a damaged file)."""
    import h5py

    names = []
    try:
        h5py.h5a.iterate(obj.id, names.append, index_type=h5py.h5.INDEX_NAME, order=h5py.h5.ITER_NATIVE)
    except RuntimeError as e:
        raise OSError(f"{obj.file.filename}: cannot list the attributes of {obj.name}: {e} (the file is damaged)") from e
    return sorted(n.decode() for n in names)


def unpack_symmetric(a, components, dimension):
    """Rows of a symmetric tensor stored by its independent components (the
    dataset attribute `components`, e.g. "xx xy xz yy yz zz") as (n, D*D)
    row-major rows, the layout of a file written without
    output.symmetric_tensors. Values keep their type (float32 stays float32).
    A component outside the D x D tensor - the "zz" (plane strain's sigma_zz)
    of a 2D stress, "xx xy yy zz" - is left out: Frame["stress_zz"] gives it."""
    names = _value(components).split()
    axes = "xyz"[:dimension]
    if a.ndim != 2 or a.shape[1] != len(names):
        raise ValueError(f"a symmetric tensor dataset of shape {a.shape} does not match its components {components!r}")
    full = np.empty((a.shape[0], dimension * dimension), dtype=a.dtype)
    for c, name in enumerate(names):
        if name[0] not in axes or name[1] not in axes:
            continue  # out of plane (2D "zz")
        i, j = axes.index(name[0]), axes.index(name[1])
        full[:, i * dimension + j] = a[:, c]
        full[:, j * dimension + i] = a[:, c]
    return full


def _array(name, data, dimension):
    """A dataset as an array; tensors (n, D*D) become (n, D, D), scalars (n, 1) become (n,).

    A symmetric tensor stored by its independent components (attribute
    `components`, output.symmetric_tensors) is expanded to the full tensor first.
    """
    a = data[()]
    components = data.attrs.get("components")
    if components is not None:
        a = unpack_symmetric(a, _value(components), dimension)
    if name in TENSOR_FIELDS and a.ndim == 2 and a.shape[1] == dimension * dimension:
        return a.reshape(a.shape[0], dimension, dimension)
    if name in SCALAR_FIELDS and a.ndim == 2 and a.shape[1] == 1:
        return a[:, 0]
    return a


class Frame(collections.abc.Mapping):
    """One frame: time (attribute) and its particle fields by name, read on access.

    frame["x"] is (particles, D); tensors (stress, strain, F) are (particles, D, D)
    with [p, i, j] = component ij, as Simulation.particles (also when the file
    stores only a symmetric tensor's independent components); scalars (volume, mass,
    density) are (particles,); other fields (a material's state) as stored.
    In 2D, frame["stress_zz"] is plane strain's out-of-plane stress sigma_zz,
    (particles,): the dataset stress_zz (output.fields) or the "zz" column of a
    symmetric stress ("xx xy yy zz", output.symmetric_tensors); a frame holding
    neither has no key "stress_zz" (files of otmpm before it, or other fields).
    """

    def __init__(self, group, dimension):
        self._group = group
        self._dimension = dimension
        self.name = group.name.rsplit("/", 1)[-1]
        self.time = float(group.attrs["time"])

    def _zz_column(self):
        """The column of sigma_zz in the frame's stress dataset, or None."""
        if self._dimension != 2 or "stress" not in self._group:
            return None
        components = self._group["stress"].attrs.get("components")
        names = _value(components).split() if components is not None else []
        return names.index("zz") if "zz" in names else None

    def __getitem__(self, field):
        if field == OUT_OF_PLANE_STRESS and field not in self._group:
            column = self._zz_column()
            if column is None:
                raise KeyError(field)
            return self._group["stress"][:, column]
        try:
            return _array(field, self._group[field], self._dimension)
        except KeyError:
            if field not in self._group:
                raise
            raise OSError(f"{self._group.file.filename}: cannot read {self._group.name}/{field} (a damaged file?)")
        except (OSError, RuntimeError) as e:
            raise OSError(f"{self._group.file.filename}: cannot read {self._group.name}/{field} (a damaged file?): {e}")

    def _names(self):
        names = link_names(self._group)
        if OUT_OF_PLANE_STRESS not in names and self._zz_column() is not None:
            names.append(OUT_OF_PLANE_STRESS)
        return names

    def __iter__(self):
        return iter(self._names())

    def __len__(self):
        return len(self._names())

    def __repr__(self):
        return f"<Frame {self.name} t={self.time:.6g}: {', '.join(self)}>"


class Results:
    """An open result file (read-only); use as a context manager or call close().

    attrs: every root attribute (strings decoded); status, dimension, scene
    (the resolved scene as a dict), scene_text (as TOML), errors (the
    rms_*/history_error_* attributes), frames (a list of Frame), times (the
    frames' times), probes (dict: name -> dict of arrays time, x, v, stress),
    energy (dict of arrays: time, kinetic, strain, external_work,
    reaction_work[, dissipated][, friction, impact][, darcy, pressure_average][, relaxation]). field(name) stacks a field
    over all frames.
    """

    def __init__(self, path):
        import h5py  # here, not at the top: `import otmpm` stays quick for those who never read a file

        self.path = os.fsdecode(path) if isinstance(path, (str, bytes, os.PathLike)) else str(path)
        if os.path.exists(self.path) and not os.path.isfile(self.path):  # a FIFO would block h5py for ever
            raise OSError(f"{self.path}: not a regular file (a directory, FIFO or device), not a result file")
        _restore_killed(self.path)
        try:
            self._file = h5py.File(self.path, "r")
        except OSError as e:  # h5py's message does not name the file
            raise OSError(f"{self.path}: cannot open it as a result file: {e}") from e
        try:
            self._read()
        except BaseException as e:
            self._file.close()
            # As they are: KeyboardInterrupt, a warning raised under warnings.simplefilter("error")
            # (link_names' RuntimeWarning), an OSError that names the file already.
            named = isinstance(e, OSError) and str(e).startswith(self.path + ": ")
            if not isinstance(e, Exception) or isinstance(e, Warning) or named:
                raise
            # h5py's errors for damaged metadata, a file of another program (TypeError, AttributeError, ...)
            raise OSError(f"{self.path}: cannot read it as a result file (a damaged file, or another program's?): "
                          f"{type(e).__name__}: {e}") from e

    def _read(self):
        self.attrs = {k: _value(self._file.attrs[k]) for k in attribute_names(self._file)}
        self.status = self.attrs.get("status")
        self.dimension = self.attrs["dimension"]
        if type(self.dimension) is not int or self.dimension not in (1, 2, 3):
            raise ValueError(f"the attribute 'dimension' is {self.dimension!r:.80}, not 1, 2 or 3")
        self.scene_text = self.attrs.get("scene", "")
        frames = self._file["frames"] if "frames" in self._file else None
        self.frames = [Frame(frames[name], self.dimension) for name in link_names(frames)] if frames is not None else []
        self.times = np.array([f.time for f in self.frames])
        probes = self._file["probes"] if "probes" in self._file else None
        self.probes = {name: self._series(probes[name]) for name in link_names(probes)} if probes is not None else {}
        self.energy = self._series(self._file["energy"]) if "energy" in self._file else {}

    def _series(self, group):
        return {name: _array(name, group[name], self.dimension) for name in link_names(group)}

    @property
    def scene(self):
        """The resolved scene (after overrides) as a dict, read from the `scene` attribute."""
        return tomllib.loads(self.scene_text)

    @property
    def errors(self):
        """The errors against the exact solution stored in the file (rms_*_error, history_error_*)."""
        return {k: v for k, v in self.attrs.items() if k.startswith(("rms_", "history_error_"))}

    def field(self, name):
        """Field `name` of every frame stacked: (frames, particles, ...). KeyError if a frame lacks it."""
        return np.stack([f[name] for f in self.frames])

    def close(self):
        """Closes the file (the frames can no longer be read)."""
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return f"<otmpm.results.Results '{self.path}': status {self.status!r}, {len(self.frames)} frames>"


def _restore_killed(path):
    """Undoes a flush that a kill cut short (the undo journal otmpm's writer leaves beside the file).

    Through otmpm's compiled part; the copy of this module that otmpm's scripts use alone (share/otmpm)
    has none, and the otmpm command that starts them has restored the file already."""
    try:
        from ._otmpm import InputError, _roll_back_interrupted_flush
    except ImportError:
        return
    try:
        _roll_back_interrupted_flush(path)
    except InputError as e:
        raise OSError(f"{path}: cannot restore it after its writer was killed: {e}") from e


def open(path):  # noqa: A001 - the module's one entry point, as in h5py.File / builtins.open
    """Opens the result file `path` (an .h5 written by otmpm) for reading: a Results.

    While a run still writes the file, HDF5's file locking refuses it
    (BlockingIOError); set HDF5_USE_FILE_LOCKING=FALSE to peek at a running result.
    A damaged file raises OSError naming it; the file of a killed run gives
    the frames it holds, with a RuntimeWarning when its last frame was left
    half-linked (docs/user-guide.md, "Damaged files").
    """
    return Results(path)


__all__ = ["open", "Results", "Frame", "TENSOR_FIELDS", "SCALAR_FIELDS", "OUT_OF_PLANE_STRESS", "unpack_symmetric"]
