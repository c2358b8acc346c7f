r"""The user's physics: a discrete-time state-space model with named parameters.

A [`PhysicsModel`][sk_offwhite.PhysicsModel] holds

$$
x_{k+1} = f(x_k, u_k; \theta), \qquad z_k = h(x_k, u_k; \theta),
$$

with named physical parameters $\theta$ (value, bounds, fixed flag), an initial-state
guess $x_0$ and optional physics constraints $p(x, u; \theta) \le 0$ and
$q(x, u; \theta) = 0$. The functions are written with ``jax.numpy`` and receive
``theta`` as a ``dict`` mapping parameter names to scalars.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..simulation._rollout import take
from ._kinds import check_kinds
from ._probe import out_of_range_reads

__all__ = [
    "DiscretizedStep",
    "MeasuredStates",
    "Parameter",
    "PhysicsModel",
    "measured_states",
    "reads_next_input",
]

StepFn = Callable[[Any, Any, Mapping[str, Any]], Any]


@dataclass(frozen=True)
class Parameter:
    """A named physical parameter.

    Parameters
    ----------
    value : float
        Initial guess (or the fixed value when ``fixed``).
    bounds : tuple of (float or None, float or None), default=(None, None)
        Box constraint ``lower <= theta <= upper`` enforced by projection during the fit.
    fixed : bool, default=False
        Keep the parameter at ``value`` instead of fitting it.
    relaxable : bool, default=False
        For a fixed parameter, a constant written into a declared law (Torricelli's 1/2,
        a laminar exponent of 1, a nominal gain) that the closed loop may free, within
        ``bounds``, as a candidate change of that law ([`RelaxedLaw`][sk_offwhite.RelaxedLaw]),
        kept only if it lowers the cross-validated error.
    """

    value: float
    bounds: tuple[float | None, float | None] = (None, None)
    fixed: bool = False
    relaxable: bool = False

    def __post_init__(self):
        _check_real("Parameter value", self.value)
        for flag in ("fixed", "relaxable"):
            object.__setattr__(self, flag, _check_flag(flag, getattr(self, flag)))
        lower, upper = _bound_pair(self.bounds)
        if not math.isfinite(float(self.value)):
            raise ValueError(f"Parameter value must be finite, got {self.value!r}.")
        if lower > upper:
            raise ValueError(f"Parameter bounds must satisfy lower <= upper, got {self.bounds}.")
        if not lower <= float(self.value) <= upper:
            raise ValueError(f"Parameter value {self.value} lies outside its bounds {self.bounds}.")
        if self.relaxable and not self.fixed:
            raise ValueError("Parameter relaxable=True applies to a fixed parameter (fixed=True).")


def value_of(parameter) -> float:
    """The number a `Parameter` or a plain number holds, as a float."""
    return float(getattr(parameter, "value", parameter))


def _check_flag(argument: str, value) -> bool:
    """``value`` as a bool: ``True``, ``False``, a NumPy boolean or the integers 0 and 1;
    anything else (a string such as ``"yes"``) is a ``TypeError`` naming ``argument``."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer) and value in (0, 1):
        return bool(value)
    raise TypeError(f"Parameter {argument} must be True or False, got {value!r}.")


def _check_real(argument: str, value) -> float:
    """``value`` as a float, or a ``TypeError`` naming ``argument`` (a string, a boolean, a
    complex number or a container is no real number)."""
    kind = np.asarray(value).dtype.kind if not isinstance(value, str | bytes) else "U"
    if kind not in "iuf" or np.ndim(value) != 0:
        raise TypeError(f"{argument} must be a real number, got {value!r}.")
    return float(value)


def _bound_pair(bounds) -> tuple[float, float]:
    """Return ``bounds`` as floats with ``None`` mapped to -inf / +inf."""
    if isinstance(bounds, str) or not hasattr(bounds, "__len__") or len(bounds) != 2:
        raise ValueError(f"bounds must be a (lower, upper) pair, got {bounds!r}.")
    lower = -np.inf if bounds[0] is None else _check_real("the lower of bounds", bounds[0])
    upper = np.inf if bounds[1] is None else _check_real("the upper of bounds", bounds[1])
    if np.isnan(lower) or np.isnan(upper):
        raise ValueError(f"bounds must not be NaN, got {bounds!r}.")
    return lower, upper


