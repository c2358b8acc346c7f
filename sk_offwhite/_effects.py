r"""Named physical effects that can be added to a [`PhysicsModel`][sk_offwhite.PhysicsModel].

An effect is the explicit, parametrised form of something a residual analysis can point
at: an overflow (a level capped at a height, the excess spilling elsewhere), a saturation of
the measured output, a leak, a friction. [`augment`][sk_offwhite.augment] returns a new physics
model whose step and output apply the effects after the declared physics,

$$
x_{k+1} = E_m \circ \dots \circ E_1\bigl(f(x_k, u_k; \theta);\ x_k, u_k, \theta_E\bigr),
\qquad z_k = O_m \circ \dots \circ O_1\bigl(h(x_k, u_k; \theta)\bigr),
$$

with the effects' own named parameters $\theta_E$ appended to $\theta$. Hard
limits are smoothed, $\mathrm{hinge}_\beta(a) = \mathrm{softplus}(\beta a)/\beta$, so
the simulation error stays differentiable. Effects are immutable and compared by value, so
augmented models are valid ``jit`` static arguments and picklable.
"""

from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np

from ._hidden import SensorReading, sensor_readings, with_hidden_states
from ._physics import DiscretizedStep, Parameter, PhysicsModel

__all__ = [
    "AdditiveEffect",
    "Backlash",
    "Bias",
    "DeadZone",
    "DifferenceDeadZone",
    "DictionaryTerm",
    "Effect",
    "Friction",
    "InputLag",
    "InputSaturation",
    "Leak",
    "OutputOffset",
    "OutputSaturation",
    "Overflow",
    "PowerDrag",
    "PowerStiffness",
    "QuadraticDrag",
    "RelaxedLaw",
    "SensorCalibration",
    "SensorStep",
    "Stiffness",
    "Switched",
    "SwitchedTerm",
    "augment",
    "hinge",
    "relaxations",
    "switched",
    "switches",
    "time_step",
]


def hinge(a, sharpness: float):
    r"""Smooth $\max(a, 0)$: $\mathrm{softplus}(\beta a)/\beta$."""
    return jax.nn.softplus(sharpness * a) / sharpness


SHARPNESS = 1000.0
r"""Default sharpness $s$ of the rounded corners of the hard input limit, the dead
zones and the play (relative to the effect's own level or width, so unit-free). A corner
moves the effect's edge by $\ln 2 / s$ of that width: 1.4 % at $s = 50$,
0.07 % at 1000. Measured with the closed loop on the generators (seed 0, 2000 samples,
``bench_loop_generators.py``): at 50 the servo's play came back at 0.05058 for 0.05 and the
heated block's limit at 60.03 for 60 (declared parameters within 0.28 % and 0.34 %), and
the loop run again on each result added a dead zone that made up for the corners; at 1000,
0.05002 and 60.00 (0.02 % and 0.06 %), validation errors 12 % and 8 % lower, and the
second loops add nothing. The dead-zone motor, the diode and the clearance are the same
to the third digit."""

RELATIVE_FLOOR = 1e-6
"""A positive level or width stays above this fraction of its start: a floor in the
parameter's own scale, so that a fit in other units meets the same floor."""


def _positive(value: float) -> Parameter:
    """A positive parameter started at ``value``, bounded below by ``RELATIVE_FLOOR`` of it."""
    return Parameter(value, (RELATIVE_FLOOR * abs(value), None))


def _beyond(ratio, sharpness: float, one_sided: bool = False):
    r"""How far ``ratio`` lies beyond $\pm 1$, smoothed and times ``sharpness``:
    $\mathrm{sp}(s(r - 1)) - \mathrm{sp}(s(-r - 1))$, or its first term alone when
    ``one_sided`` (divided by $s$, a smooth $\mathrm{sign}(r)\max(|r| - 1, 0)$,
    resp. $\max(r - 1, 0)$): the dead zones and the hard input limit."""
    passed = jax.nn.softplus(sharpness * (ratio - 1.0))
    if one_sided:
        return passed
    return passed - jax.nn.softplus(sharpness * (-ratio - 1.0))


def _hinge_corner(effect, theta):
    """The corner of ``effect``'s hinge: its fitted parameter ``{name}_corner`` with
    ``fit_corner``, else the fixed ``corner``."""
    return theta[f"{effect.name}_corner"] if effect.fit_corner else effect.corner


def _corner_parameters(effect) -> dict[str, Parameter]:
    """``{name}_corner`` when ``effect`` fits its corner, else nothing."""
    return {f"{effect.name}_corner": _positive(effect.corner)} if effect.fit_corner else {}


def _widened_range(u, index: int) -> tuple[float, float]:
    r"""Column ``index`` of the record ``u``'s range widened by itself on each side,
    $[\min u - R,\ \max u + R]$, $R = \max u - \min u$ (unbounded for a
    constant column): the bounds of a hidden state that follows an input."""
    command = np.asarray(u, float)[:, index]
    low, high = float(command.min()), float(command.max())
    if not high > low:
        return (-np.inf, np.inf)
    return (2 * low - high, 2 * high - low)


def lag_coefficients(ratio, xp=jnp):
    r"""$\alpha = 1 - e^{-T_s/\tau}$ and $\beta = 1 - \frac{\tau}{T_s}\,\alpha$
    of a first-order lag of time constant $\tau$ over a sample $T_s$, from
    ``ratio`` $= \tau / T_s$, in the array module ``xp``: the share of the gap to
    its input that the lag closes over the sample, and the share its mean over the sample
    closes ([`InputLag`][sk_offwhite.InputLag], [`SensorLag`][sk_offwhite.SensorLag])."""
    alpha = -xp.expm1(-1.0 / ratio)
    return alpha, 1.0 - ratio * alpha


def checked_positive(value, name: str) -> float:
    """``value`` as a float, or a ``ValueError`` naming ``name`` unless it is positive and
    finite."""
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return value


def _checked_corner(corner) -> float:
    return checked_positive(corner, "corner")


