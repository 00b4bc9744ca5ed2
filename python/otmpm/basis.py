"""otmpm.basis: the basis families of otmpm, evaluated at points (plots, teaching, checks).

    grid = otmpm.basis.Grid(lower=[0.0], upper=[1.0], cells=[10])
    ids, N, gradN = otmpm.basis.evaluate("lme", grid, points, gamma_lme=4)

The families are those of a scene's [basis] (docs/theory.md sect. 4):
linear, ugimp, bspline2, bspline3, lme, lme_box, maxent.
"""
import dataclasses
import reprlib

import numpy as np

from . import _otmpm

#: The basis families (basis.kind of a scene).
KINDS = tuple(_otmpm.basis_kinds())
#: The parameters of every family (the scene's [basis] keys), key -> default.
PARAMETERS = {row["key"]: row["default"] for row in _otmpm.basis_parameters()}

#: Largest cell count per axis and Newton iteration count (C++ ints).
_MAX_INT = 2**31 - 1


def _bad(what, value):
    """An InputError saying that `what` got `value` (reprlib's short repr: nesting and length bounded)."""
    return _otmpm.InputError(f"{what}, got {reprlib.repr(value)}")


def _number(name, value):
    """`value` as a float: an int or a float (NumPy's too), never a bool or a string."""
    v = value.item() if isinstance(value, np.generic) else value
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _bad(f"{name} must be a number", value)
    try:
        return float(v)
    except OverflowError:  # an int beyond the doubles
        raise _bad(f"{name} must be a number within the range of a double", value) from None


def _entries(name, v):
    """A number or a flat sequence (list, tuple, 1-D array) as a list of its entries.

    Never np.asarray(v, dtype=object) of a nested value: a ragged mix of
    arrays and lists makes NumPy raise ValueError (could not broadcast)."""
    if isinstance(v, np.ndarray):
        if v.ndim > 1:
            raise _bad(f"{name} must be a number or a flat list of numbers", v)
        return list(v.reshape(-1))
    if isinstance(v, (list, tuple)):
        return list(v)
    return [v]


def _floats(name, v):
    """A number or a sequence of numbers as a list of floats."""
    return [_number(name, x) for x in _entries(name, v)]


def _whole(name, value, lo, hi):
    """`value` as an int: a whole number from lo to hi (2.7 is refused, never taken as 2)."""
    n = _number(name, value)
    if not (n.is_integer() and lo <= n <= hi):
        raise _bad(f"{name} must be a whole number from {lo} to {hi}", value)
    return int(n)


@dataclasses.dataclass(frozen=True)
class Grid:
    """A Cartesian node lattice: `cells[k]` cells from lower[k] to upper[k] per axis
    (D = len(lower) = 1, 2 or 3). perturbation > 0 moves every interior node by a
    random vector with components uniform in [-perturbation h, perturbation h]
    (seeded by `seed`; perturbation < 0.5), as grid.kind = "perturbed"."""

    lower: tuple
    upper: tuple
    cells: tuple
    perturbation: float = 0.0
    seed: int = 1


class Basis:
    """A basis family on nodes.

    Basis(kind, nodes, h=None, *, ppc=2, **options)

    nodes: a Grid, or an (m, D) array of node positions (a cloud: lme and
    maxent only; h, the nodal spacing, is then required). options: the
    scene's [basis] keys of the families (PARAMETERS: key -> default), e.g.
    gamma_lme (LME: beta = gamma_lme / h^2), tolerance (LME support cut-off),
    newton_tolerance, max_newton_iterations, d_max (maxent support radius in
    h); ppc: uGIMP particles per cell (half-width h / (2 ppc)). Bad values
    raise otmpm.InputError, unknown keys TypeError.

    Attributes: kind, dimension, nodes ((m, D) positions of the nodes the
    functions belong to: the grid vertices, or the control points at the
    Greville abscissae for B-splines), spacing (h), linearly_complete.
    """

    def __init__(self, kind, nodes, h=None, *, ppc=2.0, **options):
        if not isinstance(kind, str):
            raise _bad(f"Basis: kind must be one of {', '.join(KINDS)}", kind)
        for key in options:
            if key not in PARAMETERS:
                raise TypeError(f"Basis() got an unexpected keyword argument '{key}' "
                                f"(the basis options are {', '.join(PARAMETERS)})")
        options = dict(options={key: _number(key, value) for key, value in options.items()}, ppc=_number("ppc", ppc))
        if isinstance(nodes, Grid):
            cells = [_whole("Grid.cells", c, 1, _MAX_INT) for c in _entries("Grid.cells", nodes.cells)]
            perturbation = _number("Grid.perturbation", nodes.perturbation)
            if not 0.0 <= perturbation < 0.5:  # NaN too: never taken as 0
                raise _bad("Grid.perturbation must be in [0, 0.5) (a fraction of h)", nodes.perturbation)
            self._basis = _otmpm.Basis.on_grid(kind, _floats("Grid.lower", nodes.lower),
                                               _floats("Grid.upper", nodes.upper), cells, perturbation,
                                               _whole("Grid.seed", nodes.seed, 0, 2**32 - 1), **options)
        else:
            if h is None:
                raise TypeError("Basis: a node cloud needs its nodal spacing h")
            try:
                positions = np.asarray(nodes, dtype=float)
            except (TypeError, ValueError, OverflowError) as e:
                raise _bad(f"Basis: nodes must be a Grid or an (m, D) array of numbers ({e})", nodes) from None
            self._basis = _otmpm.Basis.on_cloud(kind, positions, _number("h", h), **options)
        self.kind = self._basis.kind
        self.dimension = self._basis.dimension
        self.spacing = self._basis.spacing
        self.linearly_complete = self._basis.linearly_complete
        self.nodes = self._basis.nodes

    def evaluate(self, points):
        """(ids, N, gradN) at the points ((n, D) array; (n,) in 1D).

        ids (n, k) int64: the nodes of each point's stencil, k the largest
        stencil; N (n, k): N_I(x); gradN (n, k, D): grad N_I(x). Rows with
        fewer nodes are padded with id -1 and zeros, so N.sum(axis=1) and
        np.einsum("pk,pkd->pd", N, nodes[ids]) work on the whole array.
        Raises otmpm.BasisError naming the point when a point cannot be
        evaluated (outside the nodes' hull, ...).
        """
        try:
            points = np.asarray(points, dtype=float)
        except (TypeError, ValueError, OverflowError) as e:
            raise _bad(f"Basis.evaluate: points must be an (n, D) array of numbers ({e})", points) from None
        return self._basis.evaluate(points)

    def __repr__(self):
        return f"<otmpm.basis.Basis {self.kind}, {self.dimension}D, {len(self.nodes)} nodes, h = {self.spacing:.6g}>"


def evaluate(kind, nodes, points, h=None, **options):
    """Evaluates basis family `kind` on `nodes` at `points`: (ids, N, gradN).

    Basis(kind, nodes, h, **options).evaluate(points); see Basis for the
    nodes and options and Basis.evaluate for the arrays.
    """
    return Basis(kind, nodes, h, **options).evaluate(points)


__all__ = ["KINDS", "Grid", "Basis", "evaluate"]
