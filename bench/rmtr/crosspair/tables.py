#!/usr/bin/env python3
"""Markdown tables from the CSV/JSON outputs in this folder (bench convergence and bench shells)."""
import csv, json, os, sys

here = os.path.dirname(os.path.abspath(__file__))

def fmt(v, spec=".3g"):
    return "-" if v is None else format(v, spec)

def cloth(folder):
    d = json.load(open(os.path.join(here, folder, "convergence.json")))
    rows = list(csv.DictReader(open(os.path.join(here, folder, "convergence.csv"))))
    trace = {}
    for r in rows:
        trace.setdefault(r["solver"], []).append(r)
    ref = d["references"][0]
    # Common normalization: x0's energy (the reference's initial_energy) and x0's gradient norm. The bench normalizes
    # each solver by its own first trace row, which for rmtr@initial=nested is the point after nested iteration.
    E0, Es = ref["initial_energy"], ref["energy"]
    g0 = next(float(tr[0]["grad_norm"]) for tr in trace.values() if float(tr[0]["energy"]) == E0)
    print(f"### {folder}: {d['vertices']} vertices, step {d['step']}; E* = {ref['energy']:.12e} "
          f"({ref['solver']}, {ref['iterations']} it, rel. grad {ref['rel_grad']:.1e}, {ref['status']})\n")
    print("| solver | iterations | time (s) | t(1e-2) | t(1e-3) | t(1e-4) | final rel. energy error | final rel. gradient | "
          "t(rel. grad 1e-3) | t(rel. grad 1e-5) | status |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for s in d["solvers"]:
        tr = trace[s["solver"]]
        err = [(float(r["wall_s"]), (float(r["energy"]) - Es) / (E0 - Es), float(r["grad_norm"]) / g0) for r in tr]
        def first(i, th):
            return next((e[0] for e in err if e[i] <= th), None)
        own = float(tr[0]["energy"]) != E0
        mark = " (renormalized, see text)" if own else ""
        print(f"| `{s['solver']}`{mark} | {s['iterations']} | {s['seconds']:.2f} | {fmt(first(1, 1e-2))} | {fmt(first(1, 1e-3))} | "
              f"{fmt(first(1, 1e-4))} | {err[-1][1]:.2e} | {err[-1][2]:.1e} | {fmt(first(2, 1e-3))} | {fmt(first(2, 1e-5))} | {s['status']} |")
        if own:
            tt = s["time_to"]
            print(f"<!-- bench's own numbers for {s['solver']}: t(1e-2) {fmt(tt['1e-02'])}, t(1e-3) {fmt(tt['1e-03'])}, "
                  f"final {s['final_error']:.2e}, final rel. grad {s['final_rel_grad']:.1e} -->")
        else:
            assert abs(err[-1][1] - s["final_error"]) <= 1e-9 * max(1.0, abs(s["final_error"])), s["solver"]
    print()
    print("| solver | counters |")
    print("|---|---|")
    keys = ["corrections_accepted", "corrections_rejected", "final_radius", "levels", "accepted", "rejected",
            "cholmod_fallbacks", "directions", "rejected_directions", "matrix_updates", "refreshes", "assembly_ms",
            "galerkin_ms", "linear_ms", "line_search_ms", "gradient_ms"]
    for s in d["solvers"]:
        c = s["counters"]
        txt = ", ".join(f"{k} {c[k]:.4g}" for k in keys if k in c)
        ex = [f"L{l} exhausted {c[f'level{l}_radius_exhausted']:.0f}" for l in range(6) if f"level{l}_radius_exhausted" in c and c[f"level{l}_radius_exhausted"]]
        if ex: txt += ", radius exhausted: " + ", ".join(ex)
        print(f"| `{s['solver']}` | {txt or '(none)'} |")
    print()

def shells(folder):
    d = json.load(open(os.path.join(here, folder, "shells.json")))
    print(f"### {folder}\n")
    print("| shell | level (dofs) | solver | iterations | status | energy | abs. gradient | rel. gradient | wall (s) | counters |")
    print("|---|---|---|---:|---|---:|---:|---:|---:|---|")
    keys = ["corrections_accepted", "corrections_rejected", "final_radius", "directions", "rejected_directions",
            "matrix_updates", "assembly_ms", "galerkin_ms", "linear_ms", "line_search_ms"]
    g0 = {}
    for r in d["results"]:
        if "initial=nested" not in r["solver"]:
            g0.setdefault((r["shell"], r["level"]), r["initial_grad_norm"])
    for r in d["results"]:
        c = r["counters"]
        ig = g0.get((r["shell"], r["level"]), r["initial_grad_norm"])
        txt = ", ".join(f"{k} {c[k]:.4g}" for k in keys if k in c)
        nested = [f"L{l} nested {c[f'level{l}_nested_cycles']:.0f}" for l in range(6) if f"level{l}_nested_cycles" in c]
        if nested: txt += ", " + ", ".join(nested)
        print(f"| {r['shell']} | {r['level']} ({r['dofs']}) | `{r['solver']}` | {r['iterations']} | {r['status']} | "
              f"{r['energy']:.10f} | {r['grad_norm']:.2e} | {r['grad_norm']/ig:.2e} | {r['wall_s']:.2f} | {txt} |")
    print()

for a in sys.argv[1:]:
    if os.path.exists(os.path.join(here, a, "convergence.json")): cloth(a)
    elif os.path.exists(os.path.join(here, a, "shells.json")): shells(a)
