"""Structured hexahedral mesh builders (gmsh Python API): each builds a gmsh model or writes a .msh file."""
