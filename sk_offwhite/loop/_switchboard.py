"""The models of the effect sets the loop tries: one per set, or one for all of them.

`SeparateModels` builds each set's model with [`augment`][sk_offwhite.augment]: a new
``jit`` structure per set, compiled again for every record layout it is fitted on (the
candidate fits, the CV folds, the initial-state estimation). `Switchboard` puts every
candidate behind a switch ([`Switched`][sk_offwhite.Switched]) in one model, so the sets differ
only in parameter values: a switched-off effect is not computed, and its parameters are held
where they are (fixed), so a set's fit has the free variables it has on its own model. The
solver pads its free vector to one size for every set (``Model.free_multiple``), so the
sets share one compiled program per layout. Both compose a set's effects in the order the
candidates are given.

The board compiles less than separate models do. With ``LoopSettings(share_programs=True)``
the loop fits the effect sets on one, in its own process: each worker would compile the
board's programs again for itself, where a separate model is compiled only by the worker
that fits it. That pays where the fits are mostly compilation (a short record); where they
are mostly simulation (a long record), separate models spread over the workers pay, which
is why the board is not the default for the effect sets. The board's rounding also differs
from that of a set's own model: a fit on the whole record agrees with its own model's to
rounding, but the folds' fits, stopped at ``max_iter``, can amplify the difference enough
to flip a near-tie between two sets; the chosen set is fitted again on a model of its own,
the model the loop keeps.

The single candidates are another matter (`single_effect_models`). Each is fitted once, on
the estimation record (no fold), and a candidate's fit is mostly compilation. On one board,
in one process, the first fit compiles the board's programs and the others compile nothing;
a switched model pads its free vector to one size for every switch setting
(``Model.free_multiple``), so the board compiles one solver program per record layout.
Fitted on the whole record, a candidate on the board agrees with its fit on its own model
up to rounding. Effects with memory of their own stay on their own models (their hidden
states would ride along in every fit on the board), as do relaxed laws (each changes the
board's structure).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

from ..effects import Switched, augment, switched
from ..effects._switched import switches
from ..model._physics import Parameter, PhysicsModel

__all__ = ["SeparateModels", "Switchboard", "effect_sets", "single_effect_models"]


class SeparateModels(NamedTuple):
    """The declared physics and the candidate effects, in order; one model per set."""

    physics: PhysicsModel
    effects: tuple

    @classmethod
    def of(cls, physics: PhysicsModel, effects) -> SeparateModels:
        return cls(physics, tuple(effects))

    @property
    def fitted_here(self) -> bool:
        """False: each set's model is compiled only by the worker that fits it, so its
        fits may be spread over ``n_jobs`` processes."""
        return False

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

    Relaxed laws ([`RelaxedLaw`][sk_offwhite.RelaxedLaw]) need no switch: they change no
    program, only which parameters are fitted, and are applied to the board as they are; so
    is an input hold ([`InputHold`][sk_offwhite.InputHold]), which changes the integrator.
    """

    physics: PhysicsModel
    board: tuple[Switched, ...]
    laws: tuple = ()

    @classmethod
    def of(cls, physics: PhysicsModel, effects) -> Switchboard:
        """``physics`` augmented with every one of ``effects`` behind a switch (all off)."""
        board = tuple(switched(effect) for effect in effects if not _structural(effect))
        laws = tuple(effect for effect in effects if _structural(effect))
        return cls(augment(physics, *board).with_parameters(**switches(board, ())), board, laws)

    @property
    def fitted_here(self) -> bool:
        """True: the fits on the board share its compiled programs, which every worker
        would trace and compile again for itself, so they run in the loop's process."""
        return True

    def ordered(self, effects) -> tuple:
        """``effects`` in the order they act on the board (relaxed laws last)."""
        chosen = {switched(effect) for effect in effects if not _structural(effect)}
        laws = tuple(law for law in self.laws if law in set(effects))
        return tuple(s.effect for s in self.board if s in chosen) + laws

    def model(self, on, warm: dict[str, Parameter] | None = None) -> PhysicsModel:
        """The physics with the effects ``on`` switched on, started from ``warm``."""
        _check_known(on, [s.effect for s in self.board] + list(self.laws))
        laws = [effect for effect in on if _structural(effect)]
        switched_on = [effect for effect in on if not _structural(effect)]
        physics = augment(self.physics, *laws) if laws else self.physics
        physics = physics.with_parameters(**switches(self.board, switched_on), **(warm or {}))
        return physics.with_parameters(**_held(physics, self.board, switched_on))


def effect_sets(physics: PhysicsModel, effects, shared: bool) -> Switchboard | SeparateModels:
    """A `Switchboard` when ``shared``, else `SeparateModels`."""
    return (Switchboard if shared else SeparateModels).of(physics, effects)


def single_effect_models(physics: PhysicsModel, effects) -> list:
    """For each of ``effects``, what its fit alone builds its model from: one
    `Switchboard` of the effects that can share it, whose fits then share one
    compiled program per layout, and `SeparateModels` for the others (all of them
    when fewer than two would share the board).

    An effect with memory of its own (hidden states) would add them to every fit on the
    board, and a relaxed law changes the board's structure: each is fitted on its own
    model.
    """
    sharing = [_shares_a_board(effect) for effect in effects]
    separate = SeparateModels.of(physics, effects)
    if sum(sharing) < 2:
        return [separate] * len(effects)
    board = Switchboard.of(
        physics, [e for e, shares in zip(effects, sharing, strict=True) if shares]
    )
    return [board if shares else separate for shares in sharing]


def _shares_a_board(effect) -> bool:
    return not effect.hidden_states and not _structural(effect)


def _structural(effect) -> bool:
    """An effect that changes the board's structure rather than adding to it, applied to the
    board as it is: a relaxed law (which parameters are fitted) or an input hold (the
    integrator)."""
    return effect.target in ("law", "hold")


def _held(physics: PhysicsModel, board, on) -> dict[str, Parameter]:
    """The parameters of the effects of ``board`` that are not ``on``, fixed where they are:
    without influence on the fit, they would only add zero columns to its Jacobian."""
    names = {effect.name for effect in on}
    return {
        name: dataclasses.replace(physics.parameters[name], fixed=True)
        for switch in board
        if switch.name not in names
        for name in switch.effect.parameters()
    }


def _check_known(on, effects) -> None:
    unknown = [effect for effect in on if effect not in effects]
    if unknown:
        raise ValueError(f"effects not among the candidates: {unknown}.")
