# # Segmental scleral buckle: a silicone tire sutured onto the sclera
#
# The scene `demos/segmental_buckle.toml`: the seed's eye in a half model, a silicone tire 4 mm
# wide and 1 mm high over 60 degrees of azimuth, 12.5 mm behind the limbus, centred on the
# symmetry plane over a detachment of the retina, and two mattress sutures (four bites) over it
# in the half eye. The steps:
#
# 1. "pressurize": each cavity filled to 15 mmHg; the sclera, inflating, meets the tire;
# 2. "suture": the sutures, tied over the tire, shortened by 0.4 mm, press it into the sclera
#    (augmented penalty contact, both bodies deformable).
#
# The tire is a free body but for contact and sutures (and the symmetry plane, which carries
# only y forces), so along x and z the sclera's push on it and the sutures' pull must cancel,
# exactly (to the solver's tolerance).
#
# Run: `mpirun -n 2 python3 demos/segmental_buckle.py` (`EYE_N_CIRC=16` for a coarse eye);
# summary.json and the pictures go to `DEMO_OUT` (default `out/segmental_buckle`).

# +
import os

import numpy as np
from mpi4py import MPI

from eyeball_fenicsx.features.sutures import Suture
from eyeball_fenicsx.scene.loader import load_scene

here = os.path.dirname(os.path.abspath(__file__))
out = os.environ.get("DEMO_OUT", os.path.join("out", "segmental_buckle"))
overrides = {"mesh.n_circ": int(os.environ["EYE_N_CIRC"])} if "EYE_N_CIRC" in os.environ else {}
# DEMO_COMM=self: every rank runs the whole operation alone (reproducible to the last bit)
comm = MPI.COMM_SELF if os.environ.get("DEMO_COMM") == "self" else MPI.COMM_WORLD
if comm is MPI.COMM_SELF:
    out = os.path.join(out, f"rank_{MPI.COMM_WORLD.rank}")
scene = load_scene(os.path.join(here, "segmental_buckle.toml"), comm=comm, overrides=overrides)
summary = scene.run(out)
# -

# ## What holds the tire

# +
before, final = summary["steps"][0], summary["steps"][-1]
contact = np.array(final["contact"]["tire-sclera"]["force"])  # on the tire, from the sclera
sutures = sum(np.array(s["force_on_second"]) for s in final["sutures"].values())  # on the tire
held = contact + sutures
balance_error = np.hypot(held[0], held[2]) / np.linalg.norm(contact)
indentation = final["eye"]["buckle_height_mm"] - before["eye"]["buckle_height_mm"]  # by the sutures
# -

# ## How far the sutures can push it
#
# A string shortened by s, from a bite that stays put to a tire point that moves along the
# radius r, pushes that point in by s / (e . r) (e: the string's direction), to first order:
# the kinematics of the suture geometry alone, without the finite elements. The sutures are
# stiff (EA = 40 N: 0.1 N stretches a 1.5 mm string by 4 micrometres), so the tire would go in
# that far if the sclera's bites held still and the tire did not deform; they do not (the bites
# are pulled out, the tire is squeezed), so the indentation is below this bound.

# `Suture.radial_push` gives s / |e . r| for each string, from the means of its bites' points
# (the sclera's centre is the origin).

# +
strings = [f for f in scene.features if isinstance(f, Suture)]
kinematic = sum(f.share * f.radial_push() for f in strings) / sum(f.share for f in strings)
indentation_ratio = indentation / kinematic
# -

# ## What the surgeon asks

# +
if comm.rank == 0 and MPI.COMM_WORLD.rank == 0:
    print(f"tire: sclera's push {np.round(contact, 4).tolist()} N, sutures' pull {np.round(sutures, 4).tolist()} N; "
          f"x-z balance {balance_error:.1e}")
    print(f"{'step':<12}{'axial length change':>22}{'IOP':>10}{'buckle height':>16}{'retina gap':>13}{'detached':>14}")
    for step in summary["steps"]:
        eye = step["eye"]
        print(f"{step['name']:<12}{eye['axial_length_change_mm']:>19.3f} mm{eye['iop_mmHg']:>6.1f} mmHg"
              f"{eye['buckle_height_mm']:>13.3f} mm{eye['retina_gap_max_mm']:>10.3f} mm"
              f"{eye['detached_area_mm2']:>9.1f} mm^2")
    print(f"the sutures indent the sclera by {indentation:.3f} mm more: {100 * indentation_ratio:.0f} % of the "
          f"{kinematic:.3f} mm their geometry allows")
# -
