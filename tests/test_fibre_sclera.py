"""The fibre-reinforced sclera law (materials.FibreReinforced) against closed forms.

A unit cube far from the law's centre (10^6 away along z, the axis along x) sees the fibres'
tangent plane as the x-y plane: the circumferential family along y, the meridional one along
x, to a relative 1e-6. For an incompressible block with sigma_zz = 0, the strain energy
W = c10 (I1 - 3) + k1 / (2 k2) sum (exp(k2 <I4 - 1>^2) - 1) gives (Ogden, Non-linear Elastic
Deformations, sec. 7.2; each fibre adds 2 lambda_a^2 dW/dI4 to sigma_aa):

* equibiaxial stretch lambda in x and y: sigma = 2 c10 (lambda^2 - lambda^-4) + 2 lambda^2 f(lambda^2),
  f(I4) = k1 (I4 - 1) exp(k2 (I4 - 1)^2) while I4 > 1, and 0 otherwise (fibres in compression);
* uniaxial stretch lambda along x: sigma = 2 c10 (lambda^2 - 1/lambda) + 2 lambda^2 f(lambda^2) (the
  y fibres shortened by lambda^(-1/2) carry nothing).

The face x1 of reference area 1 carries the nominal stress sigma / lambda.
"""
import math
import tomllib

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.scene.solid_tables import material_table
from eyeball_fenicsx.scene.tables import Table
from eyeball_fenicsx.scene.tissues import TISSUE_SETS, tissue_set

C10, K1, K2 = 0.05, 0.8, 15.0  # MPa, MPa, - (of the order of the calibrated sclera's)


def law():
    return ef.FibreReinforced(C10, K1, K2, axis=(1.0, 0.0, 0.0), centre=(0.5, 0.5, -1.0e6))


def fibre(I4):
    return K1 * (I4 - 1) * math.exp(K2 * (I4 - 1) ** 2) if I4 > 1 else 0.0


def block_reaction(block_mesh, stretch, biaxial):
    moves = [ef.Dirichlet("x1", {"x": stretch - 1.0})] + ([ef.Dirichlet("y1", {"y": stretch - 1.0})] if biaxial else [])
    scene = ef.Scene("fibres", block_mesh((2, 1, 1)), {"solid": law()},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"z": 0.0})] + moves,
                     probes={"corner": [1.0, 1.0, 1.0]}, solver=ef.SolverSettings(increments=4))
    final = scene.run()["steps"][-1]
    return final["reactions"]["x1"][0], final["probes"]["corner"]


@pytest.mark.parametrize("stretch", [1.08, 0.92], ids=["tension", "compression"])
def test_equibiaxial_stress(block_mesh, stretch):
    sigma = 2 * C10 * (stretch**2 - stretch**-4) + 2 * stretch**2 * fibre(stretch**2)
    reaction, corner = block_reaction(block_mesh, stretch, biaxial=True)
    assert reaction == pytest.approx(sigma / stretch, rel=1e-5)
    assert corner[2] == pytest.approx(stretch**-2 - 1, rel=1e-6)  # J = 1


def test_fibres_carry_no_compression(block_mesh):
    """In equibiaxial compression the block answers as the matrix alone, a neo-Hookean solid."""
    stretch = 0.92
    reaction, _ = block_reaction(block_mesh, stretch, biaxial=True)
    assert reaction == pytest.approx(2 * C10 * (stretch - stretch**-5), rel=1e-5)
    assert abs(reaction) < 0.1 * 2 * (C10 + K1) * abs(stretch - stretch**-5)  # far softer than in tension


def test_uniaxial_along_the_meridional_fibres(block_mesh):
    stretch = 1.1
    sigma = 2 * C10 * (stretch**2 - 1 / stretch) + 2 * stretch**2 * fibre(stretch**2)
    reaction, corner = block_reaction(block_mesh, stretch, biaxial=False)
    assert reaction == pytest.approx(sigma / stretch, rel=1e-5)
    assert corner[1] == pytest.approx(stretch**-0.5 - 1, rel=1e-5)  # the circumferential fibres slack


def test_fibre_directions_on_the_eye():
    """At a point of the globe's equator (z = 0) the circumferential fibre is the azimuthal
    direction and the meridional one the axis (up to sign)."""
    msh = mesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    X = ufl.as_vector([3.0, 4.0, 0.0])
    directions = ef.FibreReinforced(0.1, 1.0, 1.0).fibre_directions(X)
    values = [fem.assemble_scalar(fem.form(d[i] * ufl.dx(domain=msh))) for d in directions for i in range(3)]
    assert np.allclose(np.abs(values), [0.8, 0.6, 0.0, 0.0, 0.0, 1.0], atol=1e-12)


def test_the_fibre_sets_sclera_stiffens_as_measured():
    """The sclera of tissues = "fibre", pulled along its circumferential fibres (the uniaxial
    closed form above): its tangent modulus at 1 MPa of nominal stress is 11.2-12.4 times that at
    0.05 MPa, as Geraghty et al. measured in circumferential strips of human sclera (J Mech
    Behav Biomed Mater 2012;16:181, anterior to posterior means)."""
    with open(f"{TISSUE_SETS}/fibre.toml", "rb") as file:
        sclera = tomllib.load(file)["materials"]["sclera"]
    c10, k1, k2 = sclera["c10"], sclera["k1"], sclera["k2"]

    def nominal(stretch):
        I4 = stretch**2
        return (2 * c10 * (I4 - 1 / stretch) + 2 * I4 * k1 * (I4 - 1) * math.exp(k2 * (I4 - 1) ** 2)) / stretch

    def tangent(stress, h=1e-7):
        stretch = brentq(lambda s: nominal(s) - stress, 1.0, 1.5)
        return (nominal(stretch + h) - nominal(stretch - h)) / (2 * h)

    assert 11.2 <= tangent(1.0) / tangent(0.05) <= 12.4


def test_the_fibre_set_gives_the_sclera_its_law():
    """tissues = "fibre" reads as the fibre-reinforced sclera about the eye builders' axis and
    centre, every other tissue as in tissues = "calibrated"."""
    fibre, calibrated = tissue_set("fibre", "scene.toml"), tissue_set("calibrated", "scene.toml")
    laws = {region: material_table(Table(data, where, data)) for region, (data, where) in fibre.items()}
    assert isinstance(laws["sclera"], ef.FibreReinforced)
    assert (laws["sclera"].axis, laws["sclera"].centre) == ((0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    assert {region: data for region, (data, _) in fibre.items() if region != "sclera"} == \
        {region: data for region, (data, _) in calibrated.items() if region != "sclera"}
