#!/usr/bin/env python3
"""Plots the convergence benchmark: relative energy error against wall time, one line per solver (Wang 2018, Fig. 4).

    python3 bench/plot_convergence.py DIR/convergence.csv OUT.png [--title T]

Reads the CSV that `mgcloth bench convergence` writes (solver,iteration,wall_s,energy,grad_norm,rel_energy_error).
The error (E_k - E*)/(E_0 - E*) is drawn on a log axis; errors at or below zero (E* reached to round-off) are drawn
at the axis floor. Each iteration is a marker (thinned to about 40 per line for solvers with many iterations).
`mgcloth` embeds this file at build time; exit status 3 means matplotlib is missing.
"""
import argparse
import csv
import math
import os
import sys

FLOOR = 1e-16
LEVELS = (1e-2, 1e-3, 1e-4)


def read_rows(path):
    """The rows of each solver, in the order the solvers first appear."""
    series = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        expected = ["solver", "iteration", "wall_s", "energy", "grad_norm", "rel_energy_error"]
        if reader.fieldnames != expected:
            raise ValueError(f"{path}: expected the columns {','.join(expected)}, got {reader.fieldnames}")
        for row in reader:
            error = float(row["rel_energy_error"])  # "nan" parses too
            series.setdefault(row["solver"], []).append((float(row["wall_s"]), error))
    if not series:
        raise ValueError(f"{path}: no rows")
    return series


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("csv", help="convergence.csv")
    parser.add_argument("png", help="output picture")
    parser.add_argument("--title", default="", help="title above the plot")
    args = parser.parse_args()
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:
        print(f"matplotlib is not available to {sys.executable} ({e}); install python3-matplotlib", file=sys.stderr)
        return 3

    series = read_rows(args.csv)
    fig, ax = plt.subplots(figsize=(8, 5), dpi=120)
    markers = "os^vD<>phX*"
    lowest = 1.0
    for k, (solver, points) in enumerate(series.items()):
        points = [(t, e) for t, e in points if not math.isnan(e)]
        if not points:
            continue
        times = [t for t, _ in points]
        errors = [max(e, FLOOR) for _, e in points]
        lowest = min(lowest, min(errors))
        ax.plot(times, errors, marker=markers[k % len(markers)], markersize=4, linewidth=1.5, label=solver,
                markevery=max(1, len(points) // 40))
    for level in LEVELS:
        ax.axhline(level, color="0.8", linewidth=0.8, linestyle="--", zorder=0)
    ax.set_yscale("log")
    ax.set_ylim(bottom=max(FLOOR, lowest / 3), top=2.0)
    ax.set_xlim(left=0.0)
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("relative energy error (E - E*) / (E0 - E*)")
    if args.title:
        ax.set_title(args.title)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    # Atomic: a reader never sees a half-written picture.
    tmp = f"{args.png}.tmp{os.getpid()}.png"
    fig.savefig(tmp, format="png")
    os.replace(tmp, args.png)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (OSError, ValueError, KeyError) as e:
        print(f"plot_convergence: {e}", file=sys.stderr)
        sys.exit(1)
