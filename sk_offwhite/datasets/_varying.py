r"""Synthetic plants whose declared constant in truth varies with a state or an input.

Each generator declares a physical model with a constant parameter $\theta_j$ (a stiffness,
an inductance, a valve coefficient, a friction coefficient) that in the true plant is a
closed-form law of one variable $v$ (a state or an input),

$$
\theta_j(v) = \theta_j\, g(v), \qquad
g \in \Big\{1 \pm \big(\tfrac{v}{v_s}\big)^2,\;
\frac{1}{1 + (v/v_s)^2},\; \Big|\frac{v}{v_s}\Big|^p,\; e^{v/v_s}\Big\},
$$

the polynomial, rational, power and exponential families. The true plant is the declared
right-hand side with that law substituted, integrated by the same integrator
(`PhysicsModel.from_ode(..., method="rk4")`), so that with no noise the declared step with
$\theta_j \to \theta_j\,g(v)$ inside its right-hand side reproduces the records to rounding.
The returned `Bunch` holds the declared `physics` (the parameter constant, at a guess), the
estimation and validation records `u_est, z_est, x_est, u_val, z_val, x_val` (two
realisations of the excitation), `true_parameters`, `kinds` and the ground truth `varying`:

```python
{"parameter": "k", "variable": "q", "family": "polynomial",
 "constants": {"x_s": 0.04}, "sign": "hardening", "formula": "k(q) = k·(1 + (q/q_s)²)"}
```

`true_physics` is the declared model with the law substituted and the true parameters. All
quantities are in SI units; the measured output is the first state plus Gaussian noise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import (
    _check_n_samples,
    _check_random_state,
    _gaussian,
    _multisine,
    _noise_stds,
    _rollout,
)
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = [
    "make_hardening_spring",
    "make_piezoviscous_bearing",
    "make_saturating_inductor",
    "make_valve_tank",
]

POSITIVE = (1e-9, None)


# --------------------------------------------------------------------------------------
# The varying law and the true right-hand side
# --------------------------------------------------------------------------------------


def _law_factor(family: str, v, constants: dict):
    r"""$g(v)$ of `family` with `constants` (`x_s`, and `p` for the power law, `sign` $\pm 1$
    for the polynomial), in `jax.numpy`."""
    scaled = v / constants["x_s"]
    if family == "polynomial":
        return 1.0 + constants.get("sign", 1.0) * scaled**2
    if family == "rational":
        return 1.0 / (1.0 + scaled**2)
    if family == "power":
        return jnp.abs(scaled) ** constants["p"]
    if family == "exponential":
        return jnp.exp(scaled)
    raise ValueError(f"unknown family {family!r}.")


@dataclass(frozen=True)
class _Law:
    r"""$\theta_j \to \theta_j\, g(v)$: the parameter, where its variable is read (`"state"`
    or `"input"` and an index), the family and its constants (sorted pairs)."""

    parameter: str
    variable: str
    where: tuple[str, int]
    family: str
    constants: tuple[tuple[str, float], ...]

    def factor(self, x, u):
        """$g(v)$ at the state `x` and input `u`."""
        source = x if self.where[0] == "state" else u
        return _law_factor(self.family, source[self.where[1]], dict(self.constants))


class _VaryingRhs:
    """A right-hand side `rhs(x, u, theta)` with `theta[law.parameter]` multiplied by the
    law's $g(v)$ at the current state and input (picklable, compared by value)."""

    def __init__(self, rhs: Callable, law: _Law):
        self.rhs, self.law = rhs, law
        self.__name__ = f"varying_{getattr(rhs, '__name__', 'rhs')}"

    def __call__(self, x, u, theta):
        scaled = dict(theta)
        scaled[self.law.parameter] = theta[self.law.parameter] * self.law.factor(x, u)
        return self.rhs(x, u, scaled)

    def __eq__(self, other) -> bool:
        return isinstance(other, _VaryingRhs) and (other.rhs, other.law) == (self.rhs, self.law)

    def __hash__(self) -> int:
        return hash((_VaryingRhs, self.rhs, self.law))


