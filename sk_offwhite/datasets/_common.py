"""Helpers shared by the synthetic generators: signals, noise, simulation, Bunch assembly.

Array helpers (``_tanh``, ``_ones_like``, ``_softplus``) dispatch on the argument so that
library functions run in float64 numpy inside pysindy and in ``jax.numpy`` (also under
``jit``/``grad``) inside the package's feature maps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from numbers import Real

import jax
import numpy as np
from sklearn.utils import Bunch, check_random_state

from sk_offwhite.dictionaries._compiled import _xp
from sk_offwhite.model._physics import PhysicsModel

# --------------------------------------------------------------------------------------
# Array helpers usable from numpy (pysindy) and jax.numpy (the package's feature maps)
# --------------------------------------------------------------------------------------


def _tanh(a):
    return _xp(a).tanh(a)


def _ones_like(a):
    return _xp(a).ones_like(a)


def _softplus(a):
    return _xp(a).logaddexp(a, 0.0)


# --------------------------------------------------------------------------------------
# Signals, noise and simulation
# --------------------------------------------------------------------------------------


def _multisine(rng: np.random.RandomState, n: int, band: float) -> np.ndarray:
    """Random-phase multisine with zero mean and unit standard deviation.

    Flat amplitude on the DFT lines ``1 .. K`` of an ``n``-sample period, with
    ``K = max(1, floor(band * n))`` and ``band`` in cycles per sample.
    """
    n_lines = max(1, int(np.floor(band * n)))
    spectrum = np.zeros(n // 2 + 1, dtype=complex)
    spectrum[1 : n_lines + 1] = np.exp(2j * np.pi * rng.random_sample(n_lines))
    signal = np.fft.irfft(spectrum, n)
    return (signal - signal.mean()) / signal.std()


def _gaussian(rng: np.random.RandomState, shape, std: float) -> np.ndarray:
    """``std`` times standard normal draws (always drawn, so ``std`` never shifts the stream)."""
    return float(std) * rng.standard_normal(shape)


def _uniform(rng: np.random.RandomState, shape, bound: float) -> np.ndarray:
    """Uniform draws in ``[-bound, bound]`` (always drawn, as in `_gaussian`)."""
    return float(bound) * rng.uniform(-1.0, 1.0, shape)


def _rollout(
    physics: PhysicsModel,
    theta: dict,
    x0: np.ndarray,
    u: np.ndarray,
    effect: Callable | None,
    w: np.ndarray,
    limit: Callable | None = None,
) -> np.ndarray:
    """Simulate ``x[k+1] = limit(f(x[k], u[k]; theta) + effect(x[k], u[k]) + w[k])``.

    ``f`` is the physics' own ``step``, jitted and evaluated in float64 under a local
    ``jax.enable_x64`` (the global JAX configuration is left untouched).
    """
    x = np.empty((u.shape[0], physics.n_states))
    x[0] = x0
    with jax.enable_x64(True):
        step = jax.jit(physics.step)
        for k in range(u.shape[0] - 1):
            nxt = np.asarray(step(x[k], u[k], theta), dtype=np.float64) + w[k]
            if effect is not None:
                nxt = nxt + effect(x[k], u[k])
            x[k + 1] = nxt if limit is None else limit(nxt)
    return x


def _check_n_samples(n_samples) -> int:
    if isinstance(n_samples, bool) or not isinstance(n_samples, int | np.integer):
        raise TypeError(f"n_samples must be an int, got {n_samples!r}.")
    if n_samples < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}.")
    return int(n_samples)


def _check_number(name: str, value, what: str) -> float:
    """``value`` as a float, or a ``TypeError`` naming ``name`` (a string, a boolean or
    anything that is not a real number); ``what`` says what it must be."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise TypeError(f"{name} must be {what}, got {value!r}.")
    return float(value)


def _check_scale(name: str, value) -> float:
    """A standard deviation or bound: a finite number >= 0."""
    value = _check_number(name, value, "a finite number >= 0")
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}.")
    return value


