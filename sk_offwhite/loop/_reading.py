r"""Reading a fitted correction back into the declared physics: which constant varies, and how.

When a declared constant $\theta_j$ is in truth a law $\theta_j\,g(v)$ of a state or input
$v$, the correction $\delta_k$ of "declared physics + sparse $\delta$" is, along the
trajectory, the change of the declared step that substituting the law makes:

$$
\delta_k \approx f\big(x_k, u_k;\ \theta \text{ with } \theta_j \to \theta_j\,g(v_k)\big)
- f(x_k, u_k; \theta)
\approx \frac{\partial f}{\partial \theta_j}(x_k, u_k)\,\theta_j\,\big(g(v_k) - 1\big).
$$

`read_varying_parameters` tests this for every declared parameter, every state and input
and four closed forms of $g$,

$$
\text{polynomial } A\big(1 + \beta\,(v/\nu)^2\big), \quad
\text{rational } \frac{A}{1 + (v/x_s)^2}, \quad
\text{power } A\,|v/\nu|^p, \quad
\text{exponential } A\,e^{\lambda (v - \mu)/\sigma},
$$

with $\nu$ the RMS of $v$, $\mu$ and $\sigma$ its mean and standard deviation: every scale
is searched in units of the variable's spread, so that rescaling a variable rescales the
constants read and changes nothing else. The amplitude $A$ lets the correction re-estimate
$\theta_j$ itself, and every other free parameter may change by a constant too (to first
order: their directions $\theta_i\,\partial f/\partial\theta_i$ are projected out of the
residual). A fitted parameter and a term of $\delta$ that duplicates it share what the data
determine, so the declared part of a law can sit on either side.

Each form is fitted in two stages. On a grid of its scale (or exponent), the amplitude
comes from the first order by least squares (the polynomial's two coefficients from the
first order alone), and the exact substitution scores the grid point after one
Gauss-Newton step on the amplitude; Levenberg-Marquardt then refines the best point on the
exact substitution. For a model built by `PhysicsModel.from_ode` the law is substituted
inside the right-hand side, at every stage of the integrator, which is what a varying
coefficient of the ODE is; for a discrete step, at the sample. The first order alone
cannot tell a rational law of a coefficient that divides the rate (an inductance) from a
polynomial one that falls; the exact substitution can. The sensitivities
$\theta_j\,\partial f/\partial\theta_j$ are forward-mode derivatives (`jax.jacfwd`) of the
substituted step in the amplitude at $g = 1$, at every sample (`jax.vmap`): one compiled
program serves every family, parameter and variable of a declared step, and is kept for
the next call on that step.

A reading's explained fraction is $1 - \sum_k\|W(\delta_k - \hat\delta_k)\|^2 /
\sum_k\|W\delta_k\|^2$, with $W$ dividing each state's correction by that state's standard
deviation along the trajectory (unit-free); a state whose correction is zero throughout
(one left out by `delta_states`) is left out.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..model._kinds import POSITION_KINDS
from ..model._physics import DiscretizedStep, PhysicsModel

__all__ = ["FAMILIES", "MIN_EXPLAINED", "VaryingReading", "read_varying_parameters"]

FAMILIES = ("polynomial", "rational", "power", "exponential")
"""The closed forms of $g$ that are read."""

MIN_EXPLAINED = 0.9
r"""Fraction a reading must explain to count, of the correction's energy and of the part
of it that no constant change of the declared parameters absorbs.

