"""How programs are compiled and run: fused simulation loops on CPU, the persistent
compilation cache and its release, worker processes whose warnings reach the caller."""

from ._backend import enable_fused_loops
from ._cache import enable_compilation_cache, release_compiled_programs, release_package_programs

__all__ = [
    "enable_compilation_cache",
    "enable_fused_loops",
    "release_compiled_programs",
    "release_package_programs",
]
