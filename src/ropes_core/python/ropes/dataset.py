"""Datasets of the ropes container (ropes_core/dataset.hpp) as numpy arrays.

A dataset directory holds named columns, one .npy file per column per shard, and a
manifest.json that records every file's size and SHA-256. ``Dataset`` opens one (the manifest
and every file's header are checked; the data is read when asked for); ``write`` makes one
from numpy arrays, so that images of your own can go through ropes-train and ropes-eval.

    >>> d = ropes.dataset.Dataset("runs/1c-tiny/train-data")
    >>> d.columns["images"]          # Column(dtype='uint8', row_shape=(1, 64, 64))
    >>> images = d.read("images", 0, 100)       # [100, 1, 64, 64] uint8, one copy
    >>> view = d.shard("angles", 0)             # memory-mapped, read-only, no copy
    >>> d.regime("observational")               # the rows of a regime, by name
"""
import collections
import json
import operator
import os

import numpy as np

from . import _core

Column = collections.namedtuple("Column", ["dtype", "row_shape"])


class Dataset:
    """A complete dataset, opened for reading. Raises ropes.FileFormatError naming the file
    and the field when the directory holds no complete dataset or a file disagrees with the
    manifest."""

    def __init__(self, path):
        self._reader = _core.Reader.open(os.fspath(path))
        self._metadata = None

    @property
    def path(self):
        return self._reader.dir

    @property
    def rows(self):
        """Rows of every column, over all shards."""
        return self._reader.rows

    def __len__(self):
        return self._reader.rows

    @property
    def shard_count(self):
        return self._reader.shard_count

    def shard_rows(self, shard):
        return self._reader.shard_rows(shard)

    @property
    def columns(self):
        """{name: Column(dtype, row_shape)}, in the manifest's order."""
        return {c["name"]: Column(c["dtype"], tuple(c["row_shape"]))
                for c in self._reader.columns}

    @property
    def metadata(self):
        """The manifest's metadata object, as a dict (the writer's; for a generated
        dataset: the config, the distribution, joint_names, regime_names, regimes, ...)."""
        if self._metadata is None:
            self._metadata = self._reader.metadata
        return self._metadata

    def read(self, column, first=0, count=None):
        """Rows [first, first + count) of `column` (all rows from `first` when count is
        None) as a new array [count, row_shape...]; the range may span shards. IndexError for
        an unknown column or a range outside the dataset."""
        if count is None:
            count = self.rows - first
        return self._reader.read(column, first, count)

    def column(self, column):
        """Every row of `column`, as one new array."""
        return self.read(column, 0, self.rows)

    def take(self, column, rows):
        """The rows `rows` (any order, repeats allowed) of `column`, in that order."""
        idx = np.asarray(rows)
        if idx.ndim != 1 or (idx.dtype.kind not in "iu" and idx.size > 0):
            raise _shape_error(f"rows: expected a 1-d array of integer row indices, got a "
                               f"{idx.dtype} array of shape {list(idx.shape)} (a boolean mask: "
                               "np.flatnonzero(mask))")
        return self._reader.read_at(column, np.ascontiguousarray(idx, dtype=np.int64))

    def shard(self, column, shard):
        """Shard `shard`'s rows of `column` as a read-only array memory-mapped from its file:
        no copy, the pages are read when touched. It stays valid after the Dataset is gone."""
        return self._reader.map_shard(column, shard)

    @property
    def regime_names(self):
        """The regimes of a generated dataset ("observational", "do(<joint>)=1", ...), in
        index order."""
        names = self.metadata.get("regime_names")
        if names is None:
            raise KeyError(f"{self.path}: the metadata has no regime_names (not a dataset "
                           "ropes-generate made)")
        return list(names)

    def regime(self, name):
        """The row indices of the regime called `name`, ascending. KeyError naming the
        regimes when there is none of that name."""
        names = self.regime_names
        if name not in names:
            raise KeyError(f"{self.path}: no regime '{name}'; it has {', '.join(names)}")
        return np.flatnonzero(self.column("regime") == names.index(name)).astype(np.int64)

    def verify(self):
        """Recomputes every file's SHA-256 and compares it with the manifest (reads every
        byte once); ropes.FileFormatError naming the file on a mismatch."""
        self._reader.verify()

    def __repr__(self):
        return f"Dataset({self.path!r}, rows={self.rows}, columns={list(self.columns)})"