One varying coefficient is one effect: a reading that leaves more than a tenth of $\delta$
unexplained says that $\delta$ holds something else besides, or a law outside the families,
and the ranking of the families is then no longer evidence (over one record's range two
monotone forms can differ by a few percent of the energy, never by a tenth when one of them
is the law). The second share keeps out a "law" that hardly varies over the record: a
constant error of a parameter (which a fitted $\delta$ often carries, the parameter having
moved while $\delta$ took over its term) is explained by any form, and only what is left
once the constants are re-estimated tells the forms apart.
"""

_LAW = "__varying_law__"
_TINY = 1e-9
_GRID_SIZE = 25
_GRIDS = {
    "rational": np.linspace(np.log(0.05), np.log(20.0), _GRID_SIZE),
    "power": np.linspace(-4.0, 4.0, _GRID_SIZE),
    "exponential": np.linspace(-4.0, 4.0, _GRID_SIZE),
}
_STIFFNESS_COSINE = 0.9
_LM_ITERATIONS = 50


@dataclass(frozen=True)
class VaryingReading:
    r"""A declared constant read as a law of one variable: $\theta_j(v) = \text{value}\cdot g(v)$.

    Attributes
    ----------
    parameter, variable : str
        The declared parameter $\theta_j$ and the state or input $v$ it depends on.
    family : str
        One of `"polynomial"`, `"rational"`, `"power"`, `"exponential"`.
    value : float
        The law's leading coefficient: $\theta_j$ at $v = 0$ for the polynomial, rational and
        exponential forms; the declared value for the power law, whose scale then carries
        the amplitude.
    constants : dict
        `x_s` (all families) and `p` (power): $1 \pm (v/x_s)^2$, $1/(1 + (v/x_s)^2)$,
        $|v/x_s|^p$, $e^{v/x_s}$.
    sign : str
        `"hardening"` or `"softening"` for a stiffness-like term (the variable a position or
        angle the parameter multiplies), else `"rising"` or `"falling"`: the coefficient
        grows or shrinks with $|v|$ (with $v$ for the exponential form).
    explained : float
        Fraction of the correction's (unit-free) energy the law explains.
    constant_explained : float
        The same for constant changes of the parameters alone ($\theta_j$ and the other
        free parameters); `(explained - constant_explained) / (1 - constant_explained)` is
        the share of the rest that the variation explains.
    formula, sentence : str
        The law with its numbers, and one sentence to print.
    """

    parameter: str
    variable: str
    family: str
    value: float
    constants: dict
    sign: str
    explained: float
    constant_explained: float
    formula: str
    sentence: str

    def law(self, v) -> np.ndarray:
        r"""$\theta_j(v)$ at the values `v` of the variable."""
        rising = self.sign in ("rising", "hardening")
        factor = _physical_factor(self.family, np.asarray(v, float), self.constants, rising)
        return self.value * factor


def _physical_factor(family: str, v: np.ndarray, constants: Mapping, rising: bool) -> np.ndarray:
    """$g(v)$ of a reading's constants (numpy); `rising` signs the polynomial."""
    scaled = v / constants["x_s"]
    if family == "polynomial":
        return 1.0 + (1.0 if rising else -1.0) * scaled**2
    if family == "rational":
        return 1.0 / (1.0 + scaled**2)
    if family == "power":
        return np.abs(scaled) ** constants["p"]
    return np.exp(scaled)


# --------------------------------------------------------------------------------------
# The substituted step
# --------------------------------------------------------------------------------------


def _forms(s, v, norm, xp) -> list:
    r"""$h(v)$ of every family at the shape constant `s` (`xp`: `numpy` or `jax.numpy`)."""
    scaled = v / norm[0]
    return [
        1.0 + s * scaled**2,
        1.0 / (1.0 + xp.exp(-2.0 * s) * scaled**2),
        xp.maximum(xp.abs(scaled), _TINY) ** s,
        xp.exp(s * (v - norm[1]) / norm[2]),
    ]


def _shape(family, phi, v, norm):
    r"""$A\,h(v)$ of the family numbered `family` (its place in `FAMILIES`, traced under
    `jit`) at constants `phi = (A, s)`; `norm = (rms, mean, std)` of $v$. The forms not
    chosen are computed and not used: their non-finite values stay out of the chosen one's
    value and of its derivatives, which forward mode takes through the selection."""
    forms = _forms(phi[1], v, norm, jnp)
    return phi[0] * jnp.select([family == i for i in range(len(forms))], forms)


