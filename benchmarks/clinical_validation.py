"""Clinical validation: the calibrated eye's predictions beside published figures.

Runs, under MPI on the default eye (``--n-circ 40``), each with the scene's defaults:

* ``demos/pressure_volume.toml``: the ocular rigidity over 15-35 mmHg (ln(P) against the
  injected volume), against Pallikaris et al. (IOVS 2005;46:409: 0.0112-0.0149 per uL, the
  logarithm not confirmed: read as natural);
* ``demos/encircling_buckle.toml`` as shipped (calibrated tissues, 8 mm of reduction, the break
  closed, the subretinal fluid drained): the axial length change and the refraction change from
  the pre-operative eye after the sutures, against clinical series (+0.7 to +1.2 mm: Smiddy et
  al., Arch Ophthalmol 1989;107:1469, +0.99 mm and -2.75 D in 75 eyes; -1.3 to -2.8 D), the
  buckle height against the geometric rule dC / 2 pi (IOVS ARVO abstract 2357577: "the
  difference between the two circumferences is always 2 pi"), the IOP after tightening and
  after drainage (no published figure for these steps: reported), the reattached fraction;
* the same with bands 1 and 2 mm wide (``mesh.band_width``): the refraction's trend with the
  band's width against Lanchares et al.'s finite-element figures (J Ophthalmol 2016:3578617:
  -0.44, -0.88, -1.07 D for 1, 2, 2.5 mm bands, their tightening not known to us: the trend is
  compared, as ratios to the 2.5 mm band);
* ``demos/segmental_buckle.toml`` with the calibrated tissues: the axial length change of a
  segmental buckle, which clinical series find small or negative (Okada et al., Jpn J
  Ophthalmol 2000;44:132: local buckles shorten the eye; magnitudes not in the abstract).

Each figure is marked inside or outside its range, with the reason when outside. Writes
benchmarks/results/clinical_validation.json and .md and clinical_validation.png (the rigidity
curve and the band-width trend), with the commit, the hardware and the date. ``--tissues SET``
runs every scene on another tissue set (``tissues = "fibre"``: the collagen-fibre sclera) and
names the files clinical_validation_SET.*.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/clinical_validation.py [--n-circ 40] [--tissues SET]
"""
import argparse
import os
import time

import numpy as np
from mpi4py import MPI
from provenance import machine_record

from eyeball_fenicsx.output.files import save_figure_atomic, write_json_atomic, write_text_atomic
from eyeball_fenicsx.output.measures import ocular_rigidity
from eyeball_fenicsx.scene.loader import load_scene

HERE = os.path.dirname(os.path.abspath(__file__))
DEMOS = os.path.join(HERE, "..", "demos")
RESULTS = os.path.join(HERE, "results")
PALLIKARIS = (0.0112, 0.0149)  # 95 % CI of the ocular rigidity, per uL (natural log)
LANCHARES = {1.0: -0.44, 2.0: -0.88, 2.5: -1.07}  # refraction change (D) by band width (mm)


def run(scene, out, overrides):
    start = time.perf_counter()
    summary = load_scene(os.path.join(DEMOS, scene), overrides=overrides).run(out)
    return summary, time.perf_counter() - start


def rigidity(summary):
    iop = np.array([s["eye"]["iop_mmHg"] for s in summary["steps"]])
    injected = np.array([s["cavities"]["eye"]["injected_volume"] for s in summary["steps"]])
    injected -= injected[0]
    return ocular_rigidity(injected, iop), injected.tolist(), iop.tolist()


def steps_eye(summary):
    return {s["name"]: s["eye"] for s in summary["steps"]}


