"""Meshes: the gmsh builders (builders/, no DOLFINx) and their distributed loading into DOLFINx (load.py)."""