class _Substituted:
    """`function(x, u, theta)` with the parameter selected by `theta[_LAW]` multiplied by the
    law's factor at the current state and input."""

    def __init__(self, function: Callable, names: tuple[str, ...]):
        self.function, self.names = function, names

    def __call__(self, x, u, theta):
        law = theta[_LAW]
        v = jnp.concatenate([jnp.atleast_1d(x), jnp.atleast_1d(u)]) @ law["variable"]
        factor = _shape(law["family"], law["phi"], v, law["norm"])
        scaled = {
            name: theta[name] * (1.0 + law["parameter"][i] * (factor - 1.0))
            for i, name in enumerate(self.names)
        }
        return self.function(x, u, scaled)


def _substituted_step(step: Callable, names: tuple[str, ...]) -> Callable:
    """The declared `step` with the law substituted: inside the right-hand side, at every
    stage, for a model of `from_ode`; at the sample otherwise."""
    if isinstance(step, DiscretizedStep):
        return step.with_rhs(_Substituted(step.rhs, names))
    return _Substituted(step, names)


# --------------------------------------------------------------------------------------
# The compiled program, one per declared step
# --------------------------------------------------------------------------------------


def _with_phi(law: dict, phi) -> dict:
    return {**law, "phi": phi}


def _residual_function(step: Callable) -> Callable:
    r"""`residual(data, law)`: $W\big(\delta - (f_{substituted} - f)\big)$, flattened, with
    `data` the arrays of a `_Problem` (arguments, not constants, of the compiled program)."""
    substituted = jax.vmap(step, in_axes=(0, 0, None))

    def residual(data: dict, law: dict):
        change = substituted(data["states"], data["inputs"], {**data["theta"], _LAW: law})
        return ((data["correction"] - (change - data["declared_next"])) * data["weights"]).ravel()

    return residual


def _program(step: Callable, names: tuple[str, ...]) -> Callable:
    """`(data, law) -> (residual, Jacobian in phi)`, compiled: the only program a reading
    runs, for every family, parameter and variable (all of them arguments)."""
    residual = _residual_function(_substituted_step(step, names))

    def residual_and_jacobian(data, law):
        in_phi = lambda p: residual(data, _with_phi(law, p))  # noqa: E731
        return in_phi(law["phi"]), jax.jacfwd(in_phi)(law["phi"])

    return jax.jit(residual_and_jacobian)


_cached_program = functools.lru_cache(maxsize=16)(_program)


def _compiled(step: Callable, names: tuple[str, ...]) -> Callable:
    """The program of `step`, kept for the next call on the same step (compiling it takes
    longer than running it), or built anew for a step that cannot be hashed."""
    try:
        hash(step)
    except TypeError:
        return _program(step, names)
    return _cached_program(step, names)


def _evaluate(program: Callable, data: dict, law: dict) -> tuple[np.ndarray, np.ndarray]:
    return tuple(np.asarray(a) for a in program(data, law))


# --------------------------------------------------------------------------------------
# The problem: data, weights, sensitivities
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Problem:
    r"""The data of one reading (numpy): samples, declared parameters, the correction, the
    state weights $W$ and the declared next states (`data`), each parameter's first-order
    direction $\theta_j\,\partial f/\partial\theta_j$, the correction's weighted energy,
    the compiled program and the names of the free parameters."""

    data: dict
    directions: dict
    energy: float
    program: Callable
    free: tuple[str, ...]


def _weights(states: np.ndarray, correction: np.ndarray) -> np.ndarray:
    """One over each state's standard deviation (over its correction's RMS for a state that
    does not move), and 0 for a state whose correction is zero throughout: one the
    correction was not given (`delta_states`), whose equation then says nothing."""
    spread = states.std(axis=0)
    size = np.sqrt(np.mean(correction**2, axis=0))
    scale = np.where(spread > 0, spread, size)
    return np.divide(1.0, scale, out=np.zeros_like(scale), where=(scale > 0) & (size > 0))


def _checked_arrays(physics: PhysicsModel, states, inputs, correction) -> tuple:
    """The three records as finite float arrays of `(n, n_x)`, `(n, n_u)`, `(n, n_x)`."""
    n = len(states)
    arrays = tuple(np.asarray(a, float).reshape(n, -1) for a in (states, inputs, correction))
    expected = (physics.n_states, physics.n_inputs, physics.n_states)
    widths = tuple(a.shape[1] for a in arrays)
    if widths != expected:
        raise ValueError(
            f"states, inputs and correction must have {expected} columns, got {widths}."
        )
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise ValueError("states, inputs and correction must be finite.")
    return arrays