class Effect:
    """Base class: an effect acting on the state update and/or the output map.

    Subclasses set ``name`` and ``target`` (``"input"``, ``"state"`` or ``"output"``) and
    implement `parameters` and one of `apply_input` (before the declared step),
    `apply_state` (after it) or `apply_output`.
    """

    target = "state"
    replaces_declared = False
    """Whether the effect's parameters replace declared, relaxable ones of the same name."""
    reads_output = False
    """Whether an output effect acts on the final reading: after every other output effect,
    whatever the order the effects are given in ([`SensorStep`][sk_offwhite.SensorStep])."""
    hidden_states: tuple[str, ...] = ()
    """Names of the hidden states the effect carries (see `sk_offwhite._hidden`)."""
    follows_output = False
    """Whether the hidden states follow the declared output map rather than the input
    (`follow` instead of `advance`; a slow sensor)."""
    hidden_free = True
    """Whether the hidden states' initial values are estimated with the initial state;
    ``False``: each record starts them where `hidden_start` puts them (the past
    commands of a dead time, which only the record's first samples see), and `advance`
    updates them from the inputs alone, so that every later sample's values are known
    (`hidden_path`) and a shooting window starts them there rather than fitting them."""

    def parameters(self) -> dict[str, Parameter]:
        """The effect's own parameters, with initial values and bounds."""
        raise NotImplementedError

    def apply_input(self, x, u, theta):
        """Return the input the declared step sees (identity by default)."""
        return u

    def apply_state(self, x, u, x_next, theta):
        """Return the state update after the effect (identity by default)."""
        return x_next

    def apply_output(self, x, u, z, theta):
        """Return the output after the effect (identity by default)."""
        return z

    def advance(self, hidden, u, theta):
        """For an effect with hidden states: ``(input the declared step sees, next hidden
        states)`` from the hidden states and the input (identity by default)."""
        return u, hidden

    def follow(self, hidden, now, after, theta):
        """For an effect that `follows_output`: the next hidden states from these
        and the declared outputs at samples $k$ (``now``) and $k + 1$
        (``after``)."""
        return hidden

    def follow_off(self, hidden, now, after):
        """`follow` of the effect switched off ([`Switched`][sk_offwhite.Switched]): hidden states
        whose reading is the declared output (the hidden states themselves by default)."""
        return hidden

    def hidden_initial(self) -> tuple[float, ...]:
        """Initial guesses of the hidden states (estimated with the initial state)."""
        return ()

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        """Physical kinds of the hidden states, given the model's input kinds."""
        return ("generic",) * len(self.hidden_states)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        """Where a record whose first input is ``u`` starts the hidden states, given the
        guess ``hidden`` (NumPy values; ``theta`` the parameters by name): the guess
        itself by default. An effect whose first step forgets a guess outside some range
        returns a value inside it, so that the fit of the initial state can move it."""
        return tuple(hidden)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        """Bounds ``(lower, upper)`` of each hidden state's initial value on a record with
        inputs ``u`` (NumPy, one row per sample): none by default."""
        return ((-np.inf, np.inf),) * len(self.hidden_states)

    def hidden_path(self, u, theta) -> np.ndarray:
        """For an effect that fixes its hidden states (`hidden_free` false): their
        values at every sample of a record with inputs ``u`` (NumPy, one row per sample),
        started by `hidden_start` and moved by `advance` (one ``lax.scan`` in
        double precision; ``theta`` the parameters by name). An effect overrides it where a
        closed form is cheaper."""
        start = np.asarray(self.hidden_start(self.hidden_initial(), u[0], theta), float)

        def step(hidden, u_k):
            return self.advance(hidden, u_k, theta)[1], hidden

        with jax.enable_x64(True):
            _, path = jax.lax.scan(step, jnp.asarray(start), jnp.asarray(u, float))
        return np.asarray(path, float)

    @property
    def mechanism(self) -> str:
        """What the effect models: variants of one mechanism (an overflow into one tank or
        another) share it, and the loop puts at most one of them in a set (default: the
        effect's name, its own mechanism)."""
        return self.name

    def describe(self, state_names, output_names, values=None) -> str:
        """One line in words, naming the variables (``values``: fitted parameters, used
        where they change the wording)."""
        raise NotImplementedError

    def richer(self) -> Effect | None:
        """The next variant of the same mechanism with one more degree of freedom, which
        holds this effect as a special case (a calibration of one degree more), or
        ``None`` (the default: no such variant). The loop tries it in place of the effect
        once the effect is chosen, started from `richer_start`."""
        return None

    def richer_start(self, values: dict) -> dict:
        """The start of `richer`'s parameters from this effect's fitted ``values``
        (by parameter name; any type): where the richer variant reproduces this effect,
        each of this effect's parameters carried into the richer one's of the same field
        (``{name}_c0`` into ``{richer name}_c0``), its extra parameters at their declared
        starts (a parameter the fit drove onto a flat direction it cannot leave may
        restart instead: see [`Friction`][sk_offwhite.Friction]); empty when there is no richer
        variant."""
        richer = self.richer()
        if richer is None:
            return {}
        start = richer.parameters()
        for name in self.parameters():
            carried = richer.name + name[len(self.name) :]
            if carried in start:
                start[carried] = values[name]
        return start

    def _key(self):
        return (type(self), tuple(sorted(vars(self).items())))

    def __eq__(self, other) -> bool:
        return isinstance(other, Effect) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def replace(self, **changes) -> Effect:
        """A copy with some constructor arguments changed (an effect's attributes are its
        constructor's arguments)."""
        return type(self)(**{**vars(self), **changes})

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in vars(self).items())
        return f"{type(self).__name__}({args})"


class RelaxedLaw(Effect):
    r"""A constant of a declared law freed: the fixed, relaxable parameter ``parameter``
    (see [`Parameter`][sk_offwhite.Parameter]) becomes a fitted one, started at its declared
    value and kept within its bounds.

    The step and output map are unchanged; only the parameter's status changes, so a model
    with the relaxation shares the declared model's compiled programs. Torricelli's
    outflow $k\sqrt{x} = k x^{1/2}$ written with a relaxable exponent ``a`` becomes
    $k x^{a}$, with $a$ fitted.
    """

    target = "law"
    replaces_declared = True

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


class Overflow(Effect):
    r"""State ``state`` cannot exceed a level; a fraction of the excess reaches ``sink``.

    $$
    o = \mathrm{hinge}_\beta(x^+_s - h), \quad x^+_s \leftarrow x^+_s - o, \quad
    x^+_{d} \leftarrow x^+_{d} + \rho\, o,
    $$

    with parameters ``{name}_level`` ($h$) and, with a sink, ``{name}_fraction``
    ($\rho \in [0, 1]$; the rest leaves the system). The hinge is rounded over
    ``corner`` ($c$, in the state's units):
    $\mathrm{hinge}(a) = c\,\mathrm{softplus}(a / c)$, so $\beta = 1/c$. The
    loop sets $c$ to 2.5 % of the state's standard deviation on the record, so the
    rounding follows the data's units. With ``fit_corner=True`` the corner is a parameter,
    ``{name}_corner``, started at ``corner`` and kept above `RELATIVE_FLOOR` of it:
    the data decide how sharp the overflow is (a weir spills gradually, a rim at once).
    A corner driven to its floor leaves the cost kinked there and the Hessian singular in
    it (infinite standard errors): start it from a fitted model, and read it as "sharp".
    """

    def __init__(
        self,
        state: int,
        level: float,
        sink: int | None = None,
        *,
        fraction: float = 0.5,
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "overflow",
    ):
        self.state, self.level, self.sink = int(state), float(level), sink
        self.fraction, self.corner, self.name = float(fraction), _checked_corner(corner), name
        self.fit_corner = bool(fit_corner)

    def parameters(self) -> dict[str, Parameter]:
        params = {f"{self.name}_level": Parameter(self.level)}
        if self.sink is not None:
            params[f"{self.name}_fraction"] = Parameter(self.fraction, (0.0, 1.0))
        return {**params, **_corner_parameters(self)}

    @property
    def mechanism(self) -> str:
        """An overflow of the state, wherever its excess goes."""
        return f"overflow of state {self.state}"

    def apply_state(self, x, u, x_next, theta):
        corner = _hinge_corner(self, theta)
        excess = hinge(x_next[self.state] - theta[f"{self.name}_level"], 1.0 / corner)
        x_next = x_next.at[self.state].add(-excess)
        if self.sink is None:
            return x_next
        return x_next.at[self.sink].add(theta[f"{self.name}_fraction"] * excess)

    def describe(self, state_names, output_names, values=None) -> str:
        fraction = (values or {}).get(f"{self.name}_fraction", self.fraction)
        where = ""
        if self.sink is not None and fraction >= 0.01:
            where = f", a fraction {fraction:.2g} of the excess flowing into "
            where += state_names[self.sink]
        elif self.sink is not None:
            where = ", the excess leaving the system"
        return f"{state_names[self.state]} overflows above a level{where}"


class OutputSaturation(Effect):
    r"""Output ``output`` saturates at an upper level.

    $z \leftarrow z - \mathrm{hinge}_\beta(z - z_{max})$;
    parameter ``{name}_level`` ($z_{max}$). The hinge is rounded over ``corner``
    (in the output's units, $\beta = 1/c$; fitted as ``{name}_corner`` with
    ``fit_corner=True``; see [`Overflow`][sk_offwhite.Overflow]); the loop sets it to 2.5 % of the
    simulated output's standard deviation.
    """

    target = "output"

    def __init__(
        self,
        output: int,
        level: float,
        *,
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "saturation",
    ):
        self.output, self.level, self.name = int(output), float(level), name
        self.corner, self.fit_corner = _checked_corner(corner), bool(fit_corner)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": Parameter(self.level), **_corner_parameters(self)}

    def apply_output(self, x, u, z, theta):
        corner = _hinge_corner(self, theta)
        excess = hinge(z[self.output] - theta[f"{self.name}_level"], 1.0 / corner)
        return z.at[self.output].add(-excess)

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the measured {output_names[self.output]} saturates at an upper level"


