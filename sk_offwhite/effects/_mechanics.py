r"""Mechanics: friction, nonlinear springs and drags, each with a richer variant of fitted
exponent or Stribeck term."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model._physics import Parameter
from ._base import AdditiveEffect
from ._terms import _check_exponent, _check_reference, signed_power

__all__ = [
    "DirectionalDamping",
    "Friction",
    "PositionForce",
    "PowerDrag",
    "PowerStiffness",
    "QuadraticDrag",
    "Stiffness",
]


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
    cannot come back.

    With ``position`` (the index of a position state $q$), the level varies along the
    stroke, as a worn or unevenly preloaded guide's or screw's does:

    $$
    g = -\bigl(F_c + F_s e^{-(v/v_s)^2}\bigr)\, e^{\,a (q - q_c)/q_r} \tanh(v / w),
    $$

    with the centre $q_c$ (``center``) and scale $q_r$ (``reference``) in the position's
    units (the position's mean and standard deviation on the record make the gradient
    independent of the position's origin and unit) and the unit-free gradient
    ``{name}_gradient`` ($a$, either sign, from 0: the friction of constant level).

    The richer variant of a Coulomb friction (`richer`) is the Stribeck friction
    whose level $F_s$ (from 0) and velocity $v_s$ (from
    `STRIBECK_START` times the starting width: half the
    velocity's RMS as the loop starts it) are both fitted: at $F_s = 0$ it is the Coulomb friction,
    and $v_s$ does not move until $F_s$ does. A broad start is narrowed by the fit; a narrow one is
    not widened: started below the true Stribeck velocity, the fit can leave $F_s$ near 0,
    at the Coulomb friction's error, which is why the start is broad.
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
        position: int | None = None,
        center: float = 0.0,
        reference: float = 1.0,
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
        self.position = None if position is None else int(position)
        self.center, self.reference = float(center), _check_reference(reference)

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
        if self.position is not None:
            params[f"{self.name}_gradient"] = Parameter(0.0)
        return params

    def term(self, x, u, theta):
        v = x[self.velocity]
        level = theta[f"{self.name}_coulomb"]
        if self.stribeck_velocity is not None:
            speed = theta.get(f"{self.name}_stribeck_velocity", self.stribeck_velocity)
            level = level + theta[f"{self.name}_stribeck"] * jnp.exp(-((v / speed) ** 2))
        if self.position is not None:
            along = (x[self.position] - self.center) / self.reference
            level = level * jnp.exp(theta[f"{self.name}_gradient"] * along)
        return -level * jnp.tanh(v / theta[f"{self.name}_width"])

    def basis(self, x, u):
        return -np.tanh(x[:, self.velocity] / self.width)

    def describe(self, state_names, output_names, values=None) -> str:
        kind = "Coulomb" if self.stribeck_velocity is None else "Coulomb and Stribeck"
        text = f"{state_names[self.velocity]} is braked by a {kind} friction"
        if self.position is None:
            return text
        gradient = float((values or {}).get(f"{self.name}_gradient", 0.0))
        trend = "rises" if gradient > 0 else "falls" if gradient < 0 else "varies"
        return f"{text} whose level {trend} along {state_names[self.position]}"


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
            f"{state_names[self.position]}^{self.power} (a {self._kind(values)}stiffness)"
        )

    def _kind(self, values) -> str:
        """``"hardening "`` or ``"softening "`` by the sign of the fitted coefficient in
        ``values``; ``"nonlinear "`` without it."""
        k = (values or {}).get(f"{self.name}_coefficient")
        if k is None or k == 0:
            return "nonlinear "
        return "hardening " if k > 0 else "softening "


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
            f"{state_names[self.position]} to the power {float(exponent):.3g} (a "
            f"{self._kind(values)}stiffness)"
        )


class PositionForce(AdditiveEffect):
    r"""A force that varies with a position: a spring, a cable or hose that the carriage
    drags, a slope, a magnet's pull; a polynomial of the position about a centre,

    $$
    g = \sum_{d=1}^{D} c_d \left(\frac{q - q_c}{q_r}\right)^d, \qquad q = x_{position},
    $$

    of ``degree`` $D \ge 1$, with the centre $q_c$ (``center``) and scale $q_r$
    (``reference``) in the position's units (with the position's mean and standard
    deviation on the record the coefficients do not depend on where the position's origin
    lies or on its unit). Parameters ``{name}_c1`` ... ``{name}_c{D}``
    (rates of the equation's state, either sign; $c_1$ from ``c1``, the others from 0).
    A constant force is a [`Bias`][sk_offwhite.Bias]; a restoring force about the
    position's origin, a [`Stiffness`][sk_offwhite.Stiffness].
    """

    def __init__(
        self,
        state: int,
        position: int,
        *,
        degree: int = 2,
        c1: float = 0.0,
        center: float = 0.0,
        reference: float = 1.0,
        name: str = "position_force",
    ):
        if int(degree) < 1:
            raise ValueError(f"degree must be >= 1, got {degree!r}.")
        self.state, self.position, self.degree = int(state), int(position), int(degree)
        self.c1, self.center = float(c1), float(center)
        self.reference, self.name = _check_reference(reference), name

    def parameters(self) -> dict[str, Parameter]:
        higher = {f"{self.name}_c{d}": Parameter(0.0) for d in range(2, self.degree + 1)}
        return {f"{self.name}_c1": Parameter(self.c1), **higher}

    def term(self, x, u, theta):
        s = (x[self.position] - self.center) / self.reference
        return sum(theta[f"{self.name}_c{d}"] * s**d for d in range(1, self.degree + 1))

    def basis(self, x, u):
        return (x[:, self.position] - self.center) / self.reference

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            f"the {state_names[self.state]} equation has a force that varies with "
            f"{state_names[self.position]} (a polynomial of degree {self.degree}: a spring, "
            "a cable, a slope)"
        )


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


class DirectionalDamping(AdditiveEffect):
    r"""A viscous friction that differs with the direction of motion: $g = -c\,|v|$.

    $$
    g = -c\, v \tanh(v / w), \qquad v = x_s,
    $$

    so that with a declared viscous friction $b\,v$ the damping is $b + c$ while $v > 0$
    and $b - c$ while $v < 0$, as a screw's, a seal's or a guide's often is. Parameter
    ``{name}_difference`` ($c$, either sign, from ``difference``); the smooth $|v|$ has the
    fixed width ``width`` ($w > 0$, in the velocity's units: the loop takes 1 % of the
    velocity's RMS, as for a friction's sign). Both directions stay dissipative while
    $|c| < b$. On a drive it is what a constant force offset fitted with a symmetric
    viscous friction often stands for: the offset pushes one way at every speed, while
    this term grows with the speed in one direction and shrinks in the other.
    """

    def __init__(
        self,
        state: int,
        *,
        difference: float = 0.0,
        width: float = 0.05,
        velocity: int | None = None,
        name: str = "directional_damping",
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.state, self.difference, self.width = int(state), float(difference), float(width)
        self.velocity = self.state if velocity is None else int(velocity)
        self.name = name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_difference": Parameter(self.difference)}

    def term(self, x, u, theta):
        v = x[self.velocity]
        return -theta[f"{self.name}_difference"] * v * jnp.tanh(v / self.width)

    def basis(self, x, u):
        v = x[:, self.velocity]
        return -v * np.tanh(v / self.width)

    def describe(self, state_names, output_names, values=None) -> str:
        difference = float((values or {}).get(f"{self.name}_difference", 0.0))
        v = state_names[self.velocity]
        if difference == 0.0:
            return f"the damping of {v} depends on its direction"
        direction = "positive" if difference > 0 else "negative"
        return (
            f"{v} is damped more while it is {direction} (a damping that depends on the direction)"
        )


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
