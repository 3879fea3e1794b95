"""Model order reduction on the belt model (MODEL.md §5): snapshots, metrics and exact DMD so far."""

from .dmd import DMDModel as DMDModel
from .dmd import fit_dmd as fit_dmd
from .metrics import rmse as rmse
from .metrics import rrmse as rrmse
from .snapshots import collect_snapshots as collect_snapshots
from .snapshots import first_order as first_order
from .snapshots import tracer_operator as tracer_operator