class InputSaturation(Effect):
    r"""Input ``input`` reaches the physics through a saturating actuator.

    Two shapes, applied before the declared step, with parameter ``{name}_level``
    ($u_{max} > 0$, kept above `RELATIVE_FLOOR` of its start):

    * ``shape="tanh"``: $u_j \leftarrow u_{max} \tanh(u_j / u_{max})$, a soft
      saturation (already 8 % below $u_j$ at half the level);
    * ``shape="clip"``: a hard limit at $\pm u_{max}$ with rounded corners,

      $$
      u_j \leftarrow u_j - \frac{u_{max}}{s}\left[\mathrm{sp}\big(s(u_j/u_{max} - 1)\big)
            - \mathrm{sp}\big(s(-u_j/u_{max} - 1)\big)\right],
      $$

      ($\mathrm{sp}$ the softplus, $s$ = ``sharpness``, relative to
      $u_{max}$ so that the rounding follows the input's units): the input passes
      unchanged below the level (a heater, a valve, a drive at its current limit).

    Both shapes are one mechanism (`mechanism`): a set holds at most one of them.
    """

    target = "input"
    SHAPES = ("tanh", "clip")

    def __init__(
        self,
        input: int,
        level: float,
        *,
        shape: str = "tanh",
        sharpness: float = SHARPNESS,
        name: str = "actuator",
    ):
        if shape not in self.SHAPES:
            raise ValueError(f"shape must be one of {self.SHAPES}, got {shape!r}.")
        if not level > 0:
            raise ValueError(f"level must be positive, got {level!r}.")
        self.input, self.level, self.name = int(input), float(level), name
        self.shape, self.sharpness = shape, float(sharpness)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": _positive(self.level)}

    @property
    def mechanism(self) -> str:
        """A saturation of the input, whatever its shape."""
        return f"saturation of input {self.input}"

    def apply_input(self, x, u, theta):
        level, value = theta[f"{self.name}_level"], u[self.input]
        if self.shape == "tanh":
            return u.at[self.input].set(level * jnp.tanh(value / level))
        s = self.sharpness
        return u.at[self.input].set(value - level * _beyond(value / level, s) / s)

    def describe(self, state_names, output_names, values=None) -> str:
        if self.shape == "clip":
            return "the actuator saturates: the input is clipped at ±u_max"
        return "the actuator saturates: the input acts as u_max tanh(u / u_max)"


class OutputOffset(Effect):
    r"""The measured output reads the model output plus a constant: $z \leftarrow z + b$.

    An uncalibrated sensor whose zero is not the physical zero of the state it measures;
    the dynamics then act on the physical level $z - b$. Parameter ``{name}_offset``
    ($b$).
    """

    target = "output"

    def __init__(self, output: int, *, offset: float = 0.0, name: str = "sensor"):
        self.output, self.offset, self.name = int(output), float(offset), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_offset": Parameter(self.offset)}

    def apply_output(self, x, u, z, theta):
        return z.at[self.output].add(theta[f"{self.name}_offset"])

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the sensor of {output_names[self.output]} reads with a constant offset"


class SensorCalibration(Effect):
    r"""Output ``output`` reads a static polynomial of what the physics predicts.

    An uncalibrated sensor whose reading is not linear in the quantity it measures (a
    level sensor, a thermocouple, a strain gauge):

    $$
    z \leftarrow z + \sum_{k=0}^{d} c_k\,\xi^k, \qquad
    \xi = \frac{z - m}{s},
    $$

    with parameters ``{name}_c0`` ... ``{name}_c{d}`` ($c_k$, in the output's units,
    starting at 0: the declared output map). The centre $m$ and scale $s$
    are fixed numbers taken from the data (the loop uses the mean and standard deviation
    of the simulated output), so $\xi$ is dimensionless and the fitted curve does
    not depend on the units of the data. With $d = 0$ this is
    [`OutputOffset`][sk_offwhite.OutputOffset]; $c_1$ is a gain error, $c_2$ a curvature.
    """

    target = "output"

    def __init__(
        self, output: int, center: float, scale: float, *, degree: int = 2, name: str = "sensor"
    ):
        if not (np.isfinite(center) and np.isfinite(scale) and scale > 0):
            raise ValueError(f"center and scale must be finite, scale > 0; got {center}, {scale}.")
        if isinstance(degree, bool) or int(degree) != degree or degree < 0:
            raise ValueError(f"degree must be an integer >= 0, got {degree!r}.")
        self.output, self.center, self.scale = int(output), float(center), float(scale)
        self.degree, self.name = int(degree), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_c{k}": Parameter(0.0) for k in range(self.degree + 1)}

    def apply_output(self, x, u, z, theta):
        xi = (z[self.output] - self.center) / self.scale
        reading = theta[f"{self.name}_c{self.degree}"]
        for k in range(self.degree - 1, -1, -1):
            reading = reading * xi + theta[f"{self.name}_c{k}"]
        return z.at[self.output].add(reading)

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            f"the sensor of {output_names[self.output]} reads a degree-{self.degree} "
            "polynomial of it (an uncalibrated, nonlinear sensor)"
        )

    @property
    def mechanism(self) -> str:
        """The calibration of one output, whatever its degree (a set holds one)."""
        return f"sensor calibration of output {self.output}"

    def richer(self) -> SensorCalibration:
        """The calibration of degree $d + 1$ (named ``{base}_degree{d+1}``, ``base``
        the name without an earlier ``_degree`` suffix), on the same $m$ and
        $s$."""
        base = re.sub(r"_degree\d+$", "", self.name)
        return self.replace(degree=self.degree + 1, name=f"{base}_degree{self.degree + 1}")


class SensorStep(Effect):
    r"""The reading of output ``output`` steps by a height where it passes a level.

    A sensor whose reading is discontinuous (a seam in a capacitive level strip, a worn
    spot on a potentiometer) jumps each time the quantity passes one value:

    $$
    z \leftarrow z + H\,\sigma\!\left(\frac{z - L}{c}\right),
    $$

    with $\sigma$ the logistic function and parameters ``{name}_level``
    ($L$) and ``{name}_height`` ($H$, positive when the reading steps up as
    the level rises), both in the output's units: below the level the reading is what
    the rest of the model says, above it $H$ more (an offset of the whole reading
    is another effect, [`OutputOffset`][sk_offwhite.OutputOffset]). The step is rounded over
    ``corner`` ($c$, output units; fitted as ``{name}_corner`` with ``fit_corner=True``, see
    [`Overflow`][sk_offwhite.Overflow]); the loop sets it to 2.5 % of the simulated output's
    standard deviation, starts $L$ and $H$ from the measured jumps
    ([`output_jumps`][sk_offwhite.diagnose.output_jumps]) and keeps $L$ within
    ``level_bounds``, the measured values the reading jumped across: the data place the
    step, and a fit may not move it to where it would stand for some other misfit of the
    model. It acts on the final reading, after
    every other output effect ([`Effect.reads_output`][sk_offwhite.Effect.reads_output]), so that
    $L$ is a measured value.
    """

    target = "output"
    reads_output = True

    def __init__(
        self,
        output: int,
        level: float,
        height: float = 0.0,
        *,
        level_bounds=(None, None),
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "step",
    ):
        self.output, self.level, self.height = int(output), float(level), float(height)
        self.level_bounds = tuple(level_bounds)
        self.corner, self.fit_corner = _checked_corner(corner), bool(fit_corner)
        self.name = name

    def parameters(self) -> dict[str, Parameter]:
        return {
            f"{self.name}_level": Parameter(self.level, self.level_bounds),
            f"{self.name}_height": Parameter(self.height),
            **_corner_parameters(self),
        }

    @property
    def mechanism(self) -> str:
        """A step in the reading of the output."""
        return f"step in output {self.output}"

    def apply_output(self, x, u, z, theta):
        reading = z[self.output]
        above = jax.nn.sigmoid((reading - theta[f"{self.name}_level"]) / _hinge_corner(self, theta))
        return z.at[self.output].add(theta[f"{self.name}_height"] * above)

    def describe(self, state_names, output_names, values=None) -> str:
        values = values or {}
        level = values.get(f"{self.name}_level", self.level)
        height = values.get(f"{self.name}_height", self.height)
        return (
            f"the reading of {output_names[self.output]} steps by {height:.3g} where it "
            f"passes {level:.4g} (a discontinuous sensor)"
        )


