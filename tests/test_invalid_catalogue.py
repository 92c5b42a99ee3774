"""Invalid scenes and meshes beyond the core's catalogue in tests/test_scenes.py (issue 7): cavities,
contact, sutures and the buckle's sutures, bands, steps, the eye measures, the eye builders'
parameters and mesh files; then (issue 19) the contact settings, the retinal break and drainage,
tissue sets, the detachment, the tire's position, the solver and the planning sweep's inputs; then
(issue 18) the planning sweep's grid and ranges.

Each case is run as a user runs it, the command line ``run scene.toml --out DIR`` (or ``sweep
scene.toml --parameter ... --values ... --out DIR``), in a child process (a fresh MPI singleton,
as in test_scenes.test_console_script_in_a_child_process) that runs a rank's share of the cases
one after the other (tests/catalogue_child.py; ``python3 -m eyeball_fenicsx`` is what
test_scenes runs), and must exit 2 with one
line ``error: ...`` on stderr that names what is wrong and where, without a traceback, having
written nothing to DIR but possibly a summary.json with ``"ok": false``.

The cases are shared out over the ranks, each rank running its share in folders of its own, all in
one module fixture (the catalogue takes half the time on two ranks); each case is then checked in a
test of its own on every rank.
"""
import json
import os
import subprocess
import sys

import pytest
from mpi4py import MPI
from test_scenes import BLOCK, CAVITY, INVALID, NEO_HOOKE, OCTANT, ROLLERS, assert_one_line_error, write_text

COMM = MPI.COMM_WORLD

# pieces of small scenes (test_scenes has the block of two cells and the coarse sphere octant)
SOLID = BLOCK + NEO_HOOKE + ROLLERS
CLOSED = 'symmetry = ["x", "y", "z"]\n'  # the octant's inner surface, closed by its symmetry planes
PLANE = '{ shape = "plane", point = [0.0, 0.0, 1.1], normal = [0.0, 0.0, -1.0] }'
EYE_REGIONS = ("cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule")
EYE_MATERIALS = "".join(f'[materials.{region}]\nmodel = "neo-hooke"\nc10 = 0.05\n' for region in EYE_REGIONS)
BUCKLED_EYE = '[mesh]\nbuilder = "buckled_eye"\n'
BUCKLE_MATERIALS = EYE_MATERIALS + '[materials.band]\nmodel = "neo-hooke"\nc10 = 0.5\n'
SMALL_EYE = "sector_deg = 90\nn_circ = 16\n"  # the quarter eye, coarse: built in a fraction of a second
TIRE_MATERIAL = '[materials.tire]\nmodel = "neo-hooke"\nc10 = 0.5\n'
FIBRES = '[materials.solid]\nmodel = "fibre-reinforced"\nc10 = 0.05\nk1 = 1.0\nk2 = 10.0\n{extra}'
PRESSURE = '[[pressure]]\nsurface = "z1"\nvalue = 0.01\n'


STEPS = '[[step]]\nname = "fill"\n[[step]]\nname = "close"\n[[step]]\nname = "drain"\n'
SUB = '[[cavity]]\nname = "sub"\nsurface = "inner"\nbulk_modulus = 2083.3\n' + CLOSED  # a subretinal space
BREAK = 'break_into = "vitreous"\nbreak_closes = "close"\n'


def table(header, **keys):
    """A TOML array-of-tables entry ``[[header]]`` with its keys (values as TOML text)."""
    return f"[[{header}]]\n" + "".join(f"{key} = {value}\n" for key, value in keys.items())


def contact(**keys):
    return table("contact", name='"c"', slave='"z1"', **keys)


def suture(**keys):
    keys = {"name": '"s"', "first": "[0.0, 0.0, 1.0]", "second": "[1.0, 1.0, 1.0]", "tension": "0.01", **keys}
    return table("suture", **{key: value for key, value in keys.items() if value is not None})


def eye(parameters):
    return '[mesh]\nbuilder = "eye"\n' + parameters + EYE_MATERIALS


def sponge(keys, parameters="sector_deg = 360\nn_circ = 16\n"):
    """The whole buckled eye with a radial sponge (``keys``: its TOML inline table)."""
    return (BUCKLED_EYE + f"sponge = {keys}\n" + parameters + EYE_MATERIALS
            + '[materials.sponge]\nmodel = "neo-hooke"\nc10 = 0.5\n')


def tire(keys, parameters=""):
    """The buckled eye with a tire (``keys``: its TOML inline table)."""
    return BUCKLED_EYE + f"tire = {keys}\n" + parameters + BUCKLE_MATERIALS + TIRE_MATERIAL


def sweep(text, names, parameter, *values):
    """A case of the planning sweep of the scene ``text`` over ``values`` of ``parameter``."""
    return text, names, {}, ["sweep", "--parameter", parameter, "--values", *values]


def sweep_with(text, names, *options):
    """A case of the planning sweep of the scene ``text`` with its command-line ``options``."""
    return text, names, {}, ["sweep", *options]


