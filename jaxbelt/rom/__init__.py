"""Model order reduction on the belt model (MODEL.md §5): snapshots, metrics, exact DMD, POD-Galerkin and modal decomposition so far."""

from .dmd import DMDModel as DMDModel
from .dmd import fit_dmd as fit_dmd
from .metrics import rmse as rmse
from .metrics import rrmse as rrmse
from .snapshots import collect_snapshots as collect_snapshots
from .snapshots import first_order as first_order
from .snapshots import tracer_operator as tracer_operator
from .pod import PODGalerkin as PODGalerkin
from .pod import choose_modes as choose_modes
from .pod import fit_pod as fit_pod
from .pod import pod_basis as pod_basis
from .modal import forcing_order as forcing_order
from .modal import modal_basis as modal_basis
