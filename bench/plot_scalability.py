#!/usr/bin/env python3
"""Plots the scalability benchmark: wall time per step against vertex count, log-log, one line per solver.

    python3 bench/plot_scalability.py DIR/scalability.csv OUT.png [--title T]

Reads the CSV that `mgcloth bench scalability` writes (vertices,solver,ms_per_step,iterations_per_step,...); the
dashed line through each solver's smallest size has slope 1 (time proportional to the vertex count), so a solver
that scales linearly runs parallel to it. Each point is labelled with its iterations per step.
`mgcloth` embeds this file at build time; exit status 3 means matplotlib is missing.
"""
import argparse
import csv
import os
import sys


def read_rows(path):
    """(vertices, ms per step, iterations per step) of each solver, sorted by vertices."""
    series = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        for column in ("vertices", "solver", "ms_per_step", "iterations_per_step"):
            if column not in (reader.fieldnames or []):
                raise ValueError(f"{path}: no column {column}")
        for row in reader:
            series.setdefault(row["solver"], []).append(
                (int(row["vertices"]), float(row["ms_per_step"]), float(row["iterations_per_step"])))
    if not series:
        raise ValueError(f"{path}: no rows")
    return {s: sorted(p) for s, p in series.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("csv", help="scalability.csv")
    parser.add_argument("png", help="output picture")
    parser.add_argument("--title", default="", help="title above the plot")
    args = parser.parse_args()
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import matplotlib.ticker
    except ImportError as e:
        print(f"matplotlib is not available to {sys.executable} ({e}); install python3-matplotlib", file=sys.stderr)
        return 3

    series = read_rows(args.csv)
    fig, ax = plt.subplots(figsize=(7, 5), dpi=120)
    markers = "os^vD<>phX*"
    for k, (solver, points) in enumerate(series.items()):
        n = [p[0] for p in points]
        ms = [p[1] for p in points]
        line, = ax.plot(n, ms, marker=markers[k % len(markers)], linewidth=1.5, label=solver)
        for v, t, it in points:
            ax.annotate(f"{it:.3g} it", (v, t), textcoords="offset points", xytext=(4, -10), fontsize=7,
                        color=line.get_color())
        # Linear scaling from the smallest size.
        ax.plot([n[0], n[-1]], [ms[0], ms[0] * n[-1] / n[0]], linestyle="--", linewidth=1.0, color=line.get_color(),
                alpha=0.6, label=f"linear scaling ({solver})" if len(series) > 1 else "linear scaling")
    ax.set_xscale("log")
    ax.set_yscale("log")
    # The measured sizes as the x ticks, plain numbers on both axes (the ranges are often less than a decade).
    sizes = sorted({p[0] for points in series.values() for p in points})
    ax.set_xticks(sizes)
    ax.set_xticklabels([f"{n:,}" for n in sizes], rotation=30 if len(sizes) > 4 else 0)
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain)
    ax.set_xlabel("vertices")
    ax.set_ylabel("wall time per step (ms)")
    if args.title:
        ax.set_title(args.title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = f"{args.png}.tmp{os.getpid()}.png"
    fig.savefig(tmp, format="png")
    os.replace(tmp, args.png)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (OSError, ValueError, KeyError) as e:
        print(f"plot_scalability: {e}", file=sys.stderr)
        sys.exit(1)
