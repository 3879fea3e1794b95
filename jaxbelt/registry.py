"""The names a scene file and the command line may give a solver, in one place.

The scene parser (:mod:`jaxbelt.scene`) validates ``[solver]`` against these tables and the
command line offers them as choices; :func:`jaxbelt.integrators.make_solver` turns the names into
solver objects. Each entry maps a name to a one-line description (what ``jaxbelt info`` and
``--help`` print). This module imports nothing: it sits below every layer that reads it.
"""

INTEGRATORS = {
    "direct": "Backward Euler on the DAE, one linear solve of size N per step (eq. 3.54)",
    "naive": "Backward Euler on the 3N system of positions, velocities and accelerations (eq. 3.43)",
    "eliminated": "Backward Euler on the ODE left after eliminating the algebraic unknowns (eq. 3.47-3.50)",
}

LINEAR_SOLVERS = {
    "kept-interior": "exact structured solve; the belt interior's factors are kept for the run where the "
                     "step matrix does not change there (shift transport), else factored every step",
    "structured": "exact structured solve, the bordered block-cyclic matrix factored in full every step",
    "cyclic-reduction": "as structured, the interior factored by block cyclic reduction (log2 n levels)",
    "reuse": "the first step's factors kept, each step refined against the current matrix",
    "dense": "dense LU of the assembled matrix (reference)",
}

TRANSPORT_RULES = {
    "shift": "the reference frame moves by the mean displacement; element masses are kept",
    "source": "each node interpolated by its own displacement, masses transported (eq. 3.56)",
}

START_RULES = {
    "rest": "belt and idle rollers at rest, the drive at speed: an impulsive start (model specification section 2)",
    "running": "belt and idle rollers already at the drive speed, consistent with no slip: no start-up swing",
}

DEFAULT_INTEGRATOR = "direct"
DEFAULT_LINEAR_SOLVER = "kept-interior"
DEFAULT_TRANSPORT = "shift"
