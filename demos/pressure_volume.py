# # The eye's ocular rigidity, with the calibrated tissues
#
# The scene `demos/pressure_volume.toml`: the whole eye with the calibrated tissues
# (`eyeball_fenicsx/tissues/calibrated.toml`), the aqueous and the vitreous one liquid, held by
# its optic nerve. The eye is filled to 15 mmHg, then liquid is injected in 10 microlitre steps
# until the pressure is past 35 mmHg, as Pallikaris et al. measured living eyes (IOVS
# 2005;46:409: saline injected into the anterior chamber of 79 eyes undergoing cataract surgery,
# in 4.5 microlitre steps).
#
# **Ocular rigidity.** Friedenwald (1937) found the logarithm of the pressure linear in the
# injected volume, log(P2/P1) = K (V2 - V1). His K (about 0.0215 per microlitre) uses the decimal
# logarithm; Pallikaris et al. report K = 0.0126 per microlitre (95 % CI 0.0112-0.0149), fitted
# over 10-35 mmHg. Which logarithm they used we could not read from the sources at hand (their
# abstract does not say; docs/published_figures.md, section 7): we take it as the natural one,
# as in the group's later reports, and give the decimal one too. Read as log10, their interval
# would be 0.0258-0.0343 per microlitre in natural-log units, about twice what the model gives.
#
# The fit: the least-squares slope of ln(IOP) against the injected volume over the states
# between 15 and 35 mmHg. The calibrated sclera's c10 was chosen so that the default eye falls
# inside the interval; the test takes the coarse eye.
#
# Run: `mpirun -n 2 python3 demos/pressure_volume.py` (`EYE_N_CIRC=16` for a coarse eye);
# summary.json and the curve go to `DEMO_OUT` (default `out/pressure_volume`).

# +
import os

import numpy as np
from mpi4py import MPI

from eyeball_fenicsx.output.files import save_figure_atomic
from eyeball_fenicsx.output.measures import ocular_rigidity
from eyeball_fenicsx.scene.loader import load_scene

here = os.path.dirname(os.path.abspath(__file__))
out = os.environ.get("DEMO_OUT", os.path.join("out", "pressure_volume"))
overrides = {"mesh.n_circ": int(os.environ["EYE_N_CIRC"])} if "EYE_N_CIRC" in os.environ else {}
scene = load_scene(os.path.join(here, "pressure_volume.toml"), overrides=overrides)
summary = scene.run(out)
# -

# ## Pressure against volume

# +
eye = [step["eye"] for step in summary["steps"]]
iop = np.array([e["iop_mmHg"] for e in eye])
injected = np.array([step["cavities"]["eye"]["injected_volume"] for step in summary["steps"]])
injected -= injected[0]  # from the filled eye
rigidity = ocular_rigidity(injected, iop)  # per microlitre, natural log, over 15-35 mmHg
rigidity_log10 = rigidity / np.log(10)
axial_length = eye[0]["axial_length_mm"]  # filled to 15 mmHg
PALLIKARIS = (0.0112, 0.0149)  # 95 % CI of K, per microlitre
if MPI.COMM_WORLD.rank == 0:
    for step, v, p in zip(summary["steps"], injected, iop):
        print(f"{step['name']:>10}: {v:5.1f} uL injected, IOP {p:6.2f} mmHg, axial length "
              f"{step['eye']['axial_length_mm']:.4f} mm")
    print(f"ocular rigidity over 15-35 mmHg: K = {rigidity:.4f} per microlitre (ln), {rigidity_log10:.4f} (log10); "
          f"Pallikaris et al.: 0.0126 ({PALLIKARIS[0]}-{PALLIKARIS[1]}); axial length at 15 mmHg {axial_length:.2f} mm")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figure, axes = plt.subplots(figsize=(5, 3.5))
    axes.semilogy(injected, iop, "o-", label="model")
    for k, style in zip(PALLIKARIS, (":", "--")):
        axes.semilogy(injected, 15.0 * np.exp(k * injected), "k" + style, lw=0.8, label=f"K = {k} per uL")
    axes.set_xlabel("volume injected (microlitres)")
    axes.set_ylabel("IOP (mmHg)")
    axes.legend(fontsize=8)
    figure.tight_layout()
    save_figure_atomic(figure, os.path.join(out, "pressure_volume.png"))
# -
