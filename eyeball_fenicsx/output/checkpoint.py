"""Checkpoints: what a run needs to continue, written after every converged step, and read back
by a resumed run (``Scene.run(out_dir, resume=True)``, ``eyeball-fenicsx run ... --resume``).

A checkpoint is the folder ``DIR/checkpoint/``:

* ``arrays-<k>-<rank>.npz``, one per rank, written by that rank: its owned dofs of the solid's
  mixed space W, sorted by their dof key (below), with their ``solution`` (the (u, p) dofs) and the
  features' dof arrays (contact multipliers, the values a prescribed displacement ramped from).
  No rank ever holds more than its own part, when writing or when reading;
* ``state.json``, written by rank 0: ``next_step`` (k, the index of the first step not done), the
  summary so far, the global unknowns of the problem (the liquids' pressures: with the (u, p)
  dofs, the solution), each feature's and observer's state that is not a dof array (a cavity's
  liquid law, the eye's pre-operative length...), the scene's fingerprint
  (output/fingerprint.py), the number of ranks that wrote it, and the name and SHA-256 of each
  of its arrays' files.

Atomic: the arrays go to files named by their step, then ``state.json`` is written under a
temporary name and renamed over the old one; it names the arrays it belongs to, so a run killed at
any moment leaves the previous checkpoint whole (the older arrays' files are removed after).

Reading on m ranks what n ranks wrote: rank r reads files r, r + m, ... (checking each file's
SHA-256) and sends every entry to the rank that keeps its key's directory (key mod m); each rank
asks those directories for the keys of the dofs it owns, and gets their values back (two
all-to-all exchanges: the memory and the reading are shared among the ranks).

Dof key: the place of a dof in a cell, ``original cell index * dofs per cell + local index``, the
smallest over the cells that hold it (a reverse ghost update with MAX of its negative reaches the
owner). The original cell index is the cell's row in the mesh as read or built, before DOLFINx
distributed it, and a cell's dofs keep their order in it, so the key names the same dof on any
number of ranks: a checkpoint written on n ranks is read on m.

The state of a feature or an observer is the ``Checkpointed`` role: ``checkpoint_state()`` gives a
dict of JSON values, the same on every rank (rank 0's are written), and of NumPy arrays over the
local dofs of W, ghosts included (as ``solid.w.x.array``); ``restore_state(state)`` takes such a
dict back. On resume the load factors of the end of the last step done are set, then the
solution, then each ``restore_state``, and the problem tells the features that follow the state
(``state_changed``). JSON keeps a float exactly (its repr), so the resumed run starts from the
state the interrupted one had, to the bit.
"""
from __future__ import annotations

import dataclasses
import glob
import hashlib
import io
import json
import os
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from ..system.stepping import ramp
from .files import raise_on_every_rank
from .fingerprint import first_difference

if TYPE_CHECKING:
    from ..system.problem import Problem

FORMAT = "eyeball-fenicsx checkpoint 2"


@runtime_checkable
class Checkpointed(Protocol):
    """A feature or observer whose state carries from one step to the next (module docstring)."""

    def checkpoint_state(self) -> dict:
        """JSON values (the same on every rank) and arrays over the local dofs of W (ghosts included)."""

    def restore_state(self, state: dict) -> None:
        """Take back what ``checkpoint_state`` gave (its arrays with their ghosts filled)."""


@dataclasses.dataclass
class Saved:
    """A checkpoint as read (its arrays are read by ``Checkpoint.restore``, shared among the ranks)."""

    next_step: int
    summary: dict
    states: dict  # "unknowns": the global unknowns; "features" / "observers": a dict of JSON values per item
    ranks: int
    arrays: list  # [file name, SHA-256] of each arrays' file
    fingerprint: dict | None = None  # rank 0 only


