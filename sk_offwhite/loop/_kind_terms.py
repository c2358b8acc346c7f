r"""What a physicist would look for first, by the declared kind of each variable.

Besides the evidence of the user's dictionary (the projected gain of every term at the
declared fit), the loop reads with ``LoopSettings(kind_notes=True)``, for a pysindy
dictionary and on a fit of its own, the functions a physicist tries first for each
declared kind:

| kind | functions |
|---|---|
| velocity, rate | $\operatorname{sign}(v)$ (a Coulomb friction), $v\lvert v\rvert$ (a drag) |
| level | $\sqrt{\lvert h\rvert}$ (an outflow through an orifice) |
| an input that changes sign | $\lvert u\rvert$ (a loss in the size of an effort) |

and notes those that explain more than the dictionary's best term: a friction then shows
up as an odd function of the velocity rather than as the sign-blind $v^2$ of a polynomial
dictionary (the first-order gains seldom tell the sign from $v\lvert v\rvert$: both name
the velocity). Each function is unit-free: rescaling its variable rescales its column,
which the gains do not see. The functions inform the reader only: the hypotheses, the
candidates and the promoted terms stay the dictionary's, whose choices the functions'
columns would otherwise shift.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dictionaries._compiled import _xp
from ..effects._hidden import n_declared_states
from ..model._kinds import LEVEL_KINDS, VELOCITY_KINDS, physical_kinds

__all__ = ["with_kind_terms"]


def sign_of(x):
    """The sign of ``x``: a Coulomb friction's shape."""
    return _xp(x).sign(x)


def signed_square(x):
    """``x |x|``: a drag's shape."""
    return x * _xp(x).abs(x)


def root_of(x):
    """``sqrt(|x|)``: an orifice's outflow from a level."""
    return _xp(x).sqrt(_xp(x).abs(x))


def size_of(x):
    """``|x|``: a loss in the size of an effort."""
    return _xp(x).abs(x)


def sign_name(x: str) -> str:
    return f"sign({x})"


def signed_square_name(x: str) -> str:
    return f"{x}|{x}|"


def root_name(x: str) -> str:
    return f"sqrt|{x}|"


def size_name(x: str) -> str:
    return f"|{x}|"


def kind_groups(physics, u: np.ndarray) -> list[tuple[tuple, tuple, list[int]]]:
    """``(functions, names, columns of v = [x; u])`` of each kind's functions, for the
    declared states and inputs that have that kind (an input only where it changes
    sign: elsewhere $|u|$ is $\\pm u$, a column the dictionary holds)."""
    n_declared = n_declared_states(physics)
    kinds = physical_kinds(physics)
    states = kinds.states[:n_declared]
    velocities = [i for i, kind in enumerate(states) if kind in VELOCITY_KINDS]
    levels = [i for i, kind in enumerate(states) if kind in LEVEL_KINDS]
    u = np.asarray(u, float)
    signed = [n_declared + j for j in range(u.shape[1]) if u[:, j].min() < 0 < u[:, j].max()]
    groups = [
        ((sign_of, signed_square), (sign_name, signed_square_name), velocities),
        ((root_of,), (root_name,), levels),
        ((size_of,), (size_name,), signed),
    ]
    return [group for group in groups if group[2]]


def with_kind_terms(library, physics, u):
    """The evidence dictionary: ``library`` with the kind functions of ``physics``'
    variables appended after its own columns (`kind_groups`); ``None`` where ``library`` is
    no pysindy library, or where no variable has a kind with functions."""
    import pysindy as ps

    if not isinstance(library, ps.feature_library.base.BaseFeatureLibrary):
        return None
    groups = kind_groups(physics, u)
    if not groups:
        return None
    n_variables = n_declared_states(physics) + physics.n_inputs
    libraries = [library] + [
        ps.CustomLibrary(list(functions), list(names)) for functions, names, _ in groups
    ]
    inputs: Sequence[list[int]] = [list(range(n_variables))] + [c for *_, c in groups]
    return ps.GeneralizedLibrary(libraries, inputs_per_library=inputs)
