#!/usr/bin/env python3
"""granrepro's dense Contact Dynamics scene in Siconos: the settled deposit (at rest, or kicked
with the pile's gradient excitation) that `granrepro bench cd-dense` times, loaded disk by disk
from the CSV that command writes, so the two engines step the same grains side by side.

    granrepro bench cd-dense --scene-out DIR            # writes DIR/cd-dense-40x25-{rest,kick13mgd}.csv
    python3 dense.py DIR/cd-dense-40x25-rest.csv NSTEPS [H] [TOL]

Scene (src/cd/bench.rs, dense_scene): the 40 x 25 deposit of deposit.py (radii in 8 classes on
[0.4, 0.6] m, density 2600 kg/m^3 per metre, floor at y = 0, side walls at x = 0 and
x = 1.22 NCOL = 48.8 m) settled for 6 s and stopped; the kicked case then has v_x = k (y_max - y)
with sum(m v_x^2)/2 = 13 M g d_mean. Every disk starts at the CSV's position and velocity, at
rest in rotation. Contact law, time stepping and solver as deposit.py: Coulomb mu = 0.4,
Newton restitution 0, Moreau-Jean theta = 0.50001, H = 2e-3 s, SICONOS_FRICTION_2D_NSGS to
a relative residual TOL = 1e-4, at most 2000 sweeps.

Prints one line in the units of `granrepro bench cd-dense`: disks, steps, wall time, mean and
last contacts, mean and largest Gauss-Seidel sweeps per step, last residual,
contact*iterations/s and the steps that hit the sweep cap.
"""
import csv
import os
import sys

from siconos.io.mechanics_run import MechanicsHdf5Runner
from siconos.mechanics.collision.tools import Contactor

import nsgs_run

args = sys.argv[1:]
scene = args[0]
nsteps = int(args[1]) if len(args) > 1 else 100
h = float(args[2]) if len(args) > 2 else 2e-3
tol = float(args[3]) if len(args) > 3 else 1e-4

MU, E_N, WIDTH = 0.4, 0.0, 40 * 1.22
rows = list(csv.DictReader(open(scene)))
radii = sorted({round(float(r["r"]), 9) for r in rows})
out = os.path.splitext(os.path.basename(scene))[0] + ".hdf5"
if os.path.exists(out):
    os.remove(out)

with MechanicsHdf5Runner(io_filename=out) as io:
    for k, r in enumerate(radii):
        io.add_primitive_shape(f"disk{k}", "Disk", (r,), insideMargin=0.0, outsideMargin=0.0)
    height = 4 * max(float(r["y"]) for r in rows) + 4
    io.add_primitive_shape("floor", "Box2d", (WIDTH + 4, 1.0), insideMargin=0.0, outsideMargin=0.0)
    io.add_primitive_shape("side", "Box2d", (1.0, height), insideMargin=0.0, outsideMargin=0.0)
    io.add_Newton_impact_friction_nsl("contact", mu=MU, e=E_N)
    for n, row in enumerate(rows):
        r, m = float(row["r"]), float(row["m"])
        k = radii.index(round(r, 9))
        io.add_object(f"g{n}", [Contactor(f"disk{k}")], translation=[float(row["x"]), float(row["y"])],
                      velocity=[float(row["vx"]), float(row["vy"]), 0.0], mass=m, inertia=0.5 * m * r * r)
    io.add_object("floor", [Contactor("floor")], translation=[WIDTH / 2, -0.5])
    io.add_object("left", [Contactor("side")], translation=[-0.5, height / 2])
    io.add_object("right", [Contactor("side")], translation=[WIDTH + 0.5, height / 2])

wall, s = nsgs_run.run(out, nsteps, h, tol)
print(f"scene={os.path.basename(scene)} disks={len(rows)} steps={len(s)} h={h} tol={tol} wall_s={wall:.2f} "
      f"mean_contacts={s[:, 0].mean():.0f} last_contacts={s[-1, 0]:.0f} sweeps_per_step={s[:, 1].mean():.1f} "
      f"max_sweeps={s[:, 1].max():.0f} last_residual={s[-1, 2]:.2e} "
      f"contact_iterations_per_s={nsgs_run.contact_iterations_per_s(s, wall):.3g} capped_steps={int((s[:, 1] >= nsgs_run.MAX_SWEEPS).sum())}")