def _checked_theta(physics: PhysicsModel, theta: Mapping) -> dict:
    """`theta` as float64 scalars, one for every declared parameter."""
    missing = sorted(set(physics.parameter_names) - set(theta))
    if missing:
        raise KeyError(f"theta lacks the parameters {missing}.")
    return {name: np.float64(theta[name]) for name in physics.parameter_names}


def _neutral_law(n_parameters: int, n_variables: int, parameter: int, variable: int) -> dict:
    r"""The law $g = 1$ (the polynomial at $A = 1$, $\beta = 0$) on one parameter and one
    variable, its normalisation still unset."""
    return {
        "parameter": np.eye(n_parameters)[parameter],
        "variable": np.eye(n_variables)[variable],
        "norm": np.ones(3),
        "phi": np.array([1.0, 0.0]),
        "family": np.int32(0),
    }


def _sensitivities(program: Callable, data: dict) -> tuple[np.ndarray, dict]:
    r"""The declared next states and each $\theta_j\,\partial f/\partial\theta_j$, read off
    the program at the neutral law: with no correction, no declared step and unit weights,
    its residual is $-f$ and its Jacobian in the amplitude $-\theta_j\,\partial f/\partial
    \theta_j$ (forward mode, every sample)."""
    shape = data["correction"].shape
    bare = {**data, "correction": np.zeros(shape), "declared_next": np.zeros(shape),
            "weights": np.ones(shape[1])}  # fmt: skip
    n_variables = data["variables"].shape[1]
    directions, declared = {}, None
    for j, name in enumerate(data["theta"]):
        law = _neutral_law(len(data["theta"]), n_variables, j, 0)
        residual, jacobian = _evaluate(program, bare, law)
        declared = -residual.reshape(shape)
        directions[name] = -jacobian[:, 0].reshape(shape)
    return declared, directions


def _problem(physics: PhysicsModel, theta: Mapping, states, inputs, correction) -> _Problem:
    states, inputs, correction = _checked_arrays(physics, states, inputs, correction)
    data = {
        "states": states,
        "inputs": inputs,
        "variables": np.concatenate([states, inputs], axis=1),
        "theta": _checked_theta(physics, theta),
        "weights": _weights(states, correction),
        "correction": correction,
    }
    program = _compiled(physics.step, physics.parameter_names)
    declared, directions = _sensitivities(program, data)
    energy = float(np.sum((correction * data["weights"]) ** 2))
    free = physics.free_parameter_names
    return _Problem({**data, "declared_next": declared}, directions, energy, program, free)


# --------------------------------------------------------------------------------------
# One candidate: a start for each family and its refinement
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Candidate:
    r"""One parameter and one variable: names, the variable's kind, the law's selectors
    (`law`, its family and constants `phi` set per family) and `others`, an orthonormal
    basis of the weighted first-order directions of the other free parameters: what a
    constant re-adjustment of those parameters can absorb, projected out of every residual."""

    parameter: str
    variable: str
    kind: str
    law: dict
    others: np.ndarray


def _others_basis(problem: _Problem, parameter: str) -> np.ndarray:
    """Orthonormal columns spanning `W a_i` of the free parameters other than `parameter`."""
    size = problem.data["correction"].size
    columns = [np.ravel(problem.directions[name] * problem.data["weights"])
               for name in problem.free if name != parameter]  # fmt: skip
    if not columns:
        return np.zeros((size, 0))
    left, singular, _ = np.linalg.svd(np.stack(columns, axis=1), full_matrices=False)
    return left[:, singular > 1e-10 * max(singular.max(), _TINY)]


