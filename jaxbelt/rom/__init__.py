"""Model order reduction on the belt model (MODEL.md §5): metrics and exact DMD so far."""

from .dmd import DMDModel as DMDModel
from .dmd import fit_dmd as fit_dmd
from .metrics import rmse as rmse
from .metrics import rrmse as rrmse
