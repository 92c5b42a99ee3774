# # The eye at rest and its pressure-volume curve
#
# The seed's eye model (`demos/eye_at_rest.toml`): eight tissues on about 10,000 hexahedra,
# neo-Hookean but for the linear elastic zonule, the vitreous and the aqueous as static
# liquids of bulk modulus $K = 2083.3$ MPa, the optic nerve held at its end.
#
# The mesh is the unloaded eye. In the first step each cavity is *filled* to the
# intraocular pressure (15 mmHg = 0.002 MPa): its pressure is prescribed and the liquid
# takes the volume that needs. From then on the liquid's law holds about the filled state,
#
# $$ p = p_1 - K\,\frac{V - V_1 - \Delta V}{V_1}, $$
#
# so injecting $\Delta V$ into the vitreous raises the IOP as the wall stretches. This is
# how ocular rigidity is measured; Friedenwald (1937) summarized it as
# $\log_{10} p = \log_{10} p_0 + E\,V$ with $E \approx 0.0215\ \mu L^{-1}$ for living eyes.
# We inject 10, 20 and 30 microlitres and withdraw all 60 again: an elastic eye must
# come back to its IOP and its axial length.
#
# **An independent estimate of the rigidity.** Seen from the centre of the sclera, the wall
# around the vitreous is, direction by direction, concentric spherical layers (retina,
# choroid, sclera; ciliary body and sclera in front of the ora serrata;
# `eyeball_fenicsx.meshing.builders.eye.scleral_wall`).
# For a closed spherical membrane, linear theory adds the directions independently and exactly:
# the stress resultants are $N = pR/2$ whatever the thickness (Laplace's law, statically
# determinate), each patch strains as its own thickness requires, and the volume change
# $\frac{R}{2}\int(\varepsilon_\theta + \varepsilon_\phi)\,dA$ takes nothing from the meridional
# displacement. For one thin neo-Hookean layer ($\mu = 2 c_{10}$) that gives
# $dp/dV = 3\mu t/(\pi R^4)$; each direction is taken instead as the exact inflated thick
# incompressible sphere of its layers (Ogden 1984, sec. 5.2.2: $r^3 - R^3$ the same through the
# layers), which carries the finite strain: at 15 mmHg the sclera is stretched by 3 % and its
# tangent stiffness is some 20 % below the linear one. The estimate's volume from the model's
# first IOP to its last gives its rigidity over the same pressures
# (`eyeball_fenicsx.analytic.wall_volume_change`).
#
# Run: `mpirun -n 2 python3 demos/eye_at_rest.py` (about a minute on two cores); the
# pictures and summary.json go to `DEMO_OUT` (default `out/eye_at_rest`).

# +
import os

import numpy as np
from mpi4py import MPI

from eyeball_fenicsx.analytic import wall_volume_change
from eyeball_fenicsx.features.cavity import Injection
from eyeball_fenicsx.meshing.builders.eye import scleral_wall
from eyeball_fenicsx.output.eye_pictures import eye_section_png, stress_section_png
from eyeball_fenicsx.output.measures import MMHG_PER_MPA, EyeMeasures
from eyeball_fenicsx.scene.loader import load_scene
from eyeball_fenicsx.scene.scene import Step

here = os.path.dirname(os.path.abspath(__file__))
out = os.environ.get("DEMO_OUT", os.path.join("out", "eye_at_rest"))
overrides = {"mesh.n_circ": int(os.environ["EYE_N_CIRC"])} if "EYE_N_CIRC" in os.environ else {}
scene = load_scene(os.path.join(here, "eye_at_rest.toml"), overrides=overrides)
# -

# ## Injections after the eye is at its pressure

# +
vitreous = next(f for f in scene.features if getattr(f, "name", None) == "vitreous")
for volume in (10.0, 20.0, 30.0, -60.0):  # mm^3 = microlitres
    scene.steps.append(Step(f"{'inject' if volume > 0 else 'withdraw'} {abs(volume):g}"))
    scene.features.append(Injection(vitreous, volume, step=len(scene.steps) - 1))
summary = scene.run(out)
# -

# ## Pressure against volume, and the pictures

# +
eye = [s["eye"] for s in summary["steps"]]
injected = np.cumsum([0.0, 10.0, 20.0, 30.0, -60.0])
iop = np.array([e["iop_mmHg"] for e in eye])
rigidity = np.polyfit(injected[:4], np.log10(iop[:4]), 1)[0]
axial = np.array([e["axial_length_mm"] for e in eye])
# the IOP rises with every injection (the smallest rise per microlitre, mmHg)
iop_rise_min = np.min(np.diff(iop[:4]) / np.diff(injected[:4]))
# the estimate (above) over the model's own pressures, its sclera and geometry
materials = {tissue: law.c for tissue, law in scene.materials.items() if hasattr(law, "c")}
estimated_volume = wall_volume_change(iop[0] / MMHG_PER_MPA, iop[3] / MMHG_PER_MPA,
                                      *scleral_wall(**scene.mesh.parameters), materials)
rigidity_estimate = np.log10(iop[3] / iop[0]) / estimated_volume
rigidity_error = rigidity / rigidity_estimate - 1
# consistency: the first step prescribes the IOP (the cavity is filled to it), so this reads it back
iop_readback_error = abs(iop[0] - 15.0)
# consistency: back at the filled volume, back at rest; relative to the excursion at 60 microlitres
# (not a number unless the injection moved the IOP and the axial length)
excursion = (iop[3] - iop[0], axial[3] - axial[0])
injection_reversible = (max(abs(iop[-1] - iop[0]) / excursion[0], abs(axial[-1] - axial[0]) / excursion[1])
                        if min(excursion) > 0 else np.nan)
measures = next(o for o in scene.observers if isinstance(o, EyeMeasures))
eye_section_png(scene.mesh, os.path.join(out, "eye_section.png"), title="eyeball-fenicsx eye model: meridional section")
stress_section_png(scene.solid, measures.mises, os.path.join(out, "eye_at_rest_mises.png"),
                   title="at 15 mmHg: von Mises stress (MPa)")
if MPI.COMM_WORLD.rank == 0:
    print(f"{'injected (uL)':>14} {'IOP (mmHg)':>11} {'axial length (mm)':>18}")
    for v, p, e in zip(injected, iop, eye):
        print(f"{v:14.0f} {p:11.3f} {e['axial_length_mm']:18.4f}")
    print(f"ocular rigidity E = {rigidity:.6f} per microlitre; the layered-shell estimate {rigidity_estimate:.6f} "
          f"({100 * rigidity_error:+.1f} %); Friedenwald's living eyes: about 0.0215")
    print(f"max von Mises at rest (MPa): {eye[0]['max_mises_MPa']}")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figure, axes = plt.subplots(figsize=(5, 3.5))
    axes.semilogy(injected[:4], iop[:4], "o-", label="injection")
    axes.semilogy(injected[3:], iop[3:], "s--", label="withdrawal")
    axes.set_xlabel("vitreous volume injected (microlitres)")
    axes.set_ylabel("IOP (mmHg)")
    axes.legend()
    figure.tight_layout()
    figure.savefig(os.path.join(out, "eye_pressure_volume.png"), dpi=120)
# -
