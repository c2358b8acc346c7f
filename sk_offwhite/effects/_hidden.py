r"""Hidden states: effects with memory appended to a model's state.

Some effects cannot be written as a function of the current state and input: the play of
a gear (backlash) remembers which side of the play it last touched. Such an effect carries
hidden states $h$ of its own, appended after the declared states,

$$
\begin{bmatrix} x_{k+1} \\ h_{k+1} \end{bmatrix} =
\begin{bmatrix} f\bigl(x_k, \tilde u_k; \theta\bigr) \\ h_{k+1} \end{bmatrix},
\qquad (\tilde u_k, h_{k+1}) = a(h_k, u_k; \theta_E),
$$

where $a$ is the effect's ``advance``: it turns the input the plant receives into the
one the declared step sees and updates its memory. An effect that ``follows_output`` (a
slow sensor, [`SensorLag`][sk_offwhite.SensorLag]) updates its memory from the declared output
map instead, $h_{k+1} = a(h_k, y_k, y_{k+1}; \theta_E)$ with
$y_k = h(x_k, u_k; \theta)$ and $y_{k+1} = h(x_{k+1}, u_k; \theta)$, and the
output reads it. The declared step, output map and
constraints see only $x$; the hidden states' initial values are estimated with the
declared ones (they are ordinary, free entries of $x_0$), unless the effect fixes
them (``hidden_free = False``: each record starts them where the effect's
``hidden_start`` puts them).

Where they are estimated and where they are not:

- every record starts them where ``hidden_start`` puts them (its first input, or the
  first measurement for a slow sensor), inside the bounds ``hidden_bounds`` gives on
  that record; free ones are then fitted with the initial state;
- a multiple-shooting window after a record's first frees them too, except the states
  the inputs alone determine (``hidden_free`` false): those start where the record's
  inputs put them (``hidden_path``: a dead time's past commands are the commands
  before the window), so no window fits what is known;
- the sparse correction $\delta$ neither reads them nor corrects them: its
  dictionary is evaluated on the declared states and the inputs, and its rows are the
  declared states' unless ``delta_states`` names others;
- the loop proposes effects on the declared states only.

An effect with memory derives from `HiddenStates` (or `FollowsOutput`) and the base of
its target.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..model._physics import measured_states

__all__ = [
    "DeclaredStates",
    "FollowsOutput",
    "HiddenStateStep",
    "HiddenStates",
    "SensorReading",
    "hidden_bounds",
    "hidden_start",
    "input_determined",
    "n_declared_states",
    "sensor_readings",
    "with_hidden_states",
    "with_input_determined",
]


class HiddenStates:
    """Mixin of an effect with memory of its own: hidden states appended to the model's.

    The effect sets ``hidden_states`` (their names) and implements `advance`,
    `hidden_initial` and, where a guess may lie where the first step forgets it,
    `hidden_start` and `hidden_bounds`. One whose memory follows the inputs alone, whatever
    the parameters, sets ``hidden_free = False``; its `hidden_path` then steps `advance`
    along a record, or gives the path in closed form.
    """

    target = "hidden"
    hidden_free = True
    """Whether the hidden states' initial values are estimated with the initial state;
    ``False``: each record starts them where `hidden_start` puts them (the past commands of
    a dead time, which only the record's first samples see), and `advance` updates them
    from the inputs alone, so that every later sample's values are known (`hidden_path`)
    and a shooting window starts them there rather than fitting them."""
    follows_output = False
    """Whether the hidden states follow the declared output map rather than the input
    ([`FollowsOutput`][sk_offwhite.effects.FollowsOutput])."""

    def advance(self, hidden, u, theta):
        """``(input the declared step sees, next hidden states)`` from the hidden states and
        the input (both unchanged by default)."""
        return u, hidden

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
        """For an effect that fixes its hidden states (`hidden_free` false): their values at
        every sample of a record with inputs ``u`` (NumPy, one row per sample), started by
        `hidden_start` and moved by `advance` (one ``lax.scan`` in double precision;
        ``theta`` the parameters by name)."""
        start = np.asarray(self.hidden_start(self.hidden_initial(), u[0], theta), float)

        def step(hidden, u_k):
            return self.advance(hidden, u_k, theta)[1], hidden

        with jax.enable_x64(True):
            _, path = jax.lax.scan(step, jnp.asarray(start), jnp.asarray(u, float))
        return np.asarray(path, float)


class FollowsOutput(HiddenStates):
    """Mixin of an effect whose hidden states follow the declared output map rather than the
    input (a slow sensor, [`SensorLag`][sk_offwhite.SensorLag]): it implements `follow`, and the
    output reads its states."""

    follows_output = True

    def follow(self, hidden, now, after, theta):
        """The next hidden states from these and the declared outputs at samples $k$
        (``now``) and $k + 1$ (``after``)."""
        return hidden

    def follow_off(self, hidden, now, after):
        """`follow` of the effect switched off ([`Switched`][sk_offwhite.Switched]): hidden
        states whose reading is the declared output (the hidden states themselves by
        default)."""
        return hidden


class HiddenStateStep:
    """Step of a model with hidden states: each effect's ``advance`` on its slice of the
    hidden states and on the input, then the ``inner`` step on the declared states, then
    the effects that follow the declared ``output`` map (``None`` when none does)."""

    def __init__(
        self, inner, effects: tuple, n_declared: int, output=None, hold="zero", n_inputs=0
    ):
        self.inner, self.effects, self.n_declared = inner, effects, int(n_declared)
        self.output, self.hold, self.n_inputs = output, hold, int(n_inputs)
        self.__name__ = getattr(inner, "__name__", "step")

    def slices(self):
        """``(effect, slice)`` of each effect's hidden states in the state vector."""
        start = self.n_declared
        for effect in self.effects:
            stop = start + len(effect.hidden_states)
            yield effect, slice(start, stop)
            start = stop

    def __call__(self, x, u, theta):
        hidden_next, command = {}, u
        for effect, part in self.slices():
            if not effect.follows_output:
                u, hidden_next[part.start] = effect.advance(x[part], u, theta)
        declared = self.inner(x[: self.n_declared], self._held(u, command), theta)
        declared = jnp.asarray(declared, dtype=x.dtype).reshape(self.n_declared)
        sample = command[: self.n_inputs] if self._pair(command) else command
        hidden_next.update(self._followed(x, declared, sample, theta))
        parts = [
            jnp.reshape(hidden_next[part.start], (part.stop - part.start,)).astype(x.dtype)
            for _, part in self.slices()
        ]
        return jnp.concatenate([declared, *parts])

    def _held(self, u, command):
        """``u`` where the step reads ``[u_k, u_{k+1}]`` (`InputHold`): the inputs the
        effects with memory delivered are held over the sample (their next value is not
        known yet), the others move to the next sample as commanded."""
        touched = sorted({e.input for e in self.effects if getattr(e, "input", None) is not None})
        if not (touched and self._pair(command)):
            return u
        for i in touched:
            u = u.at[i + self.n_inputs].set(u[i])
        return u

    def _pair(self, u) -> bool:
        """Whether the step was handed ``[u_k, u_{k+1}]`` (a first-order hold)."""
        return self.hold == "linear" and u.shape[0] == 2 * self.n_inputs

    def _followed(self, x, declared_next, u, theta) -> dict:
        """Next hidden states of the effects that follow the declared output, by the
        index of their first state."""
        following = [(e, p) for e, p in self.slices() if e.follows_output]
        if not following:
            return {}
        now = jnp.atleast_1d(self.output(x[: self.n_declared], u, theta))
        after = jnp.atleast_1d(self.output(declared_next, u, theta))
        return {part.start: effect.follow(x[part], now, after, theta) for effect, part in following}

    def _key(self):
        return (
            HiddenStateStep,
            self.inner,
            self.effects,
            self.n_declared,
            self.output,
            self.hold,
            self.n_inputs,
        )

    def __eq__(self, other) -> bool:
        return isinstance(other, HiddenStateStep) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())


