"""sk_offwhite: physics-based multi-step system identification with sparse corrections."""

from ._backend import enable_fused_loops
from ._basis import RidgeBasis, compile_basis
from ._cache import enable_compilation_cache, release_compiled_programs, release_package_programs
from ._delay import InputDelay
from ._effects import (
    AdditiveEffect,
    Backlash,
    Bias,
    DeadZone,
    DictionaryTerm,
    DifferenceDeadZone,
    Effect,
    Friction,
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
    SensorStep,
    Stiffness,
    Switched,
    augment,
    switched,
)
from ._estimator import (
    DivergenceWarning,
    GreyBoxSparseRegressor,
    RunawayParameterWarning,
    expected_failed_checks,
)
from ._path import GammaPath, fit_gamma_path, gamma_grid
from ._physics import Parameter, PhysicsModel
from ._radial import RadialBasis
from ._sensor_lag import SensorLag
from ._splitters import SequenceSplit, SequenceWarning

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
    "InputDelay",
    "InputLag",
    "InputSaturation",
    "Leak",
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
