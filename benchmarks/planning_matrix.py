"""Surgery without tuning: the surgeon's variants of the two buckle scenes, with default solver settings.

A surgeon planning an operation changes what the operation does, not how the solver runs. Each
variant below is one of the two shipped scenes, demos/encircling_buckle_seed.toml and
demos/segmental_buckle.toml, with one surgical parameter changed and nothing else:

* the encircling band's circumference reduction, 2 to 14 mm (``band.0.reduction``; 8 as shipped);
* its width, 1.5 and 4 mm (``mesh.band_width``; 2.5), and its position, 11 and 15 mm behind the
  limbus (``mesh.band_position``; 12.5), the detachment left where the shipped scene has it
  (the builder centres a detachment without ``polar_deg`` under the band: the surgeon moves
  the band, not the retina; centred under a band at 11 mm it would reach the ora serrata);
* a drainage step after the sutures: a fourth step "drain" with an ``[[injection]]`` of -100 mm^3
  into the cavity "vitreous" (the half model's half of 0.2 mL; README.md, "Contact, sutures, bands");
* the segmental tire's sutures tied by 0.1 to 1.0 mm (``buckle_sutures.shortening``; 0.4);
* the tire's height, 0.5 and 2 mm (``mesh.tire.height``; 1), and its arc, 30 and 90 degrees
  (``mesh.tire.arc_deg``; 60);
* its sutures tied by a tension of 0.04 N each instead of a shortening (``buckle_sutures.tension``
  for ``shortening``).

Every variant runs under MPI on the default eye (``--n-circ 40``) with the scene's own solver
settings, as shipped: the script adds no solver option. ``--strip-knobs`` removes what a scene
sets to make the solver converge, the ``[solver]`` table and the ``penalty`` and ``smoothing`` of
every ``[[contact]]``, to run the variants as a new user would write them.

Per variant (one row, printed by rank 0 as soon as it finishes):

* **status**: converged, or where it stopped (the ``ConvergenceError``; the next variant runs);
* per step (``a+b+c`` in the table): the converged **increments**, the **Newton** iterations of
  every attempt, failed increments included (counted by a SNES monitor), and the **cut-backs**
  (increments that failed and were halved: the solver's "failed" messages);
* **wall** time: building the mesh, the scene (forms from the disk cache; a cold cache adds the
  compilation to the first variant of each scene) and the run, with its output (fields, pictures,
  summary.json in ``--out``/NAME, beside the variant's scene file ``scene.toml``); **load**: the
  1-minute load average before it (the machine may be shared);
* the predictions after the last step (``summary["steps"][-1]["eye"]``): buckle height, axial
  length change, IOP, largest retina gap, detached area (of the half model).

At the end: whether the predictions move the right way, over the reduction series (more
reduction: a higher buckle, a longer eye, a higher IOP) and over the shortening series (sutures
tied tighter: a deeper indentation). Written to benchmarks/results/planning_matrix.json and
planning_matrix.md (``planning_matrix_strip_knobs.*`` with ``--strip-knobs``), after every
variant, with the commit, the hardware, the ranks and the date.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/planning_matrix.py [--n-circ 40]
        [--only reduction-5 segmental-0.4] [--strip-knobs] [--list] [--verbose]
"""
import argparse
import copy
import dataclasses
import json
import os
import re
import time
import tomllib

import tomli_w
from mpi4py import MPI
from provenance import machine_record

from eyeball_fenicsx.errors import ConvergenceError, SceneError
from eyeball_fenicsx.meshing.builders.buckle_placement import buckle_layout
from eyeball_fenicsx.output.console import increment_lines, silence
from eyeball_fenicsx.output.files import write_json_atomic, write_text_atomic
from eyeball_fenicsx.scene.loader import load_scene
from eyeball_fenicsx.scene.overrides import set_parameter

comm = MPI.COMM_WORLD
HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = {"encircling": os.path.join(HERE, "..", "demos", "encircling_buckle_seed.toml"),
          "segmental": os.path.join(HERE, "..", "demos", "segmental_buckle.toml")}
