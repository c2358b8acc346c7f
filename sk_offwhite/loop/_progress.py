"""Progress of long runs: each stage logged as it starts and ends, and its wall time kept.

Messages go to the ``logging`` logger ``"sk_offwhite.loop"`` at level ``INFO`` (silent
unless the application configures logging, for example
``logging.basicConfig(level=logging.INFO)``; switch them off with
``logging.getLogger("sk_offwhite.loop").setLevel(logging.WARNING)``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["StageClock", "logger"]

logger = logging.getLogger("sk_offwhite.loop")


class StageClock:
    """Wall time of each named stage (seconds, summed when a stage repeats)."""

    def __init__(self):
        self.seconds: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Log ``name`` as it starts and ends, and add its wall time to `seconds`."""
        logger.info("%s ...", name)
        start = time.perf_counter()
        try:
            yield
        finally:
            elapsed = time.perf_counter() - start
            self.seconds[name] = self.seconds.get(name, 0.0) + elapsed
            logger.info("%s: %.1f s", name, elapsed)
