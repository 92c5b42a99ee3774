"""The small common interface of everything a scene holds besides the solid.

A feature contributes to the Newton system in any of three ways, and the problem sums what
the scene holds (as FEBio's ``Residual`` / ``StiffnessMatrix`` / ``Update``):

* ``residual(solid)``: a UFL form, linear in the test functions, added to the residual;
  its tangent comes from ``ufl.derivative`` (follower pressure, liquid load);
* global unknowns (``num_unknowns > 0``): extra scalar rows and columns bordering the
  system (a cavity's liquid pressure), see ``problem.Problem``;
* custom assembly: ``add_to_residual`` / ``add_to_jacobian`` write into the PETSc vector
  and matrix by global index (node-to-segment contact, nodal forces).

Every feature ramps in one step of the load path (``step``, an index), and is held at its
full value after it.
"""


class Feature:
    """Base class with nothing to contribute: subclasses override what they need."""

    name = ""
    step = 0
    num_unknowns = 0
    section = None  # the summary.json key this feature reports under, if any
    adds_to_residual = False  # set by features with custom assembly
    adds_to_jacobian = False
    limits_steps = False  # set by features that override step_fraction

    def setup(self, solid):
        """Called once, when the problem is built; locate surfaces, create forms."""

    def residual(self, solid):
        """UFL residual contribution, or None."""
        return None

    def dirichlet_bcs(self):
        """DOLFINx Dirichlet conditions this feature imposes (while active)."""
        return []

    def begin_step(self, step_index):
        """Called when a step of the load path starts."""

    def begin_increment(self):
        """Called before each load increment (after the loads are set); a contact search
        goes here. Return True if ``coupling()`` changed, so the matrix is preallocated anew."""
        return False

    def tangent_outdated(self):
        """Collective: True if the last tangent no longer fits the state (a contact active set
        changed), so Newton must not reuse its factorization."""
        return False

    def step_fraction(self, du, residual):
        """Collective: the largest fraction (at most 1) of the state change ``du`` that Newton
        may take in one step (contact onset); du and the current residual are the owned
        entries of mixed vectors."""
        return 1.0

    def set_increment(self, final):
        """Called before each load increment: ``final`` if it ends the step."""

    def augment(self):
        """Collective: after Newton converged an increment, update what the converged state
        decides (contact multipliers); False if Newton must solve again."""
        return True

    def coupling(self):
        """(rows, cols): global indices of the matrix entries ``add_to_jacobian`` may touch
        beyond the mesh's own pattern, or None. Rows may be owned by any rank."""
        return None

    def state_changed(self):
        """Called whenever Newton moves the state, before anything is assembled."""

    def set_load_factor(self, factor):
        """Set the ramped value: factor runs 0 -> 1 in this feature's step."""

    def add_to_residual(self, b):
        """Add custom contributions to the assembled residual (PETSc Vec, global indices)."""

    def add_to_jacobian(self, A):
        """Add custom contributions to the Jacobian (PETSc Mat, global indices, ADD_VALUES)."""

    def report(self):
        """What this feature writes into summary.json at the end of a step: a dict under
        ``section`` -> ``name``, or merged into ``section`` itself if ``name`` is None."""
        return None

