"""The one place where user input is checked: numbers, vectors, flags, names.

Every check returns the value converted (``float`` for numbers) or raises a ``SceneError``
that names what is wrong (``what``: ``"bulk_modulus"``, ``"cavity 'vitreous': bulk_modulus"``)
and what it must be. The scene tables (``scene/tables.py``) prefix it with the file and table;
the features and materials call the same checks for their Python API.
"""
import math
from collections.abc import Iterable
from numbers import Integral, Real

from .errors import SceneError

_BOUNDS = {"positive": (lambda v: v > 0, "be positive"), "nonnegative": (lambda v: v >= 0, "not be negative"),
           "fraction": (lambda v: 0 < v < 1, "be in (0, 1)")}


def is_number(value) -> bool:
    """A finite real number (not a bool): the test every check of a number makes."""
    return not isinstance(value, bool) and isinstance(value, Real) and math.isfinite(value)


def number(value, what: str, sign: str | None = None) -> float:
    """A finite number; ``sign`` is None, "positive", "nonnegative" or "fraction" (0 < v < 1)."""
    if not is_number(value):
        raise SceneError(f"{what} must be a finite number, got {value!r}")
    if sign is not None and not _BOUNDS[sign][0](value):
        raise SceneError(f"{what} must {_BOUNDS[sign][1]}, got {value!r}")
    return float(value)


def integer(value, what: str) -> int:
    """A positive integer."""
    if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
        raise SceneError(f"{what} must be a positive integer, got {value!r}")
    return value


def numbers(value, what: str, length: int | None = None) -> list:
    """A non-empty list of finite numbers (of ``length`` entries if given: 3 for a vector); a
    tuple or a NumPy array of them is taken too."""
    items = list(value) if isinstance(value, Iterable) and not isinstance(value, (str, bytes, dict)) else None
    if not items or (length is not None and len(items) != length) or not all(is_number(v) for v in items):
        count = f"{length} " if length is not None else ""
        raise SceneError(f"{what} must be a list of {count}finite numbers, got {value!r}")
    return [float(v) for v in items]


def vector(value, what: str) -> list:
    """A list of 3 finite numbers."""
    return numbers(value, what, length=3)


def nonzero_vector(value, what: str) -> list:
    """A list of 3 finite numbers, not all zero (a direction)."""
    components = vector(value, what)
    if not any(components):
        raise SceneError(f"{what} must be a non-zero vector of three numbers, got {value!r}")
    return components


def string(value, what: str) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value:
        raise SceneError(f"{what} must be a non-empty string, got {value!r}")
    return value


def strings(value, what: str) -> list:
    """A list of strings."""
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise SceneError(f"{what} must be a list of strings, got {value!r}")
    return value


def flag(value, what: str) -> bool:
    """true or false."""
    if not isinstance(value, bool):
        raise SceneError(f"{what} must be true or false, got {value!r}")
    return value


def known(name, names, what: str, kind: str, plural: str, *, assigned: bool = True, in_order: bool = False):
    """``name`` must be one of ``names``: ``kind`` says what they are ("[[cavity]] of the scene"),
    ``plural`` lists them ("cavities"), sorted, or in their own order if ``in_order`` (the steps,
    in the order they run). The message quotes the name as a key's value (``break_into =
    'lens'``), or after what it names if not ``assigned`` (``step 'later'``)."""
    if name not in names:
        listed = list(names) if in_order else sorted(names)
        raise SceneError(f"{what}{' =' if assigned else ''} {name!r} is not a {kind} ({plural}: {listed})")
    return name
