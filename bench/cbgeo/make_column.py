#!/usr/bin/env python3
"""Write CB-Geo MPM (github.com/cb-geo/mpm) input files for granrepro's tall MPM column.

The scene is the quick profile's a = 6 Mohr-Coulomb column of `granrepro run --stage
col-mpm-a6 --set col-mpm.use_dem_calibration=false` (the chapter's table 4.3 material):

* 2D plane strain, unit thickness. Column area 1e-3 m^2 (the quick profile), a = 6:
  nominal L_0 = sqrt(1e-3/6) = 12.91 mm. granrepro snaps L_0 to whole cells (the gate must
  be a grid line) and H_0 = a L_0 to whole point spacings, so the column it runs is
  L_0 = 12 mm (6 cells) by H_0 = 72 mm; this script does the same (--no-snap keeps
  12.91 x 77.46 mm, with partly filled cells).
* Left wall at x = 0 and base at y = 0, Coulomb friction mu = 0.466 on both (CB-Geo's nodal
  "friction_constraints" plus a zero normal velocity); the right side is free from t = 0.
* Mohr-Coulomb, non-associated: rho = 1925 kg/m^3, E = 1.98e6 Pa, nu = 0.22,
  phi = 22.2 deg, psi = 0, c = 0, tension cut-off 0, no softening.
* Square cells h = 2 mm, 2 x 2 material points per cell (spacing 1 mm), uGIMP
  (CB-Geo's 16-node "ED2Q16G" cell; a ring of ghost nodes outside the grid gives the
  boundary cells their 16 nodes; the ghost nodes below the base and left of the wall carry
  the wall's constraints). --shape linear gives 4-node "ED2Q4" cells instead.
* Gravity 9.81 m/s^2. Initial stress geostatic, read from a file: sigma_yy = -rho g (H_0 - y),
  sigma_xx = sigma_zz = K_0 sigma_yy with K_0 = nu/(1 - nu) (tension positive, as CB-Geo).
* Explicit MPM, update stress last ("usl"), FLIP particle update (velocity_update false),
  no damping, dt = 1e-5 s (Courant ~0.17 on the P-wave speed), run to 0.45 s, particle
  output (HDF5) every 0.002 s.

Files written in OUT: input.json, mesh.txt, particles.txt, particles-volumes.txt,
particles-stresses.txt, entity_sets.json, and scene.json (for energies.py).  Run CB-Geo on them (the working directory argument needs its
trailing slash; -p sets the OpenMP threads):

    python3 make_column.py OUT
    mpm -f OUT/ -i input.json -p 1
    python3 energies.py OUT            # reads OUT/results/<uuid>/particles*.h5

Python 3 standard library only.
"""

import argparse
import json
import math
import os

