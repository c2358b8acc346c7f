"""Synthetic electrical circuit whose declared physics misses one effect.

Same conventions as `sk_offwhite.datasets._mechanical`: one explicit-Euler step of the
declared physics per sample plus an additive hidden effect on the capacitor's equation, in
SI units (volts, seconds).
"""

from __future__ import annotations

import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import _SimpleSystem
from sk_offwhite.datasets._mechanical import _generate, _Generator
from sk_offwhite.datasets._synthetic import _first_order_physics
from sk_offwhite.model._physics import PhysicsModel

__all__ = ["make_diode_rc"]

DIODE_THETA = {"tau": 0.01, "tau_load": 0.1}
DIODE_DROP, DIODE_DT, DIODE_SOURCE_STD = 0.6, 1e-3, 3.0


def diode_rc_rhs(x, u, theta):
    r"""$\dot v = (e - v)/\tau - v/\tau_L$: charged from the source through a resistor,
    discharged through the load."""
    return ((u[0] - x[0]) / theta["tau"] - x[0] / theta["tau_load"])[None]


def _diode_effect(x, u, drop, tau, dt):
    """``dt (max(e - v - drop, 0) - (e - v)) / tau`` on the capacitor's equation (numpy)."""
    drive = u[..., 0] - x[..., 0]
    return (dt * (np.maximum(drive - drop, 0.0) - drive) / tau)[..., None]


def _diode_rc_physics(values: dict, x0) -> PhysicsModel:
    return _first_order_physics(
        diode_rc_rhs, values, x0, DIODE_DT, ("v", "e"), ("voltage", "voltage")
    )


def _electrical_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=2)


_DIODE_RC = _Generator(
    system=_SimpleSystem(
        physics=_diode_rc_physics,
        theta=DIODE_THETA,
        guess={"tau": 0.013, "tau_load": 0.075},
        x0=(2.0,),
        contribution=_diode_effect,
        params={"drop": DIODE_DROP, "tau": DIODE_THETA["tau"], "dt": DIODE_DT},
        equation=0,
        variables=("e", "v"),
        effect_description="The capacitor charges through a diode: only when e - v exceeds "
        "its 0.6 V forward drop, by the excess, and never back into the source.",
        library=_electrical_library,
        process_target="capacitor equation",
        descr="RC circuit v' = (e - v)/tau - v/tau_load [SI units: V, s], tau = 10 ms, "
        "tau_load = 100 ms, Euler dt = 1 ms, capacitor voltage measured; the capacitor is "
        "charged through a diode with a 0.6 V forward drop, which the physics does not know.\n",
        dt=DIODE_DT,
    ),
    input_std=DIODE_SOURCE_STD,
    band=0.01,
    noise_std=0.02,
    rates={"drop": DIODE_DROP, "tau": DIODE_THETA["tau"]},
    kinds={"states": ("voltage",), "inputs": ("voltage",)},
)


def make_diode_rc(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    r"""An RC circuit whose physics does not know it is charged through a diode.

    True system, one explicit-Euler step of $\Delta t = 1$ ms per sample:

    $$
    \dot v = \frac{\max(e - v - V_d,\ 0)}{\tau} - \frac{v}{\tau_L}, \qquad
    z = v + \eta,
    $$

    with $\tau = RC = 10$ ms, $\tau_L = R_L C = 100$ ms and the diode's forward
    drop $V_d = 0.6$ V (source ``e`` and capacitor voltage ``v`` in volts, both of
    kind ``"voltage"``); the physics is $\dot v = (e - v)/\tau - v/\tau_L$ and fits
    $\tau$ and $\tau_L$. The hidden effect
    $\Delta t\,[\max(e - v - V_d, 0) - (e - v)]/\tau$ enters the capacitor's equation:
    a half-wave rectifier with a smoothing capacitor, a peak detector. No current flows
    back into the source, and none until the source exceeds the capacitor by the drop.
    ``hidden_effect["rates"]`` is ``{"drop": 0.6, "tau": 0.01}``. Input: multisine
    0-0.01 cycles/sample (0-10 Hz), zero mean, standard deviation 3 V.

    Suggested library: polynomials of degree 2 on ``[v, e]`` (6 features); it only
    approximates the rectified drive.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (V) of the Gaussian voltage-measurement noise; ``None`` means
        ``0.02`` V.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (V) of a Gaussian disturbance added to the capacitor update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_DIODE_RC, n_samples, noise_std, random_state, process_noise_std)