# --------------------------------------------------------------------------------------
# A plant: declared physics, law, excitation
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Excitation:
    """An input `mean + std` times a unit multisine of `band` cycles per sample, clipped to
    `[floor, ceiling]`."""

    mean: float
    std: float
    band: float
    floor: float = -np.inf
    ceiling: float = np.inf

    def draw(self, rng: np.random.RandomState, n: int) -> np.ndarray:
        signal = self.mean + self.std * _multisine(rng, n, self.band)
        return np.clip(signal, self.floor, self.ceiling)


@dataclass(frozen=True)
class _Plant:
    """Everything a generator needs: the declared `rhs`, its names, kinds and parameters
    (`theta` true, `guess` declared, `fixed` kept), the sampling time, the law and its
    description, the excitation of each input, the initial state and default noise."""

    rhs: Callable
    names: tuple[tuple[str, ...], tuple[str, ...]]
    kinds: tuple[tuple[str, ...], tuple[str, ...]]
    theta: dict
    guess: dict
    fixed: tuple[str, ...]
    dt: float
    law: _Law
    sign: str
    formula: str
    excitations: tuple[_Excitation, ...]
    x0: tuple[float, ...]
    noise_std: float
    process_state: int
    descr: str


def _parameters(plant: _Plant, values: dict) -> dict:
    """Each parameter at `values`, positive, kept where `plant.fixed` names it."""
    return {
        name: Parameter(value, POSITIVE, fixed=name in plant.fixed)
        for name, value in values.items()
    }


def _model(plant: _Plant, rhs: Callable, values: dict, x0) -> PhysicsModel:
    """`rhs` integrated by one RK4 step per sample, the first state measured."""
    states, inputs = plant.names
    return PhysicsModel.from_ode(
        rhs,
        plant.dt,
        output=0,
        parameters=_parameters(plant, values),
        n_states=len(states),
        n_inputs=len(inputs),
        method="rk4",
        x0=x0,
        state_names=states,
        input_names=inputs,
        output_names=states[:1],
        state_kinds=plant.kinds[0],
        input_kinds=plant.kinds[1],
    )


def _varying_entry(plant: _Plant) -> dict:
    """The ground truth `varying` of the Bunch."""
    return {
        "parameter": plant.law.parameter,
        "variable": plant.law.variable,
        "family": plant.law.family,
        "constants": {k: v for k, v in plant.law.constants if k != "sign"},
        "sign": plant.sign,
        "formula": plant.formula,
    }


def _record(rng, n: int, plant: _Plant, truth: PhysicsModel, stds) -> dict:
    """One record: inputs drawn, the true plant simulated, the first state measured."""
    u = np.stack([excitation.draw(rng, n) for excitation in plant.excitations], axis=1)
    w = np.zeros((n - 1, truth.n_states))
    w[:, plant.process_state] = _gaussian(rng, n - 1, stds[1])
    x = _rollout(truth, plant.theta, np.asarray(plant.x0, float), u, None, w)
    return {"u": u, "x": x, "z": x[:, :1] + _gaussian(rng, (n, 1), stds[0])}


def _generate(plant: _Plant, n_samples, noise_std, random_state, process_noise_std) -> Bunch:
    """Validate the arguments, simulate the estimation and validation records, assemble."""
    n = _check_n_samples(n_samples)
    default = plant.noise_std if noise_std is None else noise_std
    stds = _noise_stds(default, process_noise_std)
    rng = _check_random_state(random_state)
    truth = _model(plant, _VaryingRhs(plant.rhs, plant.law), plant.theta, plant.x0)
    est, val = (_record(rng, n, plant, truth, stds) for _ in range(2))
    kinds = {"states": plant.kinds[0], "inputs": plant.kinds[1]}
    return Bunch(
        **{f"{key}_est": value for key, value in est.items()},
        **{f"{key}_val": value for key, value in val.items()},
        physics=_model(plant, plant.rhs, plant.guess, plant.x0),
        true_physics=truth,
        true_parameters=dict(plant.theta),
        true_x0=np.asarray(plant.x0, float),
        varying=_varying_entry(plant),
        kinds=kinds,
        noise={"output_std": stds[0], "process_std": stds[1]},
        sampling_time=plant.dt,
        state_names=list(plant.names[0]),
        input_names=list(plant.names[1]),
        output_names=list(plant.names[0][:1]),
        DESCR=plant.descr,
    )


# --------------------------------------------------------------------------------------
# a. Mass-spring-damper whose spring hardens
# --------------------------------------------------------------------------------------