class AdditiveEffect(Effect):
    r"""A term $g(x, u; \theta_E)$ added to the equation of state ``state``.

    ``basis`` (when the term is $p\,b(x, u)$, linear in its first parameter ``p``,
    the others held) lets the loop start ``p`` from a least-squares fit to a correction.

    For a physics built with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] the term
    is added to the right-hand side, $\dot x_s = r_s(x, u) + g$, and integrated with it, so its
    parameters are rates in the state's units per unit time (per second when the sampling
    time is in seconds); for a discrete-time physics it is added to $x^+_s$ (an
    increment per sample). Subclasses implement `term`.
    """

    state: int

    def term(self, x, u, theta):
        """The added term (a scalar)."""
        raise NotImplementedError

    def basis(self, x, u):
        r"""$b(x, u)$ of a term $p\,b(x, u)$ (numpy rows), else ``None``."""
        return None

    def apply_state(self, x, u, x_next, theta):
        return x_next.at[self.state].add(self.term(x, u, theta))


class Leak(AdditiveEffect):
    r"""A loss proportional to the state: $g = -c\, x_s$.

    Parameter ``{name}_rate`` ($c \ge 0$).
    """

    def __init__(self, state: int, *, rate: float = 0.01, name: str = "leak"):
        self.state, self.rate, self.name = int(state), float(rate), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_rate": Parameter(self.rate, (0.0, None))}

    def term(self, x, u, theta):
        return -theta[f"{self.name}_rate"] * x[self.state]

    def basis(self, x, u):
        return -x[:, self.state]

    def describe(self, state_names, output_names, values=None) -> str:
        return f"{state_names[self.state]} leaks in proportion to its value"


class PowerLoss(AdditiveEffect):
    r"""A loss growing with a fitted power of a state's excess over a level:

    $$
    g = -c\,\Delta \left(\frac{|\Delta|}{\Delta_r}\right)^{a - 1},
    \qquad \Delta = x_s - \ell,
    $$

    on top of the declared loss: a heat loss by convection ($a$ = 5/4 or 4/3), or
    the curvature of a radiative one, where the physics declares Newton's law of cooling,
    whose linear part the declared conductance keeps. Parameters ``{name}_rate``
    ($c \ge 0$: the loss is $c\,\Delta_r$ at $|\Delta| = \Delta_r$
    whatever $a$),
    ``{name}_level`` ($\ell$, in the state's units) and ``{name}_exponent``
    ($a$, in `EXPONENT_BOUNDS`, started at 2: at $a = 1$ the loss is
    linear, which the declared one already is).
    ``reference`` ($\Delta_r > 0$, the loop takes the state's RMS deviation on the
    record) makes the rate convert with the state's units alone.
    """

    EXPONENT_BOUNDS = (1.0, 3.0)

    def __init__(
        self,
        state: int,
        *,
        rate: float = 0.0,
        level: float = 0.0,
        exponent: float = 2.0,
        reference: float = 1.0,
        name: str = "loss",
    ):
        self.state, self.rate, self.level, self.name = int(state), float(rate), float(level), name
        self.exponent = _check_exponent(exponent, self.EXPONENT_BOUNDS)
        self.reference = _check_reference(reference)

    def parameters(self) -> dict[str, Parameter]:
        return {
            f"{self.name}_rate": Parameter(self.rate, (0.0, None)),
            f"{self.name}_level": Parameter(self.level),
            f"{self.name}_exponent": Parameter(self.exponent, self.EXPONENT_BOUNDS),
        }

    def term(self, x, u, theta):
        excess = x[self.state] - theta[f"{self.name}_level"]
        power = signed_power(excess, self.reference, 1, theta[f"{self.name}_exponent"])
        return -theta[f"{self.name}_rate"] * power

    def describe(self, state_names, output_names, values=None) -> str:
        exponent = (values or {}).get(f"{self.name}_exponent", self.exponent)
        return (
            f"{state_names[self.state]} loses in the power {float(exponent):.3g} of its excess "
            "over a level, beyond the declared loss"
        )


