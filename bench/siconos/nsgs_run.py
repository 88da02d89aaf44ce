"""The run both Siconos scripts share (deposit.py, dense.py): Moreau-Jean theta = 0.50001, one
Newton iteration, Bullet contact detection (breaking threshold 0.02 m), the 2D friction-contact
nonlinear Gauss-Seidel (SICONOS_FRICTION_2D_NSGS) to a relative residual TOL, at most
MAX_SWEEPS sweeps; every step's contacts, sweeps and residual recorded."""
import time

import numpy as np
import siconos.kernel as sk
import siconos.numerics as sn
from siconos.io.mechanics_run import MechanicsHdf5Runner
from siconos.mechanics.collision.bullet import SiconosBulletOptions

MAX_SWEEPS = 2000


def run(out, nsteps, h, tol):
    """Run the scene in the HDF5 file `out`; return (wall seconds, per-step array of
    (contacts, sweeps, residual))."""
    bullet = SiconosBulletOptions()
    bullet.worldScale = 1.0
    bullet.contactBreakingThreshold = 0.02
    nsgs = sk.solver_options_create(sn.SICONOS_FRICTION_2D_NSGS)
    nsgs.iparam[sn.SICONOS_IPARAM_MAX_ITER] = MAX_SWEEPS
    nsgs.dparam[sn.SICONOS_DPARAM_TOL] = tol
    per_step = []

    def record(runner):
        problem = runner._simulation.oneStepNSProblem(0)
        opts = problem.numericsSolverOptions()
        per_step.append((problem.getSizeOutput() // 2, opts.iparam[sn.SICONOS_IPARAM_ITER_DONE],
                         opts.dparam[sn.SICONOS_DPARAM_RESIDU]))

    t0 = time.time()
    with MechanicsHdf5Runner(mode="r+", io_filename=out) as io:
        io.run(with_timer=False, bullet_options=bullet, t0=0, T=nsteps * h, h=h, theta=0.50001,
               Newton_max_iter=1, solver_options=nsgs, numerics_verbose=False, verbose=False,
               verbose_progress=False, output_frequency=nsteps + 1, end_run_iteration_hook=record)
    return time.time() - t0, np.array(per_step, dtype=float)


def contact_iterations_per_s(s, wall):
    """Sum over steps of contacts x sweeps, per wall second."""
    return float((s[:, 0] * s[:, 1]).sum()) / wall
