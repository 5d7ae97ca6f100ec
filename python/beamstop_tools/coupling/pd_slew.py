#!/usr/bin/env python3
"""The controller-coupling example (issue 9, item 5): a PD controller on the
hub angle slews RotatingBeamImpact.fmu from theta = -0.5 rad towards
theta_ref = +0.02 rad, past the surface at theta = 0, so the tip strikes the
surface, chatters and ends pressed against it.

    python -m beamstop_tools.coupling.pd_slew [--t-end 1.5] [--window 0.4] [--out target/coupling]
        [--report report/coupling] [--no-build] [--no-libcosim] [--quick]

(`scripts/coupling` packages the FMUs first and runs this, writing only
target/coupling; `scripts/report` refreshes report/coupling with --report.
`--quick`: 0.7 s, the last 0.1 s as "at rest", to target/report-quick/coupling,
about 5 s.) One system
structure, examples/coupling/OspSystemStructure.xml, describes the run for
both masters:

1. fmpy: RotatingBeamImpact.fmu through FMU2Slave, the controller as the
   Python mirror of PDController.fmu's law, in libcosim's (Jacobi) ordering;
   the same loop in the Gauss-Seidel ordering (no sample of delay);
2. libcosim (libcosimpy): RotatingBeamImpact.fmu and PDController.fmu
   (built from examples/coupling/pd_controller, checked by fmpy's validator)
   coupled by the system structure.

Writes <out>/pd_slew_<master>.csv, <out>/pd_slew.png, <out>/summary.md (and
copies the PNG and summary to --report), and prints the figures: the slew,
the impacts, the settling, and the checks:

- static balance: at rest against the surface the hub torque is the contact
  force's moment about the axis, torque = F x_tip (F normal to the plane
  y = 0, the tip at x_tip), and |root.M| = torque; the beam is undamped, so
  "at rest" is a time average over the last `--window` seconds, the force
  averaged exactly as (sum of stop.impulse) / window;
- the final hub angle against the static prediction: PD torque
  Kp (theta_ref - theta) balanced by the force of a cantilever whose tip is
  held on the surface, deflection F cos(theta) L^3 / (3 EI) (the exact
  cantilever, not the FMU's 6 modes) plus the Hertz penetration (F / K)^(2/3);
- fmpy against libcosim, same ordering: the largest differences (0: bit for bit).
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path

import numpy as np

from . import controller, runs, system as osp
from .. import ROOT
from ..report import common

SCENE = ROOT / "scenes" / "rotating_beam.json"

# ---------------------------------------------------------------- physics


def beam_data(sys_: osp.System) -> dict:
    """The beam (scene file) and the FMU's parameters as the run sets them."""
    from fmpy import read_model_description

    scene = json.loads(SCENE.read_text())
    b = scene["beam"]
    md = read_model_description(str(sys_.simulators["beam"].fmu))
    start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter" and v.start is not None}
    start.update(sys_.simulators["beam"].initial)
    if scene.get("hub_radius", 0.0) != 0.0:
        raise ValueError("the figures assume the root on the axis (hub_radius = 0)")
    return {"L": b["length"], "mu": b["mass_per_length"], "EI": b["bending_stiffness"], "n_modes": scene["n_modes"],
            "J_h": start["J_h"], "K": start["K"], "e": start["e"], "theta0": start["theta0"],
            "theta_dot0": start["theta_dot0"]}


def clamped_free_modes(L, mu, EI, n):
    """Mass-normalised clamped-free modes on a grid: (x, phi[j], omega[j])."""
    roots = []
    for j in range(n):
        # cos(b) cosh(b) = -1: start from (2j+1) pi / 2, Newton on cos + 1/cosh
        x = 1.8751040687 if j == 0 else (2 * j + 1) * math.pi / 2
        for _ in range(50):
            f = math.cos(x) + 1.0 / math.cosh(x)
            df = -math.sin(x) - math.tanh(x) / math.cosh(x)
            x -= f / df
        roots.append(x)
    xs = np.linspace(0.0, L, 4001)
    phis, curvatures = [], []
    for bl in roots:
        b = bl / L
        s = (math.cosh(bl) + math.cos(bl)) / (math.sinh(bl) + math.sin(bl))
        p = np.cosh(b * xs) - np.cos(b * xs) - s * (np.sinh(b * xs) - np.sin(b * xs))
        norm = math.sqrt(np.trapezoid(mu * p * p, xs))
        phis.append(p / norm)
        curvatures.append(2 * b * b / norm)   # phi''(0)
    omegas = np.array([(bl / L) ** 2 * math.sqrt(EI / mu) for bl in roots])
    return xs, np.array(phis), omegas, np.array(curvatures)


