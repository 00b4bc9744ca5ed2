"""otmpm.basis from Python: partition of unity and linear completeness of
every family on random points (docs/theory.md sect. 4)."""
import numpy as np
import pytest

import otmpm
from otmpm.basis import Basis, Grid

RNG = np.random.default_rng(16)
#: LME and max-ent solve for N to newton_tolerance * h: the identities hold to about 1e-12.
TOL = 1e-10


def random_points(grid, n=200):
    lower, upper = np.asarray(grid.lower, float), np.asarray(grid.upper, float)
    return lower + (upper - lower) * RNG.uniform(0.001, 0.999, size=(n, len(lower)))


def grids():
    yield Grid(lower=[0.0], upper=[1.0], cells=[10])
    yield Grid(lower=[-1.0, 0.0], upper=[1.0, 0.5], cells=[8, 3])
    yield Grid(lower=[0.0, 0.0, 0.0], upper=[1.0, 2.0, 1.0], cells=[3, 4, 3])


def check_identities(basis, points, complete=True):
    ids, N, dN = basis.evaluate(points)
    n, D = points.shape
    assert ids.shape == N.shape and dN.shape == N.shape + (D,)
    assert (N[ids < 0] == 0).all() and (N >= -TOL).all()
    xI = basis.nodes[ids]  # padding rows (id -1) have N = 0
    h = basis.spacing
    np.testing.assert_allclose(N.sum(axis=1), 1.0, rtol=0, atol=TOL)  # sum_I N_I = 1
    np.testing.assert_allclose(dN.sum(axis=1), 0.0, rtol=0, atol=TOL / h)  # sum_I grad N_I = 0
    if complete:
        np.testing.assert_allclose(np.einsum("pk,pkd->pd", N, xI), points, rtol=0, atol=TOL * h)  # sum N_I x_I = x
        grad_x = np.einsum("pkd,pke->ped", dN, xI)  # sum_I x_I (x) grad N_I = identity
        np.testing.assert_allclose(grad_x, np.broadcast_to(np.eye(D), grad_x.shape), rtol=0, atol=TOL)


@pytest.mark.parametrize("kind", ["linear", "bspline2", "bspline3", "lme", "lme_box", "maxent"])
@pytest.mark.parametrize("grid", list(grids()), ids=["1d", "2d", "3d"])
def test_partition_of_unity_and_linear_completeness(kind, grid):
    basis = Basis(kind, grid, gamma_lme=2.0)
    assert basis.linearly_complete and basis.dimension == len(grid.lower)
    check_identities(basis, random_points(grid))


@pytest.mark.parametrize("grid", list(grids()), ids=["1d", "2d", "3d"])
def test_ugimp_is_a_partition_of_unity(grid):
    basis = Basis("ugimp", grid, ppc=2)
    assert not basis.linearly_complete
    check_identities(basis, random_points(grid), complete=False)


@pytest.mark.parametrize("kind", ["linear", "lme", "lme_box"])
def test_perturbed_grid(kind):
    grid = Grid(lower=[0.0, 0.0], upper=[1.0, 1.0], cells=[6, 6], perturbation=0.2, seed=3)
    basis = Basis(kind, grid)
    lattice = np.stack(np.meshgrid(np.linspace(0, 1, 7), np.linspace(0, 1, 7), indexing="xy"), -1).reshape(-1, 2)
    assert not np.allclose(basis.nodes, lattice)  # the interior nodes moved
    check_identities(basis, random_points(grid))


@pytest.mark.parametrize("kind", ["lme", "lme_box", "maxent"])
def test_node_cloud(kind):
    h = 0.125
    lattice = np.stack(np.meshgrid(np.arange(9) * h, np.arange(9) * h), -1).reshape(-1, 2)
    nodes = lattice + RNG.uniform(-0.3 * h, 0.3 * h, size=lattice.shape)  # a jittered lattice
    basis = Basis(kind, nodes, h=h, gamma_lme=1.0, d_max=3.0)
    check_identities(basis, random_points(Grid(lower=[0.1, 0.1], upper=[0.9, 0.9], cells=[1, 1]), 50))


def test_evaluate_function_and_1d_points():
    ids, N, dN = otmpm.basis.evaluate("linear", Grid(lower=[0.0], upper=[1.0], cells=[4]), [0.1, 0.8])
    first = dict(zip(ids[0].tolist(), zip(N[0], dN[0, :, 0])))
    assert first.keys() == {0, 1}  # x = 0.1 lies in the first cell, h = 0.25
    np.testing.assert_allclose(first[0], (0.6, -4.0))
    np.testing.assert_allclose(first[1], (0.4, 4.0))
    assert sorted(ids[1].tolist()) == [3, 4]


def test_bad_input():
    with pytest.raises(otmpm.InputError, match="unknown basis kind 'cubic'"):
        Basis("cubic", Grid(lower=[0.0], upper=[1.0], cells=[4]))
    with pytest.raises(otmpm.InputError, match="gamma_lme must be > 0"):
        Basis("lme", Grid(lower=[0.0], upper=[1.0], cells=[4]), gamma_lme=0)
    with pytest.raises(otmpm.BasisError, match="not finite"):
        Basis("lme", Grid(lower=[0.0], upper=[1.0], cells=[4])).evaluate([[np.nan]])
    with pytest.raises(ValueError, match=r"shape \(n, 2\)"):
        Basis("linear", Grid(lower=[0.0, 0.0], upper=[1.0, 1.0], cells=[2, 2])).evaluate([0.5, 0.5])


@pytest.mark.parametrize("field, value", [
    ("cells", [np.zeros((2, 2)), [np.nan, ["x"]]]),  # ragged: NumPy cannot even make an object array of it
    ("cells", np.ones((2, 2))),
    ("lower", [[], {"fe": {}}, [3, [], -np.inf]]),
    ("upper", [np.zeros(2), 1.0]),
])
def test_nested_grid_fields_are_input_errors(field, value):
    fields = dict(lower=[0.0, 0.0], upper=[1.0, 1.0], cells=[2, 2])
    fields[field] = value
    with pytest.raises(otmpm.InputError, match=f"Grid.{field} must be"):
        Basis("lme", Grid(**fields), gamma_lme=1)
