"""Stopping a run at a safe point when it is asked to: SIGTERM (a scheduler's wall-time limit,
``kill``), SIGINT (Ctrl-C) or SIGUSR1.

While a run holds ``StopRequests`` (a context manager), these signals only raise a flag; the
load stepping asks ``requested()`` after each load increment and the scene after each step,
where the state is a converged one. The question is collective (an allreduce of the flag), so
all ranks stop together even when the signal reached only some of them. A second Ctrl-C
(SIGINT) ends the process at once (its default action; the run then resumes from its last
checkpoint); a second SIGTERM or SIGUSR1 changes nothing, since a scheduler may send one to
``mpirun`` and to the ranks both. The handlers that were installed before are put back when the
block ends, so the Python API leaves none of its own behind.

Open MPI's ``mpirun`` forwards SIGTERM to the ranks but follows it with SIGKILL a second later
(``odls_base_sigkill_timeout``): too soon to finish an increment. It forwards SIGUSR1 and
leaves the ranks running, so send SIGUSR1 to ``mpirun`` to stop a parallel run at its next safe
point (a scheduler that signals the ranks themselves, as Slurm's ``srun`` does, may send
SIGTERM).

Python runs a handler in the main thread only: a run started from another thread installs
none and is stopped by the signals' usual actions.
"""
from __future__ import annotations

import os
import signal
import threading

from mpi4py import MPI

SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGUSR1)


class StopRequests:
    """The stop requests of one run (see the module docstring)."""

    def __init__(self, comm: MPI.Comm) -> None:
        self.comm = comm
        self.received = 0  # the number of the first signal received, 0: none
        self._previous = {}

    def __enter__(self) -> StopRequests:
        if threading.current_thread() is threading.main_thread():
            self._previous = {number: signal.signal(number, self._handle) for number in SIGNALS}
        return self

    def __exit__(self, *exc) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous = {}

    def _handle(self, number: int, frame) -> None:
        """Remember the first signal; a second SIGINT ends the process at once. (A handler only
        sets a flag: printing here could break a write it interrupted.)"""
        if number == signal.SIGINT and self.received == number:
            signal.signal(number, signal.SIG_DFL)
            os.kill(os.getpid(), number)
        self.received = self.received or number

    def requested(self) -> str | None:
        """Collective: the name of a signal that asks this run to stop, received by any rank, or
        None."""
        number = self.comm.allreduce(self.received, op=MPI.MAX)
        return signal.Signals(number).name if number else None
