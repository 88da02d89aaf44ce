#!/usr/bin/env python3
"""Turn a granrepro column sample into a LAMMPS data file and rolling-resistance includes,
for the cross-check of the DEM collapse with rolling resistance (see ../../README.md).

    python3 to_lammps.py [SAMPLE.csv]      # default: reports/quick/col-dem-prep-a0.4.csv

SAMPLE.csv is a prepared column as granrepro publishes it (header, then x_m,y_m,r_m per
grain). Writes, in the working directory:
  sample.data          the grains; atom type = one of NBIN radius bins (LAMMPS sets
                       rolling coefficients per type pair, not per grain)
  roll_none.inc        pair and wall coefficients without rolling resistance
  roll_mu0.1.inc,      the same with a rolling spring of torque stiffness k_r and a rolling
  roll_mu0.3.inc       limit mu_r R_eff F_n (LAMMPS `rolling sds`, spring and cap, no dashpot)

The contact parameters are granrepro's quick profile (every stiffness x0.01 of table 4.2,
time step 1.5e-6 s in collapse.lmp); change QUICK below for another profile. Restitution
0.75 becomes granrepro's damping ratio zeta (the one that returns 0.75 when the normal
force may not pull, src/dem/params.rs) and, per pair of radius bins, LAMMPS's
`damping mass_velocity` coefficient 2 zeta sqrt(k_n / m_eff) (1/s): exact for the bins'
representative grains, and accepted by LAMMPS versions before and after 2023.
"""
import math
import sys

QUICK = 0.01                      # stiffness factor of the quick profile
RHO = 2500.0                      # grain density [kg/m^3] (docs/definitions.md b.0)
KN, KN_WALL = 1.6e8 * QUICK, 4.0e8 * QUICK   # normal = tangential stiffness [N/m], table 4.2
MU, MU_WALL = 0.53, 0.466         # table 4.2
KR = 1.0e3 * QUICK                # rolling spring [N m/rad], table 4.2 scaled like k_n
EPS = 0.75                        # restitution, table 4.2
NBIN = 8


def restitution_no_attraction(z):
    """Restitution of the linear spring-dashpot (damping ratio z) whose force is clipped at 0."""
    w = math.sqrt(1 - z * z)
    wt = math.pi - math.atan2(2 * z * w, 1 - 2 * z * z)
    t = wt / w
    return math.exp(-z * t) * abs(math.cos(wt) - z / w * math.sin(wt))


def damping_ratio(eps):
    lo, hi = 0.0, 0.7071
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if restitution_no_attraction(mid) > eps else (lo, mid)
    return 0.5 * (lo + hi)


zeta = damping_ratio(EPS)

path = sys.argv[1] if len(sys.argv) > 1 else "reports/quick/col-dem-prep-a0.4.csv"
grains = []
with open(path) as f:
    next(f)
    for line in f:
        if line.strip():
            x, y, r = map(float, line.split(",")[:3])
            grains.append((x, y, r))
radii = [g[2] for g in grains]
rmin, rmax = min(radii), max(radii)
width = (rmax - rmin) / NBIN or 1.0
kind = [min(NBIN, 1 + int((r - rmin) / width)) for r in radii]
rep = []  # representative radius of each bin: the mean of its grains
for t in range(1, NBIN + 1):
    members = [r for r, k in zip(radii, kind) if k == t]
    rep.append(sum(members) / len(members) if members else rmin + (t - 0.5) * width)

with open("sample.data", "w") as f:
    f.write(f"granrepro column sample {path}\n\n{len(grains)} atoms\n{NBIN} atom types\n\n")
    f.write("-0.002 0.5 xlo xhi\n-0.002 0.15 ylo yhi\n-0.0005 0.0005 zlo zhi\n\nAtoms # sphere\n\n")
    for i, ((x, y, r), t) in enumerate(zip(grains, kind), start=1):
        f.write(f"{i} {t} {2 * r:.17g} 1.0 {x:.17g} {y:.17g} 0.0\n")


def mass(r):
    return RHO * math.pi * r * r


def law(kn, mu, r_eff, m_eff, mu_r):
    """One `granular` coefficient string; the rolling spring k_roll acts on R_eff * theta."""
    eta = 2 * zeta * math.sqrt(kn / m_eff)
    s = f"hooke {kn:.6e} {eta:.6e} damping mass_velocity tangential linear_history {kn:.6e} 0.0 {mu}"
    if mu_r is not None:
        s += f" rolling sds {KR / r_eff**2:.6e} 0.0 {mu_r}"
    return s + " limit_damping"


for name, mu_r in (("roll_none.inc", None), ("roll_mu0.1.inc", 0.1), ("roll_mu0.3.inc", 0.3)):
    with open(name, "w") as f:
        for i in range(NBIN):
            for j in range(i, NBIN):
                r_eff = rep[i] * rep[j] / (rep[i] + rep[j])
                m_eff = mass(rep[i]) * mass(rep[j]) / (mass(rep[i]) + mass(rep[j]))
                f.write(f"pair_coeff {i + 1} {j + 1} {law(KN, MU, r_eff, m_eff, mu_r)}\n")
        for i in range(NBIN):  # walls: R_eff = the grain's radius
            f.write(f"group bin{i + 1} type {i + 1}\n")
            for wall, plane in (("left", "xplane 0.0 NULL"), ("floor", "yplane 0.0 NULL")):
                f.write(f"fix {wall}{i + 1} bin{i + 1} wall/gran granular {law(KN_WALL, MU_WALL, rep[i], mass(rep[i]), mu_r)} {plane}\n")

print(f"{len(grains)} grains, radius bins {[round(r * 1e3, 4) for r in rep]} mm, "
      f"counts {[kind.count(t) for t in range(1, NBIN + 1)]}; zeta = {zeta:.6f}")
