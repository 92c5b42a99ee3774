"""Bucket-grid search for the (point, box) pairs of contact candidates."""
from __future__ import annotations

import numpy as np


def candidate_pairs(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (point, box) index pairs with the point inside the axis-aligned box [lo, hi].

    A bucket grid with cells the size of an average box: every box is entered into the cells
    it overlaps, every point looks up its own cell, so the cost is linear in the number of
    points, boxes and pairs (numpy only, no Python loop).
    """
    empty = np.empty(0, dtype=np.int64)
    if len(points) == 0 or len(lo) == 0:
        return empty, empty
    cell = max(float(np.mean(np.max(hi - lo, axis=1))), 1e-300)
    origin = lo.min(axis=0)
    box_lo = np.floor((lo - origin) / cell).astype(np.int64)
    box_hi = np.floor((hi - origin) / cell).astype(np.int64)
    dims = box_hi.max(axis=0) + 1
    span = box_hi - box_lo + 1
    count = span.prod(axis=1)
    box = np.repeat(np.arange(len(lo)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    sx, sy = span[box, 0], span[box, 1]
    ix, iy, iz = box_lo[box, 0] + k % sx, box_lo[box, 1] + (k // sx) % sy, box_lo[box, 2] + k // (sx * sy)
    key = (ix * dims[1] + iy) * dims[2] + iz
    order = np.argsort(key, kind="stable")
    key, box = key[order], box[order]
    ip = np.floor((points - origin) / cell).astype(np.int64)
    inside = np.all((ip >= 0) & (ip < dims), axis=1)
    point_key = (ip[:, 0] * dims[1] + ip[:, 1]) * dims[2] + ip[:, 2]
    start = np.searchsorted(key, point_key, side="left")
    number = np.where(inside, np.searchsorted(key, point_key, side="right") - start, 0)
    point = np.repeat(np.arange(len(points)), number)
    j = np.arange(number.sum()) - np.repeat(np.cumsum(number) - number, number) + np.repeat(start, number)
    box = box[j]
    keep = np.all((points[point] >= lo[box]) & (points[point] <= hi[box]), axis=1)
    return point[keep], box[keep]
