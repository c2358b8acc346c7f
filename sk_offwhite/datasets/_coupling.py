"""A load driven through a spring coupling with a clearance: a threshold on a difference.

Same conventions as `sk_offwhite.datasets._mechanical`. The companion of
[`make_backlash_servo`][sk_offwhite.datasets.make_backlash_servo]: there the play has memory (the
driven side stays where the input left it), here the coupling's spring is slack inside a gap
(a dead zone on the deflection, no memory). The loop should tell them apart.
"""

from __future__ import annotations

import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._backlash import SERVO_KINDS, servo_rhs
from sk_offwhite.datasets._common import _SimpleSystem
from sk_offwhite.datasets._mechanical import _generate, _Generator, _second_order_physics

__all__ = ["make_clearance_coupling"]

COUPLING_THETA = {"k": 400.0, "c": 8.0}
COUPLING_GAP, COUPLING_DT = 0.05, 0.005


def _clearance_effect(x, u, k, gap, dt):
    """``[0, dt k (dz(u - theta) - (u - theta))]``, dz the dead zone of half-width
    ``gap`` (numpy)."""
    deflection = u[..., 0] - x[..., 0]
    slack = np.sign(deflection) * np.maximum(np.abs(deflection) - gap, 0.0)
    return np.stack([0.0 * deflection, dt * k * (slack - deflection)], axis=-1)


def _coupling_physics(values: dict, x0):
    names = ("theta", "omega", "u")
    return _second_order_physics(servo_rhs, values, x0, COUPLING_DT, names, SERVO_KINDS)


def _coupling_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=3)


_CLEARANCE = _Generator(
    system=_SimpleSystem(
        physics=_coupling_physics,
        theta=COUPLING_THETA,
        guess={"k": 300.0, "c": 6.0},
        x0=(0.0, 0.0),
        contribution=_clearance_effect,
        params={"k": COUPLING_THETA["k"], "gap": COUPLING_GAP, "dt": COUPLING_DT},
        equation=1,
        variables=("u", "theta"),
        effect_description="The coupling's spring is slack within a gap of 0.05 rad: it pulls "
        "with k (|u - theta| - 0.05) sign(u - theta), not k (u - theta).",
        library=_coupling_library,
        process_target="rate equation",
        descr="Load theta'' = k dz(u - theta) - c theta', dz a dead zone of half-width 0.05 "
        "rad (a clearance in the coupling), k=400 1/s^2, c=8 1/s, Euler dt=5 ms, load angle "
        "measured; the physics has dz(d) = d.\n",
        dt=COUPLING_DT,
    ),
    input_std=0.5,
    band=0.01,
    noise_std=5e-3,
    rates={"gap": COUPLING_GAP, "k": COUPLING_THETA["k"]},
    kinds=SERVO_KINDS,
)


def make_clearance_coupling(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""A load driven through a spring coupling whose physics ignores a clearance.

    True system, one explicit-Euler step of $\Delta t = 5$ ms per sample:

    $$
    \dot\theta = \omega, \qquad
    \dot\omega = k\,\mathrm{dz}(u - \theta) - c\,\omega, \qquad z = \theta + \eta,
    $$

    with $\mathrm{dz}(d) = \mathrm{sign}(d)\max(|d| - g, 0)$, the gap
    $g = 0.05$ rad, $k = 400$ s⁻², $c = 8$ s⁻¹ (drive angle ``u`` and load
    angle in rad, both of kind ``"angle"``); the physics has $\mathrm{dz}(d) = d$ and
    fits $k$ and $c$. The hidden effect
    $\Delta t\,k\,[\mathrm{dz}(u - \theta) - (u - \theta)]$ enters the rate equation
    (index 1); ``hidden_effect["rates"]`` is ``{"gap": 0.05, "k": 400.0}``. Unlike the
    play of [`make_backlash_servo`][sk_offwhite.datasets.make_backlash_servo], the gap has no
    memory. Input: multisine 0-0.01 cycles/sample (0-2 Hz), standard deviation 0.5 rad. The load
    starts at rest.

    Suggested library: polynomials of degree 3 on ``[theta, omega, u]``; it only
    approximates the dead zone.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (rad) of the Gaussian angle-measurement noise; ``None`` means
        ``5e-3`` rad, about 0.8 % of the load angle's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the rate update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_CLEARANCE, n_samples, noise_std, random_state, process_noise_std)