def _candidate(problem: _Problem, parameter: int, variable: int, names, kind) -> _Candidate:
    values = problem.data["variables"][:, variable]
    n_variables = problem.data["variables"].shape[1]
    law = _neutral_law(len(problem.data["theta"]), n_variables, parameter, variable)
    law["norm"] = np.array([np.sqrt(np.mean(values**2)), values.mean(), values.std()])
    return _Candidate(names[0], names[1], kind, law, _others_basis(problem, names[0]))


def _project(basis: np.ndarray, a: np.ndarray) -> np.ndarray:
    """`a` (a vector or columns) without its part in the span of `basis`."""
    return a - basis @ (basis.T @ a)


def _projected(problem: _Problem, candidate: _Candidate, phi) -> tuple:
    """Residual and Jacobian at `phi`, the other parameters' re-adjustment projected out."""
    law = _with_phi(candidate.law, phi)
    r, jac = _evaluate(problem.program, problem.data, law)
    with np.errstate(all="ignore"):  # a trial law may overflow: its cost is then not finite
        return _project(candidate.others, r), _project(candidate.others, jac)


def _first_order_amplitude(problem: _Problem, candidate: _Candidate, s: float) -> float:
    r"""$A$ of $\delta \approx a\,(A h - 1)$ by least squares, $a$ the first-order direction
    and $h$ the family's shape at `s` (the others' re-adjustment projected out)."""
    data, law = problem.data, candidate.law
    direction = problem.directions[candidate.parameter]
    shape = _forms(s, data["variables"] @ law["variable"], law["norm"], np)[int(law["family"])]
    shaped = _project(candidate.others, np.ravel(direction * data["weights"] * shape[:, None]))
    target = np.ravel((data["correction"] + direction) * data["weights"])
    return float(shaped @ target / (shaped @ shaped + _TINY))


def _grid_point(problem: _Problem, candidate: _Candidate, s: float) -> tuple:
    """`(phi, cost)` at the shape constant `s`: the first-order amplitude, then the exact
    cost that one Gauss-Newton step on the amplitude reaches (as its linearisation
    predicts)."""
    with np.errstate(all="ignore"):
        phi = np.array([_first_order_amplitude(problem, candidate, s), s])
    if not np.all(np.isfinite(phi)):
        return phi, np.inf
    r, jac = _projected(problem, candidate, phi)
    slope = jac[:, 0]
    with np.errstate(all="ignore"):
        change = -(slope @ r) / (slope @ slope + _TINY)
        return phi + np.array([change, 0.0]), float(r @ r + change * (slope @ r))


def _best_of_grid(problem: _Problem, candidate: _Candidate, values: np.ndarray) -> np.ndarray:
    """The best `phi = (A, s)` over the grid `values` of `s` (non-finite costs never best)."""
    found = [_grid_point(problem, candidate, s) for s in values]
    costs = np.array([cost for _, cost in found])
    costs = np.where(np.isfinite(costs), costs, np.inf)
    return found[int(np.argmin(costs))][0]


def _polynomial_start(problem: _Problem, candidate: _Candidate) -> np.ndarray:
    r"""$(A, \beta)$ of the polynomial by linear least squares on the first order,
    $\delta \approx a\,(A - 1) + a\,A\beta\,(v/\nu)^2$."""
    data, law = problem.data, candidate.law
    squared = ((data["variables"] @ law["variable"]) / law["norm"][0]) ** 2
    weighted = problem.directions[candidate.parameter] * data["weights"]
    columns = np.stack([np.ravel(weighted), np.ravel(weighted * squared[:, None])], axis=1)
    target = np.ravel(data["correction"] * data["weights"])
    projected = _project(candidate.others, columns)
    (offset, slope), *_ = np.linalg.lstsq(projected, target, rcond=None)
    amplitude = 1.0 + offset
    return np.array([amplitude, slope / amplitude if abs(amplitude) > _TINY else 0.0])