def msh22(names, elements):
    """An ASCII MSH 2.2 file of the unit cube's 8 nodes: physical names (dim, tag, name) and
    element lines ("type ntags physical elementary nodes...")."""
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    if names:
        text += f"$PhysicalNames\n{len(names)}\n" + "".join(f'{d} {t} "{n}"\n' for d, t, n in names)
        text += "$EndPhysicalNames\n"
    text += f"$Nodes\n{len(corners)}\n" + "".join(f"{i + 1} {x} {y} {z}\n" for i, (x, y, z) in enumerate(corners))
    text += f"$EndNodes\n$Elements\n{len(elements)}\n" + "".join(f"{i + 1} {e}\n" for i, e in enumerate(elements))
    return text + "$EndElements\n"


HEXAHEDRON = "5 2 {} {} 1 2 3 4 5 6 7 8"  # physical group, elementary entity


def mesh_file(name, text, names):
    """A case of a scene whose mesh is the file ``name`` holding ``text``."""
    return f'[mesh]\nfile = "{name}"\n' + NEO_HOOKE, names, {name: text}


# id -> (scene text, what the message must name[, {file name: text} written beside the scene[, the
# command and its options before --out, default ["run"]]]).
# None of these is in test_scenes.INVALID.
CASES = {
    # [[cavity]] and [[injection]]
    "cavity-unknown-symmetry-plane": (OCTANT + CAVITY + 'symmetry = ["x", "y", "w"]\n',
                                      ["[[cavity]] #1", "cavity 'vitreous'", "symmetry planes", "['w']"]),
    "cavity-surface-list-unknown-group": (OCTANT + CAVITY.replace('"inner"', '["inner", "lining"]') + CLOSED,
                                          ["[[cavity]] #1", "surface 'lining'", "'sym_x'"]),
    "cavity-surface-list-not-closed": (OCTANT + CAVITY.replace('"inner"', '["inner", "outer"]'),
                                       ["cavity 'vitreous'", "['inner', 'outer'] is not closed", "symmetry"]),
    "cavity-empty-surface-list": (OCTANT + CAVITY.replace('"inner"', "[]") + CLOSED,
                                  ["[[cavity]] #1", "cavity 'vitreous'", "non-empty list", "got []"]),
    "cavity-duplicate-name": (OCTANT + CAVITY + CLOSED + CAVITY + CLOSED,
                              ["[[cavity]] #2", "'vitreous' is used twice"]),
    "cavity-pressurize-not-bool": (OCTANT + CAVITY + CLOSED + 'pressurize = "yes"\n',
                                   ["[[cavity]] #1", "pressurize must be true or false", "'yes'"]),
    "cavity-surface-faces-away": (OCTANT + CAVITY.replace('"inner"', '"outer"') + CLOSED,
                                  ["cavity 'vitreous'", "enclosed by 'outer'", "not positive", "faces the liquid"]),
    "injection-unknown-cavity": (OCTANT + CAVITY + CLOSED + table("injection", cavity='"aqueous"', volume="0.1"),
                                 ["[[injection]] #1", "cavity 'aqueous'", "['vitreous']"]),
    # tissue sets
    "tissues-unknown-set": ('tissues = "living"\n' + OCTANT, ["scene.toml", "tissues = 'living' is not a tissue set",
                                                             "'calibrated'", "'seed'"]),
    "tissues-on-a-mesh-without-the-eye": ('tissues = "seed"\n' + OCTANT,
                                          ["tissues = 'seed'", "[materials.cornea]",
                                           "'cornea' is not a volume group"]),
    # a retinal break (break_into, break_closes) and drainage (drain, drain_fraction)
    "break-into-unknown-cavity": (OCTANT + STEPS + CAVITY + CLOSED + SUB + 'break_into = "lens"\n',
                                  ["[[cavity]] #2", "break_into = 'lens'", "['sub', 'vitreous']"]),
    "break-closes-without-break-into": (OCTANT + STEPS + CAVITY + CLOSED + SUB + 'break_closes = "close"\n',
                                        ["[[cavity]] #2", "break_closes needs break_into"]),
    "break-closes-unknown-step": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK.replace('"close"', '"later"'),
                                  ["[[cavity]] #2", "break_closes 'later' is not a [[step]]", "'fill', 'close'"]),
    "break-closes-with-the-filling": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK.replace('"close"', '"fill"'),
                                      ["[[cavity]] #2", "cavity 'sub'",
                                       "break_closes must be a step after 'vitreous'"]),
    "break-guest-pressurized": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK + "pressurize = true\n",
                                ["[[cavity]] #2", "cavity 'sub'", "fills with 'vitreous'", "pressurize"]),
    "drain-through-an-open-break": (OCTANT + STEPS + CAVITY + CLOSED + SUB
                                    + 'break_into = "vitreous"\ndrain = "drain"\n',
                                    ["[[cavity]] #2", "drainage of 'sub'", "break is still open", "break_closes"]),
    "drain-fraction-out-of-range": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK
                                    + 'drain = "drain"\ndrain_fraction = 1.0\n',
                                    ["[[cavity]] #2", "drain_fraction must be a number in (0, 1)", "1.0"]),
    "drain-fraction-without-drain": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK + "drain_fraction = 0.5\n",
                                     ["[[cavity]] #2", "drain_fraction needs drain"]),
    "injection-through-an-open-break": (OCTANT + STEPS + CAVITY + CLOSED + SUB + BREAK
                                        + table("injection", cavity='"sub"', volume="-0.1", step='"fill"'),
                                        ["[[injection]] #1", "injection into 'sub'", "break is open", "'vitreous'"]),
    # [[contact]]
    "contact-slave-is-master": (SOLID + contact(master='"z1"'),
                                ["[[contact]] #1", "contact 'c'", "slave and master are both 'z1'"]),
    "contact-unknown-master": (SOLID + contact(master='"sclera_outer"'),
                               ["[[contact]] #1", "surface 'sclera_outer'", "'z1'"]),
    "contact-master-and-rigid": (SOLID + contact(master='"x1"', rigid=PLANE),
                                 ["[[contact]] #1", "exactly one of master", "or rigid"]),
    "contact-unknown-rigid-shape": (SOLID + contact(rigid='{ shape = "cone", point = [0.0, 0.0, 1.0] }'),
                                    ["[[contact]] #1", "rigid.shape", "'cone'", "'plane'"]),
    "contact-plane-zero-normal": (SOLID + contact(rigid=PLANE.replace("-1.0", "0.0")),
                                  ["[[contact]] #1 rigid", "plane normal", "non-zero", "[0.0, 0.0, 0.0]"]),
    "contact-sphere-negative-radius": (
        SOLID + contact(rigid='{ shape = "sphere", center = [0.5, 0.5, 3.0], radius = -2.0 }'),
        ["[[contact]] #1 rigid", "radius must be positive, got -2.0"]),
    "contact-penalty-negative": (SOLID + contact(rigid=PLANE, penalty="-1.0e3"),
                                 ["[[contact]] #1", "penalty must be positive, got -1000.0"]),
    "contact-penalty-bool": (SOLID + contact(rigid=PLANE, penalty="true"),
                             ["[[contact]] #1", "penalty must be a finite number, got True"]),
    "contact-smoothing-negative": (SOLID + contact(rigid=PLANE, smoothing="-0.01"),
                                   ["[[contact]] #1", "smoothing must not be negative, got -0.01"]),
    "contact-displacement-two-components": (
        SOLID + contact(rigid=PLANE.replace(" }", ", displacement = [0.0, -0.1] }")),
        ["[[contact]] #1 rigid", "displacement must be a list of 3 finite numbers", "[0.0, -0.1]"]),
    "contact-duplicate-name": (SOLID + contact(rigid=PLANE) + contact(rigid=PLANE.replace("1.1", "1.2")),
                               ["[[contact]] #2", "contact name 'c' is used twice"]),
    # [[suture]] and [buckle_sutures]
    "suture-tension-and-shortening": (SOLID + suture(shortening="0.1"),
                                      ["[[suture]] #1", "suture 's'", "exactly one of tension or shortening"]),
    "suture-negative-stiffness": (SOLID + suture(tension=None, shortening="0.1", stiffness="-5.0"),
                                  ["[[suture]] #1", "stiffness must be positive, got -5.0"]),
    "suture-far-from-its-surface": (SOLID + suture(first="[0.0, 0.0, 30.0]", first_surface='"z1"'),
                                    ["suture 's'", "first = [0.0, 0.0, 30.0]", "surface 'z1'", "largest element"]),
    "buckle-sutures-without-buckled-eye": (SOLID + "[buckle_sutures]\ntension = 0.1\n",
                                           ["[buckle_sutures]", 'builder = "buckled_eye"']),
    "buckle-sutures-zero-count": (BUCKLED_EYE + BUCKLE_MATERIALS + "[buckle_sutures]\ncount = 0\ntension = 0.1\n",
                                  ["[buckle_sutures]", "count must be a positive integer, got 0"]),
    "buckle-sutures-name-clash": (BUCKLED_EYE + BUCKLE_MATERIALS + suture(name='"suture_45_back"')
                                  + "[buckle_sutures]\ntension = 0.1\n",
                                  ["[buckle_sutures]", "'suture_45_back' is used twice", "[[suture]]"]),
    # [[band]]
    "band-unknown-region": (SOLID + table("band", region='"band"', reduction="1.0"),
                            ["[[band]] #1", "region 'band'", "[materials.band]"]),
    "band-negative-reduction": (SOLID + table("band", region='"solid"', reduction="-1.0"),
                                ["[[band]] #1", "band 'solid'", "reduction", "must not be negative", "-1.0"]),
    "band-zero-axis": (SOLID + table("band", region='"solid"', reduction="0.1", axis="[0.0, 0.0, 0.0]"),
                       ["[[band]] #1", "axis must be a non-zero vector", "[0.0, 0.0, 0.0]"]),
    # [[step]] and [eye]
    "step-duplicate-names": (SOLID + table("step", name='"a"') + table("step", name='"a"'),
                             ["[[step]] names must be unique", "['a', 'a']"]),
    "step-unknown-on-suture": (SOLID + table("step", name='"a"') + suture(step='"b"'),
                               ["[[suture]] #1", "step 'b'", "['a']"]),
    "eye-vitreous-unknown-cavity": (OCTANT + CAVITY + CLOSED + '[eye]\nvitreous = "aqueous"\n',
                                    ["[eye]", "vitreous = 'aqueous'", "['vitreous']"]),
    # [mesh] builder = "eye" / "buckled_eye": parameter checks, before any meshing
    "buckled-eye-negative-band-width": (BUCKLED_EYE + "band_width = -2.5\n" + BUCKLE_MATERIALS,
                                        ["[mesh]", "band_width must be a positive number, got -2.5"]),
    "buckled-eye-band-beyond-the-sclera": (BUCKLED_EYE + "band_position = 30.0\n" + BUCKLE_MATERIALS,
                                           ["[mesh]", "must rest on the sclera", "band_position 30.0"]),
    "eye-sector-out-of-range": (eye("sector_deg = 45\n"), ["[mesh]", "sector_deg must be one of", "45"]),
    "eye-n-circ-too-small": (eye("n_circ = 4\n"), ["[mesh]", "n_circ must be a multiple of 8", "got 4"]),
    "eye-zero-wall-layers": (eye("wall_layers = 0\n"), ["[mesh]", "wall_layers must be a positive integer", "got 0"]),
    "buckled-eye-fractional-wall-layers": (BUCKLED_EYE + "wall_layers = 1.5\n" + BUCKLE_MATERIALS,
                                           ["[mesh]", "wall_layers must be a positive integer", "got 1.5"]),
    "eye-detachment-beyond-the-ora": (
        eye("detachment = { polar_deg = 0.0, extent_deg = 170.0, gap = 0.1 }\n"),
        ["[mesh]", "detachment must lie in the retina", "0.0 + 170.0"]),
    "eye-unknown-parameter": (eye("axial_lenght = 24.0\n"),
                              ["[mesh]", "unknown parameter(s) axial_lenght", "axial_length"]),
    # [mesh] file = ...: files gmsh cannot use
    "mesh-not-gmsh": mesh_file("junk.msh", "solid 8 hexahedra\n", ["[mesh]", "junk.msh", "gmsh cannot read it"]),
    "mesh-unnamed-physical-group": mesh_file("unnamed.msh", msh22([], [HEXAHEDRON.format(1, 1)]),
                                             ["[mesh]", "unnamed.msh", "volume physical group 1 has no name"]),
    "mesh-volume-in-no-group": mesh_file("loose.msh", msh22([(3, 1, "solid")], [HEXAHEDRON.format(1, 1),
                                                                               HEXAHEDRON.format(0, 2)]),
                                         ["[mesh]", "loose.msh", "volume entity 2", "in no physical group"]),
    # -- issue 19: everything added since the first catalogue (the ones marked "fixed" were
    # accepted, misreported or unlocated before it)
    # [[contact]]: symmetry, rigid bodies, the law's smoothing
    "contact-symmetry-on-a-rigid-body": (SOLID + contact(rigid=PLANE, symmetry='["x"]'),
                                         ["[[contact]] #1", "symmetry applies to a master surface",
                                          "a rigid body has none"]),
    "contact-adjust-on-a-rigid-body": (SOLID + contact(rigid=PLANE, adjust="0.05"),
                                       ["[[contact]] #1", "adjust applies to two meshed surfaces",
                                        "a rigid body has none"]),
    "contact-adjust-negative": (SOLID + contact(master='"x1"', adjust="-0.05"),
                                ["[[contact]] #1", "adjust", "-0.05"]),
    "contact-adjust-beyond-the-search": (SOLID + contact(master='"x1"', adjust="50.0"),
                                         ["contact 'c'", "adjust 50 mm is beyond the contact search's reach"]),
    "contact-symmetry-unknown-axis": (SOLID + contact(master='"x1"', symmetry='["w"]'),
                                      ["[[contact]] #1", "contact 'c'", "symmetry must list axes", "['w']"]),
    "contact-rigid-not-a-table": (SOLID + contact(rigid='"plane"'),
                                  ["[[contact]] #1", "rigid must be a table", "got 'plane'"]),
    "contact-smoothing-beyond-the-elements": (  # fixed: ran, the plane pressing 27 N from 0.1 mm
        SOLID + contact(rigid=PLANE, smoothing="5.0"),
        ["contact 'c'", "smoothing 5 mm is not below the size of the elements"]),
    # a retinal break and drainage
    "break-into-itself": (OCTANT + STEPS + CAVITY + CLOSED + SUB + 'break_into = "sub"\n',
                          ["[[cavity]] #2", "cavity 'sub'", "another cavity that has no break itself"]),
    "break-closes-after-the-drain": (OCTANT + STEPS + CAVITY + CLOSED + SUB
                                     + 'break_into = "vitreous"\nbreak_closes = "drain"\ndrain = "close"\n',
                                     ["[[cavity]] #2", "drainage of 'sub'", "break is still open"]),
    "break-with-the-previous-algorithm": (OCTANT + STEPS + CAVITY + CLOSED + 'algorithm = "previous"\n' + SUB + BREAK,
                                          ["[[cavity]] #2", "cavity 'sub'", "new algorithm"]),
    "drain-in-the-first-step": (OCTANT + STEPS + CAVITY + CLOSED + 'drain = "fill"\n',
                                ["[[cavity]] #1", "drainage of 'vitreous'", "not the first"]),
    # tissue sets
    "tissues-not-a-string": ("tissues = 3\n" + OCTANT, ["scene.toml: tissues must be a non-empty string, got 3"]),
    "tissues-and-a-region-the-mesh-lacks": ('tissues = "seed"\n[mesh]\nbuilder = "eye"\n' + SMALL_EYE
                                            + '[materials.band]\nmodel = "neo-hooke"\nc10 = 0.5\n',
                                            ["[materials.band]", "'band' is not a volume group", "build_eye"]),
    "tissues-override-without-model": ('tissues = "seed"\n[mesh]\nbuilder = "eye"\n[materials.sclera]\nc10 = 0.5\n',
                                       ["[materials.sclera]", "missing required key 'model'"]),
    "tissues-without-the-buckle": ('tissues = "calibrated"\n' + BUCKLED_EYE + SMALL_EYE,
                                   ["no [materials.<region>] table", "['band']", "build_buckled_eye"]),
    # the fibre-reinforced law's keys
    "fibre-k1-negative": (BLOCK + FIBRES.format(extra="").replace("k1 = 1.0", "k1 = -1.0") + ROLLERS,
                          ["[materials.solid]", "k1 must be positive, got -1.0"]),
    "fibre-k2-missing": (BLOCK + FIBRES.format(extra="").replace("k2 = 10.0\n", "") + ROLLERS,
                         ["[materials.solid]", "missing required key 'k2'"]),
    "fibre-axis-zero": (BLOCK + FIBRES.format(extra="axis = [0.0, 0.0, 0.0]\n") + ROLLERS,
                        ["[materials.solid]", "axis must be a non-zero vector"]),
    "fibre-centre-short": (BLOCK + FIBRES.format(extra="centre = [0.0, 0.0]\n") + ROLLERS,
                           ["[materials.solid]", "centre must be a list of 3 finite numbers"]),
    "fibre-angles-text": (BLOCK + FIBRES.format(extra='fibre_angles_deg = ["hoop"]\n') + ROLLERS,
                          ["[materials.solid]", "fibre_angles_deg must be a list of finite numbers"]),
    "fibre-unknown-key": (BLOCK + FIBRES.format(extra="k3 = 1.0\n") + ROLLERS,
                          ["[materials.solid]", "k3"]),
    # the eye builder: the detachment, the proportions
    "eye-detachment-smaller-than-an-element": (  # fixed: opened elements far beyond the cap
        eye("sector_deg = 180\nn_circ = 16\ndetachment = { polar_deg = 30.0, extent_deg = 4.0, gap = 0.1 }\n"),
        ["[mesh]", "detachment is smaller than one element", "extent_deg"]),
    "eye-detachment-off-the-cut-plane": (
        eye("sector_deg = 180\ndetachment = { polar_deg = 30.0, azimuth_deg = 90.0, extent_deg = 20.0, gap = 0.1 }\n"),
        ["[mesh]", "wedge model is mirrored", "azimuth_deg 0 or 180"]),
    "eye-out-of-proportion": (  # fixed: blamed a detachment the eye has not
        eye("sclera_thickness_limbus = 1.99\nsclera_thickness_equator = 0.05\n" + SMALL_EYE),
        ["[mesh]", "scaled Jacobian", "axial_length 24.0 mm", "thicknesses out of proportion"]),
    # the eye's biometry (issue 18)
    "eye-axial-length-out-of-range": (eye("axial_length = 500.0\n" + SMALL_EYE),
                                      ["[mesh]", "axial_length must be between 21 and 30 mm, got 500.0"]),
    "eye-axial-length-short": (eye("axial_length = 20.0\n" + SMALL_EYE),
                               ["[mesh]", "axial_length must be between 21 and 30 mm, got 20.0"]),
    "eye-corneal-radius-out-of-range": (eye("corneal_radius = 5.8\n" + SMALL_EYE),
                                        ["[mesh]", "corneal_radius must be between 6.5 and 9.5 mm, got 5.8"]),
    "eye-corneal-radius-not-a-number": (eye('corneal_radius = "7.8"\n' + SMALL_EYE),
                                        ["[mesh]", "corneal_radius must be a positive number, got '7.8'"]),
    "eye-chamber-depth-out-of-range": (eye("anterior_chamber_depth = 5.5\n" + SMALL_EYE),
                                       ["[mesh]", "anterior_chamber_depth must be between 1.5 and 4.5 mm, got 5.5"]),
    "eye-chamber-depth-negative": (eye("anterior_chamber_depth = -3.05\n" + SMALL_EYE),
                                   ["[mesh]", "anterior_chamber_depth must be a positive number, got -3.05"]),
    "eye-sclera-thickness-zero": (eye("sclera_thickness_equator = 0.0\n" + SMALL_EYE),
                                  ["[mesh]", "sclera_thickness_equator must be a positive number, got 0.0"]),
    "eye-sclera-thicker-than-2-mm": (eye("sclera_thickness_pole = 2.5\n" + SMALL_EYE),
                                     ["[mesh]", "sclera and the cornea must be thinner than 2 mm"]),
    "buckled-eye-band-behind-a-myopic-equator": (
        BUCKLED_EYE + "axial_length = 28.0\nband_position = 15.5\n" + SMALL_EYE + BUCKLE_MATERIALS,
        ["[mesh]", "band would cut into the sclera behind the equator of this 28.0 mm eye", "band_position 15.5"]),
    # the buckled eye's tire: its arc and azimuth
    "tire-arc-beyond-360": (tire("{ arc_deg = 400.0 }"), ["[mesh]", "tire arc_deg must be at most 360, got 400.0"]),
    "tire-off-the-cut-plane": (tire("{ arc_deg = 90.0, azimuth_deg = 45.0 }", "sector_deg = 180\n"),
                               ["[mesh]", "segmental tire must be centred on one", "azimuth_deg 45.0"]),
    "buckled-eye-without-band-or-tire": (BUCKLED_EYE + "band = false\n" + BUCKLE_MATERIALS,
                                         ["[mesh]", "without the band there must be a tire"]),
    "buckle-sutures-outside-the-tire": (tire("{ arc_deg = 90.0 }") + "[buckle_sutures]\nazimuths = [180.0]\n"
                                        "tension = 0.1\n",
                                        ["[buckle_sutures]", "no suture at azimuth 180.0 deg, outside the tire"]),
    # the grading of the buckled eye around its sutures ([mesh] graded) and of any eye ([mesh] graded_at,
    # graded_azimuths, graded_between)
    "graded-without-buckle-sutures": (tire("{ arc_deg = 90.0 }", "graded = true\n"),
                                      ["[mesh]", "graded refines the eye around the sutures' bites",
                                       "[buckle_sutures]"]),
    "graded-not-a-flag": (tire("{ arc_deg = 90.0 }", 'graded = "yes"\n') + "[buckle_sutures]\ntension = 0.1\n",
                          ["[mesh]", "graded must be true or false, got 'yes'"]),
    "graded-azimuths-in-a-wedge": (eye("graded_azimuths = [45.0]\n" + SMALL_EYE),
                                   ["[mesh]", "graded_azimuths needs the whole eye (sector_deg = 360)", "90"]),
    "graded-azimuths-not-a-list": (eye("graded_azimuths = 45.0\nn_circ = 16\n"),
                                   ["[mesh]", "graded_azimuths must be a list of azimuths (degrees), got 45.0"]),
    "graded-azimuths-under-a-tire": (tire("{ arc_deg = 90.0 }", "graded_azimuths = [10.0]\n"),
                                     ["[mesh]", "graded_azimuths grades the eye around a radial sponge",
                                      "a tire or a band lies on the eye's even azimuths"]),
    "graded-between-without-azimuths": (eye("graded_between = [6.0, 18.0]\nn_circ = 16\n"),
                                        ["[mesh]", "graded_between says where graded_azimuths holds",
                                         "give graded_azimuths"]),
    "graded-between-back-first": (eye("graded_azimuths = [45.0]\ngraded_between = [18.0, 6.0]\nn_circ = 16\n"),
                                  ["[mesh]", "graded_between must be two distances behind the limbus (mm), the front "
                                   "one first, got [18.0, 6.0]"]),
    "graded-between-one-circle": (eye("graded_azimuths = [45.0]\ngraded_between = [6.0]\nn_circ = 16\n"),
                                  ["[mesh]", "graded_between must be two distances", "got [6.0]"]),
    "graded-at-off-the-sclera": (eye("graded_at = [12.5, 40.0]\n" + SMALL_EYE),
                                 ["[mesh]", "graded_at 40.0 mm behind the limbus is off the sclera that can be"]),
    "graded-at-the-zonule": (eye("graded_at = [2.0]\n" + SMALL_EYE),
                             ["[mesh]", "graded_at 2.0 mm", "where the zonule meets the ciliary body"]),
    "graded-at-not-a-list": (eye("graded_at = 12.5\n" + SMALL_EYE),
                             ["[mesh]", "graded_at must be a list of distances behind the limbus (mm), got 12.5"]),
    # the buckled eye's radial sponge
    "sponge-in-a-wedge": (sponge("{ azimuth_deg = 45.0 }", "sector_deg = 180\n"),
                          ["[mesh]", "a radial sponge needs the whole eye (sector_deg = 360)", "180"]),
    "sponge-with-a-tire": (sponge("{ azimuth_deg = 45.0 }", "sector_deg = 360\ntire = { arc_deg = 60.0 }\n"),
                           ["[mesh]", "a radial sponge rests on the sclera alone"]),
    "sponge-negative-width": (sponge("{ width = -5.0 }"), ["[mesh]", "sponge width", "-5.0"]),
    "sponge-unknown-key": (sponge("{ diameter = 5.0 }"), ["[mesh]", "sponge must be None or a table", "length"]),
    "sponge-azimuth-not-a-number": (sponge('{ azimuth_deg = "temporal" }'),
                                    ["[mesh]", "sponge azimuth_deg must be a number", "temporal"]),
    "sponge-zero-elements": (sponge("{ n_length = 0 }"), ["[mesh]", "sponge n_length", "0"]),
    "sponge-off-the-sclera": (sponge("{ length = 30.0 }"), ["[mesh]", "must rest on the sclera between"]),
    "sponge-wider-than-half-the-eye": (sponge("{ width = 40.0 }"), ["[mesh]", "spans half the eye's azimuths"]),
    "sponge-sutures-at-azimuths": (sponge("{ azimuth_deg = 45.0 }") + "[buckle_sutures]\nazimuths = [45.0]\n"
                                   "tension = 0.1\n",
                                   ["[buckle_sutures]", "a radial sponge's sutures cross it along its length"]),
    "sponge-sutures-too-narrow": (sponge("{ azimuth_deg = 45.0 }") + "[buckle_sutures]\nwidth = 4.0\n"
                                  "tension = 0.1\n",
                                  ["[buckle_sutures]", "suture_width 4.0 must exceed the sponge's width"]),
    # [eye]
    "eye-buckle-on-an-eye-without-one": (eye(SMALL_EYE) + '[eye]\nbuckle = "band_inner"\n',
                                         ["[eye]", "surface 'band_inner'", "build_eye"]),
    "eye-ends-on-one-node": (eye(SMALL_EYE) + '[eye]\nanterior = [0.0, 0.0, -1e3]\n'
                             'anterior_surface = "vitreous_wall"\n',
                             ["[eye]", "pick the same node", "axial length would be 0"]),  # fixed: read 0 mm
    # [[step]], [solver], [mesh]
    "step-empty-list": ("step = []\n" + SOLID, ["scene.toml: step = [] gives no step"]),  # fixed: ran as one step
    "solver-growth-below-one": (SOLID + "[solver]\ngrowth = 0.5\n",  # fixed: named no file
                                ["[solver]", "growth must be at least 1", "0.5"]),
    "solver-unknown-linear": (SOLID + '[solver]\nlinear = "cholmod"\n',
                              ["[solver]", "linear = 'cholmod' is not a linear solver", "'mumps-blr'"]),
    "solver-linear-not-a-string": (SOLID + '[solver]\nlinear = 3\n', ["[solver]", "linear", "3"]),
    "solver-unknown-element": (SOLID + '[solver]\nelement = "Q5P4"\n',  # fixed: named no table
                               ["[solver]", "unknown element 'Q5P4'", "'Q1P0'"]),
    "solver-element-of-another-cell": (SOLID + '[solver]\nelement = "P2P0"\n',  # fixed: ran as Q2P0
                                       ["[solver]", "element 'P2P0' is for tetrahedra", "has hexahedra", "'Q1P0'"]),
    "mesh-not-a-table": ('mesh = "block"\n' + NEO_HOOKE,  # fixed: said there was no [mesh]
                         ["scene.toml: mesh = 'block' is not a table"]),
    # the planning sweep (fixed: a value, a table or an array index was accepted, or the message
    # named no file, or the variants before a bad one ran first)
    "sweep-value-nan": sweep(SOLID + PRESSURE, ["sweep of 'pressure.0.value'", "finite numbers, got 'nan'"],
                             "pressure.0.value", "0.01", "nan"),
    "sweep-of-a-table": sweep(SOLID + PRESSURE, ["sweep", "parameter 'pressure.0' names a table, not a value"],
                              "pressure.0", "1"),
    "sweep-of-a-string": sweep(SOLID, ["sweep of 'materials.solid.model'", "'neo-hooke', not a number"],
                               "materials.solid.model", "2"),
    "sweep-negative-index": sweep(SOLID + PRESSURE, ["sweep", "'pressure.-1.value' is not in the scene",
                                                     "indexed from 0"], "pressure.-1.value", "0.01"),
    "sweep-invalid-variant": sweep(SOLID + PRESSURE, ["[materials.solid]", "c10 must be positive, got -1.0",
                                                      "variant 01"], "materials.solid.c10", "0.5", "-1"),
    # the grid and the ranges of the planning sweep (issue 18)
    "sweep-grid-unknown-parameter": sweep_with(SOLID + PRESSURE, ["sweep", "'band.0.reduction' is not in the scene"],
                                               "--parameter", "pressure.0.value", "--values", "0.01", "0.02",
                                               "--parameter", "band.0.reduction", "--values", "4"),
    "sweep-grid-value-not-a-number": sweep_with(SOLID + PRESSURE, ["sweep of 'materials.solid.c10'",
                                                                   "finite numbers, got 'stiff'"],
                                                "--parameter", "pressure.0.value", "--values", "0.01",
                                                "--parameter", "materials.solid.c10", "--values", "0.5", "stiff"),
    "sweep-grid-duplicate-parameter": sweep_with(SOLID + PRESSURE, ["sweep", "'pressure.0.value' is given twice"],
                                                 "--parameter", "pressure.0.value", "--values", "0.01",
                                                 "--parameter", "pressure.0.value", "--values", "0.02"),
    "sweep-grid-no-values": sweep_with(SOLID + PRESSURE, ["sweep of 'pressure.0.value'", "one or more values, got []"],
                                       "--parameter", "pressure.0.value", "--values"),
    "sweep-grid-parameter-without-values": sweep_with(SOLID + PRESSURE, ["sweep", "2 --parameter but 1 --values"],
                                                      "--parameter", "pressure.0.value", "--values", "0.01",
                                                      "--parameter", "materials.solid.c10"),
    "sweep-grid-repeated-value": sweep_with(SOLID + PRESSURE, ["sweep of 'pressure.0.value'", "0.01 is given twice"],
                                            "--parameter", "pressure.0.value", "--values", "0.01", "0.02", "0.01"),
    "sweep-nothing-to-sweep": sweep_with(SOLID, ["sweep", "give a parameter and its values", "or a range"]),
    "sweep-range-low-above-high": sweep_with(SOLID, ["sweep: range of 'materials.solid.c10'",
                                                     "low end 0.8 must be below the high end 0.5"],
                                             "--range", "materials.solid.c10", "0.8", "0.5"),
    "sweep-range-empty": sweep_with(SOLID, ["range of 'materials.solid.c10'", "low end 0.5 must be below"],
                                    "--range", "materials.solid.c10", "0.5", "0.5"),
    "sweep-range-not-a-number": sweep_with(SOLID, ["range of 'materials.solid.c10'", "finite numbers, got 'high'"],
                                           "--range", "materials.solid.c10", "0.5", "high"),
    "sweep-range-one-end": sweep_with(SOLID, ["range of 'materials.solid.c10'", "its low and its high end",
                                              "['0.5']"], "--range", "materials.solid.c10", "0.5"),
    "sweep-range-of-a-string": sweep_with(SOLID, ["sweep of 'materials.solid.model'", "'neo-hooke', not a number"],
                                          "--range", "materials.solid.model", "1", "2"),
    "sweep-range-also-a-parameter": sweep_with(SOLID, ["'materials.solid.c10' is given twice", "or as a range"],
                                               "--parameter", "materials.solid.c10", "--values", "0.5",
                                               "--range", "materials.solid.c10", "0.4", "0.6"),
    "sweep-range-tissue-set-without-the-key": sweep_with('tissues = "calibrated"\n' + SOLID,  # the set's sclera is
                                                         ["sweep", "'materials.sclera.c10' is not in the scene",
                                                          "that table has ['c', 'model']"],  # Mooney-Rivlin: c.10
                                                         "--range", "materials.sclera.c10", "0.5", "0.8"),
    "sweep-range-invalid-corner": sweep_with(SOLID, ["[materials.solid]", "c10 must be positive, got -0.1",
                                                     "variant 00-l"], "--range", "materials.solid.c10", "-0.1", "0.5"),
}


