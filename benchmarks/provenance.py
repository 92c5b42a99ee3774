"""What every benchmark's JSON records about the run: the commit, the date, the hardware, the
ranks, the load of the machine and the number of repeats.

    from provenance import run_record
    result = {"run": run_record(comm, repeats=3, load_average_before=load), ...}

Collective: call it on every rank. The commit is read when this module is imported, at the
start of the run (a file edited while a long benchmark runs does not change what ran).
"""
import datetime
import os
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))


def commit():
    """HEAD of the repository the benchmark runs from, with "-dirty" when tracked files other
    than the results differ from it (the numbers then come from code that no commit holds)."""
    git = ["git", "-C", os.path.dirname(HERE)]
    head = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run([*git, "status", "--porcelain", "--untracked-files=no", "--", ".",
                            ":(exclude)benchmarks/results"], capture_output=True, text=True).stdout.strip()
    return (head or "unknown") + ("-dirty" if dirty else "")


def hardware():
    """The CPU model (/proc/cpuinfo), the machine's cores and the cores each rank may use."""
    cpu = "unknown"
    with open("/proc/cpuinfo") as f:
        cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    return {"cpu": cpu, "cores": os.cpu_count(), "cores_per_rank": len(os.sched_getaffinity(0))}


COMMIT_AT_START = commit()


def machine_record(**extra):
    """The commit, the date and the hardware; ``extra`` adds the benchmark's own notes (settings,
    caveats). Not collective: for a benchmark that starts its runs itself."""
    now = datetime.datetime.now(datetime.timezone.utc)
    return {"commit": COMMIT_AT_START, "date": now.isoformat(timespec="seconds"),
            **hardware(), **extra}


def run_record(comm, repeats, **extra):
    """The record of this run under MPI: ``machine_record`` with the ranks, the repeats and the load."""
    return machine_record(ranks=comm.size, repeats=repeats, load_average_1min_at_end=os.getloadavg()[0], **extra)
