r"""Changes of the declared law: a constant freed, a dictionary term promoted into it."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._physics import Parameter, PhysicsModel
from ._base import AdditiveEffect, LawEffect

__all__ = ["DictionaryTerm", "RelaxedLaw", "relaxations"]


class RelaxedLaw(LawEffect):
    r"""A constant of a declared law freed: the fixed, relaxable parameter ``parameter``
    (see [`Parameter`][sk_offwhite.Parameter]) becomes a fitted one, started at its declared
    value and kept within its bounds.

    The step and output map are unchanged; only the parameter's status changes, so a model
    with the relaxation shares the declared model's compiled programs. Torricelli's
    outflow $k\sqrt{x} = k x^{1/2}$ written with a relaxable exponent ``a`` becomes
    $k x^{a}$, with $a$ fitted.
    """

    def __init__(self, parameter: str, value: float, bounds=(None, None), *, name=None):
        self.parameter, self.value = str(parameter), float(value)
        self.bounds = tuple(bounds)
        self.name = name or f"relax_{parameter}"

    def parameters(self) -> dict[str, Parameter]:
        return {self.parameter: Parameter(self.value, self.bounds)}

    def describe(self, state_names, output_names, values=None) -> str:
        fitted = (values or {}).get(self.parameter)
        now = "" if fitted is None else f", fitted at {fitted:.3g}"
        return f"the declared constant {self.parameter} freed (was {self.value:g}){now}"


def relaxations(physics: PhysicsModel) -> list[RelaxedLaw]:
    """One [`RelaxedLaw`][sk_offwhite.RelaxedLaw] per fixed, relaxable parameter of ``physics``."""
    return [
        RelaxedLaw(name, spec.value, spec.bounds)
        for name, spec in physics.parameters.items()
        if spec.fixed and spec.relaxable
    ]


class DictionaryTerm(AdditiveEffect):
    r"""A term of the dictionary promoted into the physics: $g = c\,\varphi_j(x, u)$.

    This is how an effect outside the catalogue enters the model: a term of the sparse
    correction that survives becomes a named parameter ``{name}_coefficient`` ($c$)
    of the physics, with the physics' time units (see
    [`AdditiveEffect`][sk_offwhite.AdditiveEffect]). ``library`` is the pysindy library,
    ``input_features`` the names of ``[x; u]`` and ``column`` the index of $\varphi_j$ among its
    features.
    """

    def __init__(
        self, state: int, library, input_features, column: int, *, coefficient=0.0, name="term"
    ):
        self.state, self.library, self.column = int(state), library, int(column)
        self.input_features, self.coefficient = tuple(input_features), float(coefficient)
        self.name = name

    @property
    def feature(self) -> str:
        r"""Name of $\varphi_j$."""
        return self._compiled().names[self.column]

    def _compiled(self):
        from .._basis import compile_basis

        with jax.ensure_compile_time_eval():  # compiled eagerly, also when called in a trace
            return compile_basis(self.library, self.input_features, 1)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_coefficient": Parameter(self.coefficient)}

    def term(self, x, u, theta):
        basis = self._compiled()
        phi = basis.evaluate(basis.init_params, jnp.concatenate([x, jnp.atleast_1d(u)]))
        return theta[f"{self.name}_coefficient"] * phi[0, self.column]

    def basis(self, x, u):
        from .._basis import evaluate_matrix

        basis = self._compiled()
        with jax.enable_x64(True):
            phi = evaluate_matrix(basis, basis.init_params, np.hstack([x, u]))
        return np.asarray(phi)[:, 0, self.column]

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the {state_names[self.state]} equation gains a term in {self.feature}"

    def __repr__(self) -> str:
        return (
            f"DictionaryTerm(state={self.state}, feature={self.feature!r}, "
            f"coefficient={self.coefficient!r}, name={self.name!r})"
        )

    def _key(self):
        from .._basis import _library_key

        library = _library_key(self.library, self.input_features, 1) or id(self.library)
        return (DictionaryTerm, self.state, library, self.column, self.coefficient, self.name)
