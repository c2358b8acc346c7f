"""Opt-in persistent compilation cache: compiled programs kept on disk across processes.

Most of a first closed loop is XLA compilation (the main job on the Cascaded Tanks: about
95 of 230 s). With the cache on, a later process (the next run, a joblib or Dask worker,
a test worker) loads those programs instead of compiling them again. The package never
switches it on by itself: it changes JAX's global configuration, which is the
application's to decide (the examples switch it on; ``--no-cache`` keeps them off it).
"""

from __future__ import annotations

import gc
import os
import sys
from pathlib import Path

import jax

__all__ = [
    "DEFAULT_CACHE",
    "enable_compilation_cache",
    "release_compiled_programs",
    "release_package_programs",
]

_ROOT = __package__.partition(".")[0]  # the package whose programs are released

DEFAULT_CACHE = Path("~/.cache/sk_offwhite/xla")
"""Where [`enable_compilation_cache`][sk_offwhite.enable_compilation_cache] keeps programs unless
told otherwise (or ``$SK_OFFWHITE_CACHE``)."""


def enable_compilation_cache(directory: str | os.PathLike | None = None) -> Path:
    """Keep every compiled program in ``directory`` and load it from there when the same
    program is compiled again, in this process or a later one.

    Sets JAX's ``jax_compilation_cache_dir`` and caches programs however short their
    compilation (JAX's default keeps only those over 1 s, and the solver's programs take
    0.1-0.7 s each), in this process and, through the environment, in the processes it
    starts afterwards (joblib and Dask workers, ``GridSearchCV(n_jobs=...)``).

    Parameters
    ----------
    directory : path-like, optional
        Default ``$SK_OFFWHITE_CACHE``, else the directory JAX is already configured with
        (``$JAX_COMPILATION_CACHE_DIR``), else `DEFAULT_CACHE`; created if missing.

    Returns
    -------
    Path
        The cache directory in use.
    """
    configured = jax.config.jax_compilation_cache_dir
    chosen = directory or os.environ.get("SK_OFFWHITE_CACHE") or configured or DEFAULT_CACHE
    path = Path(chosen).expanduser().resolve()
    path.mkdir(parents=True, exist_ok=True)
    settings = {
        "jax_compilation_cache_dir": str(path),
        "jax_persistent_cache_min_compile_time_secs": 0.0,
        "jax_persistent_cache_min_entry_size_bytes": 0,
    }
    for name, value in settings.items():
        jax.config.update(name, value)
        os.environ[name.upper()] = str(value)  # inherited by joblib and Dask workers
    return path


def release_compiled_programs() -> None:
    """Drop every program compiled in this process (JAX's and the package's caches).

    Programs are compiled per model structure: every fit of a *new* physics object (a new
    step function) compiles its own, and JAX keeps them for the life of the process, so a
    study that builds thousands of physics grows in memory with each. Call this between
    such fits to return that memory; refitting the same physics afterwards compiles again,
    or loads from disk with [`enable_compilation_cache`][sk_offwhite.enable_compilation_cache]. Fits
    of the same physics reuse their programs and need no release.
    """
    from ..dictionaries._compile import release_compiled_libraries

    release_compiled_libraries()
    jax.clear_caches()


def release_package_programs() -> int:
    """Drop the programs compiled for this package's own jitted functions (the solver's,
    the simulation's), and only those: the application's jitted functions and JAX's other
    caches keep theirs.

    The closed loop fits many model structures, each once or twice in a row, and the
    programs of all of them would otherwise stay in memory until the process ends. It
    calls this between its stages (``LoopSettings(release_programs=True)``); a structure
    fitted again afterwards is traced again and compiled again, or loaded from disk with
    [`enable_compilation_cache`][sk_offwhite.enable_compilation_cache].

    Returns
    -------
    int
        How many jitted functions had their programs dropped.
    """
    cleared = {}
    for name, module in list(sys.modules.items()):
        if name.partition(".")[0] != _ROOT or module is None:
            continue
        for value in vars(module).values():
            if callable(getattr(value, "clear_cache", None)) and hasattr(value, "lower"):
                cleared[id(value)] = value
    for function in cleared.values():
        function.clear_cache()
    # the programs are freed with the last reference to them; a full collection freed no
    # more than the young generations' (60 structures fitted and released: 499 against
    # 500 MiB) and took 0.1-0.2 s a call
    gc.collect(1)
    return len(cleared)