def _levenberg_marquardt(problem, candidate, phi, free: slice = slice(None)) -> tuple:
    """Refine the entries `free` of `phi = (A, s)` on the exact residual, the others held;
    `(phi, cost)`."""
    phi = np.asarray(phi, float)
    r, jac = _projected(problem, candidate, phi)
    cost, damping = float(r @ r), 1e-3
    if not np.isfinite(cost):
        return phi, np.inf
    for _ in range(_LM_ITERATIONS):
        step = np.zeros_like(phi)
        step[free] = _damped_step(jac[:, free], r, damping)
        r_new, jac_new = _projected(problem, candidate, phi + step)
        cost_new = float(r_new @ r_new)
        if not (np.isfinite(cost_new) and cost_new < cost):
            damping *= 4.0
            continue
        done = cost - cost_new <= 1e-12 * cost
        phi, r, jac, cost, damping = phi + step, r_new, jac_new, cost_new, damping / 3.0
        if done:
            break
    return phi, cost


def _damped_step(jac: np.ndarray, r: np.ndarray, damping: float) -> np.ndarray:
    r"""$-(J^TJ + \mu\,\mathrm{diag}(J^TJ))^{-1}J^Tr$ (a tiny floor keeps it regular)."""
    normal = jac.T @ jac
    regular = normal + damping * np.diag(np.diag(normal) + _TINY)
    if not np.all(np.isfinite(regular)):
        return np.full(len(normal), np.nan)
    return np.linalg.lstsq(regular, -jac.T @ r, rcond=None)[0]


def _with_family(candidate: _Candidate, family: str) -> _Candidate:
    law = {**candidate.law, "family": np.int32(FAMILIES.index(family))}
    return dataclasses.replace(candidate, law=law)


def _fitted_constants(problem: _Problem, candidate: _Candidate, family: str) -> tuple:
    """`(phi, cost)` of `family` for one candidate: a start, then the refinement."""
    candidate = _with_family(candidate, family)
    if family == "polynomial":
        start = _polynomial_start(problem, candidate)
    else:
        start = _best_of_grid(problem, candidate, _GRIDS[family])
    return _levenberg_marquardt(problem, candidate, start)


def _constant_explained(problem: _Problem, candidate: _Candidate) -> float:
    r"""What constant changes of the parameters alone explain (the polynomial at
    $\beta = 0$, its amplitude refined, the others re-adjusted)."""
    candidate = _with_family(candidate, "polynomial")
    _, cost = _levenberg_marquardt(problem, candidate, np.array([1.0, 0.0]), free=slice(0, 1))
    return 1.0 - cost / problem.energy


# --------------------------------------------------------------------------------------
# From fitted constants to a reading
# --------------------------------------------------------------------------------------


def _physical_constants(family: str, phi: np.ndarray, theta_j: float, norm) -> tuple | None:
    r"""`(value, constants)` of the law $\theta_j A\,h(v)$ in the variable's units, or `None`
    where it is no law of $\theta_j$: an amplitude $A \le 0$ turns the parameter's term
    around, and a form without a finite scale is a constant."""
    amplitude, s = np.float64(phi[0]), np.float64(phi[1])
    rms, mean, std = (np.float64(a) for a in norm)
    if not amplitude > 0:
        return None
    with np.errstate(all="ignore"):
        value, constants = _in_units(family, amplitude, s, theta_j, (rms, mean, std))
    finite = np.isfinite(value) and all(np.isfinite(c) and c != 0 for c in constants.values())
    return (float(value), {k: float(c) for k, c in constants.items()}) if finite else None


def _in_units(family: str, amplitude, s, theta_j: float, norm) -> tuple:
    """The law's coefficient and constants from `(A, s)` and the variable's `norm`."""
    rms, mean, std = norm
    if family == "polynomial":
        return theta_j * amplitude, {"x_s": rms / np.sqrt(abs(s)), "sign": np.sign(s)}
    if family == "rational":
        return theta_j * amplitude, {"x_s": rms * np.exp(s)}
    if family == "power":
        return theta_j, {"x_s": rms * amplitude ** (-1.0 / s), "p": s}
    return theta_j * amplitude * np.exp(-s * mean / std), {"x_s": std / s}


def _rising(family: str, constants: Mapping) -> bool:
    """Whether the law grows with $|v|$ (with $v$ for the exponential)."""
    if family == "polynomial":
        return constants["sign"] > 0
    if family == "power":
        return constants["p"] > 0
    return family == "exponential" and constants["x_s"] > 0


