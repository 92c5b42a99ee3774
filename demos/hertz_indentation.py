# # A rigid sphere indenting an incompressible block (Hertz)
#
# A rigid sphere of radius $R$ pressed a depth $d$ into an elastic half-space of shear
# modulus $\mu$ and Poisson's ratio $\nu$ touches it on a disc of radius $a = \sqrt{R d}$
# and needs the force (Johnson, *Contact Mechanics*, 1985, eq. 4.23)
#
# $$ F = \frac{4}{3} E^* R^{1/2} d^{3/2}, \qquad E^* = \frac{E}{1 - \nu^2}
#      = \frac{2\mu}{1 - \nu} = 4 \mu \quad (\nu = 1/2), $$
#
# so for the incompressible neo-Hookean solid ($\mu = 2 c_{10}$) of the eye models
# $F = \frac{16}{3} \mu R^{1/2} d^{3/2}$, valid while $a \ll R$.
#
# Contact is the seed's penalty method: every node $h$ of the block's top surface that
# penetrates the sphere, gap $g = |\mathbf{x}_h - \mathbf{c}| - R < 0$, adds the energy
# $\frac{1}{2} \alpha_h g^2$, with $\alpha_h$ = (penalty per unit area) $\times$ (the node's
# tributary area); the residual is $\alpha_h g \nabla g$ and the tangent
# $\alpha_h (\nabla g \nabla g^T + g \nabla\nabla g)$, whose second term is the turning of
# the sphere's normal. An augmented Lagrangian (Uzawa's update of a multiplier per node)
# then removes the penetration, so the answer does not depend on the penalty. The default
# penalty is 3 times the stiffness $E/h$ of the surface
# layer of elements (`eyeball_fenicsx/contact/policy.py`), nothing to tune.
#
# We model a quarter of the block (symmetry planes $x = 0$, $y = 0$; the sphere's centre
# on their intersection), $30 a$ wide and deep on a roller base, with hexahedra graded from
# 7 across $1.3 a$ to the far boundary.
#
# Run it with `mpirun -n 2 python3 demos/hertz_indentation.py`.

# +
import os

import numpy as np
from mpi4py import MPI

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import hertz_layer_force
from eyeball_fenicsx.contact import RigidContact
from eyeball_fenicsx.meshing.builders.block import build_block
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.output.console import increment_lines

c10, R, d = 0.5, 10.0, 0.1  # MPa, mm, mm
mu = 2 * c10
a = np.sqrt(R * d)
L = 30 * a
# -

# ## A graded block
# `build_block` makes a uniform block; mapping its coordinates node by node grades it, as
# the mesh geometry is just the node coordinates. Along $x$ and $y$ the cells are equal on
# $[0, 1.3 a]$ and then grow geometrically to $L$; along $z$ the same, from the top down.


# +
def graded(length, fine, n_fine, n_coarse):
    """Node coordinates on [0, length]: n_fine equal cells on [0, fine], then n_coarse
    cells growing geometrically from that size."""
    h = fine / n_fine
    lo, hi = 1.0, 10.0
    for _ in range(100):  # growth ratio q: h (q + ... + q^n_coarse) = length - fine
        q = 0.5 * (lo + hi)
        lo, hi = (lo, q) if h * q * (q**n_coarse - 1) / (q - 1) > length - fine else (q, hi)
    coarse = fine + h * np.cumsum(q ** np.arange(1, n_coarse + 1))
    return np.concatenate([np.linspace(0.0, fine, n_fine + 1), coarse[:-1], [length]])


nodes = graded(L, 1.3 * a, 7, 7)
n = len(nodes) - 1
mesh = built_mesh(build_block, MPI.COMM_WORLD, lengths=(1.0, 1.0, 1.0), divisions=(n, n, n))
x = mesh.mesh.geometry.x
uniform = np.linspace(0.0, 1.0, n + 1)
x[:, 0], x[:, 1] = np.interp(x[:, 0], uniform, nodes), np.interp(x[:, 1], uniform, nodes)
x[:, 2] = L - np.interp(1.0 - x[:, 2], uniform, nodes)
# -

# ## The scene
# The sphere starts touching the top at the origin and moves down by $d$ in 6 increments.
# A fresh tangent every Newton step (`reuse_contraction=0`) shows the convergence rate.

# +
sphere = RigidContact("sphere", "z1", "sphere", center=[0.0, 0.0, L + R], radius=R, displacement=[0.0, 0.0, -d])
curve, histories = [], []


def record(line):
    if "failed" in line:  # an increment cut back: nothing converged to record
        return
    contact = sphere.report()  # collective
    curve.append((-sphere.shift[2], -4 * contact["force"][2], contact["max_penetration"]))  # 4 quarters
    histories.append(list(scene.newton.residual_norms))


scene = ef.Scene("hertz", mesh, {"solid": ef.NeoHooke(c10)},
                 features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                           ef.Dirichlet("z0", {"z": 0.0}), sphere],
                 solver=ef.SolverSettings(increments=6, growth=1.0, reuse_contraction=0.0))
with increment_lines(record):  # each load increment's line, as the run logs it
    summary = scene.run(os.environ.get("DEMO_OUT"))
# -

# ## Against Hertz
# The finite block (its far boundary $30 a$ away) is stiffer than a half-space: a layer of
# depth $L$ on a frictionless base multiplies the force by
# $1 + 0.884\chi + 0.781\chi^2 + 0.386\chi^3 + 0.0048\chi^4$, $\chi = a / L$ (Dimitriadis et
# al., Biophys. J. 82 (2002) 2798, eq. 11, non-bonded, $\nu = 1/2$): 3.0 % here. Against
# that, Q1/P0 with 7 elements across $1.3 a$ is within 2 % (the same contact on 5 and 7
# elements: +1.0 % and -0.7 %, `tests/test_contact_convergence.py`).

# +
depth, force, penetration = np.array(curve).T
hertz = hertz_layer_force(mu, R, depth, L)
error = abs(force[-1] - hertz[-1]) / hertz[-1]
if MPI.COMM_WORLD.rank == 0:
    print(f"{'depth':>8} {'force':>9} {'Hertz, layer':>12} {'ratio':>7} {'penetration/d':>14}")
    for row in zip(depth, force, hertz, force / hertz, penetration / depth):
        print("{:8.4f} {:9.5f} {:12.5f} {:7.4f} {:14.2e}".format(*row))
    print(f"force at d = {d}: {force[-1]:.5f} N, Hertz {hertz[-1]:.5f} N, error {100 * error:.2f}% "
          f"({summary['cells']} hexahedra, "
          f"{summary['steps'][-1]['contact']['sphere']['active_nodes']} nodes in contact)")
    # Newton: the residual norm squares from one iteration to the next once the nodes in
    # contact stop changing
    print("Newton residual norms, last increment:", " ".join(f"{r:.1e}" for r in histories[-1]))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fine = np.linspace(0.0, d, 100)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(fine, hertz_layer_force(mu, R, fine, L), "k-", label="Hertz, $16/3\\,\\mu R^{1/2} d^{3/2}$, finite depth")
    ax.plot(depth, force, "o", label="eyeball-fenicsx (Q1/P0, augmented penalty contact)")
    ax.set_xlabel("indentation depth d (mm)")
    ax.set_ylabel("force F (N)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(os.environ.get("DEMO_OUT", "."), "hertz_force_depth.png"), dpi=120)
# -
