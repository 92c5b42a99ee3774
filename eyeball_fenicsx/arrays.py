"""Small array operations the features and the Newton system share."""
import numpy as np


def distinct_pairs(first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct pairs (first[i], second[i]) of non-negative integers, sorted by first, then
    second, as two int64 arrays: np.unique(axis=0) on one int64 key per pair, several times faster."""
    first, second = np.asarray(first, dtype=np.int64), np.asarray(second, dtype=np.int64)
    width = np.int64(second.max(initial=-1) + 1)
    keys = np.unique(first * width + second)
    return keys // width, keys % width