def _stiffness_like(problem: _Problem, candidate: _Candidate) -> bool:
    """A position or angle to which the parameter's first-order term is proportional."""
    if candidate.kind not in POSITION_KINDS:
        return False
    direction = problem.directions[candidate.parameter] * problem.data["weights"]
    row = direction[:, int(np.argmax(np.sum(direction**2, axis=0)))]
    values = problem.data["variables"] @ candidate.law["variable"]
    denominator = np.linalg.norm(row) * np.linalg.norm(values)
    return bool(denominator > 0 and abs(row @ values) / denominator >= _STIFFNESS_COSINE)


def _sign_word(rising: bool, stiffness: bool) -> str:
    if stiffness:
        return "hardening" if rising else "softening"
    return "rising" if rising else "falling"


def _number(value: float) -> str:
    return f"{value:.3g}"


def _formula(parameter: str, variable: str, family: str, value: float, constants) -> str:
    """The law with its numbers, as `k(q) = 20·(1 + (q/0.04)²)`."""
    head, scale = f"{parameter}({variable}) = {_number(value)}", _number(abs(constants["x_s"]))
    if family == "polynomial":
        return f"{head}·(1 {'+' if constants['sign'] > 0 else '−'} ({variable}/{scale})²)"
    if family == "rational":
        return f"{head}/(1 + ({variable}/{scale})²)"
    if family == "power":
        return f"{head}·|{variable}/{scale}|^{_number(constants['p'])}"
    return f"{head}·exp({'' if constants['x_s'] > 0 else '−'}{variable}/{scale})"


def _sentence(candidate: _Candidate, stiffness: bool, formula: str, sign: str, explained) -> str:
    role = "the stiffness" if stiffness else "the parameter"
    where = "variable" if candidate.kind == "generic" else candidate.kind
    return (
        f"{role} {candidate.parameter} depends on the {where} {candidate.variable}: "
        f"{formula}, {sign}; explains {100 * explained:.1f} % of δ"
    )


def _reading(problem, candidate, family, phi, cost, constant_explained) -> VaryingReading | None:
    """The reading of one fitted family, or `None` where it has no real form."""
    theta_j = float(problem.data["theta"][candidate.parameter])
    physical = _physical_constants(family, phi, theta_j, np.asarray(candidate.law["norm"]))
    if physical is None or not np.isfinite(cost):
        return None
    value, constants = physical
    stiffness = _stiffness_like(problem, candidate)
    sign = _sign_word(_rising(family, constants), stiffness)
    explained = 1.0 - cost / problem.energy
    formula = _formula(candidate.parameter, candidate.variable, family, value, constants)
    return VaryingReading(
        parameter=candidate.parameter,
        variable=candidate.variable,
        family=family,
        value=value,
        constants={key: constants[key] for key in constants if key != "sign"},
        sign=sign,
        explained=explained,
        constant_explained=constant_explained,
        formula=formula,
        sentence=_sentence(candidate, stiffness, formula, sign, explained),
    )


# --------------------------------------------------------------------------------------
# The public function
# --------------------------------------------------------------------------------------


def _candidates(physics: PhysicsModel, problem: _Problem, variables, parameters) -> list:
    """Every parameter with an effect and every variable that moves, among those asked."""
    names = physics.state_names + physics.input_names
    kinds = physics.state_kinds + physics.input_kinds
    asked_variables = _asked("variables", variables, names)
    asked_parameters = _asked("parameters", parameters, physics.parameter_names)
    spread = problem.data["variables"].std(axis=0)
    return [
        _candidate(problem, i, j, (parameter, names[j]), kinds[j])
        for i, parameter in enumerate(physics.parameter_names)
        if parameter in asked_parameters and np.any(np.asarray(problem.directions[parameter]))
        for j in range(len(names))
        if names[j] in asked_variables and spread[j] > 0
    ]