DRAINED_MM3 = 100.0  # from the half model's vitreous: 0.2 mL from the whole eye
SUTURE_TENSION_N = 0.04  # N per suture: about what a 0.4 mm shortening of segmental-0.4's sutures pulls with
PREDICTIONS = {"buckle_height_mm": ("buckle height (mm)", "{:.3f}"),
               "axial_length_change_mm": ("axial length change (mm)", "{:.3f}"),
               "iop_mmHg": ("IOP (mmHg)", "{:.1f}"),
               "retina_gap_max_mm": ("retina gap max (mm)", "{:.3f}"),
               "detached_area_mm2": ("detached area (mm^2)", "{:.1f}")}
# what must rise along a series as its parameter grows
CHECKS = {"reduction": ("buckle_height_mm", "axial_length_change_mm", "iop_mmHg"),
          "shortening": ("buckle_height_mm",)}


@dataclasses.dataclass
class Variant:
    """One scene with surgical parameters changed: ``changes`` are {dotted path: value}
    (``scene.overrides.set_parameter``); ``drain_mm3`` adds the drainage step; ``tension_n`` ties
    the buckle's sutures by that tension (N each) instead of their shortening."""

    name: str
    scene: str
    changes: dict = dataclasses.field(default_factory=dict)
    drain_mm3: float = None
    tension_n: float = None
    series: str = None  # "reduction" or "shortening": the variant is a point of that check
    value: float = None


def variants():
    matrix = [Variant(f"reduction-{mm:g}", "encircling", {"band.0.reduction": mm}, series="reduction", value=mm)
              for mm in (2.0, 5.0, 8.0, 11.0, 14.0)]
    matrix += [Variant(f"band-width-{mm:g}", "encircling", {"mesh.band_width": mm}) for mm in (1.5, 4.0)]
    detachment = shipped_detachment("encircling")
    matrix += [Variant(f"band-position-{mm:g}", "encircling", {"mesh.band_position": mm, "mesh.detachment": detachment})
               for mm in (11.0, 15.0)]
    matrix += [Variant(f"drain-{DRAINED_MM3:g}", "encircling", drain_mm3=DRAINED_MM3)]
    matrix += [Variant(f"segmental-{mm:g}", "segmental", {"buckle_sutures.shortening": mm}, series="shortening",
                       value=mm) for mm in (0.1, 0.4, 0.8, 1.0)]
    matrix += [Variant(f"tire-height-{mm:g}", "segmental", {"mesh.tire.height": mm}) for mm in (0.5, 2.0)]
    matrix += [Variant(f"tire-arc-{deg:g}", "segmental", {"mesh.tire.arc_deg": deg}) for deg in (30.0, 90.0)]
    matrix += [Variant(f"segmental-tension-{SUTURE_TENSION_N:g}", "segmental", tension_n=SUTURE_TENSION_N)]
    return matrix


def shipped_detachment(scene):
    """The shipped scene's detachment with its centre written out (``polar_deg``: where the mesh
    builder centres it, under the buckle as shipped), so that a variant moving the buckle keeps it."""
    with open(SCENES[scene], "rb") as f:
        mesh = dict(tomllib.load(f)["mesh"])
    mesh.pop("builder")
    return buckle_layout(**mesh).detachment


def special(variant):
    """The changes that are not a value set, in words: the drainage step, the sutures' tension."""
    return ([f"drain step: {-variant.drain_mm3:g} mm^3 from the vitreous"] if variant.drain_mm3 else []) + \
        ([f"buckle_sutures.tension = {variant.tension_n:g} N, not shortening"] if variant.tension_n else [])


def described(changes):
    """The changes in words: "path = value"; a detachment by its centre, kept as shipped."""
    return [f"{path}.polar_deg = {value['polar_deg']:.1f} (as shipped)" if isinstance(value, dict)
            else f"{path} = {value:g}" for path, value in changes.items()]


def strip_knobs(data):
    """Remove the solver's knobs from a parsed scene; returns the dotted paths removed."""
    removed = ["solver"] if data.pop("solver", None) is not None else []
    for i, contact in enumerate(data.get("contact", [])):
        removed += [f"contact.{i}.{key}" for key in ("penalty", "smoothing") if contact.pop(key, None) is not None]
    return removed


