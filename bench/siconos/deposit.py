#!/usr/bin/env python3
"""granrepro's Contact Dynamics benchmark scene in Siconos: the deposit `granrepro bench cd`
times (src/cd/bench.rs, src/cd/pile.rs), so the two engines can be timed side by side.

    python3 deposit.py NCOL NROW NSTEPS [H] [TOL]       # e.g. 25 20 400

Scene: NCOL x NROW rigid disks, radii in 8 equal classes on [0.4, 0.6] m (d_max = 1.5 d_min),
density 2600 kg/m^3 (mass per metre of thickness, I = m r^2/2), dropped from a square lattice
of pitch 1.22 m (first row centred 0.61 m above the floor, x jittered by 0.01 m) into a box of
width 1.22 NCOL m with a floor and two side walls. Contact law: Coulomb mu = 0.4, Newton
restitution 0 (granrepro's CD pile values, docs/definitions.md b.4). Time stepping:
Moreau-Jean theta = 0.50001 (theta = 1/2 in granrepro), H = 2e-3 s; 2D friction-contact
nonlinear Gauss-Seidel (SICONOS_FRICTION_2D_NSGS) to a relative residual TOL = 1e-4, at most
2000 sweeps. The class of each disk and the jitter are Siconos's own random draw (seed 1):
the same scene, not the same grains.

Prints one line: disks, steps, wall time, steps/s, mean and last contact count, mean and
largest Gauss-Seidel sweeps, last residual, contact*iterations/s (the unit of
`granrepro bench cd`) and the number of steps that hit the sweep cap. Writes the Siconos
HDF5 file deposit_NCOLxNROW.hdf5 in the working directory.
"""
import os
import sys

import numpy as np
from siconos.io.mechanics_run import MechanicsHdf5Runner
from siconos.mechanics.collision.tools import Contactor

import nsgs_run

args = sys.argv[1:]
ncol = int(args[0]) if len(args) > 0 else 25
nrow = int(args[1]) if len(args) > 1 else 20
nsteps = int(args[2]) if len(args) > 2 else 400
h = float(args[3]) if len(args) > 3 else 2e-3
tol = float(args[4]) if len(args) > 4 else 1e-4

RHO, MU, E_N = 2600.0, 0.4, 0.0
PITCH = 1.22
classes = np.linspace(0.4, 0.6, 8)
width = ncol * PITCH
out = f"deposit_{ncol}x{nrow}.hdf5"
if os.path.exists(out):
    os.remove(out)

# ---- scene ------------------------------------------------------------------------------
rng = np.random.default_rng(1)
with MechanicsHdf5Runner(io_filename=out) as io:
    for k, r in enumerate(classes):
        io.add_primitive_shape(f"disk{k}", "Disk", (r,), insideMargin=0.0, outsideMargin=0.0)
    height = 2 * nrow * PITCH + 4
    io.add_primitive_shape("floor", "Box2d", (width + 4, 1.0), insideMargin=0.0, outsideMargin=0.0)
    io.add_primitive_shape("side", "Box2d", (1.0, height), insideMargin=0.0, outsideMargin=0.0)
    io.add_Newton_impact_friction_nsl("contact", mu=MU, e=E_N)
    n = 0
    for i in range(ncol):
        for j in range(nrow):
            k = rng.integers(len(classes))
            r = classes[k]
            m = RHO * np.pi * r * r
            x = (i + 0.5) * PITCH + 0.01 * rng.standard_normal()
            io.add_object(f"g{n}", [Contactor(f"disk{k}")], translation=[x, 0.5 * PITCH + j * PITCH],
                          velocity=[0, 0, 0], mass=m, inertia=0.5 * m * r * r)
            n += 1
    io.add_object("floor", [Contactor("floor")], translation=[width / 2, -0.5])
    io.add_object("left", [Contactor("side")], translation=[-0.5, nrow * PITCH])
    io.add_object("right", [Contactor("side")], translation=[width + 0.5, nrow * PITCH])

# ---- solver -----------------------------------------------------------------------------
wall, s = nsgs_run.run(out, nsteps, h, tol)
print(f"disks={ncol * nrow} steps={len(s)} h={h} tol={tol} wall_s={wall:.2f} steps_per_s={len(s) / wall:.1f} "
      f"mean_contacts={s[:, 0].mean():.0f} last_contacts={s[-1, 0]:.0f} mean_sweeps={s[:, 1].mean():.1f} "
      f"max_sweeps={s[:, 1].max():.0f} last_residual={s[-1, 2]:.2e} "
      f"contact_iterations_per_s={nsgs_run.contact_iterations_per_s(s, wall):.3g} capped_steps={int((s[:, 1] >= nsgs_run.MAX_SWEEPS).sum())}")
