"""Cutting records into padded, masked shooting segments."""

import numpy as np
import pytest

from sk_offwhite.simulation._segments import make_segments, padded_length, split_at_gaps


def _record(n, offset=0.0):
    return np.arange(n, dtype=float)[:, None] + offset, np.arange(n, dtype=float)[:, None]


def test_mask_counts_only_measured_samples_of_unequal_records():
    segments = make_segments([_record(40), _record(25)], None)
    np.testing.assert_array_equal(segments.mask.sum(axis=1), [40, 25])
    assert segments.u.shape[1] == padded_length(40)
    np.testing.assert_array_equal(segments.linked, [0, 0])


def test_windows_are_linked_within_a_record_only():
    segments = make_segments([_record(50), _record(30)], horizon=20)
    np.testing.assert_array_equal(segments.record, [0, 0, 0, 1, 1])
    np.testing.assert_array_equal(segments.linked, [0, 1, 1, 0, 1])
    np.testing.assert_array_equal(segments.mask.sum(axis=1), [20, 20, 10, 20, 10])
    np.testing.assert_array_equal(segments.u[1, :, 0][:20], np.arange(20, 40))


@pytest.mark.parametrize("length", [1, 16, 17, 100, 267, 1000, 1025, 100_000])
def test_padded_length_adds_at_most_an_eighth(length):
    padded = padded_length(length)
    assert length <= padded <= max(length * 1.125, length)


def test_split_at_gaps_cuts_where_the_index_jumps():
    u, z = _record(10)
    index = np.r_[0:3, 5:9, 20:23]
    pieces = split_at_gaps(u, z, index)
    assert [p[0].shape[0] for p in pieces] == [3, 4, 3]
    with pytest.raises(ValueError, match="sample_index"):
        split_at_gaps(u, z, index[:-1])
