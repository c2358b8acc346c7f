"""Synthetic thermal systems whose declared physics misses one effect.

Same conventions as `sk_offwhite.datasets._mechanical`: one explicit-Euler step of the
declared physics per sample plus an additive hidden effect on the temperature equation, in
SI units (kelvin, watts, joules per kelvin, seconds). Temperatures are absolute, so the
data sit far from zero (305–317 K): what the package derives from the data's scale is
tested on an offset record.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import _check_number, _SimpleSystem
from sk_offwhite.datasets._mechanical import _generate, _Generator
from sk_offwhite.datasets._synthetic import _first_order_physics
from sk_offwhite.effects._terms import signed_power
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = ["make_convective_block", "make_heated_block"]

HEATER_THETA = {"capacity": 800.0, "conductance": 2.5, "ambient": 295.0}
HEATER_LIMIT, HEATER_DT = 60.0, 2.0
HEATER_MEAN, HEATER_STD = 45.0, 25.0
CONVECTION_REFERENCE = 10.0
r"""The temperature excess (K) at which the convective block's loss law of any exponent
conducts $G\,\Delta T$: the conductance keeps its meaning whatever the exponent."""
LOSS_EXPONENT_BOUNDS = (0.5, 3.0)


def heated_block_rhs(x, u, theta):
    r"""$\dot T = (P - G\,(T - T_a)) / C$: heater power in, conduction to ambient out."""
    loss = theta["conductance"] * (x[0] - theta["ambient"])
    return (u[0] - loss)[None] / theta["capacity"]


def _heater_effect(x, u, limit, capacity, dt):
    """``dt (min(P, limit) - P) / C`` on the temperature equation (numpy)."""
    return (-dt * np.maximum(u[..., 0] - limit, 0.0) / capacity)[..., None]


def _heated_block_physics(values: dict, x0) -> PhysicsModel:
    return _first_order_physics(
        heated_block_rhs, values, x0, HEATER_DT, ("T", "P"), ("temperature", "generic")
    )


def _thermal_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=2)


_HEATED_BLOCK = _Generator(
    system=_SimpleSystem(
        physics=_heated_block_physics,
        theta=HEATER_THETA,
        guess={"capacity": 600.0, "conductance": 2.0, "ambient": 290.0},
        x0=(HEATER_THETA["ambient"] + HEATER_MEAN / HEATER_THETA["conductance"],),
        contribution=_heater_effect,
        params={"limit": HEATER_LIMIT, "capacity": HEATER_THETA["capacity"], "dt": HEATER_DT},
        equation=0,
        variables=("P",),
        effect_description="The heater delivers at most 60 W: min(P, 60) instead of the "
        "commanded P.",
        library=_thermal_library,
        process_target="temperature equation",
        descr="Heated block C T' = P - G (T - T_a) [SI units: K, W, J/K, s], C=800 J/K, "
        "G=2.5 W/K, T_a=295 K, Euler dt=2 s, temperature measured; the heater delivers at most "
        "60 W, which the physics does not know.\n",
        dt=HEATER_DT,
    ),
    input_std=HEATER_STD,
    band=0.01,
    noise_std=0.02,
    rates={"limit": HEATER_LIMIT, "capacity": HEATER_THETA["capacity"]},
    kinds={"states": ("temperature",), "inputs": ("generic",)},
    input_mean=HEATER_MEAN,
    input_floor=0.0,
)


def make_heated_block(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A heated block whose physics assumes the heater delivers the commanded power.

    True system, one explicit-Euler step of $\Delta t = 2$ s per sample:

    $$
    C\,\dot T = \min(P, P_{max}) - G\,(T - T_a), \qquad z = T + \eta,
    $$

    with $C = 800$ J/K, $G = 2.5$ W/K, $T_a = 295$ K and
    $P_{max} = 60$ W (temperature in K, commanded power ``P`` in W); the physics uses
    $P$ and fits $C$, $G$ and $T_a$. The hidden effect
    $-\Delta t\,\max(P - P_{max}, 0)/C$ enters the temperature equation (sign -1: the
    heater delivers less than commanded); ``hidden_effect["rates"]`` is
    ``{"limit": 60.0, "capacity": 800.0}``. A hard limit, not a soft (``tanh``) saturation:
    the power passes unchanged below 60 W. Time constant $C/G = 320$ s (160 samples).
    Input: multisine 0-0.01 cycles/sample with mean 45 W and standard deviation 25 W,
    floored at 0 W (a heater does not cool), so that it exceeds the limit about a quarter
    of the time. The block starts at its steady state for the mean power.

    Suggested library: polynomials of degree 2 on ``[T, P]`` (6 features); it only
    approximates the clipped power.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (K) of the Gaussian temperature-sensor noise; ``None`` means
        ``0.02`` K, about 1 % of the temperature's standard deviation (1.9 K).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (K) of a Gaussian disturbance added to the temperature update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_HEATED_BLOCK, n_samples, noise_std, random_state, process_noise_std)


def convective_block_rhs(x, u, theta):
    r"""$\dot T = (P - G\,\Delta_r\,\mathrm{sign}(\Delta)|\Delta/\Delta_r|^{a}) / C$,
    $\Delta = T - T_a$, $\Delta_r$ = `CONVECTION_REFERENCE`, $a$
    = ``theta["loss_exponent"]``: Newton's law of cooling at $a = 1$."""
    excess = x[0] - theta["ambient"]
    power = signed_power(excess, CONVECTION_REFERENCE, 1, theta["loss_exponent"])
    return (u[0] - theta["conductance"] * power)[None] / theta["capacity"]