def write_case(case, folder):
    """Write a case's files and its command line (argv.json) into ``folder``."""
    text, _, *more = CASES[case]
    files, command = more[0] if more else {}, more[1] if len(more) > 1 else ["run"]
    os.makedirs(folder)
    for name, content in {"scene.toml": text, **files}.items():
        write_text(os.path.join(folder, name), content)
    argv = [command[0], os.path.join(folder, "scene.toml"), *command[1:], "--out", os.path.join(folder, "out")]
    write_text(os.path.join(folder, "argv.json"), json.dumps(argv))


def read_outcome(folder):
    """What the command line did: exit code, stderr, the files in its output folder."""
    with open(os.path.join(folder, "outcome.json")) as f:
        outcome = json.load(f)
    out = os.path.join(folder, "out")
    written = sorted(os.listdir(out)) if os.path.isdir(out) else []
    ok = None
    if "summary.json" in written:
        with open(os.path.join(out, "summary.json")) as f:
            ok = json.load(f).get("ok")
    return {**outcome, "written": written, "summary_ok": ok}


@pytest.fixture(scope="module")
def outcomes(request, tmp_path_factory):
    """The outcome of every case selected (``-k``), on every rank; each rank runs its share in one
    child process (tests/catalogue_child.py)."""
    selected = sorted({item.callspec.params["case"] for item in request.session.items
                       if item.module is sys.modules[__name__] and hasattr(item, "callspec")})
    base = tmp_path_factory.mktemp(f"catalogue_rank{COMM.rank}")
    mine = {}
    try:
        folders = {case: os.path.join(base, case) for case in selected[COMM.rank::COMM.size]}
        for case, folder in folders.items():
            write_case(case, folder)
        # a fresh MPI singleton: none of the OMPI_* / PMIX_* variables of the mpirun that started us
        env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
        child = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "catalogue_child.py"),
                                *folders.values()], env=env, capture_output=True, text=True, timeout=600)
        for case, folder in folders.items():
            if os.path.exists(os.path.join(folder, "outcome.json")):
                mine[case] = read_outcome(folder)
            else:
                mine[case] = {"failure": f"the child ended (exit {child.returncode}) before this case: {child.stderr}"}
    except Exception as error:  # reported by the cases' tests; no rank is left waiting
        mine = {case: {"failure": repr(error)} for case in selected[COMM.rank::COMM.size]}
    return {case: outcome for share in COMM.allgather(mine) for case, outcome in share.items()}


@pytest.mark.parametrize("case", sorted(CASES))
def test_invalid_case_exits_2(case, outcomes):
    outcome = outcomes[case]
    assert "failure" not in outcome, outcome
    err = outcome["stderr"]
    assert outcome["code"] == 2, err
    assert_one_line_error(err)
    for name in CASES[case][1]:
        assert name in err
    assert err.count("scene.toml") == 1  # the scene file is named once, whatever failed
    # nothing written but, possibly, a summary that says the run failed
    assert set(outcome["written"]) <= {"summary.json"}
    if outcome["written"]:
        assert outcome["summary_ok"] is False


def test_the_catalogue_is_new():
    """No case repeats one of the core's (tests/test_scenes.py)."""
    core = {text for text, _ in INVALID.values()}
    assert len(CASES) >= 24
    assert not [case for case, (text, *_) in CASES.items() if text in core]
