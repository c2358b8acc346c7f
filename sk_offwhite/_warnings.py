"""The warnings of a fit and of a simulation that the user can act on."""

from __future__ import annotations

import warnings

import numpy as np

from .fitting._verdict import runaway_parameters

__all__ = ["DivergenceWarning", "RunawayParameterWarning"]


class DivergenceWarning(RuntimeWarning):
    """A simulation of the fitted model left the finite numbers."""


class RunawayParameterWarning(UserWarning):
    """A fitted parameter ran orders of magnitude away from its declared start, where the
    data no longer determine it (`runaway_parameters`)."""


def _warn_if_runaway(physics, theta) -> None:
    for name, start, fitted in runaway_parameters(physics, theta):
        warnings.warn(
            f"Parameter {name!r} ran from {start:.3g} to {fitted:.3g} ({abs(fitted / start):.1e} "
            "times its start): the simulation hardly depends on it there (a level never "
            "reached, a time constant so long that its term vanishes), so the data do not "
            "determine it; fix it, bound it, or drop its term "
            "(sk_offwhite.certify.identifiability names such directions).",
            RunawayParameterWarning,
            stacklevel=5,  # the caller of fit (through scikit-learn's fit context)
        )


def _warn_if_diverged(outputs: np.ndarray) -> None:
    finite = np.all(np.isfinite(outputs), axis=1)
    if not np.all(finite):
        first = int(np.argmin(finite))
        warnings.warn(
            f"The simulation diverged: its outputs are not finite from sample {first} of "
            f"{len(finite)} on (an unstable fitted model, or inputs outside the fitted range).",
            DivergenceWarning,
            stacklevel=3,
        )
