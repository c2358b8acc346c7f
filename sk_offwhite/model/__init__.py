"""The user's model: a discrete-time state-space physics with named parameters, the physical
kinds of its variables, and its equations written out."""

from ._physics import Parameter, PhysicsModel

__all__ = ["Parameter", "PhysicsModel"]