def _checked_bounds(argument: str, bounds, x0) -> tuple[float, float]:
    """``bounds`` as a float pair, ordered and holding every entry of ``x0``."""
    try:
        lower, upper = _bound_pair(bounds)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{argument} must be a (lower, upper) pair, got {bounds!r}.") from error
    if lower > upper:
        raise ValueError(f"{argument} must satisfy lower <= upper, got {bounds!r}.")
    outside = (x0 < lower) | (x0 > upper)
    if np.any(outside):
        raise ValueError(
            f"the initial-state guess x0 = {x0.tolist()} lies outside {argument} = {bounds!r} "
            f"(entries {np.flatnonzero(outside).tolist()})."
        )
    return lower, upper


def _per_state(argument: str, values, n_states: int, dtype) -> np.ndarray:
    """``values`` as one entry per state (a scalar applies to all)."""
    if dtype is bool and np.asarray(values).dtype.kind != "b":
        raise TypeError(f"{argument} must be True, False or one boolean per state, got {values!r}.")
    array = np.asarray(values, dtype=dtype)
    if array.ndim > 1 or array.size not in (1, n_states):
        raise ValueError(
            f"{argument} must be a scalar or have one entry per state ({n_states}), "
            f"got shape {array.shape}."
        )
    return np.broadcast_to(array.reshape(-1), (n_states,)).copy()


def _as_parameter(name: str, spec) -> Parameter:
    if isinstance(spec, Parameter):
        return spec
    if isinstance(spec, int | float | np.number) and not isinstance(spec, bool | np.bool_):
        if not math.isfinite(float(spec)):
            raise ValueError(f"parameters[{name!r}] must be finite, got {spec!r}.")
        return Parameter(float(spec))
    raise TypeError(
        f"parameters[{name!r}] must be a float or a Parameter, got {type(spec).__name__}."
    )


def _default_names(prefix: str, count: int) -> tuple[str, ...]:
    if count == 1 and prefix == "u":
        return ("u",)
    return tuple(f"{prefix}{i + 1}" for i in range(count))


def _check_names(argument: str, names, count: int) -> tuple[str, ...]:
    names = tuple(str(name) for name in names)
    if len(names) != count:
        raise ValueError(f"{argument} must have {count} entries, got {len(names)}.")
    if len(set(names)) != count:
        raise ValueError(f"{argument} must be unique, got {names}.")
    return names


class MeasuredStates:
    """Output map ``z = x[indices]`` (a picklable callable)."""

    def __init__(self, indices: Sequence[int], n_states: int):
        values = np.atleast_1d(np.asarray(indices))
        if values.dtype.kind not in "iu" or values.ndim != 1:
            raise ValueError(
                f"output must be a callable or state indices (integers), got {indices!r}."
            )
        self.indices = tuple(int(i) for i in values)
        if not self.indices or not all(0 <= i < n_states for i in self.indices):
            raise ValueError(
                f"output state indices {self.indices} out of range for {n_states} states."
            )

    def __call__(self, x, u, theta):
        return take(x, self.indices)

    def __repr__(self) -> str:
        return f"MeasuredStates({list(self.indices)})"

    def __eq__(self, other) -> bool:
        return isinstance(other, MeasuredStates) and other.indices == self.indices

    def __hash__(self) -> int:
        return hash((MeasuredStates, self.indices))


def measured_states(output) -> tuple[int, ...] | None:
    """The state each output reads when the output map is a reading of states (it has the
    ``indices`` of `MeasuredStates`), else ``None``."""
    return getattr(output, "indices", None)


