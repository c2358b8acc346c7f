"""Byte-plane packing of the measured records shipped with the package.

A record is stored in a `.npz` file as the planes of its bytes: plane `b` holds byte `b` of
every sample (little-endian), so the slowly varying high bytes of neighbouring samples sit
next to each other and deflate well. The packing is exact: `unpack_array(*pack_array(a))`
returns `a` bit for bit. Each packed array `name` is stored as `name` (the planes, `uint8` of
shape `(itemsize, n_samples)`) and `name__dtype` (its dtype as a string such as `"<f8"`);
other entries (scalars such as a gain or a quantisation step) are stored as they are.
"""

from __future__ import annotations

import hashlib
import zipfile
from collections.abc import Mapping
from importlib import resources

import numpy as np

__all__ = [
    "DTYPE_SUFFIX",
    "file_sha256",
    "pack_array",
    "read_packed",
    "unpack_array",
    "write_packed",
]

DTYPE_SUFFIX = "__dtype"
"""Suffix of the entry that holds a packed array's dtype."""

FIXED_DATE = (1980, 1, 1, 0, 0, 0)
"""Date written on every zip member (the earliest a zip file can hold)."""


def pack_array(values: np.ndarray) -> tuple[np.ndarray, str]:
    """Byte planes `(itemsize, n)` of a 1-D array and its little-endian dtype string."""
    values = np.asarray(values)
    if values.ndim != 1:
        raise ValueError(f"values must be one-dimensional, got shape {values.shape}.")
    little = values.astype(values.dtype.newbyteorder("<"), copy=False)
    planes = little.view(np.uint8).reshape(-1, little.dtype.itemsize).T
    return np.ascontiguousarray(planes), little.dtype.str


def unpack_array(planes: np.ndarray, dtype: str) -> np.ndarray:
    """The 1-D array whose byte planes are `planes` (the inverse of `pack_array`)."""
    samples = np.ascontiguousarray(np.asarray(planes, dtype=np.uint8).T)
    return samples.view(np.dtype(dtype)).reshape(-1)


def write_packed(path, arrays: Mapping[str, np.ndarray], scalars: Mapping[str, float]) -> None:
    """Write `arrays` byte-plane packed and `scalars` as float64 to a compressed `.npz`.

    The zip members carry a fixed date, so the same arrays always give the same file (and
    checksum); `numpy.load` reads it like any `.npz`.
    """
    entries = {}
    for name, values in arrays.items():
        entries[name], entries[name + DTYPE_SUFFIX] = pack_array(values)
    entries.update({name: np.float64(value) for name, value in scalars.items()})
    with zipfile.ZipFile(path, "w") as archive:
        for name, value in entries.items():
            _write_member(archive, name, np.asarray(value))


def _write_member(archive: zipfile.ZipFile, name: str, value: np.ndarray) -> None:
    member = zipfile.ZipInfo(name + ".npy", date_time=FIXED_DATE)
    member.compress_type = zipfile.ZIP_DEFLATED
    with archive.open(member, "w") as stream:
        np.lib.format.write_array(stream, value, allow_pickle=False)


def _decoded(entries) -> dict[str, np.ndarray]:
    names = [name for name in entries.files if not name.endswith(DTYPE_SUFFIX)]
    return {
        name: unpack_array(entries[name], str(entries[name + DTYPE_SUFFIX]))
        if name + DTYPE_SUFFIX in entries.files
        else entries[name]
        for name in names
    }


def read_packed(filename: str) -> dict[str, np.ndarray]:
    """Every entry of the package data file `data/<filename>`, packed arrays unpacked."""
    with resources.as_file(_data_file(filename)) as path, np.load(path) as entries:
        return _decoded(entries)


def file_sha256(filename: str) -> str:
    """SHA-256 hex digest of the package data file `data/<filename>`."""
    return hashlib.sha256(_data_file(filename).read_bytes()).hexdigest()


def _data_file(filename: str):
    return resources.files(__package__).joinpath("data", filename)