def _convection_effect(x, u, exponent, conductance, ambient, capacity, dt):
    r"""``-dt G (Δ |Δ/Δ_r|^(a-1) - Δ) / C`` on the temperature equation (numpy): the loss
    of exponent ``a`` less the linear one the physics declares."""
    excess = x[..., 0] - ambient
    power = signed_power(excess, CONVECTION_REFERENCE, 1, exponent, xp=np)
    return (-dt * conductance * (power - excess) / capacity)[..., None]


def _relaxable_loss(physics: PhysicsModel) -> PhysicsModel:
    """The heated block's declared ``physics`` written with its loss law's exponent, a
    parameter ``loss_exponent`` fixed at 1 that the closed loop may free."""
    values = {name: spec.value for name, spec in physics.parameters.items()}
    relaxed = _first_order_physics(
        convective_block_rhs,
        {**values, "loss_exponent": 1.0},
        physics.x0,
        HEATER_DT,
        ("T", "P"),
        ("temperature", "generic"),
    )
    law = Parameter(1.0, LOSS_EXPONENT_BOUNDS, fixed=True, relaxable=True)
    return relaxed.with_parameters(loss_exponent=law)


def _convective_generator(exponent: float) -> _Generator:
    """The heated block without a heater limit, its loss of power ``exponent``."""
    params = {"exponent": exponent, **HEATER_THETA, "dt": HEATER_DT}
    system = dataclasses.replace(
        _HEATED_BLOCK.system,
        contribution=_convection_effect,
        params=params,
        variables=("T",),
        effect_description="The block loses heat by natural convection, G Δ_r "
        f"(ΔT/Δ_r)^{exponent:g} (Δ_r = 10 K), not in proportion to ΔT.",
        descr="Heated block C T' = P - G (T - T_a) [SI units: K, W, J/K, s], C=800 J/K, "
        "G=2.5 W/K, T_a=295 K, Euler dt=2 s, temperature measured; the block loses heat by "
        f"natural convection, in the power {exponent:g} of T - T_a, which the physics does "
        "not know.\n",
    )
    return dataclasses.replace(
        _HEATED_BLOCK, system=system, rates={"exponent": exponent, **HEATER_THETA}
    )


def make_convective_block(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    exponent: float = 4.0 / 3.0,
    relaxable: bool = False,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A heated block whose physics assumes Newton's law of cooling; it loses heat by
    natural convection.

    True system, one explicit-Euler step of $\Delta t = 2$ s per sample:

    $$
    C\,\dot T = P - G\,\Delta_r \,\mathrm{sign}(\Delta)
    \left|\frac{\Delta}{\Delta_r}\right|^{a}, \qquad \Delta = T - T_a,
    \qquad z = T + \eta,
    $$

    with $C = 800$ J/K, $G = 2.5$ W/K, $T_a = 295$ K, $\Delta_r =
    10$ K (`CONVECTION_REFERENCE`) and $a$ = ``exponent`` (4/3: turbulent
    natural convection, a heat-transfer coefficient growing as $\Delta^{1/3}$; 5/4
    laminar). The physics declares $a = 1$ and fits $C$, $G$ and
    $T_a$. The hidden effect, the convective loss less the linear one, enters the
    temperature equation; ``hidden_effect["rates"]`` holds ``exponent`` and the true
    $C$, $G$, $T_a$. The input and noise are those of
    [`make_heated_block`][sk_offwhite.datasets.make_heated_block] (the heater is not limited here):
    temperatures of about 303-317 K, 8-22 K above ambient.

    With ``relaxable=True`` the declared law is written with its exponent, a parameter
    ``loss_exponent`` fixed at 1 and relaxable ([`Parameter`][sk_offwhite.Parameter]), so the
    closed loop may free it ([`RelaxedLaw`][sk_offwhite.RelaxedLaw]); otherwise the physics is
    [`make_heated_block`][sk_offwhite.datasets.make_heated_block]'s, and the loop can only add a
    loss on top of the declared linear one ([`PowerLoss`][sk_offwhite.PowerLoss], whose fitted law
    is not the true one).

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (K) of the temperature-sensor noise; ``None``: 0.02 K.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    exponent : float, default=4/3
        The true loss law's exponent $a$, in [0.5, 3].
    relaxable : bool, default=False
        Declare the loss law's exponent (fixed at 1) relaxable.
    process_noise_std : float, default=0.0
        Standard deviation (K) of a Gaussian disturbance added to the temperature update.

    Returns
    -------
    data : sklearn.utils.Bunch
        As [`make_heated_block`][sk_offwhite.datasets.make_heated_block].
    """
    lower, upper = LOSS_EXPONENT_BOUNDS
    exponent = _check_number("exponent", exponent, f"a number in [{lower}, {upper}]")
    if not lower <= exponent <= upper:
        raise ValueError(f"exponent must lie in [{lower}, {upper}], got {exponent!r}.")
    spec = _convective_generator(float(exponent))
    data = _generate(spec, n_samples, noise_std, random_state, process_noise_std)
    if relaxable:
        data.physics = _relaxable_loss(data.physics)
    return data
