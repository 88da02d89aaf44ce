#!/usr/bin/env python3
"""Energies, run-out and height of a CB-Geo MPM column run (inputs from make_column.py).

    python3 energies.py OUT [--csv series.csv]

reads OUT/scene.json (written by make_column.py) and every particle file
OUT/results/<uuid>/particles<step>.h5 that CB-Geo wrote, through `h5dump` (Debian package
hdf5-tools; Python 3 standard library only otherwise), and prints, with granrepro's
definitions (docs/definitions.md):

* D06: E_p = sum m g y (point centre above the base y = 0), normalised by E_0 = E_p(0),
  E_0 taken from the initial positions (position - displacement); E_k = sum 1/2 m |v|^2;
  E_p/E_0 at t = 0.5, 1, 2, 3 tau_c (linear interpolation between outputs);
* D05: tau_c = sqrt(H_0/g), t_KEmax = argmax E_k over the outputs (and a parabola through
  the three outputs around it);
* D01/D02/D03 for material points: the main body is the largest set of points linked by
  sharing a grid node (a point reaches the nodes within h + l_p of it on each axis, the
  uGIMP support, l_p = h/(2 sqrt(PPC))); L = max(x + l_p), H = max(y + l_p) over it;
  run-out (L_f - L_0)/L_0 and H_f/L_0 at the last output. The farthest point of all
  (x + l_p, main body or not) is printed beside it.

Checks printed when they fail: points deleted after leaving the grid; E_p + E_k climbing
by more than 0.005 E_0 (energy created by the scheme); a blown-up run (points deleted by the hundred or
E_k > E_0), after which nothing is used.

CB-Geo writes the step-s file after step s is done, so its time is (s + 1) dt.
"""

import argparse
import glob
import json
import math
import os
import re
import subprocess
import sys


def read_h5(path):
    """Return a list of dicts (one per particle) from a CB-Geo particles*.h5 table."""
    txt = subprocess.run(["h5dump", "-d", "/table", "-y", "-w", "0", "-m", "%.17g", path],
                         check=True, capture_output=True, text=True).stdout
    head, _, data = txt.partition("DATA {")
    data = data.split("ATTRIBUTE", 1)[0]  # the table's attributes follow its data
    # member names and array lengths, in order
    fields = []
    for m in re.finditer(r'(H5T_ARRAY\s*\{\s*\[(\d+)\][^}]*\}|H5T_[A-Z0-9_]+)\s+"(\w+)";', head):
        n = int(m.group(2)) if m.group(2) else 1
        fields.append((m.group(3), n))
    if not fields:
        raise RuntimeError("no compound members found in h5dump output of " + path)
    width = sum(n for _, n in fields)
    nums = re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|nan|inf|-nan|-inf",
                      data.replace("true", "1").replace("false", "0"))
    if len(nums) % width:
        raise RuntimeError("%s: %d numbers, not a multiple of the record width %d"
                           % (path, len(nums), width))
    recs = []
    for k in range(0, len(nums), width):
        rec, i = {}, k
        for name, n in fields:
            rec[name] = float(nums[i]) if n == 1 else [float(v) for v in nums[i:i + n]]
            i += n
        recs.append(rec)
    return recs


