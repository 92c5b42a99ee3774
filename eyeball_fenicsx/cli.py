"""Command line: ``eyeball-fenicsx run SCENE.toml --out DIR [--resume] [--linear-solver NAME] [PETSc
options]``, and ``eyeball-fenicsx sweep SCENE.toml --parameter P --values V... [--parameter Q --values
W...] [--range R LOW HIGH]... --out DIR [--resume] [--linear-solver NAME]`` (scene/sweep.py).
``--linear-solver`` (mumps, mumps-blr, iterative: system/linear_solvers.py) replaces the scene's
``[solver] linear``.

Exit codes (the scene contract): 0 every step converged; 2 the scene or mesh is invalid (or a
command-line option is unknown, or the checkpoint to resume is damaged or another scene's);
3 a step did not converge after the automatic cut-backs; 4 a signal (SIGTERM, SIGINT, SIGUSR1)
stopped the run at a safe point, with the last converged state kept (``--resume`` continues it);
5 the output folder could not be written (a full disk, no permission) or a picture could not be
drawn, what was written kept.
Errors are one line on stderr. Options after the scene that start with one dash
(``-eye_snes_monitor``...) go to PETSc; an option with two dashes that is not the command's own
is an error, never handed to PETSc. The load increments are printed on stdout by rank 0
(output/console.py); stderr carries the warnings and the error.
"""
import argparse
import logging
import sys

from mpi4py import MPI
from petsc4py import PETSc

from .errors import ConvergenceError, Interrupted, OutputError, SceneError
from .output.console import print_on_rank0
from .system.settings import LINEAR_SOLVERS

INTERRUPTED = 4  # the exit code of a run a signal stopped
UNWRITABLE = 5  # the exit code of a run that could not write its output folder


def _petsc_options(tokens: list[str]) -> None:
    """Put ``-key [value]`` tokens into the PETSc options database; a ``--option`` is not one."""
    opts = PETSc.Options()
    i = 0
    while i < len(tokens):
        token = tokens[i]
        if token.startswith("--"):
            raise SceneError(f"unknown option {token.split('=')[0]!r} (see --help; PETSc options take one dash: "
                             "-eye_snes_monitor)")
        if not token.startswith("-"):
            raise SceneError(f"unexpected argument {token!r}: PETSc options start with '-'")
        value = ""
        if i + 1 < len(tokens) and not tokens[i + 1].startswith("-"):
            value, i = tokens[i + 1], i + 1
        opts[token.lstrip("-")] = value
        i += 1


def _warnings_only(record: logging.LogRecord) -> bool:
    """Filter of the root logger. The JIT compiler (cffi through distutils) logs every form it
    compiles at INFO on the root logger, and ffcx's ``logging.basicConfig()`` sends that to
    stderr, which is for warnings and the one-line error."""
    return record.levelno >= logging.WARNING


def _fail(code: int, message: object) -> int:
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {message}", file=sys.stderr, flush=True)
    return code


class _Parser(argparse.ArgumentParser):
    """argparse whose errors are one-line SceneErrors (exit 2), not a usage message."""

    def error(self, message: str):  # type: ignore[override]
        raise SceneError(f"{self.prog}: {message} (see --help)")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="eyeball-fenicsx", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run a scene TOML file")
    run.add_argument("scene")
    run.add_argument("--out", required=True, help="output folder (summary.json, fields.xdmf, checkpoint/)")
    run.add_argument("--resume", action="store_true", help="continue from the checkpoint in the output folder")
    _linear_solver_option(run)
    sweep = commands.add_parser("sweep", help="run a scene over a grid of parameter values, with bands over "
                                "ranges of constants (CSV + PNG)",
                                usage="eyeball-fenicsx sweep SCENE --parameter P --values V [V ...] [--parameter Q "
                                "--values W [W ...]] [--range R LOW HIGH]... --out DIR [--resume]")
    sweep.add_argument("scene")
    sweep.add_argument("--parameter", action="append", default=[], help="dotted path into the scene, e.g. "
                       "band.0.reduction; repeat it, each with its --values, for a grid")
    # the counts of values and ends are checked by the sweep (sweep_plan.py), which names the scene
    sweep.add_argument("--values", action="append", default=[], nargs="*", help="the parameter's values")
    sweep.add_argument("--range", action="append", default=[], nargs="+", metavar=("R", "LOW HIGH"),
                       help="R LOW HIGH: an uncertain constant and its range; every grid point also runs at the "
                       "corners of the ranges' box, and bands.csv gives each prediction's smallest and largest "
                       "value there")
    sweep.add_argument("--out", required=True, help="output folder (sweep.csv, sweep.png, one folder a run)")
    sweep.add_argument("--resume", action="store_true", help="skip the runs that are done, resume the one that "
                       "was stopped")
    _linear_solver_option(sweep)
    return parser


def _linear_solver_option(command: argparse.ArgumentParser) -> None:
    command.add_argument("--linear-solver", choices=LINEAR_SOLVERS, help="the linear solver of the Newton steps, "
                         "instead of the scene's [solver] linear (README: which solver when)")


def _sweep(args: argparse.Namespace) -> None:
    """The sweep command: each --parameter with its --values, in the order given."""
    if len(args.parameter) != len(args.values):
        raise SceneError(f"{args.scene}: sweep: {len(args.parameter)} --parameter but {len(args.values)} --values: "
                         "give each --parameter its --values")
    from .scene.sweep import run_sweep
    run_sweep(args.scene, list(zip(args.parameter, args.values)), args.out, resume=args.resume,
              ranges=args.range, linear=args.linear_solver)


def main(argv: list[str] | None = None) -> int:
    logging.getLogger().addFilter(_warnings_only)
    print_on_rank0()  # the load increments, on stdout (rank 0)
    try:
        args, petsc = _parser().parse_known_args(argv)
        _petsc_options(petsc)
        if args.command == "sweep":
            _sweep(args)
            return 0
        from .scene.loader import load_scene
        scene = load_scene(args.scene, linear=args.linear_solver)
        try:
            scene.run(args.out, resume=args.resume)
        except SceneError as error:  # found while building (probes, cavities) or resuming: say which file
            raise SceneError(f"{args.scene}: {error}") from None
    except SceneError as error:
        return _fail(2, error)
    except ConvergenceError as error:
        return _fail(3, error)
    except Interrupted as error:
        return _fail(INTERRUPTED, error)
    except OutputError as error:
        return _fail(UNWRITABLE, error)
    except KeyboardInterrupt:  # Ctrl-C before the run began: nothing was written
        return _fail(INTERRUPTED, "interrupted before the first step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
