"""Synthetic thermal system whose declared physics misses one effect.

Same conventions as :mod:`sk_offwhite.datasets._mechanical`: one explicit-Euler step of the
declared physics per sample plus an additive hidden effect on the temperature equation, in
SI units (kelvin, watts, joules per kelvin, seconds). Temperatures are absolute, so the
data sit far from zero (305–317 K): what the package derives from the data's scale is
tested on an offset record.
"""

from __future__ import annotations

import numpy as np
from sklearn.utils import Bunch

from sk_offwhite._physics import PhysicsModel
from sk_offwhite.datasets._common import _SimpleSystem
from sk_offwhite.datasets._mechanical import _generate, _Generator
from sk_offwhite.datasets._synthetic import _first_order_physics

__all__ = ["make_heated_block"]

HEATER_THETA = {"capacity": 800.0, "conductance": 2.5, "ambient": 295.0}
HEATER_LIMIT, HEATER_DT = 60.0, 2.0
HEATER_MEAN, HEATER_STD = 45.0, 25.0


def heated_block_rhs(x, u, theta):
    r""":math:`\dot T = (P - G\,(T - T_a)) / C`: heater power in, conduction to ambient out."""
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

    True system, one explicit-Euler step of :math:`\Delta t = 2` s per sample:

    .. math::

        C\,\dot T = \min(P, P_{max}) - G\,(T - T_a), \qquad z = T + \eta,

    with :math:`C = 800` J/K, :math:`G = 2.5` W/K, :math:`T_a = 295` K and
    :math:`P_{max} = 60` W (temperature in K, commanded power ``P`` in W); the physics uses
    :math:`P` and fits :math:`C`, :math:`G` and :math:`T_a`. The hidden effect
    :math:`-\Delta t\,\max(P - P_{max}, 0)/C` enters the temperature equation (sign -1: the
    heater delivers less than commanded); ``hidden_effect["rates"]`` is
    ``{"limit": 60.0, "capacity": 800.0}``. A hard limit, not a soft (``tanh``) saturation:
    the power passes unchanged below 60 W. Time constant :math:`C/G = 320` s (160 samples).
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
