"""What a run prints: the load stepping's line per increment, on rank 0 only.

The package logs through ``logging.getLogger(__name__)`` (system/stepping.py logs each
increment at INFO). ``print_on_rank0`` gives the ``eyeball_fenicsx`` logger a handler that
prints them, called by the command line and by ``Scene.run`` for the Python API, unless that
logger is configured already (a handler or a level of the caller's; ``silence`` for a script
that prints its own tables). Every rank logs and rank 0 prints (as DOLFINx's demos print on
rank 0 only), so a handler may run collective code on every rank: ``increment_lines`` hands
each line to a function while a block runs (a demo recording a curve per increment).

The package's records stop at its logger: the root logger's handler, which ffcx installs on
import (``logging.basicConfig()``), would print them again on stderr, on every rank.
"""
import contextlib
import logging
from collections.abc import Callable, Iterator

from mpi4py import MPI

PACKAGE = "eyeball_fenicsx"
STEPPING = f"{PACKAGE}.system.stepping"


class _PrintOnRank0(logging.Handler):
    """Print each record's message to the current ``sys.stdout`` on rank 0 of COMM_WORLD."""

    def emit(self, record: logging.LogRecord) -> None:
        if MPI.COMM_WORLD.rank == 0:
            print(self.format(record), flush=True)


class _Call(logging.Handler):
    """Hand each record's message to a function (on every rank)."""

    def __init__(self, function: Callable[[str], object]):
        super().__init__()
        self.function = function

    def emit(self, record: logging.LogRecord) -> None:
        self.function(record.getMessage())


def _handle_with(handler: logging.Handler) -> None:
    """Make ``handler`` the package logger's only one, for its INFO lines and above."""
    logger = logging.getLogger(PACKAGE)
    for old in list(logger.handlers):
        logger.removeHandler(old)
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False


def print_on_rank0() -> None:
    """Print the package's INFO lines on rank 0, unless its logger has a handler or a level."""
    logger = logging.getLogger(PACKAGE)
    if not logger.handlers and logger.level == logging.NOTSET:
        _handle_with(_PrintOnRank0())


def silence() -> None:
    """Print none of the package's INFO lines (``increment_lines`` still receives them)."""
    _handle_with(logging.NullHandler())


@contextlib.contextmanager
def increment_lines(function: Callable[[str], object]) -> Iterator[None]:
    """Call ``function(line)`` on every rank with each line the load stepping logs (a converged
    increment, or one that failed and is cut back) while the block runs; the package's logger
    must let INFO through, as ``print_on_rank0`` (``Scene.run``) and ``silence`` set it."""
    logger = logging.getLogger(STEPPING)
    handler = _Call(function)
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
