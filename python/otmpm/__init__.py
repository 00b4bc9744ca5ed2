"""otmpm from Python: run, step and inspect MPM and OTM-style updated-Lagrangian
simulations with NumPy views of the engine's arrays (docs/python.md).

    import otmpm
    scene = otmpm.Scene.from_toml("examples/dyka/dyka_n40.toml", overrides={"basis.gamma_lme": 2})
    summary = otmpm.run(scene, out="dyka.h5")
    print(summary.errors["rms_velocity_error"])

    with otmpm.Simulation(scene, out="by_hand.h5") as sim:
        sim.advance_to(5e-5)
        v = sim.particles.v          # a view: no copy, changes with every step

Contents: Scene, run, Simulation, Summary, pair, study, the modules basis, convergence
and results, and the errors InputError, InstabilityError, BasisError.
"""
from . import basis, convergence, results
from ._otmpm import BasisError, InputError, InstabilityError, Scene, Simulation, __version__, run
from .drivers import pair, study
from .summary import Summary

__all__ = ["Scene", "run", "Simulation", "Summary", "pair", "study", "basis", "convergence", "results",
           "InputError", "InstabilityError", "BasisError", "__version__"]