def write(path, columns, metadata=None, rows_per_shard=None, dataset_id=""):
    """Writes the dataset `columns` ({name: array}, every array with the same number of rows
    in its first dimension, dtype uint8, int32, int64, float32 or float64) into the new or
    empty directory `path`, in shards of `rows_per_shard` rows (all in one when None), with
    the JSON-serialisable dict `metadata`, and returns it opened.

    Every argument is checked before anything is written (ValueError, or ropes.ShapeError
    for an array, naming the column and what was expected); a directory that holds anything
    is refused, so that nothing is overwritten. The manifest is written last: a write that
    fails part-way leaves a directory that Dataset refuses, never a dataset with rows missing.
    For ropes-train, a dataset needs the columns and metadata ropes-generate writes
    (images, angles, regime, anchor; see ropes_sim's README)."""
    path = os.fspath(path)
    if not isinstance(columns, dict) or not columns:
        raise ValueError(f"write {path}: columns must be a non-empty dict of name -> array")
    arrays = {}
    rows = None
    for name, value in columns.items():
        if not isinstance(name, str):
            raise ValueError(f"write {path}: column name {name!r} is not a str")
        a = np.ascontiguousarray(value)
        if a.ndim < 1 or a.shape[0] == 0:
            raise _shape_error(f"column '{name}': expected an array with at least one row, got "
                               f"a {a.dtype} array of shape {list(a.shape)}")
        if rows is None:
            rows = a.shape[0]
        elif a.shape[0] != rows:
            raise _shape_error(f"column '{name}': {a.shape[0]} rows; the first column has "
                               f"{rows}")
        arrays[name] = a
    if rows_per_shard is None:
        rows_per_shard = rows
    try:
        ok = not isinstance(rows_per_shard, bool) and operator.index(rows_per_shard) >= 1
    except TypeError:
        ok = False
    if not ok:
        raise ValueError(f"write {path}: rows_per_shard is {rows_per_shard!r}; expected an "
                         "int >= 1")
    rows_per_shard = operator.index(rows_per_shard)
    if metadata is None:
        metadata = {}
    if not isinstance(metadata, dict):
        raise ValueError(f"write {path}: metadata is a {type(metadata).__name__}; expected a "
                         "dict")
    if os.path.lexists(path):
        if not os.path.isdir(path) or os.listdir(path):
            raise ValueError(f"write {path}: the path exists and is not an empty directory; "
                             "a dataset is written only into a new or empty one")
    names = list(arrays)
    try:
        json.dumps(metadata, allow_nan=False)
    except (TypeError, ValueError) as e:
        raise ValueError(f"write {path}: metadata is not JSON: {e}") from None
    for name, a in arrays.items():
        if a.dtype.str not in ("|u1", "<i4", "<i8", "<f4", "<f8"):
            raise _shape_error(f"column '{name}': dtype {a.dtype} ('{a.dtype.str}') is not one "
                               "a dataset stores; expected uint8, int32, int64, float32 or "
                               "float64, little-endian")
    shards = (rows + rows_per_shard - 1) // rows_per_shard
    for shard in range(shards):
        lo, hi = shard * rows_per_shard, min(rows, (shard + 1) * rows_per_shard)
        _core.write_shard(path, shard, names, [arrays[n][lo:hi] for n in names], dataset_id)
    specs = [{"name": n, "dtype": str(arrays[n].dtype), "row_shape": list(arrays[n].shape[1:])}
             for n in names]
    _core.write_manifest(path, specs, shards, metadata, dataset_id)
    return Dataset(path)


def shuffled_indices(n, seed, epoch):
    """The permutation of range(n) that epoch `epoch` of seed `seed` visits (as ropes-train
    and ropes-eval draw it: ropes_core/dataset.hpp)."""
    return _core.shuffled_indices(n, seed, epoch)


def _shape_error(message):
    from .errors import ShapeError
    return ShapeError(message)
