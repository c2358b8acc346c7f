"""Choosing on one recorded sequence: contiguous cross-validation folds and the held-out
simulation error as a score."""

from ._scoring import held_out_rmse
from ._split import SequenceSplit, SequenceWarning

__all__ = ["SequenceSplit", "SequenceWarning", "held_out_rmse"]
