"""Named physical effects that [`augment`][sk_offwhite.augment] adds to a declared physics.

An effect is the explicit, parametrised form of something a residual analysis can point at:
an overflow, a saturation, a friction, a lag. One module per family: limits
(`Overflow`, `OutputSaturation`, `InputSaturation`, `DeadZone`, `DifferenceDeadZone`),
terms (`Bias`, `Leak`, `PowerLoss`), mechanics (`Friction`, `Stiffness`, `PowerStiffness`,
`PositionForce`, `QuadraticDrag`, `PowerDrag`), a transmission's friction
(`TransmissionFriction`), play (`Backlash`), lags and delay (`InputLag`, `SensorLag`,
`InputDelay`), the input between samples (`InputHold`), sensors (`OutputOffset`,
`SensorCalibration`, `SensorStep`), laws (`RelaxedLaw`, `DictionaryTerm`) and a declared
constant that varies (`VaryingParameter`).
Every name is also importable from `sk_offwhite`.
"""

from ._augment import augment
from ._base import (
    AdditiveEffect,
    Effect,
    InputEffect,
    LawEffect,
    OutputEffect,
    StateEffect,
)
from ._hidden import FollowsOutput, HiddenStates
from ._hold import InputHold
from ._lags import FirstOrderLag, InputDelay, InputLag, SensorLag
from ._laws import DictionaryTerm, RelaxedLaw
from ._limits import DeadZone, DifferenceDeadZone, InputSaturation, OutputSaturation, Overflow
from ._mechanics import (
    DirectionalDamping,
    Friction,
    PositionForce,
    PowerDrag,
    PowerStiffness,
    QuadraticDrag,
    Stiffness,
)
from ._play import Backlash
from ._sensors import OutputOffset, SensorCalibration, SensorStep
from ._switched import Switched, SwitchedTerm, switched
from ._terms import Bias, Leak, PowerLoss
from ._transmission import TransmissionFriction
from ._varying import VaryingParameter

__all__ = [
    "AdditiveEffect",
    "Backlash",
    "Bias",
    "DeadZone",
    "DictionaryTerm",
    "DifferenceDeadZone",
    "DirectionalDamping",
    "Effect",
    "FirstOrderLag",
    "FollowsOutput",
    "Friction",
    "HiddenStates",
    "InputDelay",
    "InputEffect",
    "InputHold",
    "InputLag",
    "InputSaturation",
    "LawEffect",
    "Leak",
    "OutputEffect",
    "OutputOffset",
    "OutputSaturation",
    "Overflow",
    "PositionForce",
    "PowerDrag",
    "PowerLoss",
    "PowerStiffness",
    "QuadraticDrag",
    "RelaxedLaw",
    "SensorCalibration",
    "SensorLag",
    "SensorStep",
    "StateEffect",
    "Stiffness",
    "Switched",
    "SwitchedTerm",
    "TransmissionFriction",
    "VaryingParameter",
    "augment",
    "switched",
]