def hidden_start(step, x0, u_first, theta: dict, fixed=None) -> np.ndarray:
    """``x0`` (a record's initial-state guess) with each effect's hidden states where a
    record whose first input is ``u_first`` starts them
    (`Effect.hidden_start`); entries marked in ``fixed`` and
    models without hidden states are left as they are, but for the states of an effect that fixes
    them (``hidden_free`` false), which are always started there."""
    x0 = np.array(x0, dtype=float)
    if not isinstance(step, HiddenStateStep):
        return x0
    u_first = np.asarray(u_first, float).reshape(-1)
    keep = np.zeros(x0.shape, bool) if fixed is None else np.asarray(fixed, bool)
    for effect, part in step.slices():
        moved = np.asarray(effect.hidden_start(x0[part], u_first, theta), float)
        x0[part] = np.where(keep[part] & effect.hidden_free, x0[part], moved)
    return x0


def n_declared_states(physics) -> int:
    """The number of states ``physics`` declares: its states less the hidden states of its
    effects ([`augment`][sk_offwhite.augment])."""
    return getattr(physics, "n_declared_states", physics.n_states)


def input_determined(step, n_states: int) -> np.ndarray:
    """Mask of the ``n_states`` states that the inputs alone determine after a record's
    start: the hidden states of effects that fix them (``hidden_free`` false)."""
    mask = np.zeros(n_states, bool)
    if isinstance(step, HiddenStateStep):
        for effect, part in step.slices():
            mask[part] = not effect.hidden_free
    return mask


def with_input_determined(step, states, u, theta: dict, samples) -> np.ndarray:
    """``states`` (one row per sample in ``samples`` of a record with inputs ``u``) with
    the states the inputs determine (`input_determined`) set to their values there
    (`Effect.hidden_path`)."""
    states = np.array(states, dtype=float)
    if not isinstance(step, HiddenStateStep):
        return states
    for effect, part in step.slices():
        if not effect.hidden_free:
            states[:, part] = effect.hidden_path(u, theta)[np.asarray(samples)]
    return states


