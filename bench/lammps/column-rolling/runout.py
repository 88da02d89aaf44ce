#!/usr/bin/env python3
"""Run-out of LAMMPS collapse runs by granrepro's rule (docs/definitions.md D01, D02).

    python3 runout.py TAG [TAG ...]      # reads dump.TAG.0 and final.TAG.dump

Two grains are linked when their gap is at most 0.01 of the mean diameter; walls link
nothing; the main mass is the linked set of largest mass (area, per metre); the front is
the largest x + r over it. L_0 is the front of the first frame (the prepared column's
width). Prints (L_f - L_0)/L_0, the main mass's share of the grains, and the rightmost
grain of all for comparison.
"""
import sys


def read_dump(path):
    lines = open(path).read().split("\n")
    start = next(i for i, l in enumerate(lines) if l.startswith("ITEM: ATOMS")) + 1
    cols = lines[start - 1].split()[2:]
    ix, iy, ir = cols.index("x"), cols.index("y"), cols.index("radius")
    return [(float(v[ix]), float(v[iy]), float(v[ir])) for v in (l.split() for l in lines[start:] if l.strip())]


def front(grains):
    """(front of the main mass, grains in it) under the D01 rule."""
    n = len(grains)
    gap = 0.01 * 2 * sum(g[2] for g in grains) / n
    parent = list(range(n))

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    cell = 2 * max(g[2] for g in grains) + gap
    buckets = {}
    for i, (x, y, _) in enumerate(grains):
        buckets.setdefault((int(x // cell), int(y // cell)), []).append(i)
    for (cx, cy), members in buckets.items():
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for j in buckets.get((cx + dx, cy + dy), []):
                    for i in members:
                        if j > i:
                            (xi, yi, ri), (xj, yj, rj) = grains[i], grains[j]
                            reach = ri + rj + gap
                            if (xi - xj) ** 2 + (yi - yj) ** 2 <= reach * reach:
                                a, b = root(i), root(j)
                                if a != b:
                                    parent[max(a, b)] = min(a, b)
    mass = {}
    for i, g in enumerate(grains):
        mass[root(i)] = mass.get(root(i), 0.0) + g[2] ** 2
    main = max(mass, key=mass.get)
    members = [g for i, g in enumerate(grains) if root(i) == main]
    return max(x + r for x, _, r in members), len(members)


for tag in sys.argv[1:]:
    first = read_dump(f"dump.{tag}.0")
    last = read_dump(f"final.{tag}.dump")
    l0, _ = front(first)
    lf, n_main = front(last)
    rightmost = max(x + r for x, _, r in last)
    print(f"{tag}: runout (L_f - L_0)/L_0 = {(lf - l0) / l0:.4f}  main mass {n_main}/{len(last)} grains  "
          f"rightmost grain {(rightmost - l0) / l0:.4f}  (L_0 = {l0 * 1e3:.2f} mm)")
