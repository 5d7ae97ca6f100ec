"""Work-precision diagrams: log-log error against wall time, one curve per method."""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FLOOR = 1e-17
STYLE = {
    "RK45": dict(color="tab:blue", marker="o"),
    "DOP853": dict(color="tab:orange", marker="s"),
    "Radau": dict(color="tab:green", marker="^"),
    "LSODA": dict(color="tab:purple", marker="v"),
    "penalty RK4": dict(color="tab:brown", marker="D"),
    "beamstop native, one call": dict(color="black", marker="*", markersize=11),
    "beamstop native, step 0.01": dict(color="tab:gray", marker="P", markersize=8),
    "beamstop FMU (fmpy)": dict(color="tab:red", marker="X", markersize=8),
}
MEASURES = {
    "err_events": "error in the first impact times",
    "err_stick": "error in the stick time",
    "err_final": "error of the state at the final time",
    "err_dense": "largest error of w at the stop (dense grid)",
}


def _series(rows, key):
    groups = {}
    for r in rows:
        if r["scene"] != key:
            continue
        name = r["method"]
        if name == "beamstop native":
            name = "beamstop native, one call" if r["step"] == 0 else "beamstop native, step 0.01"
        groups.setdefault(name, []).append(r)
    return groups


def scene_figure(rows, scene, path, events_label):
    measures = ["err_events"] + (["err_stick"] if scene.key == "S3" else []) + ["err_final", "err_dense"]
    if len(measures) == 4:
        fig, axes = plt.subplots(2, 2, figsize=(10.5, 9.4), dpi=100)
        axes = axes.ravel()
    else:
        fig, axes = plt.subplots(1, len(measures), figsize=(4.6 * len(measures), 4.9), dpi=100)
    groups = _series(rows, scene.key)
    handles = {}
    for ax, m in zip(axes, measures):
        for name, rs in groups.items():
            pts = [(r["wall_time_s"], r[m]) for r in rs if _ok(r.get(m)) and _ok(r["wall_time_s"])]
            if not pts:
                continue
            if name.startswith("beamstop native"):
                pts.sort(key=lambda p: p[1])
            elif name in ("beamstop FMU (fmpy)", "penalty RK4"):
                pts.sort(key=lambda p: p[0])
            x = [p[0] for p in pts]
            y = [max(p[1], FLOOR) for p in pts]
            st = dict(STYLE.get(name, {}))
            ls = "-" if not name.startswith("beamstop native") else ":"
            (h,) = ax.loglog(x, y, linestyle=ls, label=name, **st)
            handles[name] = h
        title = events_label if m == "err_events" else MEASURES[m]
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("max abs error")
        ax.grid(True, which="major", alpha=0.4)
        ax.axhline(1e-16, color="k", lw=0.5, alpha=0.3)
    fig.suptitle(f"{scene.key} {scene.title}: error against run time (errors below 1e-17 drawn at 1e-17)", fontsize=11)
    ncol = 4 if len(measures) == 4 else min(8, len(handles))
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=ncol, fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0, 0.07 if len(measures) == 4 else 0.09, 1, 0.95))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def truncation_figure(trunc, path):
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), dpi=100)
    Ns = [t["N"] for t in trunc]
    ref = trunc[-1]
    ax = axes[0]
    for k in range(3):
        d = [abs(t["impacts"][k] - ref["impacts"][k]) if len(t["impacts"]) > k else math.nan for t in trunc[:-1]]
        ax.loglog(Ns[:-1], [max(x, FLOOR) for x in d], marker="o", label=f"impact {k + 1}")
    ds = [abs(t["w_fixed"] - ref["w_fixed"]) for t in trunc[:-1]]
    ax.loglog(Ns[:-1], [max(x, FLOOR) for x in ds], marker="s", color="k", label=f"w at the stop, t = {ref['t_fixed']:g}")
    ax.set_xscale("log", base=2)
    ax.set_xticks(Ns[:-1], [str(n) for n in Ns[:-1]])
    ax.set_xlabel("modes N")
    ax.set_ylabel(f"|value(N) - value(N = {ref['N']})|")
    ax.set_title("S2: convergence in the number of modes", fontsize=10)
    ax.grid(True, alpha=0.4)
    ax.legend(fontsize=8)
    ax = axes[1]
    ax.plot(Ns, [t["n_impacts"] for t in trunc], marker="o", label="impacts")
    ax.plot(Ns, [t["n_sticks"] for t in trunc], marker="s", label="sticking phases")
    ax.set_xscale("log", base=2)
    ax.set_xticks(Ns, [str(n) for n in Ns])
    ax.set_xlabel("modes N")
    ax.set_title("S2: events over 5 forcing periods", fontsize=10)
    ax.grid(True, alpha=0.4)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _ok(x):
    return isinstance(x, (int, float)) and not (isinstance(x, float) and (math.isnan(x) or math.isinf(x)))
