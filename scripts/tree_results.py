"""otmpm.results of this source tree for the dev scripts beside it.

Loads python/otmpm/results.py by its path (the package's compiled module need
not be built), so that the scripts list the groups and attributes of a result
file the way the package does: h5py's own listing (`list(f["frames"])`,
`.keys()`, `.items()`, `visititems`, `dict(f.attrs)`) asks libhdf5 for the
names in increasing name order, which crashes libhdf5 1.10 (SIGSEGV) on a
result file whose writer was killed (its /frames records one link more than
its name index holds; docs/user-guide.md, "Damaged files").

    import tree_results                       # scripts/ is sys.path[0] for a script run from it
    names = tree_results.link_names(f["frames"])   # sorted; a RuntimeWarning when links are missing

scripts/render.py, installed on its own, keeps a copy of link_names instead.
"""
import importlib.util
import os
import sys

PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python", "otmpm", "results.py")


def _load():
    """The module python/otmpm/results.py, loaded once per interpreter."""
    name = "otmpm_tree_results"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, PATH)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


results = _load()
#: The names in an HDF5 group, sorted, safe on a killed run's file (otmpm.results.link_names).
link_names = results.link_names
#: The attribute names of an HDF5 object, sorted, listed the same way (otmpm.results.attribute_names).
attribute_names = results.attribute_names
