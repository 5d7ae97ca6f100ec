"""PNG plots of a sweep's table: over one parameter, the Poincare samples
(a bifurcation diagram), the peak (an amplitude-frequency curve; up and
down sweeps in two colours), impacts per period, the period and the stuck
fraction; over two, maps of impacts per period, period, stuck fraction and
peak."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .store import read_points  # noqa: E402

COLOURS = {None: "k", "up": "tab:blue", "down": "tab:red"}


def plot_sweep(path: Path) -> list[Path]:
    table, meta = read_points(path)
    settings = meta.get("settings", {})
    axes = [a["name"] for a in settings.get("param", [])]
    rows = table.to_pylist()
    out = Path(path).parent
    if len(axes) == 1:
        return [plot_line(rows, axes[0], settings, out / "sweep.png")]
    return [plot_map(rows, axes, settings, out / "map.png")]


def plot_line(rows, x, settings, png: Path) -> Path:
    fig, ax = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
    output = settings.get("output")
    for d in sorted({r["direction"] for r in rows}, key=lambda s: s or ""):
        rs = sorted((r for r in rows if r["direction"] == d and not r["error"]), key=lambda r: r[x])
        c = COLOURS.get(d, "k")
        label = d or "from rest"
        xs = np.concatenate([[r[x]] * len(r["poincare"]) for r in rs]) if rs else []
        ys = np.concatenate([r["poincare"] for r in rs]) if rs else []
        ax[0].plot(xs, ys, ",", color=c, alpha=0.8)
        ax[0].plot([], [], ".", color=c, label=label)
        ax[1].plot([r[x] for r in rs], [r["peak"] for r in rs], ".-", color=c, ms=3, lw=0.8, label=label)
        ax[2].plot([r[x] for r in rs], [r["impacts_per_period"] for r in rs], ".", color=c, ms=3)
        ax[3].plot([r[x] for r in rs], [r["period"] if r["period"] else 0 for r in rs], ".", color=c, ms=3,
                   label=f"period ({label}; 0 = none found)")
        ax[3].plot([r[x] for r in rs], [r["stuck_fraction"] * 10 for r in rs], "x", color=c, ms=3,
                   label=f"10 x stuck fraction ({label})")
    ax[0].set_ylabel(f"{output} at phase 0")
    ax[0].legend(loc="best", fontsize=8)
    ax[1].set_ylabel(f"peak of {output}")
    ax[2].set_ylabel("impacts per period")
    ax[3].set_ylabel("period [T]")
    ax[3].legend(loc="best", fontsize=7)
    ax[3].set_xlabel(x)
    fig.suptitle(f"{settings.get('fmu')}: " + ", ".join(settings.get("set", [])), fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def plot_map(rows, axes, settings, png: Path) -> Path:
    x, y = axes
    rows = [r for r in rows if r["direction"] in (None, "up")]
    xs = sorted({r[x] for r in rows})
    ys = sorted({r[y] for r in rows})
    grids = {k: np.full((len(ys), len(xs)), np.nan) for k in ("impacts_per_period", "period", "stuck_fraction", "peak")}
    for r in rows:
        i, j = ys.index(r[y]), xs.index(r[x])
        for k in grids:
            v = r[k]
            grids[k][i, j] = np.nan if v is None or r["error"] else v
    fig, ax = plt.subplots(2, 2, figsize=(11, 8), sharex=True, sharey=True)
    for a, (k, g) in zip(ax.flat, grids.items()):
        m = a.pcolormesh(xs, ys, g, shading="nearest", cmap="viridis")
        fig.colorbar(m, ax=a)
        a.set_title(k + (" (blank: none found)" if k == "period" else ""), fontsize=9)
    for a in ax[1]:
        a.set_xlabel(x)
    for a in ax[:, 0]:
        a.set_ylabel(y)
    fig.suptitle(f"{settings.get('fmu')}: " + ", ".join(settings.get("set", [])), fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png
