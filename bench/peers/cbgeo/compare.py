#!/usr/bin/env python3
"""Compare an otmpm result and a CB-Geo particle file after the same steps.

    python3 compare.py OTMPM.h5 CBGEO_particles.h5

OTMPM.h5: `otmpm run` of the block (fields x, v, stress; its last frame is
used); CBGEO file: results/block/particlesNNN.h5 of the CB-Geo run (the file
of 0-based step s holds the state after s + 1 steps).  Particles are matched
by index (make_block.py writes them in otmpm's seeding order; the initial
positions are checked).  Needs numpy and h5py.
"""
import sys

import h5py
import numpy as np

RHO, H = 1000.0, 1.0 / 200


def main():
    ot = h5py.File(sys.argv[1], "r")
    frames = sorted(ot["frames"].keys())
    last = ot["frames"][frames[-1]]
    x0 = ot["frames"][frames[0]]["x"][:]
    xo, vo, so = last["x"][:], last["v"][:], last["stress"][:]
    cb = h5py.File(sys.argv[2], "r")["table"][:]
    cb = cb[np.argsort(cb["id"])]
    xc = np.stack([cb["coord_x"], cb["coord_y"]], 1)
    x0c = xc - np.stack([cb["displacement_x"], cb["displacement_y"]], 1)
    vc = np.stack([cb["velocity_x"], cb["velocity_y"]], 1)
    syy_c = cb["stress_yy"]
    print("otmpm t = %r (%s)" % (last.attrs["time"], frames[-1]))
    print("initial positions: max |x0_ot - x0_cb| = %.3g" % np.abs(x0 - x0c).max())
    m = cb["mass"]
    ke_o = 0.5 * (m * (vo ** 2).sum(1)).sum()
    ke_c = 0.5 * (m * (vc ** 2).sum(1)).sum()
    print("kinetic energy: otmpm %.15g  cbgeo %.15g  rel diff %.3g"
          % (ke_o, ke_c, abs(ke_o - ke_c) / ke_c))
    k = int(np.argmin((x0[:, 0] - 0.5 + H / 4) ** 2 + (x0[:, 1] - 1.0) ** 2))
    print("top-centre particle %d at %s: v_y otmpm %.15g  cbgeo %.15g  rel diff %.3g"
          % (k, x0[k], vo[k, 1], vc[k, 1], abs(vo[k, 1] - vc[k, 1]) / abs(vc[k, 1])))
    uo, uc = xo[k, 1] - x0[k, 1], xc[k, 1] - x0c[k, 1]
    print("  u_y otmpm %.15g  cbgeo %.15g  rel diff %.3g" % (uo, uc, abs(uo - uc) / abs(uc)))
    vmax = np.abs(vc).max()
    print("all particles: max |v_ot - v_cb| / max |v| = %.3g (max |v| = %.6g)"
          % (np.abs(vo - vc).max() / vmax, vmax))
    syy_o = so[:, 3]  # 2D stress rows: xx, xy, yx, yy
    print("sigma_yy: max |ot - cb| / max |cb| = %.3g (max |sigma_yy| = %.6g Pa)"
          % (np.abs(syy_o - syy_c).max() / np.abs(syy_c).max(), np.abs(syy_c).max()))


if __name__ == "__main__":
    main()
