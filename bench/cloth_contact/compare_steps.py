#!/usr/bin/env python3
"""Times to a relative gradient and to a relative energy error of every solver in `mgcloth bench convergence`
folders (one per frozen step), as a markdown table.

With contact the energy is not convex, and solvers end in different local minima; the energy error is measured
against the lowest energy any solver of the folder reached (E_low), not against an E* polished from one of them:
    error(t) = (E(t) - E_low) / (E(x0) - E_low).
"-" means not reached within the budget. Usage: compare_steps.py DIR...
"""
import csv
import sys


def first_time(rows, test):
    for r in rows:
        if test(r):
            return float(r["wall_s"])
    return None


def fmt(t):
    return "-" if t is None else f"{t:.1f}"


def main(dirs):
    print("| step folder | solver | t(grad 1e-2) s | t(grad 1e-3) s | t(error 1e-2) s | t(error 3e-3) s "
          "| final energy | final relative gradient |")
    print("|---|---|---|---|---|---|---|---|")
    for d in dirs:
        rows = list(csv.DictReader(open(f"{d}/convergence.csv")))
        low = min(float(r["energy"]) for r in rows)
        for s in dict.fromkeys(r["solver"] for r in rows):
            rs = [r for r in rows if r["solver"] == s]
            g0, e0 = float(rs[0]["grad_norm"]), float(rs[0]["energy"])
            tg = [first_time(rs, lambda r, l=l: float(r["grad_norm"]) <= l * g0) for l in (1e-2, 1e-3)]
            te = [first_time(rs, lambda r, l=l: (float(r["energy"]) - low) / (e0 - low) <= l) for l in (1e-2, 3e-3)]
            print(f"| {d.rstrip('/').split('/')[-1]} | {s} | {fmt(tg[0])} | {fmt(tg[1])} | {fmt(te[0])} | {fmt(te[1])} "
                  f"| {float(rs[-1]['energy']):.6f} | {float(rs[-1]['grad_norm']) / g0:.1e} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