def plant_frequencies(d: dict) -> dict:
    """Rigid inertia and the first bending frequencies (Hz): clamped-free,
    with the hub free (the linearised hub + modes at rest), and with the tip
    held on the surface (a stiff spring on the tip); and what the FMU's modes
    carry of a static tip force's tip deflection and root moment (against
    the exact cantilever's L^3 / 3 EI and F L)."""
    L, mu, EI, J_h = d["L"], d["mu"], d["EI"], d["J_h"]
    xs, phi, om, curv = clamped_free_modes(L, mu, EI, d["n_modes"])
    J_b = mu * L ** 3 / 3
    b = np.array([np.trapezoid(mu * xs * p, xs) for p in phi])
    n = len(om)
    M = np.zeros((n + 1, n + 1))
    M[0, 0] = J_h + J_b
    M[0, 1:] = M[1:, 0] = b
    M[1:, 1:] = np.eye(n)
    K = np.zeros_like(M)
    K[1:, 1:] = np.diag(om ** 2)
    free = np.sort(np.sqrt(np.abs(np.linalg.eigvals(np.linalg.solve(M, K)))))
    g = np.concatenate([[L], phi[:, -1]])
    pinned = np.sort(np.sqrt(np.abs(np.linalg.eigvals(np.linalg.solve(M, K + 1e9 * np.outer(g, g))))))
    q = phi[:, -1] / om ** 2   # modal response to a unit static tip force
    return {"J": J_h + J_b, "J_b": J_b, "f_clamped_free": om[0] / (2 * math.pi),
            "f_hub_free": free[1] / (2 * math.pi), "f_tip_held": pinned[0] / (2 * math.pi),
            "modal_tip_compliance": float(np.dot(phi[:, -1], q) * 3 * EI / L ** 3),
            "modal_root_moment": float(EI * np.dot(curv, q) / L)}


def static_rest(d: dict, c: dict) -> dict:
    """Where a PD (Ki = 0) holds the hub against the surface: theta with
    torque = Kp (theta_ref - theta) = F x_tip, the tip's transverse deflection
    F cos(theta) L^3 / (3 EI), and tip.y = (F / K)^(2/3) (the Hertz penetration)."""
    if c["Ki"] != 0.0:
        return {}
    L, EI, K = d["L"], d["EI"], d["K"]
    theta = 0.0
    for _ in range(200):
        torque = c["Kp"] * (c["theta_ref"] - theta)
        F = torque / (L * math.cos(theta))
        w = -F * math.cos(theta) * L ** 3 / (3 * EI)
        p = (F / K) ** (2 / 3) if F > 0 else 0.0
        # tip.y = L sin(theta) + w cos(theta) = p
        new = math.asin((p - w * math.cos(theta)) / L)
        if abs(new - theta) < 1e-16:
            break
        theta = new
    return {"theta": theta, "torque": c["Kp"] * (c["theta_ref"] - theta), "force": F, "w": w, "penetration": p}


# ---------------------------------------------------------------- figures