class Friction(AdditiveEffect):
    r"""Coulomb (and optionally Stribeck) friction braking a velocity, with a smooth sign.

    $$
    g = -\bigl(F_c + F_s e^{-(v/v_s)^2}\bigr) \tanh(v / w),
    $$

    $v = x_s$ (or ``x[velocity]`` when the friction acts in another state's
    equation). Parameters ``{name}_coulomb`` ($F_c \ge 0$), ``{name}_width``
    ($w > 0$, in the velocity's units: how sharp the sign is; the loop starts it at
    1 % of the velocity's RMS, so it follows the data's units) and, when
    ``stribeck_velocity`` ($v_s$) is given, ``{name}_stribeck``
    ($F_s \ge 0$). ``fit_width=False`` keeps $w$ fixed; with
    ``fit_stribeck_velocity=True`` $v_s$ is fitted too (``{name}_stribeck_velocity``,
    above ``min_width``), from ``stribeck_velocity``. The fitted width stays
    above ``min_width`` (default: 1 % of the starting width): at a width far below every
    speed on the record the sign is flat in $w$, and a fit that overshoots there
    cannot come back (measured on a drive: stuck at the old floor of 1e-12 with a 2 %
    worse fit, from starts 10x too wide or a Coulomb level 300x too small).

    The richer variant of a Coulomb friction (`richer`) is the Stribeck friction
    whose level $F_s$ (from 0) and velocity $v_s$ (from
    `STRIBECK_START` times the starting width: half the
    velocity's RMS as the loop starts it) are both fitted: at $F_s = 0$ it is the Coulomb friction,
    and $v_s$ does not move until $F_s$ does. A broad start is narrowed by the fit; a narrow one is
    not widened (measured on
    [`make_friction_oscillator`][sk_offwhite.datasets.make_friction_oscillator] with
    ``stribeck=0.5``, $v_s = 0.3$, velocity RMS 1.46, the Coulomb fit's width 0.0045 carried: from
    0.145 the fit ended at $F_s = 0.0001$ with validation RMSE 0.0223, the Coulomb friction's; from
    0.3, 0.6, 0.725 and 1.0 at $F_s = 0.478$, $v_s = 0.303$, validation 0.00497,
    the sensor's noise).
    """

    STRIBECK_START = 50.0

    def __init__(
        self,
        state: int,
        *,
        coulomb: float = 0.01,
        width: float = 0.05,
        velocity: int | None = None,
        stribeck_velocity: float | None = None,
        fit_width: bool = True,
        min_width: float | None = None,
        fit_stribeck_velocity: bool = False,
        name: str = "friction",
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        min_width = width / 100.0 if min_width is None else float(min_width)
        if not 0 < min_width <= width:
            raise ValueError(f"min_width must lie in (0, width], got {min_width!r}.")
        if stribeck_velocity is not None and not stribeck_velocity >= min_width:
            raise ValueError(
                f"stribeck_velocity must be at least min_width, got {stribeck_velocity!r}."
            )
        self.state, self.coulomb, self.width = int(state), float(coulomb), float(width)
        self.min_width = min_width
        self.velocity = self.state if velocity is None else int(velocity)
        self.stribeck_velocity = None if stribeck_velocity is None else float(stribeck_velocity)
        self.fit_width, self.name = bool(fit_width), name
        self.fit_stribeck_velocity = bool(fit_stribeck_velocity)

    def parameters(self) -> dict[str, Parameter]:
        params = {
            f"{self.name}_coulomb": Parameter(self.coulomb, (0.0, None)),
            f"{self.name}_width": Parameter(
                self.width, (self.min_width, None), fixed=not self.fit_width
            ),
        }
        if self.stribeck_velocity is not None:
            params[f"{self.name}_stribeck"] = Parameter(0.0, (0.0, None))
        if self.stribeck_velocity is not None and self.fit_stribeck_velocity:
            params[f"{self.name}_stribeck_velocity"] = Parameter(
                self.stribeck_velocity, (self.min_width, None)
            )
        return params

    def term(self, x, u, theta):
        v = x[self.velocity]
        level = theta[f"{self.name}_coulomb"]
        if self.stribeck_velocity is not None:
            speed = theta.get(f"{self.name}_stribeck_velocity", self.stribeck_velocity)
            level = level + theta[f"{self.name}_stribeck"] * jnp.exp(-((v / speed) ** 2))
        return -level * jnp.tanh(v / theta[f"{self.name}_width"])

    def basis(self, x, u):
        return -np.tanh(x[:, self.velocity] / self.width)

    def describe(self, state_names, output_names, values=None) -> str:
        kind = "Coulomb" if self.stribeck_velocity is None else "Coulomb and Stribeck"
        return f"{state_names[self.velocity]} is braked by a {kind} friction"

    @property
    def mechanism(self) -> str:
        """The friction on ``velocity`` in ``state``'s equation, whatever its law."""
        return f"friction of state {self.velocity} in state {self.state}"

    def richer(self) -> Friction | None:
        """The Stribeck friction of fitted level and velocity (named ``{name}_stribeck``)
        of a Coulomb friction; ``None`` for a friction that has a Stribeck term."""
        if self.stribeck_velocity is not None:
            return None
        return self.replace(
            stribeck_velocity=self.STRIBECK_START * self.width, fit_stribeck_velocity=True,
            name=f"{self.name}_stribeck",
        )  # fmt: skip

    def richer_start(self, values: dict) -> dict:
        """The Coulomb level carried over, the Stribeck level at 0; the width carried over
        unless the fit made it sharper than it started, where it restarts (a sign far
        sharper than every speed on the record is flat in $w$: from there the
        Stribeck fit could not smooth it again)."""
        start = super().richer_start(values)
        width = values[f"{self.name}_width"]
        if start and getattr(width, "value", width) < self.width:
            richer = self.richer()
            start[f"{richer.name}_width"] = richer.parameters()[f"{richer.name}_width"]
        return start


class Bias(AdditiveEffect):
    r"""A constant in the equation of state ``state``: $g = b$ (a force offset, a
    constant inflow, a heat source). Parameter ``{name}_value``."""

    def __init__(self, state: int, *, value: float = 0.0, name: str = "bias"):
        self.state, self.value, self.name = int(state), float(value), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_value": Parameter(self.value)}

    def term(self, x, u, theta):
        return theta[f"{self.name}_value"]

    def basis(self, x, u):
        return np.ones(len(x))

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the {state_names[self.state]} equation has a constant term (an offset)"


def signed_power(v, reference: float, base: int, exponent, xp=jnp):
    r"""$v|v|^{b-1} (|v|/v_r)^{a-b}$, $b$ = ``base``, $a$ = ``exponent``,
    $v_r$ = ``reference``: the signed power $a$ of $v$ whose size at
    $|v| = v_r$ does not depend on $a$, and which is $v|v|^{b-1}$ at
    $a = b$. Zero at $v = 0$, where the power of the zero ratio is left out,
    so that no $\log 0$ reaches the derivative in $a$ (``xp``: ``jax.numpy``,
    or ``numpy`` for the basis)."""
    ratio = xp.abs(v) / reference
    moving = ratio > 0
    safe_ratio = xp.where(moving, ratio, 1.0)
    scale = xp.where(moving, safe_ratio ** (exponent - base), 0.0)
    return v * xp.abs(v) ** (base - 1) * scale


def _check_reference(reference: float) -> float:
    if not (np.isfinite(reference) and reference > 0):
        raise ValueError(f"reference must be finite and positive, got {reference!r}.")
    return float(reference)


def _check_exponent(exponent: float, bounds: tuple[float, float]) -> float:
    lower, upper = bounds
    if not lower <= exponent <= upper:
        raise ValueError(f"exponent must lie in [{lower}, {upper}], got {exponent!r}.")
    return float(exponent)


class Stiffness(AdditiveEffect):
    r"""A polynomial restoring term: $g = -k\, q |q|^{p-1}$ with $q = x_{position}$.

    ``power`` $p \ge 2$ (3: a hardening / softening cubic spring, $k > 0$
    hardens). Parameter ``{name}_coefficient`` ($k$, either sign). ``reference``
    ($q_r > 0$, in the position's units; the loop takes the position's RMS on the
    record) is the scale at which the richer variant,
    [`PowerStiffness`][sk_offwhite.PowerStiffness], keeps $k$'s meaning.
    """

    def __init__(
        self,
        state: int,
        position: int,
        *,
        power: int = 3,
        coefficient: float = 0.0,
        reference: float = 1.0,
        name: str = "stiffness",
    ):
        if int(power) < 2:
            raise ValueError(f"power must be >= 2, got {power!r}.")
        self.state, self.position, self.power = int(state), int(position), int(power)
        self.coefficient, self.name = float(coefficient), name
        self.reference = _check_reference(reference)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_coefficient": Parameter(self.coefficient)}

    def term(self, x, u, theta):
        q = x[self.position]
        return -theta[f"{self.name}_coefficient"] * q * jnp.abs(q) ** (self.power - 1)

    def basis(self, x, u):
        q = x[:, self.position]
        return -q * np.abs(q) ** (self.power - 1)

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            f"the {state_names[self.state]} equation has a restoring term in "
            f"{state_names[self.position]}^{self.power} (a nonlinear stiffness)"
        )

    @property
    def mechanism(self) -> str:
        """The nonlinear spring on ``position`` in ``state``'s equation, whatever its law."""
        return f"stiffness of state {self.position} in state {self.state}"

    def richer(self) -> PowerStiffness:
        """The spring of fitted exponent ([`PowerStiffness`][sk_offwhite.PowerStiffness], named
        ``{name}_power``), started at ``power``, on the same reference position."""
        return PowerStiffness(
            self.state, self.position, power=self.power, reference=self.reference,
            name=f"{self.name}_power",
        )  # fmt: skip


class PowerStiffness(Stiffness):
    r"""A restoring term of fitted exponent:

    $$
    g = -k\, q|q|^{p-1} \left(\frac{|q|}{q_r}\right)^{a - p}
      = -k\, q_r^{p - a}\, \mathrm{sign}(q) |q|^{a},
    $$

    $q = x_{position}$. Parameters ``{name}_coefficient`` ($k$, either sign,
    in the units of [`Stiffness`][sk_offwhite.Stiffness]'s of power $p$) and ``{name}_exponent``
    ($a$ in $[1, p + 2]$, starting at ``power``). At $a = p$ it
    is the spring of power $p$. The fixed reference position $q_r$ (the loop
    takes the position's RMS) makes $k$ the term's size at a typical deflection
    whatever $a$, so the fit of $a$ does not trade off against $k$
    through the units of $q$.
    """

    def __init__(
        self,
        state: int,
        position: int,
        *,
        power: int = 3,
        coefficient: float = 0.0,
        exponent: float | None = None,
        reference: float = 1.0,
        name: str = "stiffness_power",
    ):
        super().__init__(
            state, position, power=power, coefficient=coefficient, reference=reference,
            name=name,
        )  # fmt: skip
        exponent = float(self.power) if exponent is None else exponent
        self.exponent = _check_exponent(exponent, self.exponent_bounds)

    @property
    def exponent_bounds(self) -> tuple[float, float]:
        """$[1, p + 2]$: from a linear spring to two powers beyond the declared one."""
        return (1.0, self.power + 2.0)

    def parameters(self) -> dict[str, Parameter]:
        return {
            **super().parameters(),
            f"{self.name}_exponent": Parameter(self.exponent, self.exponent_bounds),
        }

    def term(self, x, u, theta):
        exponent = theta[f"{self.name}_exponent"]
        power = signed_power(x[self.position], self.reference, self.power, exponent)
        return -theta[f"{self.name}_coefficient"] * power

    def basis(self, x, u):
        q = x[:, self.position]
        return -signed_power(q, self.reference, self.power, self.exponent, xp=np)

    def describe(self, state_names, output_names, values=None) -> str:
        exponent = (values or {}).get(f"{self.name}_exponent", self.exponent)
        return (
            f"the {state_names[self.state]} equation has a restoring term in "
            f"{state_names[self.position]} to the power {float(exponent):.3g} (a nonlinear "
            "stiffness)"
        )

    def richer(self) -> None:
        """None: the exponent is already free."""
        return None