class PhysicsModel:
    """Discrete-time physical model with named parameters.

    Parameters
    ----------
    step : callable
        ``step(x, u, theta) -> x_next``, written with ``jax.numpy``; ``x`` has shape
        ``(n_states,)``, ``u`` shape ``(n_inputs,)``, ``theta`` is a dict of scalars.
    output : callable or int or sequence of int
        ``output(x, u, theta) -> z`` of shape ``(n_outputs,)``, or the indices of the
        measured states (``z = x[output]``).
    parameters : dict
        Maps each parameter name to a float (initial guess) or a
        [`Parameter`][sk_offwhite.Parameter].
    n_states : int
        Dimension of the state ``x``.
    n_inputs : int
        Dimension of the input ``u``.
    x0 : array-like of shape (n_states,), default=None
        Initial-state guess; zeros when ``None``.
    x0_fixed : bool or array-like of bool, default=False
        Initial-state entries kept at ``x0`` instead of being estimated.
    x0_bounds : tuple of (float or None, float or None), default=(None, None)
        Box constraint on the estimated initial state (applied to every entry).
    state_names, input_names, output_names : sequence of str, default=None
        Names used in print-outs and feature names (``x1..``, ``u``/``u1..``, ``z1..``).
    inequality : callable, default=None
        ``p(x, u, theta) -> array`` that should stay ``<= 0`` along the trajectory.
    equality : callable, default=None
        ``q(x, u, theta) -> array`` that should stay ``== 0`` along the trajectory.
    state_kinds, input_kinds : sequence of str, default=None
        Physical kind of each state and input, one of
        `KINDS` (``"level"``, ``"position"``, ``"velocity"``,
        ``"angle"``, ``"rate"``, ``"force"``, ``"torque"``, ``"flow"``, ``"voltage"``,
        ``"current"``, ``"temperature"``, ``"generic"``); ``None``: all ``"generic"``. The
        closed loop proposes only the missing effects that make sense for a kind.
    """

    def __init__(
        self,
        step: StepFn,
        output: StepFn | int | Sequence[int],
        parameters: Mapping[str, float | Parameter],
        n_states: int,
        n_inputs: int,
        *,
        x0=None,
        x0_fixed=False,
        x0_bounds=(None, None),
        state_names: Sequence[str] | None = None,
        input_names: Sequence[str] | None = None,
        output_names: Sequence[str] | None = None,
        inequality: StepFn | None = None,
        equality: StepFn | None = None,
        state_kinds: Sequence[str] | None = None,
        input_kinds: Sequence[str] | None = None,
    ):
        if not callable(step):
            raise TypeError("step must be callable as step(x, u, theta).")
        self.n_states = _positive_int("n_states", n_states)
        self.n_inputs = _positive_int("n_inputs", n_inputs, allow_zero=True)
        self.step = step
        self.output = output if callable(output) else MeasuredStates(output, self.n_states)
        if not isinstance(parameters, Mapping):
            raise TypeError(
                "parameters must be a mapping of names to floats or Parameter objects "
                f"(a dict), got {type(parameters).__name__}."
            )
        self.parameters = {str(k): _as_parameter(str(k), v) for k, v in parameters.items()}
        self.x0 = self._initial_state(x0)
        self.x0_fixed = _per_state("x0_fixed", x0_fixed, self.n_states, bool)
        self.x0_bounds = _checked_bounds("x0_bounds", x0_bounds, self.x0)
        self.state_names = _check_names(
            "state_names", state_names or _default_names("x", self.n_states), self.n_states
        )
        self.input_names = _check_names(
            "input_names", input_names or _default_names("u", self.n_inputs), self.n_inputs
        )
        self.output_names = _output_names(output_names, self.output, self.n_states)
        self.inequality = inequality
        self.equality = equality
        self.state_kinds = check_kinds("state_kinds", state_kinds, self.n_states)
        self.input_kinds = check_kinds("input_kinds", input_kinds, self.n_inputs)
        _check_reads(self)

    @classmethod
    def from_ode(
        cls,
        rhs: StepFn,
        sampling_time: float,
        output,
        parameters,
        n_states: int,
        n_inputs: int,
        *,
        method: str = "rk4",
        n_substeps: int = 1,
        hold: str = "zero",
        **kwargs,
    ) -> PhysicsModel:
        """Build a model from a continuous-time right-hand side ``dx/dt = rhs(x, u, theta)``.

        The ODE is integrated over each sampling interval with ``n_substeps`` steps of
        explicit Euler or classical RK4, as MATLAB ``idnlgrey`` users expect from a
        continuous-time grey-box model. ``hold`` says what the input does between two
        samples: ``"zero"`` holds it (an input that moves in steps, such as a digital
        command), ``"linear"`` moves it linearly to the next sample (a smooth signal that
        was sampled: each RK4 step reads $u_k$, $(u_k + u_{k+1})/2$ and $u_{k+1}$).
        """
        sampling_time = _check_real("sampling_time", sampling_time)
        if not (math.isfinite(sampling_time) and sampling_time > 0):
            raise ValueError(f"sampling_time must be finite and positive, got {sampling_time!r}.")
        n = _positive_int("n_inputs", n_inputs, allow_zero=True)
        step = DiscretizedStep(rhs, float(sampling_time), method, n_substeps, hold, n)
        model = cls(step, output, parameters, n_states, n_inputs, **kwargs)
        model.rhs, model.sampling_time, model.method = rhs, float(sampling_time), method
        model.input_hold = step.hold
        return model

    @classmethod
    def linear(cls, n_inputs: int, n_outputs: int) -> PhysicsModel:
        """Black-box linear state-space model used when no physics is given.

        One state per output: $x_{k+1} = A x_k + B u_k + b$, $z_k = x_k + D u_k$,
        with every entry of ``A, B, b, D`` a named parameter (``A[i,j]`` etc.), ``A`` started
        at zero. It makes the estimator usable (and checkable) without a physical model.
        """
        step = LinearStateSpace(n_inputs, n_outputs, "step")
        output = LinearStateSpace(n_inputs, n_outputs, "output")
        names = step.parameter_names()
        return cls(step, output, dict.fromkeys(names, 0.0), n_outputs, n_inputs)

    def _initial_state(self, x0) -> np.ndarray:
        if x0 is None:
            return np.zeros(self.n_states)
        try:
            x0 = np.asarray(x0, dtype=float).reshape(-1)
        except (TypeError, ValueError) as error:
            raise ValueError(f"x0 must be {self.n_states} finite values, got {x0!r}.") from error
        if x0.shape != (self.n_states,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"x0 must be {self.n_states} finite values, got {x0!r}.")
        return x0

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of all physical parameters, in declaration order."""
        return tuple(self.parameters)

    @property
    def free_parameter_names(self) -> tuple[str, ...]:
        """Names of the parameters that are fitted (not ``fixed``)."""
        return tuple(name for name, p in self.parameters.items() if not p.fixed)

    def parameter_values(self) -> np.ndarray:
        """Initial values of all parameters, in declaration order."""
        return np.array([p.value for p in self.parameters.values()], dtype=float)

    def parameter_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of all parameters, in declaration order."""
        pairs = [_bound_pair(p.bounds) for p in self.parameters.values()]
        return np.array([lo for lo, _ in pairs]), np.array([hi for _, hi in pairs])

    def with_parameters(self, **updates) -> PhysicsModel:
        """Copy of the model with some parameters replaced (floats or
        [`Parameter`][sk_offwhite.Parameter])."""
        clone = self.__class__.__new__(self.__class__)
        clone.__dict__.update(self.__dict__)
        clone.parameters = dict(self.parameters)
        for name, spec in updates.items():
            if name not in self.parameters:
                raise KeyError(f"unknown parameter {name!r}; known: {self.parameter_names}.")
            clone.parameters[name] = _as_parameter(name, spec)
        return clone

    def __repr__(self) -> str:
        params = ", ".join(
            f"{k}={p.value:g}" + (" (fixed)" if p.fixed else "") for k, p in self.parameters.items()
        )
        step_name = getattr(self.step, "__name__", type(self.step).__name__)
        return (
            f"PhysicsModel(step={step_name}, n_states={self.n_states}, "
            f"n_inputs={self.n_inputs}, parameters={{{params}}})"
        )