def _check_fraction(name: str, value) -> float:
    """A fraction: a number in ``[0, 1]``."""
    value = _check_number(name, value, "a number in [0, 1]")
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"{name} must be a number in [0, 1], got {value!r}.")
    return value


def _check_random_state(random_state) -> np.random.RandomState:
    """scikit-learn's ``check_random_state``, its refusal naming ``random_state``."""
    try:
        return check_random_state(random_state)
    except (TypeError, ValueError) as error:
        raise ValueError(
            "random_state must be None, an int in [0, 2**32 - 1] or a numpy RandomState, "
            f"got {random_state!r} ({error})"
        ) from error


def _effect_sign(effect: Callable, x: np.ndarray, u: np.ndarray, equation: int) -> int:
    """Sign of ``sum_k Delta_k x_{equation,k}`` along a trajectory."""
    return int(np.sign(np.sum(effect(x[:-1], u[:-1]) * x[:-1, equation])))


class _HiddenEffect:
    """Picklable numpy callable ``(x, u) -> contribution`` of a hidden effect.

    ``contribution(x, u, **params)`` returns the additive contribution to every state
    equation, shape ``(..., n_states)``; with ``equation`` set only that entry is returned.
    """

    def __init__(self, contribution: Callable, params: dict, equation: int | None = None):
        self.contribution, self.params, self.equation = contribution, dict(params), equation

    def __call__(self, x, u):
        x, u = np.asarray(x, dtype=np.float64), np.asarray(u, dtype=np.float64)
        full = self.contribution(x, u, **self.params)
        return full if self.equation is None else full[..., self.equation]

    def _key(self):
        return (self.contribution, tuple(sorted(self.params.items())), self.equation)

    def __eq__(self, other) -> bool:
        return isinstance(other, _HiddenEffect) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"HiddenEffect({self.contribution.__name__}, {params}, equation={self.equation})"


def _hidden_effect(contribution, params, equation, variables, sign, description) -> dict:
    return {
        "equation": equation,
        "variables": tuple(variables),
        "sign": int(sign),
        "description": description,
        "function": _HiddenEffect(contribution, params, equation),
        "state_function": _HiddenEffect(contribution, params, None),
    }


def _record_noise(output: dict, process: dict, est: tuple, val: tuple) -> dict:
    """Noise description plus the realised sequences (``e``: output, ``w``: process)."""
    return {
        "output": output,
        "process": process,
        "output_noise": est[0],
        "process_noise": est[1],
        "output_noise_val": val[0],
        "process_noise_val": val[1],
    }


def printable(library):
    """``library`` with every nested pysindy ``CustomLibrary`` made printable (returned).

    pysindy 2.1's ``CustomLibrary`` keeps its ``library_functions`` argument as
    ``functions``, so its scikit-learn ``repr`` (and so the repr of a Bunch holding it)
    raises ``AttributeError``; the argument is kept under its own name as well.
    """
    for inner in getattr(library, "libraries", ()):
        printable(inner)
    if hasattr(library, "functions") and not hasattr(library, "library_functions"):
        library.library_functions = library.functions
    return library


def _memory_effect(
    equation, contribution, state, description, rates, realised, kinds, variables=("u",)
) -> dict:
    """``hidden_effect`` of an effect with memory on the input named ``variables`` (a play,
    a lag): no function of the state and input, so its realised ``contribution`` to
    equation ``equation`` along the estimation record's ``state`` (which signs it) and the
    ``realised`` inputs the plant saw (by name) instead of a function."""
    return {
        "target": "input",
        "equation": equation,
        "variables": tuple(variables),
        "sign": int(np.sign(np.sum(contribution * state))),
        "description": description,
        "rates": rates,
        "contribution": contribution,
        **realised,
        "kinds": {key: tuple(value) for key, value in kinds.items()},
    }