class QuadraticDrag(AdditiveEffect):
    r"""Drag growing with the square of a velocity: $g = -c\, v|v|$, $v = x_s$.

    Parameter ``{name}_coefficient`` ($c \ge 0$). ``reference`` ($v_r > 0$, in
    the velocity's units; the loop takes the velocity's RMS on the record) is the scale at
    which the richer variant, [`PowerDrag`][sk_offwhite.PowerDrag], keeps $c$'s meaning.
    """

    def __init__(
        self, state: int, *, coefficient: float = 0.0, reference: float = 1.0, name="drag"
    ):
        self.state, self.coefficient, self.name = int(state), float(coefficient), name
        self.reference = _check_reference(reference)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_coefficient": Parameter(self.coefficient, (0.0, None))}

    def term(self, x, u, theta):
        v = x[self.state]
        return -theta[f"{self.name}_coefficient"] * v * jnp.abs(v)

    def basis(self, x, u):
        v = x[:, self.state]
        return -v * np.abs(v)

    def describe(self, state_names, output_names, values=None) -> str:
        return f"{state_names[self.state]} is braked by a drag in its square"

    @property
    def mechanism(self) -> str:
        """The drag on state ``state``, whatever its law (a set holds one)."""
        return f"drag of state {self.state}"

    def richer(self) -> PowerDrag:
        """The drag of fitted exponent ([`PowerDrag`][sk_offwhite.PowerDrag], named
        ``{name}_power``) on the same reference velocity."""
        return PowerDrag(self.state, reference=self.reference, name=f"{self.name}_power")


class PowerDrag(QuadraticDrag):
    r"""Drag growing with a fitted power of a velocity:

    $$
    g = -c\, v|v| \left(\frac{|v|}{v_r}\right)^{a - 2}
      = -c\, v_r^{2 - a}\, \mathrm{sign}(v) |v|^{a},
    $$

    $v = x_s$. Parameters ``{name}_coefficient`` ($c \ge 0$, in the units of
    [`QuadraticDrag`][sk_offwhite.QuadraticDrag]'s) and ``{name}_exponent`` ($a$, in
    `EXPONENT_BOUNDS`, starting at ``exponent``). At $a = 2$ it is the quadratic drag; $a = 1$ a
    viscous one; between them the drag of a flow neither laminar nor turbulent. The fixed
    reference velocity $v_r$ (the loop takes the velocity's RMS) makes $c$ the
    drag's size at a typical speed whatever $a$, so the fit of $a$ does not
    trade off against $c$ through the units of $v$.
    """

    EXPONENT_BOUNDS = (1.0, 3.0)

    def __init__(
        self,
        state: int,
        *,
        coefficient: float = 0.0,
        exponent: float = 2.0,
        reference: float = 1.0,
        name: str = "drag_power",
    ):
        super().__init__(state, coefficient=coefficient, reference=reference, name=name)
        self.exponent = _check_exponent(exponent, self.EXPONENT_BOUNDS)

    def parameters(self) -> dict[str, Parameter]:
        return {
            **super().parameters(),
            f"{self.name}_exponent": Parameter(self.exponent, self.EXPONENT_BOUNDS),
        }

    def term(self, x, u, theta):
        power = signed_power(x[self.state], self.reference, 2, theta[f"{self.name}_exponent"])
        return -theta[f"{self.name}_coefficient"] * power

    def basis(self, x, u):
        return -signed_power(x[:, self.state], self.reference, 2, self.exponent, xp=np)

    def describe(self, state_names, output_names, values=None) -> str:
        exponent = (values or {}).get(f"{self.name}_exponent", self.exponent)
        return f"{state_names[self.state]} is braked by a drag in its power {float(exponent):.3g}"

    def richer(self) -> None:
        """None: the exponent is already free."""
        return None


class DeadZone(Effect):
    r"""Input ``input`` acts only beyond a dead zone of half-width $w$.

    $u_j \leftarrow w\,[\mathrm{sp}(s(u_j/w - 1)) - \mathrm{sp}(s(-u_j/w - 1))]/s$,
    a smooth $\mathrm{sign}(u)\max(|u| - w, 0)$ ($\mathrm{sp}$ the softplus,
    $s$ = ``sharpness``, relative to $w$, so the smoothing follows the input's
    units). Parameter ``{name}_width`` ($w > 0$, kept above `RELATIVE_FLOOR`
    of its start, as every positive width of this module).
    """

    target = "input"

    def __init__(self, input: int, width: float, *, sharpness: float = SHARPNESS, name="dead_zone"):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.width, self.sharpness, self.name = (
            int(input),
            float(width),
            sharpness,
            name,
        )

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    def apply_input(self, x, u, theta):
        width, s = theta[f"{self.name}_width"], self.sharpness
        return u.at[self.input].set(width * _beyond(u[self.input] / width, s) / s)

    def describe(self, state_names, output_names, values=None) -> str:
        return "the actuator has a dead zone: inputs smaller than a width do nothing"