def _output_names(names, output, n_states: int) -> tuple[str, ...] | None:
    """``output_names`` as a tuple, one per output when the output map reads states."""
    if names is None:
        return None
    names = tuple(str(name) for name in names)
    indices = measured_states(output)
    if indices is not None and len(names) != len(indices):
        raise ValueError(
            f"output_names must have one name per output ({len(indices)}), got {len(names)}."
        )
    return names


def _check_reads(model: PhysicsModel) -> None:
    """Refuse a step or output map that reads an element past the end of ``x`` or ``u``,
    which JAX would silently clamp to the last one (`out_of_range_reads`)."""
    x, u = np.zeros(model.n_states), np.zeros(model.n_inputs)
    theta = {name: p.value for name, p in model.parameters.items()}
    for name, function in (("step", model.step), ("output", model.output)):
        reads = sorted(set(out_of_range_reads(function, x, u, theta)))
        if reads:
            shown = ", ".join(f"element {r.index} of a length-{r.length} array" for r in reads)
            raise ValueError(
                f"physics {name} reads {shown}, past its end; with n_states={model.n_states} "
                f"and n_inputs={model.n_inputs} check the indices into x and u (JAX would "
                "read the last element instead, silently)."
            )


def _positive_int(argument: str, value, allow_zero: bool = False) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{argument} must be an int, got {value!r}.")
    if value < (0 if allow_zero else 1):
        raise ValueError(f"{argument} must be {'>= 0' if allow_zero else '>= 1'}, got {value}.")
    return int(value)