def _bunch(physics, records, theta, x0s, effect, library, noise, descr, **extra) -> Bunch:
    (u, x, z), (u_val, x_val, z_val) = records
    return Bunch(
        u=u,
        z=z,
        u_val=u_val,
        z_val=z_val,
        x=x,
        x_val=x_val,
        physics=physics,
        true_parameters=dict(theta),
        true_x0=np.array(x0s[0], dtype=np.float64),
        true_x0_val=np.array(x0s[1], dtype=np.float64),
        hidden_effect=effect,
        suggested_library=None if library is None else printable(library),
        noise=noise,
        state_names=list(physics.state_names),
        input_names=list(physics.input_names),
        output_names=list(physics.output_names),
        DESCR=descr,
        **extra,
    )


class _TermName:
    """Picklable pysindy name function: ``template.format(*variable_names)``."""

    def __init__(self, template: str):
        self.template = template

    def __call__(self, *names) -> str:
        return self.template.format(*names)

    def __eq__(self, other) -> bool:
        return isinstance(other, _TermName) and other.template == self.template

    def __hash__(self) -> int:
        return hash((_TermName, self.template))


def _simple_record(rng, n, physics, theta, x0, u, effect, stds, noisy_states):
    """Simulate one record with Gaussian process noise on ``noisy_states`` and output noise."""
    w = np.zeros((n - 1, physics.n_states))
    w[:, noisy_states] = _gaussian(rng, (n - 1, len(noisy_states)), stds[1])
    x = _rollout(physics, theta, x0, u, effect, w)
    e = _gaussian(rng, (n, 1), stds[0])
    return (u, x, x[:, :1] + e), (e, w)


def _simple_records(rng, n, physics, theta, x0, inputs, effect, stds, noisy_states=(0,)):
    records, noises = [], []
    for u in inputs:
        record, noise = _simple_record(rng, n, physics, theta, x0, u, effect, stds, noisy_states)
        records.append(record)
        noises.append(noise)
    return records, noises


def _gaussian_noise(stds, noises, process_target: str) -> dict:
    gaussian = {"distribution": "gaussian"}
    return _record_noise(
        {**gaussian, "std": stds[0], "applied_to": "z"},
        {**gaussian, "std": stds[1], "applied_to": process_target},
        *noises,
    )


@dataclass(frozen=True)
class _SimpleSystem:
    """A system with one measured state and one hidden effect on one equation.

    ``physics(values, x0)`` builds the declared physics; the true system adds
    ``contribution(x, u, **params)`` to equation ``equation``. ``library()`` makes a new
    suggested library for every dataset.
    """

    physics: Callable
    theta: dict
    guess: dict
    x0: tuple
    contribution: Callable
    params: dict
    equation: int
    variables: tuple
    effect_description: str
    library: Callable
    process_target: str
    descr: str
    dt: float
    guess_x0_measured: bool = False


def _noise_stds(noise_std, process_noise_std) -> tuple[float, float]:
    return (
        _check_scale("noise_std", noise_std),
        _check_scale("process_noise_std", process_noise_std),
    )


def _simple_dataset(system: _SimpleSystem, rng, n: int, inputs, stds) -> Bunch:
    """Estimation and validation records of ``system`` (inputs drawn by the caller first).

    The physics returned starts from ``system.guess``, and from the first measured output
    as initial state when ``guess_x0_measured`` (else from the true ``x0``).
    """
    x0, eq = np.asarray(system.x0, dtype=np.float64), system.equation
    effect = _HiddenEffect(system.contribution, system.params)
    plain = system.physics(system.theta, system.x0)
    (est, val), noises = _simple_records(
        rng, n, plain, system.theta, x0, inputs, effect, stds, (eq,)
    )
    u, x, z = est
    sign = _effect_sign(_HiddenEffect(system.contribution, system.params, eq), x, u, eq)
    hidden = _hidden_effect(
        system.contribution, system.params, eq, system.variables, sign, system.effect_description
    )
    guess_x0 = (z[0, 0],) if system.guess_x0_measured else system.x0
    return _bunch(
        system.physics(system.guess, guess_x0),
        (est, val),
        system.theta,
        (x0, x0),
        hidden,
        system.library(),
        _gaussian_noise(stds, noises, system.process_target),
        system.descr,
        sampling_time=system.dt,
    )
