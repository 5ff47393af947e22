"""Small helpers for models that work on columns of measurements (arrays over (time, point) pairs)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


def last_of_each(values: np.ndarray) -> np.ndarray:
    """Indexes of the last occurrence of each distinct value (non-negative integers), in the values' order."""
    if len(values) <= 8:  # (a few: a dict keeps each value's last index)
        last_index = {v: i for i, v in enumerate(values.tolist())}
        return np.array([last_index[v] for v in sorted(last_index)], dtype=np.intp)
    last = np.full(int(values.max()) + 1, -1, dtype=np.intp)
    np.maximum.at(last, values, np.arange(len(values)))
    return last[last >= 0]


def occurrence(values: np.ndarray) -> np.ndarray:
    """For each element, how many equal elements come before it (its row when each value gets a column)."""
    if len(values) <= 1:
        return np.zeros(len(values), dtype=np.int64)
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    starts = np.flatnonzero(np.concatenate(([True], ordered[1:] != ordered[:-1])))
    rank = np.arange(len(values)) - np.repeat(starts, np.diff(np.append(starts, len(values))))
    out = np.empty(len(values), dtype=np.int64)
    out[order] = rank
    return out


def signed16(words: npt.ArrayLike) -> np.ndarray:
    """16-bit words as signed values."""
    return (np.asarray(words, dtype=np.int64) ^ 0x8000) - 0x8000