def _euler(rhs, x, inputs, theta, dt):
    return x + dt * rhs(x, inputs(0.0), theta)


def _rk4(rhs, x, inputs, theta, dt):
    k1 = rhs(x, inputs(0.0), theta)
    k2 = rhs(x + 0.5 * dt * k1, inputs(0.5), theta)
    k3 = rhs(x + 0.5 * dt * k2, inputs(0.5), theta)
    k4 = rhs(x + dt * k3, inputs(1.0), theta)
    return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


_INTEGRATORS = {"euler": _euler, "rk4": _rk4}

HOLDS = ("zero", "linear")
"""How a sampled input is taken between two samples: held (``"zero"``) or interpolated
linearly to the next sample (``"linear"``)."""


def check_hold(hold) -> str:
    """``hold`` if it is one of `HOLDS`, else a ``ValueError`` naming it."""
    if not isinstance(hold, str) or hold not in HOLDS:
        raise ValueError(f"hold must be one of {list(HOLDS)}, got {hold!r}.")
    return hold


def _held_inputs(u, n_inputs: int, hold: str, start: float, width: float):
    """The input at the fraction ``start + width * s`` of the sample, as a function of the
    sub-step's fraction ``s``: ``u`` itself under a zero-order hold, or when ``u`` holds
    only this sample's input; under a linear hold ``u = [u_k, u_{k+1}]`` and the input is
    interpolated between them."""
    if hold == "zero" or u.shape[0] != 2 * n_inputs:
        return lambda s: u
    now, following = u[:n_inputs], u[n_inputs:]
    return lambda s: now + (start + width * s) * (following - now)


