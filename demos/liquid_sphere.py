# # A liquid-filled sphere inflated through its pressure maximum
#
# The vitreous is a static liquid: its pressure follows from the volume it fills,
#
# $$ p = p_\mathrm{ini} - K\, \frac{V - V_\mathrm{ini} - \Delta V}{V_\mathrm{ini}}, \qquad
#    V = -\frac{1}{3} \int_{\partial\Omega_\ell} \mathbf{x}\cdot\mathbf{n}\, da , $$
#
# with $\Delta V$ the liquid injected. Following the seed's *new algorithm*, $p$ is one
# more unknown of the Newton system, next to the displacements and the element pressures:
# the matrix gains one sparse row and column over the wetted surface. Because the unknown
# is the pressure and the load is the injected volume, the solution can pass the pressure
# maximum of a thin sphere, where a pressure-controlled inflation must stop.
#
# For a thick incompressible sphere of radii $A < B$ the wall carries the pressure
# (Ogden 1984, eq. 5.2.38)
#
# $$ P(\lambda_a) = \int_{\lambda_b}^{\lambda_a} \frac{\hat W'(\lambda)}{\lambda^3-1} d\lambda,
#    \qquad \lambda_a^3 = V / V_\mathrm{ini}, $$
#
# which for a neo-Hookean thin wall ($B/A = 1.1$) peaks at $\lambda_a \approx 1.43$. We
# inject the liquid in stages (one step each) and compare the pressure-volume curve.

# +
import os

import numpy as np
from mpi4py import MPI

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_pressure
from eyeball_fenicsx.features.cavity import Injection, LiquidCavity
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh

A, B, c10, K = 1.0, 1.1, 0.5, 1.0e3
stages, final_stretch = int(os.environ.get("STAGES", 8)), 1.8
mesh = built_mesh(build_sphere_octant, MPI.COMM_WORLD, inner_radius=A, outer_radius=B,
                  n=int(os.environ.get("SPHERE_N", 8)), layers=2)
# -

# The liquid fills the octant's inner surface, closed by the three symmetry planes. The
# exact octant volume $\pi A^3/6$ sets the injected volumes.

# +
liquid = LiquidCavity("liquid", "inner", bulk_modulus=K, symmetry=["x", "y", "z"])
total = (final_stretch**3 - 1) * np.pi * A**3 / 6
steps = [ef.Step(f"inject {i + 1}", increments=2) for i in range(stages)]
injections = [Injection(liquid, total / stages, step=i) for i in range(stages)]
scene = ef.Scene("liquid-sphere", mesh, {"wall": ef.NeoHooke(c10)},
                 features=[ef.Dirichlet("sym_x", {"x": 0}), ef.Dirichlet("sym_y", {"y": 0}),
                           ef.Dirichlet("sym_z", {"z": 0}), liquid, *injections],
                 probes={"inner": [A, 0, 0]}, steps=steps)
summary = scene.run(os.environ.get("DEMO_OUT"))
# -

# ## Pressure against volume

# +
volumes = np.array([s["cavities"]["liquid"]["volume"] for s in summary["steps"]])
pressures = np.array([s["cavities"]["liquid"]["pressure"] for s in summary["steps"]])
stretches = (volumes / liquid.V_ini) ** (1 / 3)
exact = np.array([sphere_pressure(lam, {(1, 0): c10}, A, B) for lam in stretches])
error = np.max(np.abs(pressures - exact)) / exact.max()
if MPI.COMM_WORLD.rank == 0:
    for lam, p, pe in zip(stretches, pressures, exact):
        print(f"stretch {lam:.4f}  pressure {p:.5f}  closed form {pe:.5f}")
    print(f"largest pressure error {100 * error:.2f}% of the maximum pressure")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    lam = np.linspace(1.0, final_stretch, 200)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(lam**3, [sphere_pressure(x, {(1, 0): c10}, A, B) for x in lam], "k-", label="closed form")
    ax.plot(stretches**3, pressures, "o", label="eyeball-fenicsx (Q1/P0)")
    ax.set_xlabel("V / V_ini")
    ax.set_ylabel("liquid pressure")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(os.environ.get("DEMO_OUT", "."), "liquid_sphere_pv.png"), dpi=120)
# -
