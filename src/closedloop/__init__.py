"""closedloop: Lagrange's equations with multipliers for closed-loop multibody systems.

A companion library to Khang, Quyen and Mai Anh (2018), "Influence of initial
conditions on movement behaviors of the slide-crank mechanism" (the paper's own
English title). Equation numbers in docstrings are the paper's.
"""

__version__ = "0.1.0"

from .errors import (ClosedLoopError, ConvergenceError, InputError, IntegrationError,
                     SingularConfigurationError)
from .formulations import (Augmented, Baumgarte, ClosedForm, Formulation, Minimal, NullSpace, Orthogonal, Projected,
                           baumgarte_from_step, baumgarte_p2, formulation_from_name, project_state)
from .forces import SwitchedForce
from .kinematics import InitialState, consistent_initial_state
from .linalg import null_space_basis
from .model import DerivedModel, MultibodyModel, System, derive
from .simulation import SimulationResult, simulate

__all__ = [
    "Formulation", "Augmented", "Baumgarte", "Orthogonal", "Minimal", "baumgarte_from_step", "baumgarte_p2", "formulation_from_name",
    "MultibodyModel", "DerivedModel", "derive", "System", "SwitchedForce",
    "InitialState", "consistent_initial_state", "simulate", "SimulationResult",
    "NullSpace", "null_space_basis", "ClosedForm",
    "Projected", "project_state",
    "ClosedLoopError", "InputError", "ConvergenceError", "SingularConfigurationError", "IntegrationError",
]