SPRING_THETA = {"m": 0.5, "c": 0.6, "k": 20.0}
SPRING_QS, SPRING_DT = 0.04, 0.01


def spring_rhs(x, u, theta):
    r"""$[v,\ (F - c v - k q)/m]$: a mass on a linear spring and damper, driven by $F$."""
    accel = (u[0] - theta["c"] * x[1] - theta["k"] * x[0]) / theta["m"]
    return jnp.stack([x[1], accel])


_SPRING = _Plant(
    rhs=spring_rhs,
    names=(("q", "v"), ("F",)),
    kinds=(("position", "velocity"), ("force",)),
    theta=SPRING_THETA,
    guess={"m": SPRING_THETA["m"], "c": 0.5, "k": 15.0},
    fixed=("m",),
    dt=SPRING_DT,
    law=_Law("k", "q", ("state", 0), "polynomial", (("sign", 1.0), ("x_s", SPRING_QS))),
    sign="hardening",
    formula="k(q) = k·(1 + (q/q_s)²)",
    excitations=(_Excitation(0.0, 0.8, 0.02),),
    x0=(0.0, 0.0),
    noise_std=1e-3,
    process_state=1,
    descr="Mass-spring-damper m q'' = F - c q' - k(q) q [SI units], m=0.5 kg, c=0.6 N s/m, "
    "k(q) = k (1 + (q/q_s)^2) with k=20 N/m and q_s=0.04 m (a hardening spring), RK4 "
    "dt=0.01 s, deflection measured; the physics knows m and declares a constant stiffness k.\n",
)


