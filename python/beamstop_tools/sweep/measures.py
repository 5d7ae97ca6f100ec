"""What is measured from one recorded point: the period of the response from
its stroboscopic (Poincare) samples, the peak and the local maxima of an
output from samples refined by cubic Hermite interpolation with its rate.

Pure functions on arrays, tested on synthetic signals with known answers.
"""
from __future__ import annotations

import math

import numpy as np


def response_period(poincare: np.ndarray, poincare_rate: np.ndarray | None, tol: float, max_period: int,
                    scales: tuple[float, float] | None = None) -> int | None:
    """The smallest p (in forcing periods) with x[k + p] = x[k] for every
    stroboscopic sample k, to `tol` times each signal's scale, seen
    repeating at least twice; None if there is none up to `max_period`.

    `poincare` and `poincare_rate` hold the output and its rate at phase 0
    of consecutive forcing periods; `scales` are the ranges of the two over
    the whole recording (the Poincare samples of a period-1 orbit have
    none), by default the Poincare samples' own ranges."""
    signals = [np.asarray(poincare, float)]
    if poincare_rate is not None:
        signals.append(np.asarray(poincare_rate, float))
    n = len(signals[0])
    if n < 3 or not all(np.all(np.isfinite(s)) for s in signals):
        return None
    if scales is None:
        scales = [float(np.ptp(s)) for s in signals]
    scales = [max(float(sc), 1e-12 * float(np.max(np.abs(s))), 1e-300) for sc, s in zip(scales, signals)]
    for p in range(1, min(max_period, (n - 1) // 2) + 1):
        if all(float(np.max(np.abs(s[p:] - s[:-p]))) <= tol * scale for s, scale in zip(signals, scales)):
            return p
    return None


def hermite_max(y0: float, y1: float, d0: float, d1: float, h: float) -> float:
    """The largest value over [0, h] of the cubic with values y0, y1 and
    slopes d0, d1 at its ends."""
    m0, m1 = d0 * h, d1 * h
    # p(s) = a s^3 + b s^2 + c s + y0 on s in [0, 1]
    a = 2 * y0 + m0 - 2 * y1 + m1
    b = -3 * y0 - 2 * m0 + 3 * y1 - m1
    c = m0
    best = max(y0, y1)
    roots = []
    if abs(a) > 1e-300:
        disc = b * b - 3 * a * c
        if disc >= 0:
            r = math.sqrt(disc)
            roots = [(-b + r) / (3 * a), (-b - r) / (3 * a)]
    elif abs(b) > 1e-300:
        roots = [-c / (2 * b)]
    for s in roots:
        if 0 < s < 1:
            best = max(best, ((a * s + b) * s + c) * s + y0)
    return best


def maxima(t: np.ndarray, y: np.ndarray, rate: np.ndarray | None, smooth: np.ndarray) -> np.ndarray:
    """Local maxima of y: where the rate changes sign from + to - between two
    samples, refined by Hermite interpolation if the interval had no event
    (smooth[i] true for the interval i .. i+1), else the larger sample; without a
    rate, the samples larger than both neighbours."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    out = []
    if rate is not None:
        rate = np.asarray(rate, float)
        for i in np.nonzero((rate[:-1] > 0) & (rate[1:] <= 0))[0]:
            if smooth[i]:
                out.append(hermite_max(y[i], y[i + 1], rate[i], rate[i + 1], t[i + 1] - t[i]))
            else:
                out.append(max(y[i], y[i + 1]))
    else:
        inner = (y[1:-1] >= y[:-2]) & (y[1:-1] > y[2:])
        out = list(y[1:-1][inner])
    return np.asarray(out, float)


def peak(y: np.ndarray, found_maxima: np.ndarray) -> float:
    """The largest value of the output: samples and refined maxima."""
    best = float(np.max(y)) if len(y) else math.nan
    if len(found_maxima):
        best = max(best, float(np.max(found_maxima)))
    return best
