"""The four report scenes, written from the papers (not from beamstop's code).

Pinned-pinned beam (VSM12: Vyasarayani, Sandhu & McPhee 2012), scaled units, N modes:
    W_j(x) = sqrt(2) sin(j pi x), omega_j = (j pi)^2,
    alpha_j = sqrt(2) (1 - cos j pi) / (j pi)  (modal load of a uniform load),
    q_j'' + 2 zeta omega_j q_j' + omega_j^2 q_j = alpha_j F sin(Omega t),
    stop at x_s on the +w side: g = d - w.q >= 0, w_j = W_j(x_s).
Two-mass chain (WB00: Wagg & Bishop 2000), physical coordinates x1, x2:
    x'' + c E x' + k E x = (0.5 cos(0.9 t), 0),  E = [[2, -1], [-1, 1]],
    stop x2 <= 0.1, restitution on mass 2's velocity (w = (0, 1), w.w = 1).

Both are written as y = (q, qd), qdd = f(t) - D qd - K q with a stop row w,
so the event-driven baselines, the penalty stop and the error measures share
one description. Every parameter is a float64, given to beamstop, to the FMU
and to the references exactly as written here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

PI = math.pi
SCENE_PINNED = "scenes/pinned_beam.json"
SCENE_CHAIN = "scenes/wagg_bishop_chain.json"
FMU_PINNED = "target/fmu/PinnedBeamStop.fmu"
FMU_CHAIN = "target/fmu/WaggBishopChain.fmu"


@dataclass
class Scene:
    key: str
    title: str
    kind: str  # "beam" or "chain"
    n: int
    K: np.ndarray
    D: np.ndarray
    w: np.ndarray
    fs: np.ndarray  # load = fs sin(Omega t) + fc cos(Omega t)
    fc: np.ndarray
    Omega: float
    d: float
    R: float
    eps: float
    q0: np.ndarray
    qd0: np.ndarray
    t_end: float
    dense_dt: float
    start_stuck: bool = False
    # beam parameters (for the closed form)
    x_s: float = 0.4
    zeta: float = 0.0
    F: float = 0.0
    # what beamstop is told
    scene_file: str = SCENE_PINNED
    set_values: dict = field(default_factory=dict)
    fmu: str = FMU_PINNED
    fmu_prefix: str = ""  # "stop." for the chain's stop outputs
    # how many impact times enter the impact-time error
    k_impacts: int = 10
    description: str = ""
    # modal -> physical map for beamstop's chain coordinates (None for beams)
    phi: np.ndarray | None = None

    @property
    def ww(self) -> float:
        return float(self.w @ self.w)

    def forcing(self, t: float) -> np.ndarray:
        return self.fs * math.sin(self.Omega * t) + self.fc * math.cos(self.Omega * t)

    def y0(self) -> np.ndarray:
        return np.concatenate([self.q0, self.qd0])

    def with_horizon(self, t_end: float) -> "Scene":
        import copy

        s = copy.copy(self)
        s.t_end = t_end
        return s


def beam_modes(n: int, x_s: float):
    j = np.arange(1, n + 1, dtype=float)
    omega = (j * PI) ** 2
    w = math.sqrt(2.0) * np.sin(j * PI * x_s)
    alpha = math.sqrt(2.0) * (1.0 - np.cos(j * PI)) / (j * PI)
    return omega, w, alpha


def pinned(key, title, *, n=4, F, Omega, zeta, R, eps, d, q0=None, qd0=None, t_end, dense_dt=1e-3,
           start_stuck=False, set_values=None, k_impacts=10, description="", x_s=0.4) -> Scene:
    omega, w, alpha = beam_modes(n, x_s)
    q0 = np.zeros(n) if q0 is None else np.asarray(q0, float)
    qd0 = np.zeros(n) if qd0 is None else np.asarray(qd0, float)
    return Scene(
        key=key, title=title, kind="beam", n=n,
        K=np.diag(omega**2), D=np.diag(2.0 * zeta * omega), w=w,
        fs=alpha * F, fc=np.zeros(n), Omega=Omega, d=d, R=R, eps=eps, q0=q0, qd0=qd0,
        t_end=t_end, dense_dt=dense_dt, start_stuck=start_stuck, x_s=x_s, zeta=zeta, F=F,
        scene_file=SCENE_PINNED, set_values=dict(set_values or {}), fmu=FMU_PINNED,
        k_impacts=k_impacts, description=description,
    )


def chain_phi() -> np.ndarray:
    """beamstop's chain modal basis as its docs state it: unit eigenvectors of
    E, ascending eigenvalues, signed so that mass 2 moves positively (m = 1)."""
    E = np.array([[2.0, -1.0], [-1.0, 1.0]])
    lam, V = np.linalg.eigh(E)
    order = np.argsort(lam)
    V = V[:, order]
    for c in range(V.shape[1]):
        if V[-1, c] < 0:
            V[:, c] = -V[:, c]
        V[:, c] /= np.linalg.norm(V[:, c])
    return V


Q0_FREE = -3.0 / math.sqrt(2.0)  # -2.1213203435596424: first impact at 1/(2 pi)
PERIOD_S2 = 2.0 * PI / (0.7 * PI**2)
PERIOD_S4 = 2.0 * PI / 0.9


def scenes(s1_horizon: float = 1.0) -> dict[str, Scene]:
    s1 = pinned(
        "S1", "free vibration, R = 1", F=0.0, Omega=0.1 * PI**2, zeta=0.0, R=1.0, eps=1e-6, d=0.0,
        q0=[Q0_FREE, 0.0, 0.0, 0.0], t_end=s1_horizon,
        set_values={"R": 1.0, "F": 0.0, "zeta": 0.0, "d": 0.0, "q0[1]": Q0_FREE},
        k_impacts=10,
        description="4 modes, F = 0, zeta = 0, R = 1, d = 0, released from q1(0) = -3/sqrt(2) "
        "(mode 1 only): the first impact is at exactly 1/(2 pi), after which energy spreads to "
        "all four modes and the impact sequence becomes sensitive to the last digit.",
    )
    s2 = pinned(
        "S2", "Figure 10 regime", F=72.0, Omega=0.7 * PI**2, zeta=0.05, R=0.7, eps=1e-3, d=1.2,
        t_end=5.0 * PERIOD_S2,
        set_values={"F": 72.0, "omega": 0.7 * PI**2, "zeta": 0.05, "R": 0.7, "eps": 1e-3, "d": 1.2},
        k_impacts=8,
        description="4 modes, F = 72, Omega = 0.7 pi^2, d = 1.2, R = 0.7, zeta = 0.05, eps = 1e-3, "
        "beam at rest at t = 0; horizon 5 forcing periods (T = 2 pi / Omega = 0.9095). "
        "Two impacts per forcing period once settled, no sticking.",
    )
    s3 = pinned(
        "S3", "Figure 4 chatter and sticking", F=76.8, Omega=0.1 * PI**2, zeta=0.05, R=0.7, eps=1e-6,
        d=0.0, t_end=7.0, start_stuck=True, set_values={}, k_impacts=10,
        description="the default pinned scene (VSM12 Figure 4): F = 76.8, Omega = 0.1 pi^2, R = 0.7, "
        "d = 0, zeta = 0.05, eps = 1e-6, at rest on the stop with the load pressing: it starts stuck, "
        "is released near t = 3.18, chatters from t = 6.377 (30 impacts, the last with R = 0) and "
        "sticks at t = 6.4865; it is released again near 6.4996, chatters and sticks again near 6.5902. "
        "Horizon t = 7.",
    )
    phi = chain_phi()
    E = np.array([[2.0, -1.0], [-1.0, 1.0]])
    s4 = Scene(
        key="S4", title="chain P(1,1)", kind="chain", n=2, K=1.0 * E, D=0.1 * E,
        w=np.array([0.0, 1.0]), fs=np.zeros(2), fc=np.array([0.5, 0.0]), Omega=0.9, d=0.1, R=0.7,
        eps=1e-6, q0=np.zeros(2), qd0=np.zeros(2), t_end=10.0 * PERIOD_S4, dense_dt=1e-2,
        scene_file=SCENE_CHAIN, set_values={}, fmu=FMU_CHAIN, fmu_prefix="stop.", k_impacts=10,
        description="WB00 Fig. 2 two-mass chain: m = 1, k = 1, c = 0.1, forcing 0.5 cos(0.9 t) on "
        "mass 1, stop x2 <= 0.1, r = 0.7, from rest; horizon 10 forcing periods (69.8), "
        "during which the motion settles towards the P(1,1) orbit (one impact per period).",
        phi=phi,
    )
    return {"S1": s1, "S2": s2, "S3": s3, "S4": s4}
