r"""Dictionaries of basis functions for the sparse correction, compiled to pure ``jax.numpy``.

The correction of ``x[k+1] = f(x, u; θ) + δ(x, u; ω)`` is a sparse linear combination of
basis functions evaluated on $v = [x; u]$:

$$
\delta_i(v) = \sum_{j=1}^{m} \Omega_{ij}\, \Phi_{ij}(v), \qquad i = 1, \dots, n_\delta.
$$

Three kinds are supported: pysindy 2.1 feature libraries (re-implemented in ``jax.numpy``
and checked against their ``transform``), ridge functions
([`RidgeBasis`][sk_offwhite.RidgeBasis], the paper's basis, with trainable inner weights) and
Gaussian bumps ([`RadialBasis`][sk_offwhite.RadialBasis]).
[`compile_basis`][sk_offwhite.compile_basis] turns any of them into a
[`CompiledBasis`][sk_offwhite.dictionaries.CompiledBasis].
"""

from ._compile import compile_basis
from ._compiled import CompiledBasis, evaluate_matrix
from ._radial import RadialBasis
from ._ridge import RidgeBasis

__all__ = ["CompiledBasis", "RadialBasis", "RidgeBasis", "compile_basis", "evaluate_matrix"]