def scene_data(variant, base, n_circ):
    """The variant's scene (a new dict) and a description of what differs from ``base``."""
    data = copy.deepcopy(base)
    for path, value in variant.changes.items():
        if isinstance(value, dict):  # a table, set whole (set_parameter sets a value)
            section, key = path.split(".")
            data[section][key] = dict(value)
        else:
            set_parameter(data, path, value)
    if variant.drain_mm3:
        data["step"].append({"name": "drain"})
        data.setdefault("injection", []).append({"cavity": "vitreous", "volume": -variant.drain_mm3, "step": "drain"})
    if variant.tension_n:
        del data["buckle_sutures"]["shortening"]
        data["buckle_sutures"]["tension"] = variant.tension_n
    changed = "as shipped" if data == base else ", ".join(described(variant.changes) + special(variant))
    set_parameter(data, "mesh.n_circ", n_circ)
    if "file" in data["mesh"]:  # the scene is written elsewhere: its mesh path must not depend on that
        data["mesh"]["file"] = os.path.join(os.path.dirname(os.path.abspath(SCENES[variant.scene])),
                                            data["mesh"]["file"])
    return data, changed


class RunLog:
    """The load stepping's lines (``increment_lines``), counted per step: Newton iterations of every attempt
    (from a SNES monitor, booked to the step of the message that ends the attempt) and cut-backs."""

    def __init__(self, step_names, verbose):
        self.steps = {name: {"newton_iterations": 0, "cutbacks": 0} for name in step_names}
        self.verbose, self.iterations = verbose, 0

    def monitor(self, snes, its, norm):
        if its > 0:  # its = 0 reports the initial residual
            self.iterations += 1

    def __call__(self, message):
        name = next((n for n in self.steps if message.startswith(f"step {n}:")), None)
        if name is not None:
            self.steps[name]["newton_iterations"] += self.iterations
            self.steps[name]["cutbacks"] += "failed" in message
            self.iterations = 0
        if self.verbose and comm.rank == 0:
            print(f"    {message}", flush=True)


