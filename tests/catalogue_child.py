"""Run several command lines of the catalogue (tests/test_invalid_catalogue.py) in one fresh
process, as ``python3 -m eyeball_fenicsx`` would run each: ``cli.main(argv)`` with its stdout and
stderr captured (an exception that escapes is written as the traceback Python would print, so it
fails the one-line test). One process for a rank's share of the cases saves starting Python,
MPI and DOLFINx for every case.

    python3 tests/catalogue_child.py FOLDER...   (each FOLDER holds argv.json; outcome.json is written)
"""
import contextlib
import io
import json
import os
import sys
import traceback

from eyeball_fenicsx import cli


def run(folder: str) -> None:
    with open(os.path.join(folder, "argv.json")) as f:
        argv = json.load(f)
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        try:
            code = cli.main(argv)
        except SystemExit as exit:
            code = exit.code if isinstance(exit.code, int) else 1
        except BaseException:
            traceback.print_exc()
            code = 1
    with open(os.path.join(folder, "outcome.json"), "w") as f:
        json.dump({"code": code, "stderr": stderr.getvalue()}, f)


if __name__ == "__main__":
    for folder in sys.argv[1:]:
        run(folder)