def figure(name, value, low, high, source, why_not=""):
    inside = low <= value <= high
    return {"figure": name, "model": value, "range": [low, high], "inside": bool(inside), "source": source,
            "why_not": "" if inside else why_not}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n-circ", type=int, default=40)
    parser.add_argument("--out", default=os.path.join("out", "clinical_validation"))
    parser.add_argument("--tissues", default=None, help="a tissue set for every scene (default: the scenes' own)")
    args = parser.parse_args()
    mesh = {"mesh.n_circ": args.n_circ, **({"tissues": args.tissues} if args.tissues else {})}
    name = "clinical_validation" + (f"_{args.tissues}" if args.tissues else "")
    runs, figures = {}, []

    pv, wall = run("pressure_volume.toml", os.path.join(args.out, "pressure_volume"), mesh)
    k, injected, iop = rigidity(pv)
    runs["pressure_volume"] = {"wall_s": wall, "injected_uL": injected, "iop_mmHg": iop}
    figures.append(figure("ocular rigidity K over 15-35 mmHg (per uL, ln)", k, *PALLIKARIS,
                          "Pallikaris et al., IOVS 2005;46:409 (95 % CI; logarithm read as natural)",
                          "read as log10 their interval is 0.0258-0.0343"))
    figures.append(figure("axial length at 15 mmHg (mm)", pv["steps"][0]["eye"]["axial_length_mm"], 23.0, 25.0,
                          "adult eyes (the mesh is built 24.0 mm long unloaded)"))

    widths = {}
    for width in (2.5, 2.0, 1.0):
        overrides = {**mesh, "mesh.band_width": width}
        summary, wall = run("encircling_buckle.toml", os.path.join(args.out, f"band_{width:g}"), overrides)
        eye = steps_eye(summary)
        widths[width] = eye
        runs[f"encircling band {width:g} mm"] = {"wall_s": wall, "eye": eye}
    shipped = widths[2.5]
    suture, reduction = shipped["suture"], 8.0
    figures.append(figure("encircling: axial length change after suturing (mm)", suture["axial_length_change_mm"],
                          0.7, 1.2, "Smiddy et al. 1989 (+0.99 mm, 75 eyes); BMC Ophthalmol 2021 (+0.83 mm)",
                          "the buckle is a third of the clinical one (below)"))
    figures.append(figure("encircling: refraction change after suturing (D)", suture["refraction_change_D"],
                          -2.8, -1.3, "Smiddy et al. 1989 (-2.75 D); later series", "follows the axial length"))
    figures.append(figure("encircling: buckle height (mm) for 8 mm of reduction", suture["buckle_height_mm"],
                          0.5 * reduction / (2 * np.pi), reduction / (2 * np.pi),
                          "geometric rule dC / 2 pi = 1.27 mm (an upper bound: the band also stretches); "
                          "surgeons shorten about 5 mm per mm of height (IOVS ARVO abstract 2357577)",
                          "the isotropic sclera, calibrated on the inflated globe (stiff at 15-35 mmHg), is as "
                          "stiff in hoop compression under the band, where measured sclera is far softer "
                          "(crimped fibres; Battaglioli & Kamm 1984: radial compression 100 x softer); not the "
                          "IOP: restored to 15 mmHg after the operation, the buckle deepens by 0.02 mm only; a fibre "
                          "sclera soft in compression (tissues = fibre) gives the same buckle in the closed eye, "
                          "whose IOP rises higher; a band four times stiffer gives 0.77 mm (README)"))
    ratios = {w: widths[w]["suture"]["refraction_change_D"] / shipped["suture"]["refraction_change_D"] for w in widths}
    for w in (1.0, 2.0):
        expected = LANCHARES[w] / LANCHARES[2.5]
        figures.append(figure(f"band width {w:g} mm: refraction change / that of 2.5 mm", ratios[w],
                              expected - 0.15, expected + 0.15,
                              f"Lanchares et al. 2016 (FE): {expected:.2f}, within 0.15",
                              "the trend with width differs from Lanchares' model"))
    for label, value in (("IOP after tightening (mmHg)", shipped["tighten"]["iop_mmHg"]),
                         ("IOP after drainage (mmHg)", shipped["drain"]["iop_mmHg"]),
                         ("reattached fraction after drainage", shipped["drain"]["reattached_fraction"])):
        figures.append({"figure": label, "model": value, "range": None, "inside": None,
                        "source": "no published figure for this step (intraoperative peaks reach 210 mmHg "
                                  "during depression and cryopexy: Gardner et al. 1993)" if "IOP" in label else
                                  "the issue's aim: at least 0.9", "why_not": ""})

    segmental, wall = run("segmental_buckle.toml", os.path.join(args.out, "segmental"),
                          {"tissues": "calibrated", **mesh})
    eye = steps_eye(segmental)
    runs["segmental"] = {"wall_s": wall, "eye": eye}
    figures.append(figure("segmental: axial length change after suturing (mm)", eye["suture"]["axial_length_change_mm"],
                          -0.5, 0.2, "Okada et al. 2000: local buckles shorten the eye (no magnitudes in the "
                          "abstract; the range is ours: small, shortening)", "lengthens the eye"))

    if MPI.COMM_WORLD.rank == 0:
        record = {**machine_record(ranks=MPI.COMM_WORLD.size, n_circ=args.n_circ), "tissues": args.tissues,
                  "figures": figures, "runs": runs}
        os.makedirs(RESULTS, exist_ok=True)
        write_json_atomic(os.path.join(RESULTS, name + ".json"), record, MPI.COMM_SELF)
        lines = [f"# Clinical validation (tissues {args.tissues or 'of the scenes'}, eye n_circ = {args.n_circ}, "
                 f"{MPI.COMM_WORLD.size} ranks, "
                 f"commit {record['commit']}, {record['date']})", "",
                 "| figure | model | published range | inside | source | why not |", "|---|--:|---|---|---|---|"]
        for f in figures:
            span = "-" if f["range"] is None else f"{f['range'][0]:.4g} to {f['range'][1]:.4g}"
            inside = "-" if f["inside"] is None else ("yes" if f["inside"] else "**no**")
            lines.append(f"| {f['figure']} | {f['model']:.4g} | {span} | {inside} | {f['source']} | {f['why_not']} |")
        text = "\n".join(lines) + "\n"
        write_text_atomic(os.path.join(RESULTS, name + ".md"), text, MPI.COMM_SELF)
        print(text, flush=True)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        left.semilogy(injected, iop, "o-", label="model")
        for k_ref, style in zip(PALLIKARIS, (":", "--")):
            left.semilogy(injected, 15.0 * np.exp(k_ref * np.array(injected)), "k" + style, lw=0.8,
                          label=f"Pallikaris CI: K = {k_ref}")
        left.set_xlabel("volume injected (uL)")
        left.set_ylabel("IOP (mmHg)")
        left.legend(fontsize=8)
        w = sorted(widths)
        right.plot(w, [widths[x]["suture"]["refraction_change_D"] for x in w], "o-", label="model")
        right.plot(sorted(LANCHARES), [LANCHARES[x] for x in sorted(LANCHARES)], "s--",
                   label="Lanchares et al. 2016 (FE)")
        right.set_xlabel("band width (mm)")
        right.set_ylabel("refraction change after suturing (D)")
        right.legend(fontsize=8)
        fig.tight_layout()
        save_figure_atomic(fig, os.path.join(RESULTS, name + ".png"))


if __name__ == "__main__":
    main()
