#!/usr/bin/env python3
"""Kopaničáková 2019 Tables 4-8 from `mgcloth bench shells` outputs, next to the paper's numbers, as Markdown.

    python3 bench/rmtr_tables.py --rmtr SPEC [--ls SPEC] CSV... > tables.md

Every CSV is a shells.csv of `mgcloth bench shells`. Rows are picked by solver: `tr-dogleg` (the paper's TR),
SPEC (the RMTR configuration studied, e.g. rmtr@smoother=schwarz@smoother_sweeps=1@initial=nested) and, for
Table 8, the --ls SPEC (the same with projection=least_squares). Where several files hold the same (scene, level,
solver), the last one given wins. A cell is the iteration (V-cycle) count, with the wall time in seconds:
`N` converged (‖g‖ < 1e-7), `N (7.1b)` stopped by the second clause of (7.1), the
limiting accuracy (status stagnated, converged by (7.1)), `N s` stalled by the second clause of (7.1) with ‖g‖/‖g₀‖ < 1e-5 (which the paper
counts as convergence), `> N, ‖g‖ = …` not converged (cap, or a stall far from a minimum), `—` not run.
Work units (Tables 6-7) are eq. 7.3: the bench's work_assembly and work_qp columns for RMTR, and Hessian
assemblies and QP calls for the single-level TR (W^L = 1 per call).
"""
import argparse
import csv
import sys

SCENES = [("trampoline", "Trampoline"), ("drooping", "Drooping"), ("reentrant", "Re-entrant corner"),
          ("drape", "Drape")]
PAPER_T4 = {"trampoline": [633, 150, 81, 88, 52], "drooping": [4671, 645, 707, 1636, 333],
            "reentrant": [3188, 1508, 282, 124, 30], "drape": [9732, 7653, 5718, 792, 423]}  # levels 2..6
PAPER_T3 = {"trampoline": {3: 34456}, "drooping": {3: 15444, 4: 12792}, "reentrant": {3: 18873, 4: 47536},
            "drape": {3: 175132}}
PAPER_T6 = {"trampoline": (30981, 370), "drooping": (13858, 1612), "reentrant": (16632, 3788),
            "drape": (120089, 19163)}  # assembly W: TR, RMTR at 1,083 dofs
PAPER_T7 = {"trampoline": (34456, 370), "drooping": (15444, 1612), "reentrant": (18873, 3788),
            "drape": (175132, 19163)}  # QP W
PAPER_T8 = {"trampoline": (84, 81), "drooping": (659, 707), "reentrant": (277, 282), "drape": (5691, 5718)}
DOFS = {2: "363", 3: "1,083", 4: "3,675", 5: "13,467", 6: "51,483", 7: "201,243"}


def load(paths):
    rows = {}
    for p in paths:
        with open(p, newline="") as f:
            for r in csv.DictReader(f):
                rows[(r["shell"], int(r["level"]), r["solver"])] = r
    return rows


def solved(r):
    if r["status"] == "converged":
        return "yes"
    if r["status"] == "stagnated":  # (7.1)'s second clause, which the solver counts as converged
        return "stagnated"
    if r["status"] == "stalled" and float(r["rel_grad"]) < 1e-5:
        return "stalled"
    return "no"


