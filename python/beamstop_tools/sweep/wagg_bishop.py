"""WB00 section 4 (Wagg & Bishop 2000): the impacting cantilever's
experiment impacts once per forcing period (a P(1,1) motion), and both a
1-mode model with r = 0.2 and a 4-mode model with r = 0.75 reproduce it.

A sweep over the base excitation's frequency and amplitude maps where each
model (WaggBishopCantilever4: 4 modes, r = 0.75; WaggBishopCantilever1: 1
mode, r = 0.2) moves with one impact per forcing period and period 1; the
point chosen for the scenes is the one of the common P(1,1) region whose
grid neighbours are most often P(1,1) too, then nearest the first natural
frequency.
"""
from __future__ import annotations


import matplotlib.pyplot as plt
import numpy as np

OMEGA1 = 1.8751040687119611 ** 2      # first clamped-free frequency, scaled units
GRID = ["base.omega=3.1:3.6:21", "base.amplitude=0.02:0.22:21"]


def p11(r) -> bool:
    return r["period"] == 1 and r["impacts_per_period"] == 1


def study(client, sweep, write_md, write_csv, report):
    maps, metas = {}, {}
    for fmu in ("WaggBishopCantilever4", "WaggBishopCantilever1"):
        rows, meta, wall = sweep(client, f"wagg-bishop-{fmu[-1]}", fmu, GRID, [], 150, 20,
                                 output="tip.w", rate="tip.v")
        maps[fmu] = {(round(r["base.omega"], 9), round(r["base.amplitude"], 9)): r for r in rows}
        metas[fmu] = (meta, wall)
    keys = sorted(maps["WaggBishopCantilever4"])
    oms = sorted({k[0] for k in keys})
    amps = sorted({k[1] for k in keys})
    both = {k for k in keys if k in maps["WaggBishopCantilever1"] and p11(maps["WaggBishopCantilever4"][k])
            and p11(maps["WaggBishopCantilever1"][k])}

    def neighbours(k):
        i, j = oms.index(k[0]), amps.index(k[1])
        nb = [(oms[a], amps[b]) for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1))
              if 0 <= a < len(oms) and 0 <= b < len(amps)]
        return sum(n in both for n in nb)

    # the most P(1,1) neighbours (robust to small changes), then nearest omega_1, then the smaller amplitude
    chosen = min(both, key=lambda k: (-neighbours(k), abs(k[0] - OMEGA1), k[1])) if both else None

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    for a, fmu, title in ((ax[0], "WaggBishopCantilever4", "4 modes, r = 0.75"),
                          (ax[1], "WaggBishopCantilever1", "1 mode, r = 0.2")):
        g = np.full((len(amps), len(oms)), np.nan)
        for (om, am), r in maps[fmu].items():
            g[amps.index(am), oms.index(om)] = min(r["impacts_per_period"], 6)
        m = a.pcolormesh(np.array(oms) / OMEGA1, amps, g, shading="nearest", cmap="viridis", vmin=0, vmax=6)
        for (om, am), r in maps[fmu].items():
            if p11(r):
                a.plot(om / OMEGA1, am, "s", mfc="none", mec="w", ms=7)
            elif r["period"] is None:
                a.plot(om / OMEGA1, am, "x", color="r", ms=4)
        if chosen:
            a.plot(chosen[0] / OMEGA1, chosen[1], "*", color="orange", ms=14, mec="k")
        a.set_title(f"{fmu}: {title}", fontsize=9)
        a.set_xlabel("base.omega / omega_1")
    ax[0].set_ylabel("base.amplitude (base acceleration)")
    fig.colorbar(m, ax=ax, label="impacts per forcing period (6 = 6 or more)")
    fig.suptitle("white squares: P(1,1) (period 1, one impact per period); red x: no period up to 16; "
                 "star: the scenes' new point", fontsize=9)
    fig.savefig(report / "wagg-bishop.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    rows = []
    for k in keys:
        r4, r1 = maps["WaggBishopCantilever4"][k], maps["WaggBishopCantilever1"].get(k)
        rows.append({"base.omega": k[0], "base.amplitude": k[1],
                     "impacts_per_period_4": r4["impacts_per_period"], "period_4": r4["period"], "peak_4": r4["peak"],
                     "impacts_per_period_1": r1["impacts_per_period"] if r1 else None,
                     "period_1": r1["period"] if r1 else None, "peak_1": r1["peak"] if r1 else None})
    write_csv("wagg-bishop", rows, list(rows[0]))
    old = maps["WaggBishopCantilever4"].get((3.4, 0.15))
    n4 = sum(p11(r) for r in maps["WaggBishopCantilever4"].values())
    n1 = sum(p11(r) for r in maps["WaggBishopCantilever1"].values())
    statements = [
        ("the experiment (Figure 4) is a P(1,1) motion near the first natural frequency; the 1-mode model "
         "with r = 0.2 and the 4-mode model with r = 0.75 both reproduce it (Figure 5)",
         f"P(1,1) at {n4} of {len(keys)} grid points with 4 modes, {n1} with 1 mode, {len(both)} with both"),
        ("(the old scene point, base.omega = 3.4, base.amplitude = 0.15)",
         f"4 modes: {old['impacts_per_period']:g} impacts per period, period {old['period']}" if old else "not on the grid"),
    ]
    if chosen:
        c4, c1 = maps["WaggBishopCantilever4"][chosen], maps["WaggBishopCantilever1"][chosen]
        statements.append((
            "the new scene point (of the common P(1,1) points, the one with most P(1,1) grid neighbours, then nearest omega_1)",
            f"base.omega = {chosen[0]:g} ({chosen[0] / OMEGA1:.3f} omega_1), base.amplitude = {chosen[1]:g}: "
            f"peak tip deflection {c4['peak']:.4f} (4 modes) and {c1['peak']:.4f} (1 mode)"))
    meta, wall = metas["WaggBishopCantilever4"]
    meta1, wall1 = metas["WaggBishopCantilever1"]
    meta = dict(meta, points_computed=meta["points_computed"] + meta1["points_computed"])
    write_md("wagg-bishop", "WB00 section 4: where the impacting cantilever moves P(1,1)",
             "scripts/sweep-figures wagg-bishop", statements, meta, wall + wall1)
    return chosen