def sensor_readings(step) -> tuple[tuple[int, int], ...]:
    """``(output, state)`` for each hidden state that an output reads (an effect that
    follows the output, [`SensorLag`][sk_offwhite.SensorLag]); empty for other models."""
    if not isinstance(step, HiddenStateStep):
        return ()
    return tuple(
        (effect.output, part.start) for effect, part in step.slices() if effect.follows_output
    )


def hidden_bounds(step, u, n_states: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the ``n_states`` initial states on a record with inputs
    ``u`` that the effects' hidden states set
    (`Effect.hidden_bounds`); the declared states and models
    without hidden states are unbounded here."""
    lower, upper = np.full(n_states, -np.inf), np.full(n_states, np.inf)
    if not isinstance(step, HiddenStateStep):
        return lower, upper
    for effect, part in step.slices():
        bounds = np.asarray(effect.hidden_bounds(u), float).reshape(-1, 2)
        lower[part], upper[part] = bounds[:, 0], bounds[:, 1]
    return lower, upper


class DeclaredStates:
    """``function(x[:n_declared], u, theta)``: a declared map (output, constraint) that
    never sees the hidden states."""

    def __init__(self, function, n_declared: int):
        self.function, self.n_declared = function, int(n_declared)

    def __call__(self, x, u, theta):
        return self.function(x[: self.n_declared], u, theta)

    def __eq__(self, other) -> bool:
        return isinstance(other, DeclaredStates) and (self.function, self.n_declared) == (
            other.function,
            other.n_declared,
        )

    def __hash__(self) -> int:
        return hash((DeclaredStates, self.function, self.n_declared))


class SensorReading:
    """Output map of a model whose sensors lag: the declared map on the declared states,
    output ``j`` replaced by hidden state ``i`` for each pair ``(j, i)`` of ``lagged``.
    ``indices`` are the declared map's measured states, when it reads states (the first
    guess of a record's initial state), and ``readings`` the ``(output, state)`` pairs."""

    def __init__(self, function, n_declared: int, lagged: tuple):
        self.function, self.n_declared = function, int(n_declared)
        self.readings = tuple((int(j), int(i)) for j, i in lagged)
        declared = getattr(function, "indices", None)
        if declared is not None:
            self.indices = declared

    def __call__(self, x, u, theta):
        z = jnp.atleast_1d(self.function(x[: self.n_declared], u, theta))
        for output, state in self.readings:
            z = z.at[output].set(x[state])
        return z

    def _key(self):
        return (SensorReading, self.function, self.n_declared, self.readings)

    def __eq__(self, other) -> bool:
        return isinstance(other, SensorReading) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())


def _declared_only(function, n_declared: int):
    """``function`` restricted to the declared states (``None`` and wrapped maps kept)."""
    if function is None or isinstance(function, DeclaredStates):
        return function
    return DeclaredStates(function, n_declared)


def with_hidden_states(model, physics, hidden: tuple, new: tuple) -> None:
    """Give ``model`` (a copy of ``physics`` being augmented, modified in place) the hidden
    states of the effects ``hidden`` (all of them, in order); ``new`` are those ``physics``
    does not have yet, whose states are appended to its ``x0``, names and kinds.

    The output map (unless it reads states by index), the constraints and the step see the
    declared states only; an effect that follows the output reads ``model.declared``'s map.
    """
    n_declared = n_declared_states(physics)
    for effect in new:
        index = getattr(effect, "input", None)
        if index is not None and not 0 <= index < physics.n_inputs:
            raise ValueError(
                f"{effect!r} acts on input {index}, but the physics has {physics.n_inputs}."
            )
    added = [(effect, name) for effect in new for name in effect.hidden_states]
    initial = [value for effect in new for value in effect.hidden_initial()]
    low, high = physics.x0_bounds
    model.n_declared_states = n_declared
    model.n_states = physics.n_states + len(added)
    followed = model.declared[1] if any(e.follows_output for e in hidden) else None
    hold = getattr(model, "input_hold", "zero")
    model.step = HiddenStateStep(model.step, hidden, n_declared, followed, hold, model.n_inputs)
    if callable(model.output) and measured_states(model.output) is None:
        model.output = _declared_only(model.output, n_declared)
    model.inequality = _declared_only(physics.inequality, n_declared)
    model.equality = _declared_only(physics.equality, n_declared)
    model.x0 = np.concatenate([physics.x0, np.clip(initial, low, high)])
    fixed = [not effect.hidden_free for effect, _ in added]
    model.x0_fixed = np.concatenate([physics.x0_fixed, np.asarray(fixed, bool)])
    model.state_names = tuple(physics.state_names) + tuple(name for _, name in added)
    kinds = [kind for effect in new for kind in effect.hidden_kinds(physics.input_kinds)]
    model.state_kinds = tuple(physics.state_kinds) + tuple(kinds)