def make_hardening_spring(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A mass on a spring whose stiffness grows with the square of its deflection.

    True plant, one RK4 step of $\Delta t = 0.01$ s per sample:

    $$
    \dot q = v, \qquad m\,\dot v = F - c\,v - k(q)\,q, \qquad
    k(q) = k\,\big(1 + (q/q_s)^2\big), \qquad z = q + \eta,
    $$

    with $m = 0.5$ kg, $c = 0.6$ N s/m, $k = 20$ N/m and $q_s = 0.04$ m (deflection $q$ in m,
    velocity $v$ in m/s, force $F$ in N). The declared physics has the constant stiffness
    $k$, knows the mass (`m` fixed at 0.5 kg) and fits $c$ and $k$. The force is a
    multisine of 0–2 Hz (0.02 cycles per sample) with a standard deviation of 0.8 N around
    the 1 Hz natural frequency, so that $|q|$ reaches about $2.5\,q_s$, where the stiffness
    is seven times $k$. The mass starts at rest.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (m) of the Gaussian deflection-sensor noise; `None` means
        `1e-3` m, about 3 % of the deflection's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (m/s) of a Gaussian disturbance added to the velocity update.

    Returns
    -------
    data : sklearn.utils.Bunch
        `u_est, z_est, x_est, u_val, z_val, x_val, physics, true_physics, true_parameters,
        true_x0, varying, kinds, noise, sampling_time, state_names, input_names,
        output_names, DESCR`.
    """
    return _generate(_SPRING, n_samples, noise_std, random_state, process_noise_std)


# --------------------------------------------------------------------------------------
# b. Series RL circuit whose inductor saturates
# --------------------------------------------------------------------------------------

INDUCTOR_THETA = {"R": 2.0, "L": 0.05}
INDUCTOR_IS, INDUCTOR_DT = 1.0, 1e-3


def inductor_rhs(x, u, theta):
    r"""$(V - R\,i)/L$: a series resistor and inductor driven by the voltage $V$."""
    return ((u[0] - theta["R"] * x[0]) / theta["L"])[None]


_INDUCTOR = _Plant(
    rhs=inductor_rhs,
    names=(("i",), ("V",)),
    kinds=(("current",), ("voltage",)),
    theta=INDUCTOR_THETA,
    guess={"R": 2.5, "L": 0.04},
    fixed=(),
    dt=INDUCTOR_DT,
    law=_Law("L", "i", ("state", 0), "rational", (("x_s", INDUCTOR_IS),)),
    sign="falling",
    formula="L(i) = L/(1 + (i/i_s)²)",
    excitations=(_Excitation(0.0, 2.5, 0.01),),
    x0=(0.0,),
    noise_std=1e-2,
    process_state=0,
    descr="Series RL circuit L(i) i' = V - R i [SI units], R=2 ohm, L(i) = L/(1 + (i/i_s)^2) "
    "with L=0.05 H and i_s=1 A (an iron core that saturates), RK4 dt=1 ms, current "
    "measured; the physics declares a constant inductance L.\n",
)


def make_saturating_inductor(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A series RL circuit whose inductance falls with the square of its current.

    True plant, one RK4 step of $\Delta t = 1$ ms per sample:

    $$
    L(i)\,\dot i = V - R\,i, \qquad L(i) = \frac{L}{1 + (i/i_s)^2}, \qquad z = i + \eta,
    $$

    with $R = 2\ \Omega$, $L = 0.05$ H and $i_s = 1$ A (current in A, voltage in V): the
    differential inductance of an iron core that saturates. The declared physics has the
    constant inductance $L$ and fits $R$ and $L$. The voltage is a multisine of 0–10 Hz
    (0.01 cycles per sample) with a standard deviation of 2.5 V, so that $|i|$ reaches
    about $3.5\,i_s$, where the inductance is a thirteenth of $L$ and the time constant
    $L(i)/R$ about 2 ms instead of 25 ms. The circuit starts without current.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (A) of the Gaussian current-sensor noise; `None` means `1e-2` A,
        about 1 % of the current's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (A) of a Gaussian disturbance added to the current update.

    Returns
    -------
    data : sklearn.utils.Bunch
        The keys of `make_hardening_spring`.
    """
    return _generate(_INDUCTOR, n_samples, noise_std, random_state, process_noise_std)


# --------------------------------------------------------------------------------------
# c. Tank filled through a valve whose coefficient depends on its opening
# --------------------------------------------------------------------------------------

VALVE_THETA = {"area": 0.1, "Cv": 1.5e-3, "k_out": 1e-3}
VALVE_AS, VALVE_P, VALVE_DT = 0.5, 0.6, 2.0
_VALVE_MEAN_OPENING = 0.55


def valve_tank_rhs(x, u, theta):
    r"""$(C_v\,a - k_{out}\sqrt{h})/A$: a tank filled through a valve of opening $a$ and
    drained through an orifice (Torricelli)."""
    outflow = theta["k_out"] * jnp.sqrt(jnp.maximum(x[0], 1e-9))
    return ((theta["Cv"] * u[0] - outflow) / theta["area"])[None]


def _valve_steady_level(opening: float) -> float:
    """The level at which the true inflow at `opening` equals the outflow."""
    coefficient = VALVE_THETA["Cv"] * (opening / VALVE_AS) ** VALVE_P
    return float((coefficient * opening / VALVE_THETA["k_out"]) ** 2)


_VALVE = _Plant(
    rhs=valve_tank_rhs,
    names=(("h",), ("a",)),
    kinds=(("level",), ("generic",)),
    theta=VALVE_THETA,
    guess={"area": VALVE_THETA["area"], "Cv": 1.2e-3, "k_out": 1.2e-3},
    fixed=("area",),
    dt=VALVE_DT,
    law=_Law("Cv", "a", ("input", 0), "power", (("p", VALVE_P), ("x_s", VALVE_AS))),
    sign="rising",
    formula="Cv(a) = Cv·|a/a_s|^p",
    excitations=(_Excitation(_VALVE_MEAN_OPENING, 0.15, 0.005, 0.2, 1.0),),
    x0=(_valve_steady_level(_VALVE_MEAN_OPENING),),
    noise_std=5e-3,
    process_state=0,
    descr="Tank A h' = Cv(a) a - k_out sqrt(h) [SI units], A=0.1 m^2 (known), k_out=1e-3 "
    "m^2.5/s, Cv(a) = Cv |a/a_s|^p with Cv=1.5e-3 m^3/s, a_s=0.5 and p=0.6 (a valve whose "
    "coefficient rises with its opening a), RK4 dt=2 s, level measured; the physics "
    "declares a constant valve coefficient Cv.\n",
)


def make_valve_tank(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A tank filled through a valve whose coefficient rises with its opening.

    True plant, one RK4 step of $\Delta t = 2$ s per sample:

    $$
    A\,\dot h = C_v(a)\,a - k_{out}\sqrt h, \qquad
    C_v(a) = C_v\,\Big|\frac{a}{a_s}\Big|^p, \qquad z = h + \eta,
    $$

    with $A = 0.1$ m² (declared, fixed), $k_{out} = 10^{-3}$ m$^{2.5}$/s,
    $C_v = 1.5\cdot 10^{-3}$ m³/s, $a_s = 0.5$ and $p = 0.6$ (level $h$ in m, opening $a$
    between 0 and 1): the valve's coefficient equals $C_v$ at half opening, and the inflow grows as
    $a^{1.6}$ instead of $a$. The declared physics has the constant coefficient $C_v$ and
    fits $C_v$ and $k_{out}$ (the area is known). The opening is a multisine of 0–2.5 mHz
    (0.005 cycles per sample) around 0.55 with a standard deviation of 0.15, clipped to
    $[0.2, 1]$; the level moves between about 0.1 m and 2 m with a time constant of 2–4
    minutes. The tank starts at the level of the mean opening.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (m) of the Gaussian level-sensor noise; `None` means `5e-3` m,
        about 1.5 % of the level's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (m) of a Gaussian disturbance added to the level update.

    Returns
    -------
    data : sklearn.utils.Bunch
        The keys of `make_hardening_spring`.
    """
    return _generate(_VALVE, n_samples, noise_std, random_state, process_noise_std)


# --------------------------------------------------------------------------------------
# d. Rotor in a bearing whose oil thickens under pressure
# --------------------------------------------------------------------------------------

BEARING_THETA = {"J": 0.02, "b": 0.01}
BEARING_PS, BEARING_DT = 4e7, 0.02


def bearing_rhs(x, u, theta):
    r"""$(\tau - b\,\omega)/J$: a rotor driven by the torque $\tau$ against viscous friction
    (the load pressure $p$, the second input, does not enter the declared law)."""
    return ((u[0] - theta["b"] * x[0]) / theta["J"])[None]


_BEARING = _Plant(
    rhs=bearing_rhs,
    names=(("omega",), ("tau", "p")),
    kinds=(("rate",), ("torque", "generic")),
    theta=BEARING_THETA,
    guess={"J": 0.025, "b": 0.02},
    fixed=(),
    dt=BEARING_DT,
    law=_Law("b", "p", ("input", 1), "exponential", (("x_s", BEARING_PS),)),
    sign="rising",
    formula="b(p) = b·exp(p/p_s)",
    excitations=(_Excitation(0.0, 0.05, 0.02), _Excitation(6e7, 3e7, 0.004, 0.0)),
    x0=(0.0,),
    noise_std=2e-2,
    process_state=0,
    descr="Rotor J omega' = tau - b(p) omega [SI units], J=0.02 kg m^2, b(p) = b exp(p/p_s) "
    "with b=0.01 N m s/rad and p_s=40 MPa (the Barus law of an oil's viscosity under the "
    "load pressure p), RK4 dt=0.02 s, speed measured; the physics declares a constant "
    "friction coefficient b.\n",
)


def make_piezoviscous_bearing(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A rotor in an oil-lubricated bearing whose friction rises exponentially with the load.

    True plant, one RK4 step of $\Delta t = 0.02$ s per sample:

    $$
    J\,\dot\omega = \tau - b(p)\,\omega, \qquad b(p) = b\,e^{p/p_s}, \qquad
    z = \omega + \eta,
    $$

    with $J = 0.02$ kg m², $b = 0.01$ N m s/rad and $p_s = 40$ MPa (speed $\omega$ in rad/s,
    torque $\tau$ in N m, load pressure $p$ in Pa): the Barus law of a lubricant whose
    viscosity grows by $e$ for every 40 MPa of pressure. The declared physics has the
    constant coefficient $b$ and fits $J$ and $b$. The torque is a multisine of 0–1 Hz
    (0.02 cycles per sample) with a standard deviation of 0.05 N m; the pressure a slower
    one (0.004 cycles per sample) around 60 MPa with a standard deviation of 30 MPa,
    floored at 0, so that it reaches about 130 MPa, where the friction is 25 times $b$. The
    rotor starts at rest.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (rad/s) of the Gaussian speed-sensor noise; `None` means `2e-2`
        rad/s, about 2.5 % of the speed's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (rad/s) of a Gaussian disturbance added to the speed update.

    Returns
    -------
    data : sklearn.utils.Bunch
        The keys of `make_hardening_spring`.
    """
    return _generate(_BEARING, n_samples, noise_std, random_state, process_noise_std)