def _asked(argument: str, asked, known: Sequence[str]) -> tuple[str, ...]:
    """`asked` checked against `known` (`None`: all of them)."""
    if asked is None:
        return tuple(known)
    asked = (asked,) if isinstance(asked, str) else tuple(asked)
    unknown = sorted(set(asked) - set(known))
    if unknown:
        raise ValueError(f"{argument} {unknown} are not declared; declared: {tuple(known)}.")
    return asked


def _checked_families(families) -> tuple[str, ...]:
    families = (families,) if isinstance(families, str) else tuple(families)
    unknown = sorted(set(families) - set(FAMILIES))
    if unknown or not families:
        raise ValueError(f"families must be among {FAMILIES}, got {families}.")
    return families


def _counts(reading: VaryingReading, min_explained: float) -> bool:
    """Explains at least `min_explained` of the correction and of what constant changes of
    the parameters leave unexplained."""
    rest = 1.0 - reading.constant_explained
    share = (reading.explained - reading.constant_explained) / rest if rest > 0 else 0.0
    return reading.explained >= min_explained and share >= min_explained


def _candidate_readings(problem: _Problem, families, candidate) -> list[VaryingReading]:
    """The readings of every family for one candidate (those with a real form)."""
    constant = _constant_explained(problem, candidate)
    readings = []
    for family in families:
        phi, cost = _fitted_constants(problem, candidate, family)
        readings.append(_reading(problem, candidate, family, phi, cost, constant))
    return [reading for reading in readings if reading is not None]


def read_varying_parameters(
    physics: PhysicsModel,
    theta: Mapping[str, float],
    states,
    inputs,
    correction,
    *,
    families: Sequence[str] = FAMILIES,
    variables: Sequence[str] | None = None,
    parameters: Sequence[str] | None = None,
    min_explained: float = MIN_EXPLAINED,
) -> list[VaryingReading]:
    r"""Read a correction $\delta$ as declared constants that depend on a state or an input.

    For every declared parameter $\theta_j$ (free or fixed), every state and input $v$ and
    every family of `families`, fits $\delta_k \approx f(x_k, u_k; \theta_j \to
    \theta_j\,g(v_k)) - f(x_k, u_k; \theta)$ along the given trajectory, the other free
    parameters allowed a constant change (see the module's description), and keeps the
    readings that count: those that explain at least `min_explained` of the correction's
    energy and of what constant changes of the parameters leave unexplained (`MIN_EXPLAINED`
    says why). Nothing is fitted but the two constants of each form. A parameter whose
    value is 0, a variable that does not move, and a law that turns the parameter's sign
    are not read.

    Parameters
    ----------
    physics : PhysicsModel
        The declared physics ([PhysicsModel][sk_offwhite.PhysicsModel]).
    theta : mapping of str to float
        Its parameters, e.g. the `parameters_` of a fitted
        [GreyBoxSparseRegressor][sk_offwhite.GreyBoxSparseRegressor].
    states : array-like of shape (n_samples, n_states)
        The trajectory $x_k$, e.g. `simulate(u).states`.
    inputs : array-like of shape (n_samples, n_inputs)
        The inputs $u_k$.
    correction : array-like of shape (n_samples, n_states)
        $\delta_k$, the term added to each state update, e.g. `simulate(u).correction`.
    families : sequence of str, default=FAMILIES
        Among `"polynomial"`, `"rational"`, `"power"`, `"exponential"`.
    variables, parameters : sequence of str, default=None
        Names of the states and inputs, and of the parameters, to try; `None`: all.
    min_explained : float, default=MIN_EXPLAINED
        The explained fraction under which a reading does not count; `0` keeps them all.

    Returns
    -------
    readings : list of VaryingReading
        The readings that count, the one that explains most first; empty when none does or
        the correction is zero.
    """
    families = _checked_families(families)
    with jax.enable_x64(True):
        problem = _problem(physics, theta, states, inputs, correction)
        if not problem.energy > 0:
            return []
        candidates = _candidates(physics, problem, variables, parameters)
        readings = [
            reading
            for candidate in candidates
            for reading in _candidate_readings(problem, families, candidate)
        ]
    kept = [reading for reading in readings if _counts(reading, min_explained)]
    return sorted(kept, key=lambda reading: -reading.explained)
