"""Linear algebra for the belt DAE: the bordered cyclic block-tridiagonal structure, and restarted
GMRES and Newton's method for the steady-state solves (:mod:`jaxbelt.linalg.gmres`,
:mod:`jaxbelt.linalg.newton`)."""

from .bordered import BorderedBlockCyclic as BorderedBlockCyclic
from .bordered import bordered_solve as bordered_solve
from .bordered import dense_solve as dense_solve
from .bordered import join as join
from .bordered import split as split
