"""The models of the effect sets the loop tries: one per set, or one for all of them.

:class:`SeparateModels` builds each set's model with :func:`~sk_offwhite.augment`: a new
``jit`` structure per set, compiled again for every record layout it is fitted on (the
candidate fits, the CV folds, the initial-state estimation). :class:`Switchboard` puts every
candidate behind a switch (:class:`~sk_offwhite.Switched`) in one model, so the sets differ
only in parameter values and share one compiled program per layout; the switched-off
effects' parameters stay in the fit as variables without influence (zero Jacobian
columns). Both compose a set's effects in the order the candidates are given.

Measured on the Cascaded Tanks main job (jax 0.10.2, 2 CPU cores): the switchboard cuts XLA
compilation from 95 s to 64 s (349 to 251 compilations) and the run from 232 s to 220 s,
but the fits of the effect sets, which stop at ``max_iter`` there, end elsewhere (their
linear algebra has more columns, so other rounding): the cross-validated error of the
3-effect set moved from 0.523 to 0.605 and the loop kept 2 effects instead of 3. Measured
again with the per-variable damping floor (warm compilation cache, 2 quiet cores, two
runs each): the same effects, CV and validation errors to every printed digit, and no
faster: 53-58 s against 50-60 s with separate models, since every fit carries the
switched-off parameters' columns. The loop therefore uses separate models unless
``LoopSettings(share_programs=True)``.
"""

from __future__ import annotations

from typing import NamedTuple

from .._effects import Switched, augment, switched, switches
from .._physics import Parameter, PhysicsModel

__all__ = ["SeparateModels", "Switchboard", "effect_sets"]


class SeparateModels(NamedTuple):
    """The declared physics and the candidate effects, in order; one model per set."""

    physics: PhysicsModel
    effects: tuple

    @classmethod
    def of(cls, physics: PhysicsModel, effects) -> SeparateModels:
        return cls(physics, tuple(effects))

    def ordered(self, effects) -> tuple:
        """``effects`` in the order of the candidates."""
        chosen = set(effects)
        return tuple(effect for effect in self.effects if effect in chosen)

    def model(self, on, warm: dict[str, Parameter] | None = None) -> PhysicsModel:
        """The physics augmented with the effects ``on``, started from ``warm``."""
        _check_known(on, self.effects)
        return augment(self.physics, *self.ordered(on)).with_parameters(**(warm or {}))


class Switchboard(NamedTuple):
    """The declared physics with every candidate effect switched off, and the switches.

    Relaxed laws (:class:`~sk_offwhite.RelaxedLaw`) need no switch: they change no
    program, only which parameters are fitted, and are applied to the board as they are.
    """

    physics: PhysicsModel
    board: tuple[Switched, ...]
    laws: tuple = ()

    @classmethod
    def of(cls, physics: PhysicsModel, effects) -> Switchboard:
        """``physics`` augmented with every one of ``effects`` behind a switch (all off)."""
        board = tuple(switched(effect) for effect in effects if effect.target != "law")
        laws = tuple(effect for effect in effects if effect.target == "law")
        return cls(augment(physics, *board).with_parameters(**switches(board, ())), board, laws)

    def ordered(self, effects) -> tuple:
        """``effects`` in the order they act on the board (relaxed laws last)."""
        chosen = {switched(effect) for effect in effects if effect.target != "law"}
        laws = tuple(law for law in self.laws if law in set(effects))
        return tuple(s.effect for s in self.board if s in chosen) + laws

    def model(self, on, warm: dict[str, Parameter] | None = None) -> PhysicsModel:
        """The physics with the effects ``on`` switched on, started from ``warm``."""
        _check_known(on, [s.effect for s in self.board] + list(self.laws))
        laws = [effect for effect in on if effect.target == "law"]
        switched_on = [effect for effect in on if effect.target != "law"]
        physics = augment(self.physics, *laws) if laws else self.physics
        return physics.with_parameters(**switches(self.board, switched_on), **(warm or {}))


def effect_sets(physics: PhysicsModel, effects, shared: bool) -> Switchboard | SeparateModels:
    """A :class:`Switchboard` when ``shared``, else :class:`SeparateModels`."""
    return (Switchboard if shared else SeparateModels).of(physics, effects)


def _check_known(on, effects) -> None:
    unknown = [effect for effect in on if effect not in effects]
    if unknown:
        raise ValueError(f"effects not among the candidates: {unknown}.")
