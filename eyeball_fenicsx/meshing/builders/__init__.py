"""gmsh-only mesh builders (8-node hexahedra into gmsh models and .msh files): they import without DOLFINx."""
