"""sk_offwhite: physics-based multi-step system identification with sparse corrections."""

from ._estimator import GreyBoxSparseRegressor
from ._estimator_cv import GreyBoxSparseRegressorCV
from ._path import GammaPath, fit_gamma_path, gamma_grid
from ._sklearn_glue import expected_failed_checks
from ._warnings import DivergenceWarning, RunawayParameterWarning
from .dictionaries import RadialBasis, RidgeBasis, compile_basis
from .effects import (
    AdditiveEffect,
    Backlash,
    Bias,
    DeadZone,
    DictionaryTerm,
    DifferenceDeadZone,
    Effect,
    Friction,
    InputDelay,
    InputLag,
    InputSaturation,
    Leak,
    OutputOffset,
    OutputSaturation,
    Overflow,
    PowerDrag,
    PowerLoss,
    PowerStiffness,
    QuadraticDrag,
    RelaxedLaw,
    SensorCalibration,
    SensorLag,
    SensorStep,
    Stiffness,
    Switched,
    augment,
    switched,
)
from .model import Parameter, PhysicsModel
from .model_selection import SequenceSplit, SequenceWarning
from .runtime import (
    enable_compilation_cache,
    enable_fused_loops,
    release_compiled_programs,
    release_package_programs,
)
from .solvers import LevenbergMarquardt, Optax

__all__ = [
    "AdditiveEffect",
    "Backlash",
    "Bias",
    "DeadZone",
    "DifferenceDeadZone",
    "DictionaryTerm",
    "DivergenceWarning",
    "Effect",
    "Friction",
    "GammaPath",
    "GreyBoxSparseRegressor",
    "GreyBoxSparseRegressorCV",
    "InputDelay",
    "InputLag",
    "InputSaturation",
    "LevenbergMarquardt",
    "Leak",
    "Optax",
    "OutputOffset",
    "OutputSaturation",
    "Overflow",
    "Parameter",
    "PhysicsModel",
    "PowerDrag",
    "PowerLoss",
    "PowerStiffness",
    "QuadraticDrag",
    "RadialBasis",
    "RelaxedLaw",
    "RidgeBasis",
    "RunawayParameterWarning",
    "SensorCalibration",
    "SensorLag",
    "SensorStep",
    "SequenceSplit",
    "SequenceWarning",
    "Stiffness",
    "Switched",
    "augment",
    "compile_basis",
    "enable_compilation_cache",
    "enable_fused_loops",
    "release_compiled_programs",
    "release_package_programs",
    "expected_failed_checks",
    "fit_gamma_path",
    "gamma_grid",
    "switched",
]
__version__ = "0.1.0.dev0"