class DifferenceDeadZone(Effect):
    r"""Input ``input`` drives the physics through its difference with state ``state``,
    and that difference acts only beyond a threshold $w$.

    With the drive $d = u_j - x_i$ (both in the same units: a source and a capacitor
    voltage, a commanded and a measured position, a supply and a tank level), the declared
    step sees $u_j \leftarrow x_i + g(d)$ in place of $u_j$, so every term in
    $u_j - x_i$ becomes $g(d)$:

    * ``one_sided=False``: $g(d) = \mathrm{sign}(d)\max(|d| - w, 0)$, a dead zone
      (a clearance in a spring, two anti-parallel diodes);
    * ``one_sided=True``: $g(d) = \max(d - w, 0)$, conduction in one direction only
      past a forward drop (a diode, a check valve's cracking pressure).

    Both are smoothed as [`DeadZone`][sk_offwhite.DeadZone] (softplus, $s$ = ``sharpness``, relative
    to $w$, so the rounding follows the variables' units). Parameter
    ``{name}_width`` ($w > 0$, in the state's units). Both shapes are one mechanism:
    a set holds at most one of them.
    """

    target = "input"

    def __init__(
        self,
        input: int,
        state: int,
        width: float,
        *,
        one_sided: bool = False,
        sharpness: float = SHARPNESS,
        name: str = "drop",
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.state, self.width = int(input), int(state), float(width)
        self.one_sided, self.sharpness, self.name = bool(one_sided), float(sharpness), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    @property
    def mechanism(self) -> str:
        """A threshold on the drive ``u_j - x_i``, whichever its shape."""
        return f"threshold on input {self.input} minus state {self.state}"

    def apply_input(self, x, u, theta):
        width, s, level = theta[f"{self.name}_width"], self.sharpness, x[self.state]
        passed = _beyond((u[self.input] - level) / width, s, self.one_sided)
        return u.at[self.input].set(level + width * passed / s)

    def describe(self, state_names, output_names, values=None) -> str:
        drive = f"the difference between its input and {state_names[self.state]}"
        if self.one_sided:
            return f"{drive} drives it in one direction only, past a forward drop (a diode)"
        return f"{drive} acts only beyond a dead zone (a clearance)"


class Backlash(Effect):
    r"""Input ``input`` drives the plant through a play of half-width $w$ (backlash).

    The driven side's position $p$ is a hidden state: it stays where it is until the
    input pushes it from one side of the play,

    $$
    p_{k+1} = \mathrm{clip}(p_k,\ u_k - w,\ u_k + w)
    \approx p_k + \eta(u_k - w - p_k) - \eta(p_k - u_k - w),
    \qquad \eta(a) = \frac{w}{s}\,\mathrm{sp}\Bigl(\frac{s\,a}{w}\Bigr),
    $$

    and the declared step sees $p_{k+1}$ in place of $u_k$ ($\mathrm{sp}$
    the softplus, $s$ = ``sharpness``, relative to $w$, so the smoothing
    follows the input's units). A gear's or a lead screw's play between a commanded position
    and the load: proposed for inputs of kind ``"position"`` or ``"angle"``. Parameter
    ``{name}_width`` ($w > 0$, in the input's units); hidden state
    ``{name}_position`` ($p$, started at ``position`` and estimated with the initial
    state).
    """

    target = "hidden"

    def __init__(
        self, input: int, width: float, *, position=0.0, sharpness=SHARPNESS, name="backlash"
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.width, self.position = int(input), float(width), float(position)
        self.sharpness, self.name = sharpness, name

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return (f"{self.name}_position",)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    def hidden_initial(self) -> tuple[float, ...]:
        return (self.position,)

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return (input_kinds[self.input],)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        r"""The guess where the play holds it at the first input ($|p - u| \le w$),
        else the input itself: beyond the play the first step moves $p$ to its edge
        whatever the guess, so a fit started there cannot move it."""
        position, command = float(hidden[0]), float(u[self.input])
        inside = abs(position - command) <= float(theta[f"{self.name}_width"])
        return (position if inside else command,)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        r"""The record's input range widened by itself on each side,
        $[\min u - R,\ \max u + R]$ with $R = \max u - \min u$. A start
        farther out is held at the play's edge by the first step as long as $w \le R$
        (a wider play never moves), so the bounds remove no model; without them a fit
        can run the start along that flat direction (measured on the servo:
        $1.7\cdot10^{14}$ rad, where doubles are 0.03 rad apart against a half-width
        of 0.05). A constant input ($R = 0$) bounds nothing."""
        return (_widened_range(u, self.input),)

    def advance(self, hidden, u, theta):
        width, s = theta[f"{self.name}_width"], self.sharpness
        position, command = hidden[0], u[self.input]

        def push(gap):
            return width * jax.nn.softplus(s * gap / width) / s

        moved = position + push(command - width - position) - push(position - command - width)
        return u.at[self.input].set(moved), jnp.reshape(moved, (1,))

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            "the transmission has play (backlash): the load follows the input only once "
            "the input has crossed the play"
        )


class FirstOrderLag(Effect):
    """What the first-order lags of an input ([`InputLag`][sk_offwhite.InputLag]) and of an output
    ([`SensorLag`][sk_offwhite.SensorLag]) share: the time constant $\\tau$, a positive
    parameter ``{name}_time_constant`` in the effects' unit of time, like the sampling time
    $T_s$, and one hidden state started at ``initial``."""

    target = "hidden"

    def _set_lag(self, time_constant, sampling_time, initial, name) -> None:
        self.time_constant = checked_positive(time_constant, "time_constant")
        self.sampling_time = checked_positive(sampling_time, "sampling_time")
        self.initial, self.name = float(initial), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_time_constant": _positive(self.time_constant)}

    def hidden_initial(self) -> tuple[float, ...]:
        return (self.initial,)

    def ratio(self, theta):
        r"""$\tau / T_s$ at the parameters ``theta``."""
        return theta[f"{self.name}_time_constant"] / self.sampling_time


class InputLag(FirstOrderLag):
    r"""Input ``input`` reaches the plant through a first-order lag (actuator dynamics).

    A drive's amplifier, a valve's positioner, a heater's element: the actuator's output
    $p$ follows the command with a time constant $\tau$ that the declared
    physics leaves out. Held over each sample (zero-order hold), exactly,

    $$
    p_{k+1} = p_k + \alpha\,(u_k - p_k), \qquad
    \tilde u_k = p_k + \beta\,(u_k - p_k), \qquad
    \alpha = 1 - e^{-T_s/\tau}, \quad \beta = 1 - \frac{\tau}{T_s}\,\alpha,
    $$

    where $\tilde u_k$, what the declared step sees, is the lag's mean over the
    sample. As $\tau \to 0$ it is the command itself (the declared model), so a fit
    started at a short lag starts near the declared model. Parameter
    ``{name}_time_constant`` ($\tau > 0$, in the effects' unit of time,
    `time_step`, like ``sampling_time`` $T_s$); hidden state
    ``{name}_output`` ($p$, started at ``initial``, the actuator settled at the
    first command, and estimated with the initial state).
    """

    def __init__(
        self,
        input: int,
        time_constant: float,
        *,
        sampling_time: float = 1.0,
        initial: float = 0.0,
        name: str = "lag",
    ):
        self.input = int(input)
        self._set_lag(time_constant, sampling_time, initial, name)

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return (f"{self.name}_output",)

    @property
    def mechanism(self) -> str:
        """The dynamics of one input's actuator."""
        return f"dynamics of input {self.input}"

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return (input_kinds[self.input],)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        """The actuator settled at the first command."""
        return (float(u[self.input]),)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        r"""The record's input range widened by itself on each side (the lag's output is
        an average of commands, $[\min u - R,\ \max u + R]$); a constant input
        bounds nothing."""
        return (_widened_range(u, self.input),)

    def advance(self, hidden, u, theta):
        alpha, beta = lag_coefficients(self.ratio(theta))
        output, gap = hidden[0], u[self.input] - hidden[0]
        seen = output + beta * gap
        return u.at[self.input].set(seen), jnp.reshape(output + alpha * gap, (1,))

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            "the actuator lags its command: the input acts through a first-order lag "
            "(its time constant fitted)"
        )


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
        from ._basis import compile_basis

        with jax.ensure_compile_time_eval():  # compiled eagerly, also when called in a trace
            return compile_basis(self.library, self.input_features, 1)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_coefficient": Parameter(self.coefficient)}

    def term(self, x, u, theta):
        basis = self._compiled()
        phi = basis.evaluate(basis.init_params, jnp.concatenate([x, jnp.atleast_1d(u)]))
        return theta[f"{self.name}_coefficient"] * phi[0, self.column]

    def basis(self, x, u):
        from ._basis import evaluate_matrix

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
        from ._basis import _library_key

        library = _library_key(self.library, self.input_features, 1) or id(self.library)
        return (DictionaryTerm, self.state, library, self.column, self.coefficient, self.name)


class Switched(Effect):
    r"""``effect`` behind a switch: a fixed parameter ``{name}_on`` ($s$) says
    whether it acts,

    $$
    u \leftarrow E(u) \text{ if } s > \tfrac12 \text{ else } u
    $$

    (and likewise for the state update and the output), so $s = 1$ is the effect,
    exactly as [`augment`][sk_offwhite.augment] adds it, and $s = 0$ the model without it. The
    switch is a parameter value, not structure: models that differ only in which effects are on
    share one compiled program (``LoopSettings(share_programs=True)`` fits the loop's
    candidate sets this way, see `sk_offwhite.loop._switchboard`). An effect that is off is not
    computed (a ``lax.cond`` on the switch) and has zero derivatives; a fit leaves its
    parameters where they start. The memory of an effect whose hidden states follow the
    inputs alone (``hidden_free`` false: a dead time's past commands) follows them on or
    off, so a shooting window starts it where the inputs put it either way.
    """

    def __init__(self, effect: Effect):
        if not isinstance(effect, Effect) or isinstance(effect, Switched):
            raise TypeError(f"Switched takes an Effect that is not switched, got {effect!r}.")
        self.effect, self.name, self.target = effect, effect.name, effect.target

    @property
    def reads_output(self) -> bool:
        return self.effect.reads_output

    @property
    def switch(self) -> str:
        """Name of the switch parameter."""
        return f"{self.name}_on"

    def parameters(self) -> dict[str, Parameter]:
        return {**self.effect.parameters(), self.switch: _switch_value(True)}

    def on(self, theta):
        """Whether the effect acts (a traced boolean)."""
        return theta[self.switch] > 0.5

    def apply_input(self, x, u, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_input(x, u, theta), u)

    def apply_state(self, x, u, x_next, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_state(x, u, x_next, theta), x_next)

    def apply_output(self, x, u, z, theta):
        return _if_on(self.on(theta), lambda: self.effect.apply_output(x, u, z, theta), z)

    @property
    def hidden_states(self) -> tuple[str, ...]:
        return self.effect.hidden_states

    def hidden_initial(self) -> tuple[float, ...]:
        return self.effect.hidden_initial()

    def hidden_kinds(self, input_kinds) -> tuple[str, ...]:
        return self.effect.hidden_kinds(input_kinds)

    def hidden_start(self, hidden, u, theta) -> tuple[float, ...]:
        return self.effect.hidden_start(hidden, u, theta)

    def hidden_bounds(self, u) -> tuple[tuple[float, float], ...]:
        return self.effect.hidden_bounds(u)

    @property
    def hidden_free(self) -> bool:
        return self.effect.hidden_free

    def hidden_path(self, u, theta) -> np.ndarray:
        return self.effect.hidden_path(u, theta)

    def advance(self, hidden, u, theta):
        if self.effect.hidden_free:
            return _if_on(
                self.on(theta), lambda: self.effect.advance(hidden, u, theta), (u, hidden)
            )
        seen, memory = self.effect.advance(hidden, u, theta)  # the inputs' memory, on or off
        return _if_on(self.on(theta), lambda: seen, u), memory

    @property
    def follows_output(self) -> bool:
        return self.effect.follows_output

    @property
    def output(self) -> int:
        """The output the effect acts on or reads (when it has one)."""
        return self.effect.output

    def follow(self, hidden, now, after, theta):
        off = self.effect.follow_off(hidden, now, after)
        return _if_on(self.on(theta), lambda: self.effect.follow(hidden, now, after, theta), off)

    def describe(self, state_names, output_names, values=None) -> str:
        return self.effect.describe(state_names, output_names, values)


