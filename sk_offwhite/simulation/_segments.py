"""Cutting records into the simulated segments of the multi-step cost.

A *record* is one contiguous measured sequence (an experiment, or one block of a
cross-validation fold). With ``horizon=None`` each record is simulated whole from its own
initial state; with ``horizon=T`` it is cut into windows of ``T`` steps, each with its own
initial state, linked to the end of the previous window by a continuity penalty (multiple
shooting). Segments are padded to a common length and masked, so all of them are simulated
at once with ``vmap``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Segments", "make_segments", "pad_rows", "padded_length", "split_at_gaps"]


class Segments(NamedTuple):
    """Padded segments ready for a batched rollout.

    Attributes
    ----------
    u : array of shape (n_segments, length, n_inputs)
    z : array of shape (n_segments, length, n_outputs)
    mask : array of shape (n_segments, length)
        1 for measured samples, 0 for padding.
    linked : array of shape (n_segments,)
        1 where the segment continues the previous one (its initial state must match the
        previous segment's final state), 0 at the start of a record.
    record : array of shape (n_segments,)
        Index of the record each segment belongs to.
    """

    u: np.ndarray
    z: np.ndarray
    mask: np.ndarray
    linked: np.ndarray
    record: np.ndarray


def split_at_gaps(u: np.ndarray, z: np.ndarray, sample_index) -> list[tuple]:
    """Split one array into contiguous records where ``sample_index`` jumps.

    ``sample_index`` holds the original time index of every row (for example the indices a
    cross-validation splitter selected); a record ends wherever consecutive indices differ
    by anything other than one, so a gap is never simulated through.
    """
    if sample_index is None:
        return [(u, z)]
    index = np.asarray(sample_index).reshape(-1)
    if index.shape[0] != u.shape[0]:
        raise ValueError(
            f"sample_index must have one entry per sample ({u.shape[0]}), got {index.shape[0]}."
        )
    breaks = np.flatnonzero(np.diff(index) != 1) + 1
    return list(zip(np.split(u, breaks), np.split(z, breaks), strict=True))


def _windows(length: int, horizon: int | None) -> list[tuple[int, int]]:
    if horizon is None or horizon >= length:
        return [(0, length)]
    return [(start, min(start + horizon, length)) for start in range(0, length, horizon)]


def make_segments(records: list[tuple], horizon: int | None) -> Segments:
    """Cut ``records`` (a list of ``(u, z)`` pairs) into padded, masked segments."""
    pieces, linked, record_of = [], [], []
    for r, (u, z) in enumerate(records):
        for w, (start, stop) in enumerate(_windows(u.shape[0], horizon)):
            pieces.append((u[start:stop], z[start:stop]))
            linked.append(w > 0)
            record_of.append(r)
    length = padded_length(max(piece_u.shape[0] for piece_u, _ in pieces))
    u_pad = np.stack([pad_rows(piece_u, length) for piece_u, _ in pieces])
    z_pad = np.stack([pad_rows(piece_z, length) for _, piece_z in pieces])
    mask = np.zeros((len(pieces), length))
    for s, (piece_u, _) in enumerate(pieces):
        mask[s, : piece_u.shape[0]] = 1.0
    return Segments(u_pad, z_pad, mask, np.asarray(linked, float), np.asarray(record_of))


def padded_length(length: int) -> int:
    """``length`` rounded up to one of 8 steps per octave (at most 12.5 % padding).

    Records of nearby lengths (the training folds of a cross-validation, test blocks)
    then share one array shape, so the jitted cost is compiled once for all of them.
    """
    if length <= 16:
        return length
    granularity = 2 ** (int(np.log2(length)) - 3)
    return int(-(-length // granularity) * granularity)


def pad_rows(values: np.ndarray, length: int) -> np.ndarray:
    """Pad along the first axis with the last row (keeps padded inputs physical)."""
    extra = length - values.shape[0]
    if extra == 0:
        return values
    return np.concatenate([values, np.repeat(values[-1:], extra, axis=0)])
