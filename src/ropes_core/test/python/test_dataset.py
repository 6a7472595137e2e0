"""ropes.dataset: the dataset container from Python (ropes._core). Witness: numpy, which
reads every shard file we write and whose np.save gives the same bytes."""
import hashlib
import json
import os

import numpy as np
import pytest

import ropes
from ropes import dataset


def _columns(rows=10):
    rng = np.random.default_rng(0)
    return {
        "images": rng.integers(0, 256, size=(rows, 2, 8, 8), dtype=np.uint8),
        "angles": rng.standard_normal((rows, 3)).astype(np.float32),
        "regime": (np.arange(rows) % 3).astype(np.int32),
        "anchor": np.arange(rows, dtype=np.int64) // 3,
    }


def test_write_then_read_round_trips_every_column(tmp_path):
    cols = _columns()
    d = dataset.write(tmp_path / "d", cols, metadata={"regime_names": ["obs", "a", "b"]},
                      rows_per_shard=4)
    assert len(d) == 10 and d.shard_count == 3
    assert [d.shard_rows(s) for s in range(3)] == [4, 4, 2]
    assert d.columns["images"] == dataset.Column("uint8", (2, 8, 8))
    assert list(d.columns) == ["images", "angles", "regime", "anchor"]
    for name, a in cols.items():
        np.testing.assert_array_equal(d.column(name), a)
        np.testing.assert_array_equal(d.read(name, 3, 5), a[3:8])  # spans two shards
        np.testing.assert_array_equal(d.take(name, [9, 0, 0, 5]), a[[9, 0, 0, 5]])
        assert d.column(name).dtype == a.dtype
    assert d.metadata == {"regime_names": ["obs", "a", "b"]}
    np.testing.assert_array_equal(d.regime("a"), [1, 4, 7])
    d.verify()


def test_shard_files_are_numpys_own_bytes(tmp_path):
    cols = _columns()
    dataset.write(tmp_path / "d", cols, rows_per_shard=4)
    manifest = json.loads((tmp_path / "d" / "manifest.json").read_text())
    for shard, (lo, hi) in enumerate([(0, 4), (4, 8), (8, 10)]):
        for name, a in cols.items():
            entry = manifest["shards"][shard]["files"][name]
            raw = (tmp_path / "d" / entry["path"]).read_bytes()
            np.save(tmp_path / "witness.npy", a[lo:hi])
            assert raw == (tmp_path / "witness.npy").read_bytes()
            assert hashlib.sha256(raw).hexdigest() == entry["sha256"]


def test_a_shard_is_memory_mapped_not_copied(tmp_path):
    cols = _columns()
    d = dataset.write(tmp_path / "d", cols, rows_per_shard=4)
    view = d.shard("images", 1)
    np.testing.assert_array_equal(view, cols["images"][4:8])
    assert not view.flags.writeable
    with pytest.raises(ValueError):
        view[0, 0, 0, 0] = 1
    # the array's first byte lies in a mapping of the shard file: no copy was made
    address = view.__array_interface__["data"][0]
    shard_file = os.path.realpath(tmp_path / "d" / "shards" / "images-00001.npy")
    mapped = False
    with open("/proc/self/maps") as maps:
        for line in maps:
            fields = line.split()
            lo, hi = (int(x, 16) for x in fields[0].split("-"))
            if lo <= address < hi and len(fields) >= 6 and fields[5] == shard_file:
                mapped = True
    assert mapped, f"{address:#x} is not in a mapping of {shard_file}"
    del d  # the view keeps its mapping
    np.testing.assert_array_equal(view, cols["images"][4:8])


def test_a_missing_or_incomplete_dataset_is_a_file_format_error(tmp_path):
    with pytest.raises(ropes.FileFormatError, match="holds no complete dataset"):
        dataset.Dataset(tmp_path / "nothing")
    d = dataset.write(tmp_path / "d", _columns())
    (tmp_path / "d" / "shards" / "angles-00000.npy").write_bytes(b"\x93NUMPY")
    with pytest.raises(ropes.FileFormatError, match="angles-00000.npy"):
        dataset.Dataset(tmp_path / "d")
    assert isinstance(ropes.FileFormatError("x"), ValueError)
    del d


def test_bad_arrays_and_names_are_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "d"
    bad = _columns()
    bad["angles"] = bad["angles"].astype(np.float16)
    with pytest.raises(ropes.ShapeError, match=r"column 'angles': dtype float16 .* expected "
                                               r"uint8, int32, int64, float32 or float64"):
        dataset.write(out, bad)
    short = _columns()
    short["regime"] = short["regime"][:9]
    with pytest.raises(ropes.ShapeError, match="column 'regime': 9 rows; the first column has 10"):
        dataset.write(out, short)
    with pytest.raises(ValueError, match="'../x'"):
        dataset.write(out, {"../x": np.zeros(3, np.float32)})
    with pytest.raises(ValueError, match="metadata is not JSON"):
        dataset.write(out, _columns(), metadata={"x": object()})
    with pytest.raises(ValueError, match="rows_per_shard is 0"):
        dataset.write(out, _columns(), rows_per_shard=0)
    assert not out.exists() or not any(out.iterdir())
    # a directory that holds something is never written into
    out.mkdir(exist_ok=True)
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="not an empty directory"):
        dataset.write(out, _columns())
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]


def test_unknown_columns_and_rows_name_what_exists(tmp_path):
    d = dataset.write(tmp_path / "d", _columns())
    with pytest.raises(IndexError, match="no column 'pixels'.*images"):
        d.read("pixels")
    with pytest.raises(IndexError, match="outside the dataset's 10 rows"):
        d.read("angles", 8, 5)
    with pytest.raises(ropes.ShapeError, match=r"rows: expected a int64 array of shape \[n\]"):
        d._reader.read_at("angles", np.zeros((2, 2), np.int64))
    with pytest.raises(KeyError, match="no regime 'c'; it has obs, a, b"):
        dataset.write(tmp_path / "e", _columns(),
                      metadata={"regime_names": ["obs", "a", "b"]}).regime("c")


def test_shuffled_indices_is_a_seeded_permutation():
    a = dataset.shuffled_indices(1000, 7, 0)
    assert sorted(a.tolist()) == list(range(1000))
    np.testing.assert_array_equal(a, dataset.shuffled_indices(1000, 7, 0))
    assert not np.array_equal(a, dataset.shuffled_indices(1000, 7, 1))


def test_row_indices_are_integers_and_counts_may_be_numpy_integers(tmp_path):
    d = dataset.write(tmp_path / "d", _columns(), rows_per_shard=np.int64(4))
    assert d.shard_count == 3
    with pytest.raises(ropes.ShapeError, match="a boolean mask: np.flatnonzero"):
        d.take("angles", np.ones(10, bool))
    with pytest.raises(ropes.ShapeError, match="got a float64 array"):
        d.take("angles", [0.5, 1.5])
    with pytest.raises(ropes.ShapeError, match=r"of shape \[2, 1\]"):
        d.take("angles", [[0], [1]])
    assert d.take("angles", []).shape == (0, 3)
