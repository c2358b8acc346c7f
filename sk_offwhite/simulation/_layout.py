"""Packing of the decision variables into one flat vector and back.

The fit optimises named blocks (``theta``, ``x0``, ``omega`` and the inner parameters of a
ridge basis). Solvers see one flat vector of the *free* entries; fixed entries (fixed
physical parameters, a fixed initial state, masked dictionary weights) stay at their base
value. `Layout` is hashable so it can be a static argument of ``jax.jit``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

__all__ = ["Layout"]


@dataclass(frozen=True)
class Layout:
    """Names and shapes of the decision-variable blocks, in packing order."""

    blocks: tuple[tuple[str, tuple[int, ...]], ...]

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Layout:
        return cls(tuple((name, tuple(np.shape(value))) for name, value in arrays.items()))

    @property
    def size(self) -> int:
        """Total number of entries, free and fixed."""
        return sum(math.prod(shape) for _, shape in self.blocks)

    def flatten(self, arrays: dict[str, np.ndarray]) -> np.ndarray:
        """Concatenate the blocks of ``arrays`` into one float vector."""
        parts = [np.asarray(arrays[name], dtype=float).reshape(-1) for name, _ in self.blocks]
        return np.concatenate(parts) if parts else np.zeros(0)

    def unflatten(self, flat) -> dict:
        """Split a flat vector (numpy or JAX) into named blocks of the recorded shapes."""
        out, start = {}, 0
        for name, shape in self.blocks:
            stop = start + math.prod(shape)
            out[name] = flat[start:stop].reshape(shape)
            start = stop
        return out

    def expand(self, free, base, free_index):
        """Full vector: ``base`` with the entries at ``free_index`` replaced by ``free``."""
        return jnp.asarray(base).at[free_index].set(free)