def run_variant(variant, data, out_dir, verbose):
    """Build and run one variant; its record (rank 0's is written)."""
    path = os.path.join(out_dir, "scene.toml")  # kept: `eyeball-fenicsx run` reruns it
    if comm.rank == 0:
        os.makedirs(out_dir, exist_ok=True)
        with open(path, "wb") as f:
            tomli_w.dump(data, f)
        if os.path.exists(os.path.join(out_dir, "summary.json")):
            os.remove(os.path.join(out_dir, "summary.json"))
    comm.barrier()
    log = RunLog([s["name"] for s in data["step"]], verbose)
    record = {"ok": True, "error": None, "load_average": os.getloadavg()[0]}
    start = time.perf_counter()
    try:
        scene = load_scene(path, comm)
        record["mesh_s"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        scene.build()
        scene.newton.snes.setMonitor(log.monitor)
        with increment_lines(log):
            summary = scene.run(out_dir)
    except (ConvergenceError, SceneError) as error:
        record.update(ok=False, error=str(error))
        summary = None
        if isinstance(error, ConvergenceError):  # the summary of what converged, written by the scene
            with open(os.path.join(out_dir, "summary.json")) as f:
                summary = json.load(f)
    record["wall_s"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    record["steps"] = []
    if summary is None:
        return record
    record.update(cells=summary["cells"], dofs=summary["dofs"])
    for step in summary["steps"]:
        increments = step["increments"]
        record["steps"].append({
            "name": step["name"], "increments": len(increments), **log.steps[step["name"]],
            "newton_iterations_converged": sum(i["newton_iterations"] for i in increments),
            "factorizations": sum(i["factorizations"] for i in increments),
            "wall_s": sum(i["wall_s"] for i in increments)})
    eye = summary["steps"][-1].get("eye", {})
    record["eye" if record["ok"] else "eye_last_converged"] = eye
    return record


def status(record):
    if record["ok"]:
        return "converged"
    where = re.search(r"step '(.+?)' did not converge beyond load factor ([0-9.eE+-]+)", record["error"])
    if where:
        return f"**FAILED** in {where[1]} at {float(where[2]):.3g}"
    return f"**FAILED**: {record['error'][:60]}"


COLUMNS = ["variant", "change", "status", "incr.", "Newton", "cut-backs", "wall s", "load",
           *(label for label, _ in PREDICTIONS.values())]


def table_row(name, record):
    per_step = {key: "+".join(str(s[key]) for s in record["steps"]) or "-"
                for key in ("increments", "newton_iterations", "cutbacks")}
    eye = record.get("eye", {})
    predictions = [form.format(eye[key]) if key in eye else "-" for key, (_, form) in PREDICTIONS.items()]
    cells = [name, record["change"], status(record), per_step["increments"], per_step["newton_iterations"],
             per_step["cutbacks"], f"{record['wall_s']:.1f}", f"{record['load_average']:.1f}", *predictions]
    return "| " + " | ".join(cells) + " |"


def table_header():
    aligns = ["---"] * 3 + ["---:"] * (len(COLUMNS) - 3)
    return "| " + " | ".join(COLUMNS) + " |\n| " + " | ".join(aligns) + " |"


def series_checks(matrix, records):
    """Whether each prediction of CHECKS rises along its series (converged points, in order)."""
    checks = []
    for series, keys in CHECKS.items():
        points = sorted((v.value, v.name) for v in matrix if v.series == series and v.name in records)
        if not points:  # not run (--only)
            continue
        done = [(value, records[name]["eye"]) for value, name in points if records[name]["ok"]]
        for key in keys:
            values = [eye[key] for _, eye in done]
            rises = all(b > a for a, b in zip(values, values[1:])) if len(values) >= 2 else None
            checks.append({"series": series, "prediction": key, "rises": rises,
                           "points": [[value, eye[key]] for value, eye in done], "variants": len(points)})
    return checks


def check_line(check):
    verdict = {True: "yes", False: "NO", None: "not checked (fewer than 2 converged)"}[check["rises"]]
    along = ", ".join(f"{y:.3g} at {x:g}" for x, y in check["points"])
    grows = {"reduction": "more circumference reduction", "shortening": "sutures tied tighter"}[check["series"]]
    return (f"{grows}: {check['prediction']} rises: {verdict}"
            f" [{len(check['points'])} of {check['variants']} converged{': ' + along if along else ''}]")


def write_results(stem, meta, matrix, records, checks):
    """planning_matrix.json and .md (collective: every rank calls, rank 0 writes)."""
    done = [v for v in matrix if v.name in records]
    write_json_atomic(os.path.join(HERE, "results", f"{stem}.json"),
                      {**meta, "variants": {v.name: {"scene": v.scene, **records[v.name]} for v in done},
                       "checks": checks}, comm)
    commit_of = {v.name: records[v.name].get("commit", meta["commit"]) for v in done}
    dates = sorted({(commit_of[v.name], records[v.name].get("date", meta["date"])) for v in done}, key=lambda cd: cd[1])
    knobs = ("knobs stripped: " + ", ".join(meta["knobs_stripped"]) if meta["strip_knobs"]
             else "scenes as shipped (their own [solver] and contact settings)")
    lines = [f"# Planning matrix: {len(done)} variants, default solver settings",
             "",
             f"`benchmarks/planning_matrix.py`, n_circ {meta['n_circ']}, {knobs}; {meta['ranks']} ranks on "
             f"{meta['cores']} cores ({meta['cpu']}); rows from " + "; ".join(
                 f"commit {c} ({d}): {', '.join(v.name for v in done if commit_of[v.name] == c)}"
                 for c, d in dates) + ".",
             "Per step (a+b+c): converged increments, Newton iterations of every attempt, cut-backs. "
             "Predictions after the last step; load: the 1-minute load average before the variant.",
             "", table_header(), *(table_row(v.name, records[v.name]) for v in done), "",
             *(f"* {check_line(c)}" for c in checks)]
    failed = [v for v in done if not records[v.name]["ok"]]
    if failed:
        lines += ["", "Failed variants:", ""] + [f"* {v.name}: {records[v.name]['error']}" for v in failed]
    write_text_atomic(os.path.join(HERE, "results", f"{stem}.md"), "\n".join(lines) + "\n", comm)


def previous_records(stem, meta):
    """The rows of the results file, each with the commit and date of the run that made it."""
    path = os.path.join(HERE, "results", f"{stem}.json")
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        previous = json.load(f)
    if previous["n_circ"] != meta["n_circ"] or previous["strip_knobs"] != meta["strip_knobs"]:
        raise SystemExit(f"--update: {path} holds another matrix (n_circ, strip_knobs)")
    return {name: {"commit": previous["commit"], "date": previous["date"],
                   **{k: v for k, v in record.items() if k != "scene"}}
            for name, record in previous["variants"].items()}


def main():
    silence()  # the lines per load increment: printed by RunLog with --verbose
    matrix = variants()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-circ", type=int, default=40, help="the eye's elements around (40: the default eye)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run these variants only (--list names them)")
    parser.add_argument("--strip-knobs", action="store_true",
                        help="remove [solver] and the contact penalty and smoothing from the scenes")
    parser.add_argument("--out", default=os.path.join("out", "planning_matrix"), help="output folder, one per variant")
    parser.add_argument("--list", action="store_true", help="name the variants and exit")
    parser.add_argument("--update", action="store_true",
                        help="with --only: keep the other variants' rows of the results file "
                             "(each row keeps its commit)")
    parser.add_argument("--verbose", action="store_true", help="print the solver's messages")
    args = parser.parse_args()
    if args.list:
        if comm.rank == 0:
            for v in matrix:
                print(f"{v.name:<24}{v.scene:<12}{', '.join(described(v.changes) + special(v))}")
        return
    unknown = sorted(set(args.only or []) - {v.name for v in matrix})
    if unknown:
        parser.error(f"unknown variant(s) {unknown}; --list names them")
    matrix = [v for v in matrix if not args.only or v.name in args.only]

    bases, stripped = {}, set()
    for scene, path in SCENES.items():
        with open(path, "rb") as f:
            bases[scene] = tomllib.load(f)
        if args.strip_knobs:
            stripped.update(f"{scene}: {key}" for key in strip_knobs(bases[scene]))
    meta = {"benchmark": "planning_matrix", **machine_record(ranks=comm.size, n_circ=args.n_circ,
                                                              strip_knobs=args.strip_knobs,
                                                              knobs_stripped=sorted(stripped))}
    stem = "planning_matrix_strip_knobs" if args.strip_knobs else "planning_matrix"
    if comm.rank == 0:
        print(f"planning matrix: {len(matrix)} variants, n_circ {args.n_circ}, {comm.size} ranks, "
              + ("knobs stripped" if args.strip_knobs else "scenes as shipped"), flush=True)
        print(table_header(), flush=True)

    records = previous_records(stem, meta) if args.update else {}
    matrix = [v for v in variants() if v.name in records or v in matrix] if args.update else matrix
    start = time.perf_counter()
    for variant in (v for v in matrix if not args.only or v.name in args.only):
        data, changed = scene_data(variant, bases[variant.scene], args.n_circ)
        records[variant.name] = {"change": changed, "commit": meta["commit"], "date": meta["date"],
                                 **run_variant(variant, data, os.path.join(args.out, variant.name), args.verbose)}
        if comm.rank == 0:
            print(table_row(variant.name, records[variant.name]), flush=True)
        write_results(stem, meta, matrix, records, series_checks(matrix, records))
    checks = series_checks(matrix, records)
    if comm.rank == 0:
        failed = sum(not r["ok"] for r in records.values())
        print(f"\n{len(records) - failed} of {len(records)} variants converged in {time.perf_counter() - start:.0f} s")
        for check in checks:
            print(check_line(check))
        print(f"written: benchmarks/results/{stem}.json, {stem}.md", flush=True)


if __name__ == "__main__":
    main()
