#!/usr/bin/python3
"""A custom diagnostic through the per-step callback: the speed of the
tension wave in the Dyka bar, measured while the simulation runs.

At t = 0 the left quarter of the bar moves at V0 = -5 m/s away from the
rest, which sends a tension wave of height rho c |V0| / 2 to the right from
x = L/4 at the bar speed c = sqrt(E / rho). After every step the callback
reads the stress and the initial positions (NumPy views of the engine's
arrays, no copy), finds where the stress crosses half the wave's height (the
front, linearly interpolated between particles) and keeps the energies of
the step. The measured speed is the slope of a line fitted to the front
positions; the plot shows the front against x = L/4 + c t and the energies
of every step:

    /usr/bin/python3 examples/python/wave_front.py [--mesh 133] [--out DIR]

writes DIR/wave_front.png.
"""
import argparse
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import otmpm  # noqa: E402

EXAMPLES = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class FrontTracker:
    """The per-step callback: front position and energies after every step."""

    def __init__(self, height):
        self.half = 0.5 * height
        self.t, self.front, self.energy = [], [], []

    def __call__(self, sim):
        X = sim.particles.X[:, 0]
        sxx = sim.particles.stress[:, 0, 0]
        ahead = np.nonzero(sxx >= self.half)[0]
        if len(ahead) and ahead.max() + 1 < len(X):
            p = ahead.max()  # the last particle (in X, the seeding order) at or above half the height
            s0, s1 = sxx[p], sxx[p + 1]
            self.front.append(X[p] + (X[p + 1] - X[p]) * (s0 - self.half) / (s0 - s1))
            self.t.append(sim.t)
        self.energy.append((sim.t, *(sim.energy()[k] for k in ("kinetic", "strain", "total"))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", type=int, default=133, help="h = L/MESH (examples/dyka/dyka_nMESH.toml)")
    ap.add_argument("--out", default=".", help="folder for the plot")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    scene = otmpm.Scene.from_toml(os.path.join(EXAMPLES, "dyka", f"dyka_n{args.mesh}.toml"))
    d = scene.to_dict()
    rho, E = d["material"][0]["density"], d["material"][0]["young"]
    L, V0 = d["body"][0]["upper"][0], d["initial_velocity"][0]["velocity"][0]
    c = math.sqrt(E / rho)
    t_reflect = 0.75 * L / c  # the front reaches the fixed end x = L
    scene = scene.with_overrides({"simulation.t_end": 0.95 * t_reflect})

    tracker = FrontTracker(rho * c * abs(V0) / 2)
    with otmpm.Simulation(scene, write_results=False, callback=tracker) as sim:
        sim.advance_to(sim.t_end)
    t, front = np.array(tracker.t), np.array(tracker.front)
    fit = (t > 0.1 * t_reflect) & (t < 0.9 * t_reflect)  # away from the start and the end
    speed, x0 = np.polyfit(t[fit], front[fit], 1)
    print(f"{sim.steps} steps, front tracked after {len(t)} of them")
    print(f"wave speed: measured {speed:.1f} m/s, c = sqrt(E/rho) = {c:.1f} m/s "
          f"({100 * (speed / c - 1):+.2f} %); front at t = 0: {x0 * 1e3:.3f} mm (L/4 = {L / 4 * 1e3:.3f} mm)")

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    a.plot(t * 1e6, front * 1e3, "C0-", lw=2.0, label="front (half the wave height), every step")
    a.plot(t * 1e6, (L / 4 + c * t) * 1e3, "k--", lw=1.0, label=f"L/4 + c t, c = {c:.0f} m/s")
    a.set(xlabel="t [us]", ylabel="x of the front [mm]", title=f"measured speed {speed:.0f} m/s")
    a.legend(loc="upper left")
    a.grid(alpha=0.3)
    e = np.array(tracker.energy)
    for k, (label, style) in enumerate((("kinetic", "C0-"), ("strain", "C1-"), ("kinetic + strain", "k-")), start=1):
        b.plot(e[:, 0] * 1e6, e[:, k], style, label=label)
    b.set(xlabel="t [us]", ylabel="energy per unit area [J/m^2] (1D)", title="energies after every step")
    b.legend(loc="center right")
    b.grid(alpha=0.3)
    fig.suptitle(f"Dyka bar, h = L/{args.mesh}, {scene.mode} {scene.basis} {scene.integrator}: per-step callback")
    fig.tight_layout()
    path = os.path.join(args.out, "wave_front.png")
    fig.savefig(path, dpi=120)
    print("plot:", path)


if __name__ == "__main__":
    main()
