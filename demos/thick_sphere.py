# # Inflation of a thick-walled incompressible sphere
#
# A hollow sphere of inner radius $A$ and outer radius $B$, made of an incompressible
# Mooney-Rivlin (or neo-Hooke) material, is inflated by a pressure $P$ on its inner surface.
# Incompressibility makes the deformation one-parametric: a material sphere of radius $R$
# goes to radius $r$ with $r^3 - a^3 = R^3 - A^3$, and with the hoop stretch
# $\lambda = r/R$ and the energy of the equibiaxial stretch
# $\hat W(\lambda) = W(I_1 = 2\lambda^2 + \lambda^{-4},\ I_2 = \lambda^4 + 2\lambda^{-2})$,
# equilibrium gives (Ogden, *Non-linear elastic deformations*, 1984, sec. 5.2.2)
#
# $$ P = \int_{\lambda_b}^{\lambda_a} \frac{\hat W'(\lambda)}{\lambda^3 - 1}\, d\lambda,
#    \qquad \lambda_b^3 = 1 + (\lambda_a^3 - 1) A^3 / B^3 . $$
#
# We mesh one octant with the seed's element (8-node hexahedra, one pressure per element),
# fix the normal displacement on the three symmetry planes and compare the inner stretch
# $\lambda_a = a/A$ with the closed form.
#
# Run it with `mpirun -n 2 python3 demos/thick_sphere.py`; the size is set by the
# environment variables `SPHERE_N` (elements along a patch edge) and `SPHERE_LAYERS`.

# +
import os

from mpi4py import MPI

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_inner_stretch
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh

A, B, P = 1.0, 2.0, 0.6
c = {(1, 0): 0.5}  # neo-Hooke, c10 = 0.5 (shear modulus 1)
n = int(os.environ.get("SPHERE_N", 8))
layers = int(os.environ.get("SPHERE_LAYERS", 4))
# -

# ## The closed form
# `eyeball_fenicsx.analytic` evaluates the integral by quadrature and inverts it for
# $\lambda_a$ (the rising branch).

lam_exact = sphere_inner_stretch(P, c, A, B)

# ## The scene
# Three symmetry planes, the pressure on the inner surface, and a probe at the inner
# surface on the x axis.

# +
mesh = built_mesh(build_sphere_octant, MPI.COMM_WORLD, inner_radius=A, outer_radius=B, n=n, layers=layers)
scene = ef.Scene(
    "thick-sphere", mesh, {"wall": ef.MooneyRivlin(c)},
    features=[ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}),
              ef.Dirichlet("sym_z", {"z": 0.0}), ef.Pressure("inner", P)],
    probes={"inner": [A, 0.0, 0.0], "outer": [B, 0.0, 0.0]},
    solver=ef.SolverSettings(increments=2))
summary = scene.run(os.environ.get("DEMO_OUT"))
# -

# ## Against the closed form

# +
lam_fe = 1 + summary["steps"][-1]["probes"]["inner"][0] / A
error = abs(lam_fe - lam_exact) / (lam_exact - 1)
if MPI.COMM_WORLD.rank == 0:
    print(f"inner stretch: FE {lam_fe:.6f}, closed form {lam_exact:.6f}, "
          f"error {100 * error:.3f}% of the radial displacement ({summary['cells']} hexahedra)")
# -
