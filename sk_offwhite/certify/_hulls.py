r"""Fig. 2 of Donati et al., the Monte Carlo way: FPS and SFPS as convex hulls of estimates.

Section 5.1 approximates the feasible parameter sets by the convex hulls of the Monte
Carlo estimates $\hat\theta_i$: FPS from every estimate, SFPS from those whose
$\hat\omega$ passes Theorem 5, shown in the plane of the first two principal
components of $\theta$. The worst-case error of an estimate over a hull,

$$
e(\hat\theta_i) = \max_{\theta \in \mathrm{conv}\{\hat\theta_j\}}
\|\theta - \hat\theta_i\|_2 = \max_j \|\hat\theta_j - \hat\theta_i\|_2,
$$

is attained at a vertex (a convex function on a polytope), so it needs no hull at all;
[`hull_errors`][sk_offwhite.certify.hull_errors] returns its mean and standard deviation over the
estimates in the hull, the paper's "mean $\pm 1\sigma$". These are statistics of a finite sample: a
hull of $N$ estimates grows with $N$, and the paper's numbers come from 5000 runs.
The exact sets (19)/(20) of one record are in `_feasible`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["hull_errors", "hull_polygon", "principal_components"]


def _points(points, name: str = "points") -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or not np.all(np.isfinite(points)):
        raise ValueError(f"{name} must be a finite 2-D array (one estimate per row).")
    return points


def hull_errors(points) -> tuple[float, float]:
    r"""Mean and standard deviation of $\max_j \|\hat\theta_j - \hat\theta_i\|_2$.

    Parameters
    ----------
    points : array-like of shape (N, d)
        The estimates spanning the hull (in $\theta$ or in principal components).

    Returns
    -------
    mean, std : float
        Over the ``N`` estimates of their worst-case error over the hull; ``nan`` with
        fewer than two estimates (a hull of one point says nothing about the spread).
    """
    points = _points(points)
    if len(points) < 2:
        return np.nan, np.nan
    worst = np.max(np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2), axis=1)
    return float(np.mean(worst)), float(np.std(worst))


def principal_components(points, reference=None, n_components: int = 2) -> np.ndarray:
    r"""Coordinates of ``points`` on the first principal axes of ``reference``.

    Parameters
    ----------
    points : array-like of shape (N, d)
    reference : array-like of shape (K, d), optional
        The estimates that define the axes (centred on their mean); default ``points``.
        Give the FPS estimates so that FPS and SFPS share one plane.
    n_components : int, default=2

    Returns
    -------
    ndarray of shape (N, n_components)
        $(\hat\theta_i - \bar\theta_{\rm ref}) V_{:, :k}$, with $V$ the right
        singular vectors of the centred reference (signs fixed: the largest entry of each
        axis is positive).
    """
    points = _points(points)
    reference = points if reference is None else _points(reference, "reference")
    if reference.shape[1] != points.shape[1]:
        raise ValueError("reference must have as many columns as points.")
    if not 1 <= n_components <= min(reference.shape):
        raise ValueError(
            f"n_components must be in [1, {min(reference.shape)}] for a reference of "
            f"{len(reference)} estimates in dimension {reference.shape[1]}."
        )
    centre = reference.mean(axis=0)
    axes = np.linalg.svd(reference - centre, full_matrices=False)[2][:n_components].T
    axes = axes * np.sign(axes[np.argmax(np.abs(axes), axis=0), range(n_components)])
    return (points - centre) @ axes


def hull_polygon(points) -> np.ndarray:
    """Vertices of the 2-D convex hull of ``points``, closed (first vertex repeated).

    Parameters
    ----------
    points : array-like of shape (N, 2)

    Returns
    -------
    ndarray of shape (V + 1, 2)
        Counter-clockwise (Andrew's monotone chain); the points themselves when there are
        fewer than three distinct ones.
    """
    points = _points(points)
    if points.shape[1] != 2:
        raise ValueError("points must have two columns (a plane).")
    unique = sorted(set(map(tuple, points)))
    if len(unique) < 3:
        return np.array(unique + unique[:1]).reshape(-1, 2)
    lower, upper = _chain(unique), _chain(unique[::-1])
    hull = lower[:-1] + upper[:-1]
    return np.array(hull + hull[:1])


def _chain(points: list) -> list:
    """One half of Andrew's monotone chain over sorted points."""
    chain: list = []
    for p in points:
        while len(chain) >= 2 and _cross(chain[-2], chain[-1], p) <= 0:
            chain.pop()
        chain.append(p)
    return chain


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