class DiscretizedStep:
    r"""Discretisation of ``rhs`` with ``n_substeps`` integrator steps and an input hold.

    With step ``dt = sampling_time / n_substeps`` each sub-step applies explicit Euler,
    $x \leftarrow x + dt\, r(x, u(t))$, or classical RK4, whose stages read the input at
    the start, the middle and the end of the sub-step. Under a zero-order hold
    (``hold="zero"``) the input is $u_k$ throughout the sample; under a first-order hold
    (``hold="linear"``) it moves linearly from $u_k$ to $u_{k+1}$,
    $u(t_k + s T_s) = u_k + s\,(u_{k+1} - u_k)$, the input of a smooth signal that was
    sampled. The step then takes ``u = [u_k, u_{k+1}]`` (``2 * n_inputs`` entries, as the
    simulation hands it); given ``u_k`` alone it holds it.
    """

    def __init__(
        self,
        rhs: StepFn,
        sampling_time: float,
        method: str,
        n_substeps: int,
        hold: str = "zero",
        n_inputs: int = 0,
    ):
        if method not in _INTEGRATORS:
            raise ValueError(f"method must be one of {sorted(_INTEGRATORS)}, got {method!r}.")
        self.rhs, self.method = rhs, method
        self.n_substeps = _positive_int("n_substeps", n_substeps)
        self.dt = float(sampling_time) / self.n_substeps
        self.hold = check_hold(hold)
        self.n_inputs = _positive_int("n_inputs", n_inputs, allow_zero=True)
        self.__name__ = f"{method}({getattr(rhs, '__name__', 'rhs')})"

    def _key(self):
        return (self.rhs, self.method, self.n_substeps, self.dt, self.hold, self.n_inputs)

    def __eq__(self, other) -> bool:
        return isinstance(other, DiscretizedStep) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def with_hold(self, hold: str) -> DiscretizedStep:
        """The same discretisation under another input ``hold``."""
        return self._changed(self.rhs, hold)

    def with_rhs(self, rhs: StepFn) -> DiscretizedStep:
        """The same discretisation of another right-hand side."""
        return self._changed(rhs, self.hold)

    def _changed(self, rhs: StepFn, hold: str) -> DiscretizedStep:
        sampling_time = self.dt * self.n_substeps
        return DiscretizedStep(
            rhs, sampling_time, self.method, self.n_substeps, hold, self.n_inputs
        )

    def __call__(self, x, u, theta):
        integrate, width = _INTEGRATORS[self.method], 1.0 / self.n_substeps
        for j in range(self.n_substeps):
            inputs = _held_inputs(u, self.n_inputs, self.hold, j * width, width)
            x = integrate(self.rhs, x, inputs, theta, self.dt)
        return x


def reads_next_input(physics) -> bool:
    """Whether the step of ``physics`` takes ``[u_k, u_{k+1}]`` (a first-order hold)."""
    return getattr(physics, "input_hold", "zero") == "linear"


class LinearStateSpace:
    """Step or output map of [`PhysicsModel.linear`][sk_offwhite.PhysicsModel.linear] (picklable,
    compared by value)."""

    def __init__(self, n_inputs: int, n_outputs: int, part: str):
        self.n_inputs, self.n_outputs, self.part = int(n_inputs), int(n_outputs), part
        self.__name__ = f"linear_{part}"

    def parameter_names(self) -> list[str]:
        n, m = self.n_outputs, self.n_inputs
        return (
            [f"A[{i},{j}]" for i in range(n) for j in range(n)]
            + [f"B[{i},{j}]" for i in range(n) for j in range(m)]
            + [f"b[{i}]" for i in range(n)]
            + [f"D[{i},{j}]" for i in range(n) for j in range(m)]
        )

    def _matrix(self, theta, prefix, rows, cols):
        import jax.numpy as jnp

        entries = [[theta[f"{prefix}[{i},{j}]"] for j in range(cols)] for i in range(rows)]
        return jnp.asarray(entries).reshape(rows, cols)

    def __call__(self, x, u, theta):
        import jax.numpy as jnp

        n, m = self.n_outputs, self.n_inputs
        if self.part == "output":
            return x + self._matrix(theta, "D", n, m) @ u
        bias = jnp.asarray([theta[f"b[{i}]"] for i in range(n)])
        return self._matrix(theta, "A", n, n) @ x + self._matrix(theta, "B", n, m) @ u + bias

    def __eq__(self, other) -> bool:
        return isinstance(other, LinearStateSpace) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def _key(self):
        return (LinearStateSpace, self.n_inputs, self.n_outputs, self.part)