def analyse(run: dict, d: dict, c: dict, window: float) -> dict:
    t = run["time"]
    h = t[1] - t[0]
    contacts = run["stop.contacts"]
    first = int(np.argmax(contacts >= 1)) if contacts[-1] >= 1 else None
    last_onset = int(np.argmax(contacts >= contacts[-1])) if first is not None else None
    tail = t > t[-1] - window * (1 + 1e-9)
    T = t[tail][-1] - t[tail][0] + h
    torque = float(np.mean(run["torque"][tail]))                 # held over each step: the exact mean
    force = float(np.sum(run["stop.impulse"][tail]) / T)         # the exact mean of F
    x_tip = float(np.mean(run["tip.x"][tail]))
    theta_end = float(np.mean(run["theta"][tail]))
    off = np.abs(run["theta"] - theta_end) > 1e-3
    settle = float(t[np.nonzero(off)[0][-1] + 1]) if off.any() else float(t[0])
    rest = static_rest(d, c)
    out = {
        "t_end": float(t[-1]), "step": float(h), "window": float(T),
        "first_contact": float(t[first]) if first is not None else None,
        "approach_tip_speed": float(d["L"] * run["theta_dot"][first - 1]) if first else None,
        "contacts": int(contacts[-1]),
        "last_onset": float(t[last_onset]) if last_onset is not None else None,
        "peak_force_sampled": float(np.max(run["stop.force"])),
        "peak_mean_force_step": float(np.max(run["stop.impulse"]) / h),
        "peak_torque": float(np.max(np.abs(run["torque"]))),
        "settling_1mrad": settle,
        "theta_end": theta_end,
        "theta_end_span": float(np.ptp(run["theta"][tail])),
        "torque_end": torque, "force_end": force, "x_tip_end": x_tip,
        "force_end_span": [float(np.min(run["stop.force"][tail])), float(np.max(run["stop.force"][tail]))],
        "root_M_end": float(np.mean(run["root.M"][tail])),
        "balance_rel": (force * x_tip - torque) / torque if torque else math.nan,
        "root_M_rel": (abs(float(np.mean(run["root.M"][tail]))) - torque) / torque if torque else math.nan,
        "contact_fraction_end": float(np.mean(run["stop.contact"][tail])),
        "wall": run["wall"],
    }
    if rest:
        out["static"] = rest
        out["theta_end_vs_static"] = theta_end - rest["theta"]
    return out


def compare(a: dict, b: dict) -> dict:
    """Largest differences between two runs, column by column."""
    diff = {c: float(np.max(np.abs(a[c] - b[c]))) for c in runs.COLUMNS}
    diff["identical"] = all(np.array_equal(a[c], b[c]) for c in runs.COLUMNS)
    return diff


# ---------------------------------------------------------------- output


def write_csv(run: dict, path: Path):
    common.write_csv(path, runs.COLUMNS, zip(*(run[c] for c in runs.COLUMNS)), lambda x: repr(float(x)))