def dof_keys(W: fem.FunctionSpace) -> np.ndarray:
    """The key (module docstring) of every local dof of W, ghosts included (collective)."""
    msh = W.mesh
    cells = msh.topology.index_map(msh.topology.dim)
    count = cells.size_local + cells.num_ghosts
    dofs = W.dofmap.list.array.reshape(count, -1)
    per_cell = dofs.shape[1]
    original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[:count]
    work = fem.Function(W)
    keys = np.full(len(work.x.array), np.inf)
    np.minimum.at(keys, dofs.ravel(), (original[:, None] * per_cell + np.arange(per_cell)).ravel().astype(float))
    work.x.array[:] = -keys
    work.vector.ghostUpdate(addv=PETSc.InsertMode.MAX_VALUES, mode=PETSc.ScatterMode.REVERSE)
    work.x.scatter_forward()
    return (-work.x.array).astype(np.int64)


def _write_bytes_atomic(path: str, data: bytes) -> None:
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _plain(value):
    """JSON for NumPy scalars and small arrays."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} in a checkpoint's state is not JSON")


class Checkpoint:
    """The checkpoint folder of a run's output folder (module docstring); every method is collective."""

    def __init__(self, out_dir: str, comm: MPI.Comm) -> None:
        self.out_dir, self.comm = out_dir, comm
        self.folder = os.path.join(out_dir, "checkpoint")
        self.state_file = os.path.join(self.folder, "state.json")
        self._keys = None

    def exists(self) -> bool:
        return self.comm.bcast(os.path.exists(self.state_file) if self.comm.rank == 0 else None, root=0)

    def keys(self, W: fem.FunctionSpace) -> np.ndarray:
        if self._keys is None:
            self._keys = dof_keys(W)
        return self._keys

    # -- writing -------------------------------------------------------------------------
    def write(self, next_step: int, summary: dict, fingerprint: dict, problem: Problem, observers: list) -> None:
        """The checkpoint after a converged step: ``next_step`` is the first step not done."""
        n_owned = problem.n_owned
        columns = {"solution": problem.solid.w.x.array[:n_owned]}
        shared = {"unknowns": [float(v) for f in problem.global_unknowns for v in f.unknowns]}  # on every rank
        for group, items in (("features", problem.features), ("observers", observers)):
            shared[group] = []
            for i, item in enumerate(items):
                state = item.checkpoint_state() if isinstance(item, Checkpointed) else {}
                shared[group].append({key: value for key, value in state.items() if not isinstance(value, np.ndarray)})
                columns.update({f"{group}.{i}.{key}": value[:n_owned] for key, value in state.items()
                                if isinstance(value, np.ndarray)})
        keys = self.keys(problem.solid.W)[:n_owned]
        order = np.argsort(keys)
        arrays = {"keys": keys[order], **{name: values[order] for name, values in columns.items()}}
        name = f"arrays-{next_step:04d}-{self.comm.rank:05d}.npz"
        written, failure = None, None
        try:  # every rank must answer, whatever goes wrong, or the others would wait for ever
            written = [name, self._write_arrays(name, arrays)]
        except Exception as error:
            failure = self._unwritten(error)
        files = self.comm.gather((written, failure), root=0)
        if self.comm.rank == 0:
            failure = next((f for _, f in files if f), None)
            state = {"format": FORMAT, "next_step": next_step, "ranks": self.comm.size, "fingerprint": fingerprint,
                     **shared, "summary": summary, "arrays": [w for w, _ in files]}
            try:
                if failure is None:
                    self._write_state(state)
            except Exception as error:
                failure = self._unwritten(error)
        raise_on_every_rank(failure, self.comm)

    def _unwritten(self, error: Exception) -> str:
        return (f"could not write the checkpoint in {self.folder} ({type(error).__name__}: {error}); the "
                "checkpoint before it is kept")

    def _write_arrays(self, name: str, arrays: dict) -> str:
        """This rank's arrays under a new name; their SHA-256."""
        os.makedirs(self.folder, exist_ok=True)
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        data = buffer.getvalue()
        _write_bytes_atomic(os.path.join(self.folder, name), data)
        return hashlib.sha256(data).hexdigest()

    def _write_state(self, state: dict) -> None:
        """Rank 0: state.json over the old one, then the old arrays away."""
        _write_bytes_atomic(self.state_file, json.dumps(state, indent=1, default=_plain).encode())
        current = {name for name, _ in state["arrays"]}
        for old in glob.glob(os.path.join(self.folder, "arrays-*.npz*")) + glob.glob(f"{self.state_file}.tmp*"):
            if os.path.basename(old) not in current:  # older arrays, and what a killed run left half written
                os.remove(old)

    # -- reading -------------------------------------------------------------------------
    def read(self, fingerprint: dict, num_steps: int) -> Saved | None:
        """The checkpoint in the folder (None if there is none), checked against the scene's
        fingerprint; a SceneError on every rank if it is damaged or another scene's."""
        saved, message = None, None
        if self.comm.rank == 0:
            try:  # whatever the files hold: rank 0 must answer, or the other ranks would wait for ever
                saved = self._load(num_steps)
                message = self._mismatch(saved, fingerprint) if saved is not None else None
            except Exception as error:
                message = self._damaged(error)
        message = self.comm.bcast(message, root=0)
        if message:
            raise SceneError(message)
        head = self.comm.bcast(None if saved is None else (saved.next_step, saved.summary, saved.states, saved.ranks,
                                                           saved.arrays), root=0)
        return None if head is None else Saved(*head)

    def _damaged(self, error: Exception) -> str:
        return (f"{self.state_file}: the checkpoint is damaged ({type(error).__name__}: {error}); nothing in "
                f"{self.out_dir} was changed: run without --resume to start again")

    def _load(self, num_steps: int) -> Saved | None:
        """Rank 0: read and check the files; raises an exception if they are damaged."""
        if not os.path.exists(self.state_file):
            return None
        with open(self.state_file, "rb") as f:
            state = json.loads(f.read())
        if state.get("format") != FORMAT:
            raise ValueError(f"format {state.get('format')!r}, not {FORMAT!r}")
        for name, _ in state["arrays"]:
            if not os.path.exists(os.path.join(self.folder, os.path.basename(name))):
                raise FileNotFoundError(f"its arrays {name} are missing")
        if not 0 < state["next_step"] <= num_steps or not isinstance(state["summary"]["steps"], list):
            raise ValueError(f"next step {state['next_step']} of {num_steps}")
        states = {group: state[group] for group in ("unknowns", "features", "observers")}
        return Saved(state["next_step"], state["summary"], states, state["ranks"], state["arrays"],
                     state["fingerprint"])

    def _mismatch(self, saved: Saved, fingerprint: dict) -> str | None:
        difference = first_difference(fingerprint, saved.fingerprint)
        if difference is None:
            return None
        return (f"{self.out_dir}: its checkpoint was written by another scene: {difference}; nothing in "
                f"{self.out_dir} was changed: resume with the scene that wrote it, or run without --resume")

    # -- restoring -----------------------------------------------------------------------
    def restore(self, saved: Saved, problem: Problem, observers: list) -> None:
        """Put the run back in the state the checkpoint holds (module docstring)."""
        if saved.next_step > 0:  # the load factors at the end of the last step done
            problem.set_load_factor([ramp(f.step, saved.next_step - 1, 1.0) for f in problem.features])
        columns = self._local_arrays(saved, problem.solid.W, problem.n_owned)
        problem.solid.w.x.array[:] = columns["solution"]
        start = 0
        for f in problem.global_unknowns:  # the liquids' pressures, in the problem's block order
            f.unknowns = np.array(saved.states["unknowns"][start: start + f.num_unknowns])
            start += f.num_unknowns
        try:  # the same on every rank: a state.json edited by hand fails on all of them
            for group, items in (("features", problem.features), ("observers", observers)):
                for i, item in enumerate(items):
                    if isinstance(item, Checkpointed):
                        prefix = f"{group}.{i}."
                        state = dict(saved.states[group][i])
                        state.update({name[len(prefix):]: values for name, values in columns.items()
                                      if name.startswith(prefix)})
                        item.restore_state(state)
        except (KeyError, IndexError, TypeError, ValueError) as error:
            raise SceneError(self._damaged(error)) from None
        problem.state_to_vector(problem.x)
        problem.vector_to_state(problem.x)  # the features that follow the state (state_changed)

    def _local_arrays(self, saved: Saved, W: fem.FunctionSpace, n_owned: int) -> dict[str, np.ndarray]:
        """Each rank's entries of the checkpoint's dof arrays (module docstring), ghosts filled by
        their owners."""
        size = self.comm.size
        message, names, table = None, None, None
        try:
            names, keys, table = self._read_share(saved.arrays[self.comm.rank::size])
        except Exception as error:
            message = self._damaged(error)
        self._agree(message)
        names = next(n for n in self.comm.allgather(names) if n is not None)  # a rank may read no file
        if table is None:
            keys, table = np.zeros(0, dtype=np.int64), np.zeros((0, len(names)))
        directory = [(keys[keys % size == d], table[keys % size == d]) for d in range(size)]
        received = self.comm.alltoall(directory)
        keys = np.concatenate([k for k, _ in received])
        table = np.concatenate([t for _, t in received])
        order = np.argsort(keys)
        keys, table = keys[order], table[order]
        mine = self.keys(W)[:n_owned]
        asked = self.comm.alltoall([mine[mine % size == d] for d in range(size)])
        where = [np.minimum(np.searchsorted(keys, k), max(len(keys) - 1, 0)) for k in asked]
        missing = sum(int(np.sum(keys[w] != k)) if len(keys) else len(k) for w, k in zip(where, asked))
        missing, stored, wanted = self.comm.allreduce(np.array([missing, len(keys), n_owned]), op=MPI.SUM)
        if missing or stored != wanted:
            raise SceneError(f"{self.state_file}: its arrays hold {stored} dofs, and {missing} of this mesh's {wanted} "
                             "are not among them: the checkpoint is damaged or another mesh's")
        answers = self.comm.alltoall([table[w] for w in where])
        values = np.zeros((n_owned, len(names)))
        for d in range(size):
            values[mine % size == d] = answers[d]
        work = fem.Function(W)
        local = {}
        for j, name in enumerate(names):
            work.x.array[:n_owned] = values[:, j]
            work.x.scatter_forward()
            local[name] = work.x.array.copy()
        return local

    def _read_share(self, files: list) -> tuple[list | None, np.ndarray | None, np.ndarray | None]:
        """This rank's share of the arrays' files, checked: the column names, the keys and the table."""
        names, keys, tables = None, [], []
        for name, digest in files:
            path = os.path.join(self.folder, os.path.basename(name))
            with open(path, "rb") as f:
                data = f.read()
            if hashlib.sha256(data).hexdigest() != digest:
                raise ValueError(f"{path} is not the file it wrote (its SHA-256 differs: truncated or changed)")
            with np.load(io.BytesIO(data), allow_pickle=False) as npz:
                if "keys" not in npz.files or "solution" not in npz.files:
                    raise KeyError(f"{path} lacks the dof keys or the solution")
                names = sorted(n for n in npz.files if n != "keys")
                keys.append(npz["keys"])
                tables.append(np.column_stack([npz[n] for n in names]))
        if names is None:
            return None, None, None
        return names, np.concatenate(keys), np.concatenate(tables)

    def _agree(self, message: str | None) -> None:
        """A SceneError on every rank if any rank found one."""
        message = next((m for m in self.comm.allgather(message) if m), None)
        if message:
            raise SceneError(message)