def cell(r, with_time=True):
    if r is None:
        return "—"
    n = int(r["iterations"])
    t = f" ({float(r['wall_s']):.0f} s)" if with_time else ""
    s = solved(r)
    if s == "yes":
        return f"{n:,}{t}"
    if s == "stalled":
        return f"{n:,} s{t}"
    if s == "stagnated":
        return f"{n:,} (7.1b){t}, ‖g‖ = {float(r['grad_norm']):.1e}"
    return f"> {n:,}{t}, ‖g‖ = {float(r['grad_norm']):.1e}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rmtr", required=True)
    ap.add_argument("--ls")
    ap.add_argument("csv", nargs="+")
    a = ap.parse_args()
    rows = load(a.csv)
    get = lambda scene, level, solver: rows.get((scene, level, solver))
    levels = sorted({lv for (_, lv, s) in rows if s == a.rmtr})
    out = []
    out.append("**Table 4** (V-cycles, dt = 1; paper / mgcloth)\n")
    out.append("| scenario | " + " | ".join(f"{lv} levels ({DOFS.get(lv, '?')} dofs)" for lv in levels) + " |")
    out.append("|---|" + "---|" * len(levels))
    for key, name in SCENES:
        cells = []
        for lv in levels:
            paper = PAPER_T4[key][lv - 2] if 2 <= lv <= 6 else None
            cells.append(f"{paper:,} / {cell(get(key, lv, a.rmtr))}" if paper else f"— / {cell(get(key, lv, a.rmtr))}")
        out.append(f"| {name} | " + " | ".join(cells) + " |")

    out.append("\n**Table 5** (TR iterations vs RMTR V-cycles; paper / mgcloth)\n")
    out.append("| scenario | TR 1,083 | RMTR 1,083 | TR 3,675 | RMTR 3,675 | TR 51,483 | RMTR 51,483 |")
    out.append("|---|---|---|---|---|---|---|")
    for key, name in SCENES:
        c = []
        for lv in (3, 4, 6):
            pt = PAPER_T3[key].get(lv)
            c.append(f"{pt:,}" if pt else "—")
            c[-1] += f" / {cell(get(key, lv, 'tr-dogleg'))}"
            c.append(f"{PAPER_T4[key][lv - 2]:,} / {cell(get(key, lv, a.rmtr))}")
        out.append(f"| {name} | " + " | ".join(c) + " |")

    for title, col_tr, col_ml, paper in (("**Table 6** (assembly work units W of eq. 7.3 at 1,083 dofs, three levels)",
                                          "hessian_assemblies", "work_assembly", PAPER_T6),
                                         ("**Table 7** (QP work units at 1,083 dofs)", "qp_calls", "work_qp", PAPER_T7)):
        out.append(f"\n{title}\n")
        out.append("| scenario | paper TR | paper RMTR | paper TR/RMTR | TR | RMTR | TR/RMTR | TR avg | RMTR avg | "
                   "TR s | RMTR s | TR/RMTR time |")
        out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for key, name in SCENES:
            tr, ml = get(key, 3, "tr-dogleg"), get(key, 3, a.rmtr)
            ptr, pml = paper[key]
            if tr is None or ml is None:
                out.append(f"| {name} | {ptr:,} | {pml:,} | {ptr / pml:.2f} | — | — | — | — | — | — | — | — |")
                continue
            wtr, wml = float(tr[col_tr]), float(ml[col_ml])
            ntr, nml = int(tr["iterations"]), int(ml["iterations"])
            ttr, tml = float(tr["wall_s"]), float(ml["wall_s"])
            flag = lambda r: "" if solved(r) != "no" else " (not converged)"
            out.append(f"| {name} | {ptr:,} | {pml:,} | {ptr / pml:.2f} | {wtr:,.0f}{flag(tr)} | {wml:,.1f}{flag(ml)} | "
                       f"{wtr / wml:.2f} | {wtr / max(ntr, 1):.2f} | {wml / max(nml, 1):.2f} | {ttr:.1f} | {tml:.1f} | "
                       f"{ttr / tml:.2f} |")

    if a.ls:
        out.append("\n**Table 8** (V-cycles at 3,675 dofs, four levels; paper / mgcloth)\n")
        out.append("| scenario | least-squares fit | reverse subdivision |")
        out.append("|---|---|---|")
        for key, name in SCENES:
            pls, pq = PAPER_T8[key]
            out.append(f"| {name} | {pls:,} / {cell(get(key, 4, a.ls))} | {pq:,} / {cell(get(key, 4, a.rmtr))} |")
    print("\n".join(out))


if __name__ == "__main__":
    sys.exit(main())
