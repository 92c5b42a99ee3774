"""Frictionless contact: deformable pairs and rigid bodies, penalty with augmented Lagrangian.

``segments``: the facets' shape functions; ``geometry``: the continuous master normal
field, projection and its derivatives; ``search``: candidate pairs; ``law``: pressure from
the gap; ``surface``: the solid's surfaces and the default penalty; ``base``: what every
contact feature shares (assembly, the Newton-step limit at contact onset, the report);
``augmented``: its nodal multipliers and their updates; ``compliance``: the closing step;
``master``: the master surface over the ranks; ``pair``: two deformable surfaces;
``rigid``: a surface against a rigid plane, sphere or cylinder; ``policy``: every policy
constant.
"""
from .geometry import patches, project, traction
from .law import pressure
from .pair import ContactPair
from .rigid import Cylinder, Plane, RigidContact, Sphere
from .search import candidate_pairs
from .segments import Quad, Triangle

__all__ = ["ContactPair", "Cylinder", "Plane", "Quad", "RigidContact", "Sphere", "Triangle", "candidate_pairs",
           "patches", "pressure", "project", "traction"]
