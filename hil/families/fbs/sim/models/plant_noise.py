"""The thermal plant's measurement noise: seeded standard normal values, clipped at ±NOISE_CLIP, indexed by point
and time so that a measurement's noise is the same whichever scan takes it (stepping, or after a jump)."""

from __future__ import annotations

import random

import numpy as np

#: measurement noise is clipped at this many standard deviations (so a reading has a hard bound: the FUN86 model
#: can then skip the scans at measurements that can never reach the pre-alarm limit)
NOISE_CLIP = 6.0


_NORMALS: dict[int, np.ndarray] = {}


def normals(seed: int) -> np.ndarray:
    """65536 standard normal values, clipped at ±NOISE_CLIP, drawn once per seed."""
    table = _NORMALS.get(seed)
    if table is None:
        rng = random.Random(seed)
        table = _NORMALS[seed] = np.array([min(max(rng.gauss(0.0, 1.0), -NOISE_CLIP), NOISE_CLIP)
                                           for _ in range(65536)])
    return table


_MASK64 = (1 << 64) - 1
_U = np.uint64
_MIX1, _MIX2, _MIX3 = _U(0x9E3779B97F4A7C15), _U(0xBF58476D1CE4E5B9), _U(0x94D049BB133111EB)
_S30, _S27, _S31, _LOW16 = _U(30), _U(27), _U(31), _U(0xFFFF)


def noise_index(seed: int, points: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Which of the 65536 normals a measurement of ``points`` at ``times`` draws: splitmix64's finaliser over
    (t in µs, point, seed), modulo 2^64 (exact for any seed: the seed's term is taken as a Python int)."""
    terms = _POINT_TERMS.get(seed)
    if terms is None:  # point × K2 + seed × K3 for each point
        terms = _POINT_TERMS[seed] = np.arange(64, dtype=np.uint64) * _MIX2 + _U(seed * 0x94D049BB133111EB & _MASK64)
    x = np.rint(np.asarray(times, dtype=float) * 1000000.0).astype(np.uint64) * _MIX1 + terms[points]  # (t ≥ 0)
    x = (x ^ (x >> _S30)) * _MIX2
    x = (x ^ (x >> _S27)) * _MIX3
    return (x ^ (x >> _S31)) & _LOW16


_POINT_TERMS: dict[int, np.ndarray] = {}
