"""otmpm.basis: the basis families of otmpm, evaluated at points (plots, teaching, checks).

    grid = otmpm.basis.Grid(lower=[0.0], upper=[1.0], cells=[10])
    ids, N, gradN = otmpm.basis.evaluate("lme", grid, points, gamma_lme=4)

The families are those of a scene's [basis] (docs/theory.md sect. 4):
linear, ugimp, bspline2, bspline3, lme, maxent.
"""
import dataclasses

import numpy as np

from . import _otmpm

#: The basis families (basis.kind of a scene).
KINDS = ("linear", "ugimp", "bspline2", "bspline3", "lme", "maxent")


def _floats(v):
    """A number or a sequence of numbers as a list of floats."""
    return [float(x) for x in np.atleast_1d(v)]


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

    Basis(kind, nodes, h=None, gamma_lme=4.0, tolerance=1e-6, newton_tolerance=1e-12,
          max_newton_iterations=100, d_max=2.0, ppc=2)

    nodes: a Grid, or an (m, D) array of node positions (a cloud: lme and
    maxent only; h, the nodal spacing, is then required). Options as the
    scene's [basis]: gamma_lme (LME: beta = gamma_lme / h^2), tolerance (LME
    support cut-off), newton_tolerance, max_newton_iterations, d_max
    (maxent support radius in h); ppc: uGIMP particles per cell (half-width
    h / (2 ppc)). Bad options raise otmpm.InputError.

    Attributes: kind, dimension, nodes ((m, D) positions of the nodes the
    functions belong to: the grid vertices, or the control points at the
    Greville abscissae for B-splines), spacing (h), linearly_complete.
    """

    def __init__(self, kind, nodes, h=None, *, gamma_lme=4.0, tolerance=1e-6, newton_tolerance=1e-12,
                 max_newton_iterations=100, d_max=2.0, ppc=2.0):
        options = dict(gamma_lme=float(gamma_lme), tolerance=float(tolerance),
                       newton_tolerance=float(newton_tolerance),
                       max_newton_iterations=int(max_newton_iterations), d_max=float(d_max), ppc=float(ppc))
        if isinstance(nodes, Grid):
            self._basis = _otmpm.Basis.on_grid(kind, _floats(nodes.lower), _floats(nodes.upper),
                                               [int(c) for c in np.atleast_1d(nodes.cells)],
                                               float(nodes.perturbation), int(nodes.seed), **options)
        else:
            if h is None:
                raise TypeError("Basis: a node cloud needs its nodal spacing h")
            self._basis = _otmpm.Basis.on_cloud(kind, np.asarray(nodes, dtype=float), float(h), **options)
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
        return self._basis.evaluate(np.asarray(points, dtype=float))

    def __repr__(self):
        return f"<otmpm.basis.Basis {self.kind}, {self.dimension}D, {len(self.nodes)} nodes, h = {self.spacing:.6g}>"


def evaluate(kind, nodes, points, h=None, **options):
    """Evaluates basis family `kind` on `nodes` at `points`: (ids, N, gradN).

    Basis(kind, nodes, h, **options).evaluate(points); see Basis for the
    nodes and options and Basis.evaluate for the arrays.
    """
    return Basis(kind, nodes, h, **options).evaluate(points)


__all__ = ["KINDS", "Grid", "Basis", "evaluate"]