def main_body(pts, h, lp):
    """Indices of the largest set of points linked through shared grid nodes."""
    parent = list(range(len(pts)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner = {}
    reach = h + lp
    for k, (x, y) in enumerate(pts):
        ix0, ix1 = math.floor((x - reach) / h) + 1, math.ceil((x + reach) / h) - 1
        iy0, iy1 = math.floor((y - reach) / h) + 1, math.ceil((y + reach) / h) - 1
        for ix in range(ix0, ix1 + 1):
            for iy in range(iy0, iy1 + 1):
                o = owner.setdefault((ix, iy), k)
                if o != k:
                    a, b = find(o), find(k)
                    if a != b:
                        parent[a] = b
    groups = {}
    for k in range(len(pts)):
        groups.setdefault(find(k), []).append(k)
    return max(groups.values(), key=len)


def interp(ts, ys, t):
    for i in range(1, len(ts)):
        if ts[i] >= t:
            w = (t - ts[i - 1]) / (ts[i] - ts[i - 1])
            return ys[i - 1] + w * (ys[i] - ys[i - 1])
    return float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", help="the folder make_column.py wrote and CB-Geo ran in")
    ap.add_argument("--csv", help="write t/tau_c, E_p/E_0, E_k/E_0, L, H per output")
    args = ap.parse_args()
    meta = json.load(open(os.path.join(args.out, "scene.json")))
    g, h0, l0, h = meta["g"], meta["H0"], meta["L0"], meta["cell"]
    lp = h / (2.0 * meta["ppc_1d"])
    tau = math.sqrt(h0 / g)
    files = glob.glob(os.path.join(args.out, "results", "*", "particles*.h5"))
    steps = sorted((int(re.search(r"particles(\d+)\.h5$", f).group(1)), f) for f in files)
    if not steps:
        sys.exit("no particles*.h5 under %s/results/" % args.out)
    ts, eps, eks, ekms, ls, hs, lall, ns = [], [], [], [], [], [], [], []
    e0 = None
    blown = None
    for step, f in steps:
        recs = read_h5(f)
        t = (step + 1) * meta["dt"]
        if e0 is None:
            e0 = sum(r["mass"] * g * (r["coord_y"] - r["displacement_y"]) for r in recs)
            m0 = sum(r["mass"] for r in recs)
            n0 = len(recs)
        ek = sum(0.5 * r["mass"] * (r["velocity_x"] ** 2 + r["velocity_y"] ** 2) for r in recs)
        # a run that blew up: points deleted by the hundred, or more kinetic energy than the
        # column ever had
        if len(recs) < 0.9 * n0 or ek > e0:
            blown = t
            break
        ep = sum(r["mass"] * g * r["coord_y"] for r in recs)
        pts = [(r["coord_x"], r["coord_y"]) for r in recs]
        body = main_body(pts, h, lp)
        ekm = sum(0.5 * recs[k]["mass"] * (recs[k]["velocity_x"] ** 2 + recs[k]["velocity_y"] ** 2)
                  for k in body)
        ts.append(t)
        ns.append(len(recs))
        eps.append(ep / e0)
        eks.append(ek / e0)
        ekms.append(ekm / e0)
        ls.append(max(pts[k][0] for k in body) + lp)
        hs.append(max(pts[k][1] for k in body) + lp)
        lall.append(max(x for x, _ in pts) + lp)
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("t_over_tau,points,Ep_over_E0,Ek_over_E0,Ek_main_over_E0,"
                    "L_over_L0,H_over_L0,Lall_over_L0\n")
            for k in range(len(ts)):
                f.write("%.6f,%d,%.6f,%.6g,%.6g,%.5f,%.5f,%.5f\n"
                        % (ts[k] / tau, ns[k], eps[k], eks[k], ekms[k], ls[k] / l0,
                           hs[k] / l0, lall[k] / l0))
    print("points %d, mass %.6g kg/m, E_0 = %.6g J/m, L_0 = %.5f m, H_0 = %.5f m, "
          "tau_c = %.5f s, outputs used %d, up to t = %.4f s = %.3f tau_c"
          % (n0, m0, e0, l0, h0, tau, len(ts), ts[-1], ts[-1] / tau))
    if blown is not None:
        print("BLOWN UP: the output at t = %.4f s = %.3f tau_c has %d of %d points or "
              "E_k > E_0; everything below stops at the output before it"
              % (blown, blown / tau, len(recs), n0))
    # energy check: E_p + E_k can only fall (dissipation; the elastic energy is small and
    # released early), so report where it first climbs more than 0.5 % of E_0 above its
    # lowest earlier value: the scheme creating energy
    low, created = float("inf"), None
    for k in range(len(ts)):
        tot = eps[k] + eks[k]
        if tot > low + 0.005:
            created = k
            break
        low = min(low, tot)
    if created is not None:
        k = created
        print("ENERGY CREATED: (E_p + E_k)/E_0 = %.3f at t = %.3f tau_c, %.3f above its lowest "
              "earlier value; the output before, t = %.3f tau_c, has E_p/E_0 = %.3f, "
              "E_k/E_0 = %.3f" % (eps[k] + eks[k], ts[k] / tau, eps[k] + eks[k] - low,
                                 ts[k - 1] / tau, eps[k - 1], eks[k - 1]))
    lost = [k for k in range(len(ns)) if ns[k] < n0]
    if lost:
        print("points deleted after leaving the grid: first at t = %.3f tau_c, %d by the "
              "last output used" % (ts[lost[0]] / tau, n0 - ns[-1]))
    for tt in (0.5, 1.0, 2.0, 3.0):
        print("E_p/E_0 at %.1f tau_c: %.3f" % (tt, interp(ts, eps, tt * tau)))
    for name, series in (("all points", eks), ("main body", ekms)):
        i = max(range(len(series)), key=lambda k: series[k])
        t_peak = ts[i]
        if 0 < i < len(series) - 1:
            y0, y1, y2 = series[i - 1], series[i], series[i + 1]
            den = y0 - 2 * y1 + y2
            if den < 0:
                t_peak = ts[i] + 0.5 * (y0 - y2) / den * (ts[i + 1] - ts[i])
        print("t_KEmax (%s) = %.3f tau_c (output %.3f tau_c), E_k,max/E_0 = %.4f"
              % (name, t_peak / tau, ts[i] / tau, series[i]))
    print("last output used (t = %.3f tau_c): E_p/E_0 = %.3f, E_k/E_0 = %.2e (main body "
          "%.2e), run-out (L-L_0)/L_0 = %.2f (main body, shared grid nodes; farthest point "
          "of all %.2f), H/L_0 = %.2f"
          % (ts[-1] / tau, eps[-1], eks[-1], ekms[-1], (ls[-1] - l0) / l0,
             (lall[-1] - l0) / l0, hs[-1] / l0))


if __name__ == "__main__":
    main()
