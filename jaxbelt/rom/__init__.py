"""Model order reduction on the belt model (model specification §5): snapshots, metrics, modal decomposition,
POD-Galerkin (as the source), the fully reduced POD step, exact DMD, DMD with control and
parametric DMD, and an a-posteriori error estimate (the error ROM of :mod:`jaxbelt.rom.error_estimate`);
each reduction behind one interface (:mod:`jaxbelt.rom.reduced_model`: ``fit`` and
``predict(z0, mu, n)``); :func:`reduce_and_compare` trains one and measures it against the full
model (``jaxbelt reduce``)."""

from .reduced_model import AbstractReducedModel as AbstractReducedModel
from .reduced_model import AbstractReduction as AbstractReduction
from .reduced_model import Prediction as Prediction
from .reduced_model import TrainingRuns as TrainingRuns
from .reduced_model import observation as observation
from .pod_step import ReducedPOD as ReducedPOD
from .dmd import DMD as DMD
from .dmdc import DMDc as DMDc
from .dmdc import ParametricDMD as ParametricDMD
from .dmd import DMDModel as DMDModel
from .dmd import fit_dmd as fit_dmd
from .dmd import stack_trajectories as stack_trajectories
from .dmdc import DMDcModel as DMDcModel
from .dmdc import ParametricDMDModel as ParametricDMDModel
from .dmdc import belt_inputs as belt_inputs
from .dmdc import fit_dmdc as fit_dmdc
from .dmdc import fit_parametric_dmd as fit_parametric_dmd
from .dmdc import interpolation_weights as interpolation_weights
from .dmdc import stack_controlled as stack_controlled
from .calibration import Calibration as Calibration
from .error_estimate import BasisTrajectory as BasisTrajectory
from .error_estimate import ErrorEstimate as ErrorEstimate
from .error_estimate import ErrorRomOptions as ErrorRomOptions
from .calibration import calibrate as calibrate
from .dmd import dmd_coordinates as dmd_coordinates
from .error_estimate import error_rom as error_rom
from .error_estimate import warm_error_rom as warm_error_rom
from .error_estimate import residual_indicator as residual_indicator
from .calibration import safety_factor as safety_factor
from .calibration import snapshot_count as snapshot_count
from .metrics import rmse as rmse
from .metrics import rrmse as rrmse
from .modal import fit_modal as fit_modal
from .modal import forcing_order as forcing_order
from .modal import modal_basis as modal_basis
from .pipeline import reduce_and_compare as reduce_and_compare
from .config import ReduceConfig as ReduceConfig
from .comparison import ReductionResult as ReductionResult
from .pod import PODGalerkin as PODGalerkin
from .pod import choose_modes as choose_modes
from .pod import fit_pod as fit_pod
from .pod import pod_basis as pod_basis
from .pod_step import ReducedStep as ReducedStep
from .pod_step import ReducedTrajectory as ReducedTrajectory
from .pod_step import fit_reduced_pod as fit_reduced_pod
from .pod_step import fit_reduced_pod_ranks as fit_reduced_pod_ranks
from .pod_step import parameters as parameters
from .pod_step import parameters_outside_training as parameters_outside_training
from .pod_step import with_parameters as with_parameters
from .snapshots import collect_first_order as collect_first_order
from .snapshots import collect_snapshots as collect_snapshots
from .snapshots import first_order as first_order
from .snapshots import state_to_z as state_to_z
from .snapshots import tracer_operator as tracer_operator
from .snapshots import z_to_state as z_to_state
from .sizing import BoxTraining as BoxTraining
from .sizing import SizingLevel as SizingLevel
from .sizing import train_over_box as train_over_box
from .training import axial_design as axial_design
from .training import box_from_distribution as box_from_distribution
from .training import position_in_box as position_in_box