def plot(main: dict, other: dict | None, fig_: dict, c: dict, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = main["time"]
    fig, ax = plt.subplots(2, 2, figsize=(12, 7.5), sharex="col")
    a = ax[0, 0]
    a.plot(t, main["theta_r"], color="0.6", lw=1.2, label="reference $\\theta_r$ (min-jerk slew)")
    a.plot(t, main["theta"], color="C0", lw=1.2, label=f"hub angle $\\theta$, {main['master']}")
    if other is not None:
        a.plot(t, other["theta"], color="C1", lw=1, ls="--", label=f"$\\theta$, {other['master']}")
    a.axhline(0.0, color="k", lw=0.8, ls=":", label="surface ($\\theta$ = 0 at the undeformed tip)")
    a.set_ylabel("rad")
    a.set_title("Slew: hub angle")
    a.legend(fontsize=8, loc="lower right")
    a = ax[0, 1]
    a.plot(t, 1e3 * main["theta"], color="C0", lw=1)
    if other is not None:
        a.plot(t, 1e3 * other["theta"], color="C1", lw=0.8, ls="--")
    a.axhline(0.0, color="k", lw=0.8, ls=":")
    if "static" in fig_:
        a.axhline(1e3 * fig_["static"]["theta"], color="C3", lw=0.8, ls="--",
                  label=f"static rest {1e3 * fig_['static']['theta']:.4f} mrad (cantilever + Hertz)")
        a.legend(fontsize=8, loc="lower right")
    a.set_ylim(-5.0, 3.0)
    if fig_["first_contact"] is not None:
        a.set_xlim(fig_["first_contact"] - 0.05, t[-1])
    a.set_ylabel("mrad")
    a.set_title("Hub angle near the surface")
    a = ax[1, 0]
    a.step(t, main["torque"], where="pre", color="C2", lw=1, label="torque (held over each step)")
    a.axhline(c["torque_max"], color="k", lw=0.6, ls=":")
    a.axhline(-c["torque_max"], color="k", lw=0.6, ls=":", label=f"limit $\\pm${c['torque_max']:g} N m")
    a.set_ylabel("N m")
    a.set_xlabel("t [s]")
    a.set_title(f"Hub torque: PD Kp = {c['Kp']:g} N m/rad, Kd = {c['Kd']:g} N m s/rad")
    a.legend(fontsize=8)
    a = ax[1, 1]
    F = np.where(main["stop.force"] > 0, main["stop.force"], np.nan)
    a.semilogy(t, F, color="C3", lw=0.8, marker=".", ms=1.5, label="contact force (at communication points)")
    a.axhline(fig_["torque_end"] / fig_["x_tip_end"], color="k", lw=0.8, ls="--",
              label=f"torque / x_tip at rest = {fig_['torque_end'] / fig_['x_tip_end']:.4g} N")
    a.set_ylabel("N")
    a.set_xlabel("t [s]")
    a.set_title(f"Contact force: {fig_['contacts']} contacts")
    a.legend(fontsize=8, loc="upper right")
    for a in ax.flat:
        a.grid(alpha=0.3)
    fig.suptitle("RotatingBeamImpact.fmu slewed by a PD controller against the surface "
                 f"(communication step {fig_['step']:g} s)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary_text(fig_: dict, plant: dict, c: dict, d: dict, agree: dict | None, gs: dict | None) -> str:
    s = fig_.get("static", {})
    lines = [
        "# Coupling example: a PD slew of RotatingBeamImpact.fmu against the surface",
        "",
        "Written by `python -m beamstop_tools.coupling.pd_slew` (examples/coupling/OspSystemStructure.xml): "
        "`scripts/coupling` writes it to target/coupling, `scripts/report` to report/coupling.",
        "",
        "## Plant and gains",
        "",
        f"- rigid inertia J = J_h + mu L^3/3 = {d['J_h']:g} + {plant['J_b']:.5f} = {plant['J']:.4f} kg m^2",
        f"- first bending mode: {plant['f_clamped_free']:.2f} Hz clamped-free, {plant['f_hub_free']:.2f} Hz with the hub free "
        f"(J_h = {d['J_h']:g}), {plant['f_tip_held']:.2f} Hz with the tip held on the surface",
        f"- PD: Kp = {c['Kp']:g} N m/rad, Kd = {c['Kd']:g} N m s/rad, Ki = {c['Ki']:g}: on the rigid inertia "
        f"omega_n = {math.sqrt(c['Kp'] / plant['J']):.2f} rad/s ({math.sqrt(c['Kp'] / plant['J']) / (2 * math.pi):.2f} Hz), "
        f"zeta = {c['Kd'] / (2 * math.sqrt(c['Kp'] * plant['J'])):.2f}; torque limit {c['torque_max']:g} N m; "
        "hub angle and speed are collocated with the torque, so the PD cannot destabilise the bending modes",
        f"- slew: theta from {d['theta0']:g} to theta_ref = {c['theta_ref']:g} rad over T_slew = {c['T_slew']:g} s "
        "(minimum-jerk reference; the target lies past the surface at theta = 0)",
        "",
        f"## Run ({fig_['t_end']:g} s, communication step {fig_['step']:g} s)",
        "",
        f"- first contact at t = {fig_['first_contact']:.4f} s, tip approaching at {fig_['approach_tip_speed']:.3f} m/s",
        f"- contacts (onsets): {fig_['contacts']}; the last at t = {fig_['last_onset']:.4f} s, then the tip stays pressed",
        f"- peak contact force {fig_['peak_force_exact']:.4g} N (exact, from the FMU's event log; "
        f"{fig_['peak_force_sampled']:.4g} N at a communication point); peak torque {fig_['peak_torque']:.3g} N m"
        if "peak_force_exact" in fig_ else
        f"- peak contact force at a communication point {fig_['peak_force_sampled']:.4g} N; peak torque {fig_['peak_torque']:.3g} N m",
        f"- hub within 1 mrad of its final angle from t = {fig_['settling_1mrad']:.4f} s",
        "",
        f"## At rest against the surface (means over the last {fig_['window']:g} s)",
        "",
        f"- hub angle {fig_['theta_end']:.6e} rad (peak to peak {fig_['theta_end_span']:.1e}); static prediction "
        f"{s.get('theta', float('nan')):.6e} rad (difference {fig_.get('theta_end_vs_static', float('nan')):.1e} rad)",
        f"- torque {fig_['torque_end']:.6f} N m; contact force (impulse / time) {fig_['force_end']:.6f} N "
        f"(between {fig_['force_end_span'][0]:.3g} and {fig_['force_end_span'][1]:.3g} N: the undamped beam still rings "
        "against the surface); tip at x = "
        f"{fig_['x_tip_end']:.7f} m",
        f"- moment balance F x_tip = {fig_['force_end'] * fig_['x_tip_end']:.6f} N m against the torque: "
        f"{100 * fig_['balance_rel']:+.3f} %",
        f"- root bending moment |root.M| = {abs(fig_['root_M_end']):.6f} N m against the torque: {100 * fig_['root_M_rel']:+.3f} % "
        f"(the modal sum: {d['n_modes']} clamped-free modes carry {100 * plant['modal_root_moment']:.2f} % of a static tip "
        f"force's root moment F L, so {100 * (plant['modal_root_moment'] - 1):+.3f} % is expected; of its tip deflection "
        f"{100 * plant['modal_tip_compliance']:.3f} %)",
        f"- in contact {100 * fig_['contact_fraction_end']:.1f} % of the window",
    ]
    if agree is not None:
        lines += ["", "## fmpy against libcosim", ""]
        if agree["identical"]:
            lines.append("- same ordering (libcosim's fixed-step Jacobi, the fmpy loop mirroring it, the controller "
                         "in Python against PDController.fmu in libcosim): every column equal bit for bit")
        else:
            lines.append("- same ordering: largest differences " + ", ".join(
                f"{k} {v:.3g}" for k, v in agree.items() if k not in ("identical",)))
    if gs is not None:
        lines += ["", "## Ordering", "",
                  f"- Gauss-Seidel (no sample of delay) against Jacobi (one sample): up to the first contact the hub "
                  f"angles differ by {gs['max_dtheta_before_contact']:.1e} rad at most; the chatter that follows is "
                  "sensitive to such differences, so the contacts differ in number and time; at rest the final angle differs by "
                  f"{gs['theta_end'] - fig_['theta_end']:.2e} rad, resting force by {gs['force_end'] - fig_['force_end']:.2e} N; "
                  f"contacts {gs['contacts']} against {fig_['contacts']}, first contact at {gs['first_contact']:.4f} s, "
                  f"peak force {gs.get('peak_force_exact', gs['peak_force_sampled']):.4g} N"]
    lines += ["", f"Run time: fmpy {fig_['wall']:.1f} s for {round(fig_['t_end'] / fig_['step'])} steps.", ""]
    return "\n".join(lines)


def print_figures(fig_: dict, agree: dict | None, gs: dict | None):
    s = fig_.get("static", {})
    print(f"first contact      t = {fig_['first_contact']:.4f} s at {fig_['approach_tip_speed']:.3f} m/s (tip)")
    print(f"contacts           {fig_['contacts']} (last onset t = {fig_['last_onset']:.4f} s)")
    if "peak_force_exact" in fig_:
        print(f"peak force         {fig_['peak_force_exact']:.4g} N (event log; {fig_['peak_force_sampled']:.4g} N sampled)")
    else:
        print(f"peak force         {fig_['peak_force_sampled']:.4g} N (sampled at communication points)")
    print(f"settling (1 mrad)  t = {fig_['settling_1mrad']:.4f} s")
    print(f"final angle        {fig_['theta_end']:.6e} rad; static prediction {s.get('theta', float('nan')):.6e} rad")
    print(f"resting torque     {fig_['torque_end']:.6f} N m; force {fig_['force_end']:.6f} N at x_tip = {fig_['x_tip_end']:.7f} m")
    print(f"moment balance     F x_tip / torque - 1 = {fig_['balance_rel']:+.2e}; |root.M| / torque - 1 = {fig_['root_M_rel']:+.2e}")
    if agree is not None:
        print("fmpy vs libcosim   " + ("bit for bit identical" if agree["identical"] else
                                      f"max |d theta| {agree['theta']:.3g} rad, |d F| {agree['stop.force']:.3g} N"))
    if gs is not None:
        print(f"Gauss-Seidel       max |d theta| before contact {gs['max_dtheta_before_contact']:.1e} rad; "
              f"final angle {gs['theta_end']:.6e} rad, {gs['contacts']} contacts, resting force {gs['force_end']:.6f} N")


# ---------------------------------------------------------------- main


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--t-end", type=float, help="the run's end (s; default 1.5, 0.7 with --quick)")
    ap.add_argument("--window", type=float,
                    help="the final stretch averaged as 'at rest' (s; default 0.4, 0.1 with --quick)")
    ap.add_argument("--out", type=Path, help="default target/coupling, target/report-quick/coupling with --quick")
    ap.add_argument("--quick", action="store_true", help="a smoke run: a short slew (the tip reaches the surface, "
                                                         "does not settle)")
    ap.add_argument("--report", type=Path, default=None, help="also copy the PNG and summary.md here")
    ap.add_argument("--no-build", action="store_true", help="use target/coupling/PDController.fmu as it is")
    ap.add_argument("--no-libcosim", action="store_true")
    ap.add_argument("--no-gauss-seidel", action="store_true")
    args = ap.parse_args(argv)
    args.t_end = args.t_end or (0.7 if args.quick else 1.5)
    args.window = args.window or (0.1 if args.quick else 0.4)
    args.out = args.out or (ROOT / "target" / "report-quick" / "coupling" if args.quick else ROOT / "target" / "coupling")

    sys_ = osp.load()
    if not args.no_build:
        controller.build_fmu()
    from fmpy.validation import validate_fmu
    problems = validate_fmu(str(sys_.simulators["controller"].fmu))
    if problems:
        raise SystemExit("PDController.fmu fails fmpy's validation:\n" + "\n".join(problems))
    for s in sys_.simulators.values():
        if not s.fmu.is_file():
            raise SystemExit(f"{s.fmu} missing: run `cargo run --release -- package` (scripts/coupling does)")
    d = beam_data(sys_)
    c = {k: float(sys_.simulators["controller"].initial[k]) for k in controller.PARAMETERS}
    plant = plant_frequencies(d)
    args.out.mkdir(parents=True, exist_ok=True)

    main_run = runs.run_fmpy(sys_, args.t_end, "jacobi")
    fig_ = analyse(main_run, d, c, args.window)
    if main_run.get("peaks"):
        fig_["peak_force_exact"] = max(main_run["peaks"])
    write_csv(main_run, args.out / "pd_slew_fmpy.csv")
    other, agree, gs = None, None, None
    if not args.no_libcosim:
        other = runs.run_libcosim(sys_, args.t_end)
        write_csv(other, args.out / "pd_slew_libcosim.csv")
        agree = compare(main_run, other)
    if not args.no_gauss_seidel:
        gs_run = runs.run_fmpy(sys_, args.t_end, "gauss-seidel")
        write_csv(gs_run, args.out / "pd_slew_fmpy_gauss_seidel.csv")
        gs = analyse(gs_run, d, c, args.window)
        before = main_run["time"] < fig_["first_contact"]
        gs["max_dtheta_before_contact"] = float(np.max(np.abs(gs_run["theta"][before] - main_run["theta"][before])))
        if gs_run.get("peaks"):
            gs["peak_force_exact"] = max(gs_run["peaks"])
    plot(main_run, other, fig_, c, args.out / "pd_slew.png")
    text = summary_text(fig_, plant, c, d, agree, gs)
    (args.out / "summary.md").write_text(text)
    (args.out / "figures.json").write_text(json.dumps({"figures": fig_, "plant": plant, "controller": c, "beam": d,
                                                       "fmpy_vs_libcosim": agree, "gauss_seidel": gs}, indent=1))
    print_figures(fig_, agree, gs)
    print(f"wrote {args.out / 'pd_slew.png'}, {args.out / 'summary.md'}, CSVs in {args.out}")
    if args.report is not None:
        args.report.mkdir(parents=True, exist_ok=True)
        shutil.copy(args.out / "pd_slew.png", args.report / "pd_slew.png")
        shutil.copy(args.out / "summary.md", args.report / "summary.md")
        print(f"copied the plot and summary to {args.report}")
    return {"figures": fig_, "agree": agree, "gauss_seidel": gs}


if __name__ == "__main__":
    main()