class SwitchedTerm(Switched, AdditiveEffect):
    """[`Switched`][sk_offwhite.Switched] for an [`AdditiveEffect`][sk_offwhite.AdditiveEffect]: the
    term, or zero when off (inside the integrated right-hand side of a continuous-time model, like
    the term itself)."""

    def __init__(self, effect: AdditiveEffect):
        super().__init__(effect)
        self.state = effect.state

    def term(self, x, u, theta):
        return _if_on(self.on(theta), lambda: self.effect.term(x, u, theta), jnp.zeros_like(x[0]))

    def basis(self, x, u):
        return self.effect.basis(x, u)


def _if_on(on, changed, unchanged):
    """``changed()`` where the switch ``on`` is set, else ``unchanged`` (arrays or a tuple
    of them, ``changed()`` cast to their types); a switched-off effect is not computed."""
    unchanged = jax.tree.map(jnp.asarray, unchanged)

    def computed():
        return jax.tree.map(lambda new, old: jnp.asarray(new, old.dtype), changed(), unchanged)

    return jax.lax.cond(on, computed, lambda: unchanged)


def switched(effect: Effect) -> Switched:
    """``effect`` behind a switch (`SwitchedTerm` for an additive term)."""
    return SwitchedTerm(effect) if isinstance(effect, AdditiveEffect) else Switched(effect)


def switches(effects, on) -> dict[str, Parameter]:
    """Switch parameters of the switched ``effects``: ``1`` for those in ``on``, else ``0``
    (to pass to [`PhysicsModel.with_parameters`][sk_offwhite.PhysicsModel.with_parameters])."""
    names = {e.name for e in on}
    return {e.switch: _switch_value(e.name in names) for e in effects}


def _switch_value(on: bool) -> Parameter:
    return Parameter(float(on), (0.0, 1.0), fixed=True)


class _EffectChain:
    """A base map and the effects applied around it; compared by value (a ``jit`` static
    argument), picklable."""

    def __init__(self, base, effects: tuple[Effect, ...]):
        self.base, self.effects = base, effects

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and (self.base, self.effects) == (
            other.base,
            other.effects,
        )

    def __hash__(self) -> int:
        return hash((type(self), self.base, self.effects))


class AugmentedStep(_EffectChain):
    """``step`` of an augmented model: input effects, the base step, then state effects."""

    def __call__(self, x, u, theta):
        u_seen = u
        for effect in self.effects:
            u_seen = effect.apply_input(x, u_seen, theta)
        x_next = jnp.asarray(self.base(x, u_seen, theta), dtype=x.dtype).reshape(x.shape)
        for effect in self.effects:
            x_next = effect.apply_state(x, u, x_next, theta)
        return x_next


class AugmentedOutput(_EffectChain):
    """``output`` of an augmented model: the base map, then each output effect in turn."""

    def __call__(self, x, u, theta):
        z = jnp.atleast_1d(self.base(x, u, theta))
        for effect in self.effects:
            z = effect.apply_output(x, u, z, theta)
        return z


class AugmentedRhs(_EffectChain):
    """Right-hand side of an augmented continuous-time model: input effects, the declared
    right-hand side, then the additive terms."""

    def __init__(self, base, effects: tuple[Effect, ...]):
        super().__init__(base, effects)
        self.__name__ = getattr(base, "__name__", "rhs")  # names the discretised step

    def __call__(self, x, u, theta):
        u_seen = u
        for effect in self.effects:
            u_seen = effect.apply_input(x, u_seen, theta)
        rate = jnp.asarray(self.base(x, u_seen, theta), dtype=x.dtype).reshape(x.shape)
        for effect in self.effects:
            if isinstance(effect, AdditiveEffect):
                rate = rate.at[effect.state].add(effect.term(x, u, theta))
        return rate


def time_step(physics: PhysicsModel) -> float:
    """The unit of time of the effects' rates: the sampling time of a physics built with
    [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], else 1 (one sample)."""
    return float(physics.sampling_time) if _continuous(physics) else 1.0


def _continuous(physics: PhysicsModel) -> bool:
    declared = getattr(physics, "declared", (physics.step,))[0]
    return isinstance(declared, DiscretizedStep)


def _in_rhs(effect: Effect) -> bool:
    return isinstance(effect, AdditiveEffect) or effect.target == "input"


def _step(declared_step, effects: tuple[Effect, ...]):
    """The augmented step: additive and input effects inside the integrated right-hand
    side of a continuous-time model, the others after the step."""
    after = effects
    if isinstance(declared_step, DiscretizedStep):
        inside = tuple(e for e in effects if _in_rhs(e))
        after = tuple(e for e in effects if not _in_rhs(e))
        if inside:
            rhs = AugmentedRhs(declared_step.rhs, inside)
            sampling_time = declared_step.dt * declared_step.n_substeps
            declared_step = DiscretizedStep(
                rhs, sampling_time, declared_step.method, declared_step.n_substeps
            )
    return AugmentedStep(declared_step, after) if after else declared_step


def _merged_parameters(physics: PhysicsModel, effects) -> dict[str, Parameter]:
    parameters = dict(physics.parameters)
    for effect in effects:
        for name, spec in effect.parameters().items():
            relaxing = effect.replaces_declared and getattr(parameters.get(name), "relaxable", 0)
            if name in parameters and not relaxing:
                raise ValueError(
                    f"effect parameter {name!r} clashes with an existing parameter; "
                    "give the effect another name=."
                )
            parameters[name] = spec
    return parameters


def augment(physics: PhysicsModel, *effects: Effect) -> PhysicsModel:
    """A copy of ``physics`` with ``effects`` added to its step and output map.

    Parameters
    ----------
    physics : PhysicsModel
        The declared model; it is not modified.
    *effects : Effect
        Effects applied in order after the declared step (state effects) and output map
        (output effects; those that act on the final reading,
        [`Effect.reads_output`][sk_offwhite.Effect.reads_output], after the others); for a physics
        built with [`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode], input effects and
        [`AdditiveEffect`][sk_offwhite.AdditiveEffect] terms act inside the integrated right-hand
        side instead. Effects with memory ([`Backlash`][sk_offwhite.Backlash]) act first, on the
        input, through hidden states of their own. Their parameters are appended to the model's, by
        name. Augmenting an augmented model adds to its effects.

    Returns
    -------
    PhysicsModel
        Same states, inputs, names, initial-state settings and constraints; the hidden
        states of the effects that have some are appended to the states (with free initial
        values, see `sk_offwhite._hidden`), and ``n_declared_states`` counts the
        declared ones.
    """
    for effect in effects:
        if not isinstance(effect, Effect):
            raise TypeError(f"effects must be Effect instances, got {effect!r}.")
    declared = getattr(physics, "declared", (physics.step, physics.output))
    everything = tuple(getattr(physics, "effects", ())) + tuple(effects)
    states = tuple(e for e in everything if e.target in ("input", "state"))
    outputs = tuple(e for e in everything if e.target == "output" and not e.reads_output)
    outputs += tuple(e for e in everything if e.target == "output" and e.reads_output)
    model = PhysicsModel.__new__(PhysicsModel)
    model.__dict__.update(physics.__dict__)
    model.declared = declared
    model.step = _step(declared[0], states) if states else declared[0]
    model.output = AugmentedOutput(declared[1], outputs) if outputs else declared[1]
    model.parameters = _merged_parameters(physics, effects)
    model.effects = everything
    hidden = tuple(e for e in everything if e.hidden_states)
    if hidden:
        with_hidden_states(model, physics, hidden, tuple(e for e in effects if e.hidden_states))
    readings = sensor_readings(model.step)
    if readings:
        base = SensorReading(declared[1], model.n_declared_states, readings)
        model.output = AugmentedOutput(base, outputs) if outputs else base
    return model