RHO = 1925.0
YOUNG = 1.98e6
POISSON = 0.22
PHI_DEG = 22.2
WALL_MU = 0.466
G = 9.81


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", help="folder to write the inputs into")
    ap.add_argument("--aspect", type=float, default=6.0)
    ap.add_argument("--area", type=float, default=1.0e-3, help="column area [m^2]")
    ap.add_argument("--cell", type=float, default=2.0e-3, help="cell size h [m]")
    ap.add_argument("--ppc-1d", type=int, default=2, help="points per cell per direction")
    ap.add_argument("--no-snap", action="store_true",
                    help="keep the nominal L_0 = sqrt(area/a) instead of granrepro's snapped one")
    ap.add_argument("--xmax", type=float, default=0.30, help="grid width [m]")
    ap.add_argument("--ymax", type=float, default=0.10, help="grid height [m]")
    ap.add_argument("--dt", type=float, default=1.0e-5)
    ap.add_argument("--t-end", type=float, default=0.45)
    ap.add_argument("--output-every", type=float, default=2.0e-3, help="[s]")
    ap.add_argument("--shape", choices=["gimp", "linear"], default="gimp")
    ap.add_argument("--scheme", choices=["usl", "usf"], default="usl")
    ap.add_argument("--wall-friction", type=float, default=WALL_MU)
    ap.add_argument("--cohesion", type=float, default=0.0, help="[Pa]")
    ap.add_argument("--phi", type=float, default=PHI_DEG, help="friction angle [deg]")
    ap.add_argument("--k0", type=float, default=None, help="default nu/(1-nu)")
    ap.add_argument("--pic", action="store_true",
                    help="CB-Geo's velocity_update true: particle velocity = interpolated "
                         "nodal velocity (PIC) instead of FLIP")
    ap.add_argument("--keep-all", action="store_true",
                    help="stop with an error when a point leaves the grid (CB-Geo's "
                         "locate_particles true) instead of deleting it")
    args = ap.parse_args()

    h = args.cell
    s = h / args.ppc_1d  # point spacing
    a = args.aspect
    l0_nominal = math.sqrt(args.area / a)
    if args.no_snap:
        l0, h0 = l0_nominal, a * l0_nominal
        nx = int(round(l0 / s))
        ny = int(round(h0 / s))
        sx, sy = l0 / nx, h0 / ny
    else:
        # granrepro (src/mpm/column.rs): L_0 to whole cells, H_0 to whole spacings
        cells = max(1, int(round(l0_nominal / h)))
        nx = cells * args.ppc_1d
        ny = max(1, int(round(a * cells * h / s)))
        l0, h0 = nx * s, ny * s
        sx = sy = s
    k0 = args.k0 if args.k0 is not None else POISSON / (1.0 - POISSON)

    ncx = int(math.ceil(args.xmax / h - 1e-9))
    ncy = int(math.ceil(args.ymax / h - 1e-9))
    gimp = args.shape == "gimp"
    ghost = 1 if gimp else 0

    os.makedirs(args.out, exist_ok=True)

    # ---- nodes: ix in [-ghost, ncx + ghost], iy in [-ghost, ncy + ghost]
    nnx = ncx + 1 + 2 * ghost
    nny = ncy + 1 + 2 * ghost

    def nid(ix, iy):
        return (iy + ghost) * nnx + (ix + ghost)

    nodes = []
    for iy in range(-ghost, ncy + 1 + ghost):
        for ix in range(-ghost, ncx + 1 + ghost):
            nodes.append((ix * h, iy * h))
    cells = []
    for j in range(ncy):
        for i in range(ncx):
            c = [nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1)]
            if gimp:
                # ED2Q16G natural coordinates: corners, then the outer ring from (-3,-3)
                # counter-clockwise (include/elements/2d/quadrilateral_gimp_element.tcc)
                c += [nid(i - 1, j - 1), nid(i, j - 1), nid(i + 1, j - 1), nid(i + 2, j - 1),
                      nid(i + 2, j), nid(i + 2, j + 1), nid(i + 2, j + 2), nid(i + 1, j + 2),
                      nid(i, j + 2), nid(i - 1, j + 2), nid(i - 1, j + 1), nid(i - 1, j)]
            cells.append(c)
    with open(os.path.join(args.out, "mesh.txt"), "w") as f:
        f.write("%d %d\n" % (len(nodes), len(cells)))
        for x, y in nodes:
            f.write("%.10e %.10e\n" % (x, y))
        for c in cells:
            f.write(" ".join(str(n) for n in c) + "\n")

    # ---- node sets: 0 base (+ ghost row below), 1 left wall (+ ghost column)
    base = [nid(ix, iy) for iy in range(-ghost, 1) for ix in range(-ghost, ncx + 1 + ghost)]
    wall = [nid(ix, iy) for ix in range(-ghost, 1) for iy in range(-ghost, ncy + 1 + ghost)]

    # ---- particles: row by row from the base
    pts = [((i + 0.5) * sx, (j + 0.5) * sy) for j in range(ny) for i in range(nx)]
    with open(os.path.join(args.out, "particles.txt"), "w") as f:
        f.write("%d\n" % len(pts))
        for x, y in pts:
            f.write("%.10e %.10e\n" % (x, y))
    # volumes s_x s_y (CB-Geo's default, cell area / points in the cell, is wrong in the
    # partly filled cells of --no-snap); ids are the file order from 0
    with open(os.path.join(args.out, "particles-volumes.txt"), "w") as f:
        for k in range(len(pts)):
            f.write("%d %.10e\n" % (k, sx * sy))
    with open(os.path.join(args.out, "particles-stresses.txt"), "w") as f:
        f.write("%d\n" % len(pts))
        for _, y in pts:
            syy = -RHO * G * (h0 - y)
            sxx = k0 * syy
            # Voigt order xx yy zz xy yz xz, tension positive
            f.write("%.10e %.10e %.10e 0 0 0\n" % (sxx, syy, sxx))

    with open(os.path.join(args.out, "entity_sets.json"), "w") as f:
        json.dump({"node_sets": [{"id": 0, "set": base}, {"id": 1, "set": wall}],
                   "particle_sets": [{"id": 1, "set": list(range(len(pts)))}]}, f)

    nsteps = int(round(args.t_end / args.dt)) + 1
    out_steps = max(1, int(round(args.output_every / args.dt)))
    mu = args.wall_friction
    inp = {
        "title": "granrepro a=%g MPM column (quick profile)" % a,
        "mesh": {
            "mesh": "mesh.txt",
            "entity_sets": "entity_sets.json",
            "particles_volumes": "particles-volumes.txt",
            "particles_stresses": "particles-stresses.txt",
            "io_type": "Ascii2D",
            "check_duplicates": False,
            "isoparametric": False,
            "node_type": "N2D",
            "cell_type": "ED2Q16G" if gimp else "ED2Q4",
            "boundary_conditions": {
                "velocity_constraints": [
                    {"nset_id": 0, "dir": 1, "velocity": 0.0},
                    {"nset_id": 1, "dir": 0, "velocity": 0.0},
                ],
                # normal direction and the sign of the normal pointing into the wall
                "friction_constraints": [
                    {"nset_id": 0, "dir": 1, "sign_n": -1, "friction": mu},
                    {"nset_id": 1, "dir": 0, "sign_n": -1, "friction": mu},
                ],
            },
        },
        "particles": [{"generator": {
            "type": "file", "io_type": "Ascii2D", "location": "particles.txt",
            "check_duplicates": False, "pset_id": 0, "particle_type": "P2D",
            "material_id": 0}}],
        "materials": [{
            "id": 0, "type": "MohrCoulomb2D", "density": RHO,
            "youngs_modulus": YOUNG, "poisson_ratio": POISSON, "softening": False,
            "friction": args.phi, "dilation": 0.0, "cohesion": args.cohesion,
            "residual_friction": args.phi, "residual_dilation": 0.0,
            "residual_cohesion": args.cohesion, "peak_pdstrain": 0.0,
            "residual_pdstrain": 0.0, "tension_cutoff": 0.0}],
        "external_loading_conditions": {"gravity": [0.0, -G]},
        "analysis": {
            "type": "MPMExplicit2D", "mpm_scheme": args.scheme,
            # false: CB-Geo deletes a point that leaves the grid (a few points near the
            # gate's foot are shot out at several m/s; energies.py counts them)
            "locate_particles": bool(args.keep_all),
            "velocity_update": bool(args.pic), "dt": args.dt, "nsteps": nsteps,
            "uuid": "column-a%g" % a,
            "resume": {"resume": False}},
        "post_processing": {"path": "results/", "output_steps": out_steps, "vtk": []},
    }
    with open(os.path.join(args.out, "input.json"), "w") as f:
        json.dump(inp, f, indent=2)

    # scene summary for energies.py
    meta = {"L0": l0, "H0": h0, "cell": h, "ppc_1d": args.ppc_1d, "rho": RHO, "g": G,
            "dt": args.dt, "output_steps": out_steps, "points": len(pts), "shape": args.shape,
            "scheme": args.scheme, "k0": k0}
    with open(os.path.join(args.out, "scene.json"), "w") as f:
        json.dump(meta, f, indent=2)
    tau = math.sqrt(h0 / G)
    print("L_0 = %.5f m, H_0 = %.5f m, points %d (%d x %d), cells %d x %d, nodes %d, "
          "tau_c = %.5f s, steps %d, output every %d steps"
          % (l0, h0, len(pts), nx, ny, ncx, ncy, len(nodes), tau, nsteps, out_steps))


if __name__ == "__main__":
    main()
