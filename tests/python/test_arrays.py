"""Array arguments of the Python module: float64, int64 and lists are converted (to float32 and
uint32); a wrong dtype, shape or value is an InputError naming the argument and the dtype and shape
expected; empty arrays give a clear error (eval) or a documented result (write_strands: a file of
no strands). Runs in well under a second, without Blender."""

from __future__ import annotations

import numpy as np
import pytest

hairrecon = pytest.importorskip("hairrecon")

PTS = np.array([[0, 0, 0], [0, 0, 0.01], [0, 0, 0.02], [0.01, 0, 0], [0.01, 0, 0.01]], np.float32)
COUNTS = np.array([3, 2], np.uint32)


@pytest.mark.parametrize(
    "points, counts",
    [
        (PTS.astype(np.float64), COUNTS.astype(np.int64)),
        (PTS.tolist(), COUNTS.tolist()),
        (PTS.astype(np.float16).astype(np.float64), COUNTS.astype(np.int32)),
        (np.asfortranarray(PTS), COUNTS.astype(np.uint64)),
    ],
    ids=["float64-int64", "lists", "float64-int32", "fortran-uint64"],
)
def test_other_dtypes_and_lists_are_converted(tmp_path, points, counts):
    hairrecon.write_strands(str(tmp_path / "a.hair"), points, counts)
    p, c = hairrecon.read_strands(str(tmp_path / "a.hair"))
    assert p.dtype == np.float32 and c.dtype == np.uint32
    assert np.array_equal(p, np.asarray(points, np.float32)) and c.tolist() == [3, 2]
    ref = hairrecon.eval(PTS, COUNTS, PTS, COUNTS)
    assert hairrecon.eval(points, counts, points, counts) == ref
    assert ref["directed"][0]["f1"] == pytest.approx(100.0)


def test_meshes_take_other_dtypes_too(tmp_path):
    v = np.eye(3).tolist()  # float64 lists
    hairrecon.write_mesh(str(tmp_path / "m.ply"), v, np.array([[0, 1, 2]], np.int64), uvs=np.zeros((3, 2)))
    m = hairrecon.read_mesh(str(tmp_path / "m.ply"))
    assert m["vertices"].dtype == np.float32 and np.array_equal(m["vertices"], np.eye(3, dtype=np.float32))
    assert m["triangles"].tolist() == [[0, 1, 2]]


@pytest.mark.parametrize(
    "args, words",
    [
        ((PTS[:, :2], COUNTS), ["points", "float32", "(N, 3)", "float32 of shape (5, 2)"]),
        ((PTS, COUNTS.astype(np.float64)), ["counts", "uint32", "(S,)", "float64 of shape (2,)"]),
        ((PTS, COUNTS.reshape(2, 1)), ["counts", "(S,)", "shape (2, 1)"]),
        ((PTS.astype(str), COUNTS), ["points", "float32", "str"]),
        ((PTS.astype(bool), COUNTS), ["points", "float32", "bool"]),
        ((PTS, np.array([3, -2])), ["counts", "-2", "uint32"]),
        ((PTS, np.array([3, 2**32 + 2], np.uint64)), ["counts", "4294967298", "uint32"]),
        ((np.full((5, 3), 1e39), COUNTS), ["points", "1e39", "finite float32"]),
        ((np.where(PTS > 0.015, np.nan, PTS), COUNTS), ["points", "NaN at flat index 8", "finite float32"]),
        (([[0, 0], [1]], COUNTS), ["points", "float32", "(N, 3)"]),
        ((PTS, [3]), ["points and counts", "add up to 3", "5 points"]),
    ],
    ids=["points-shape", "counts-float", "counts-2d", "points-str", "points-bool", "negative", "too-big",
         "overflow", "nan", "ragged", "mismatch"],
)
def test_a_bad_array_names_the_argument_and_what_it_expected(tmp_path, args, words):
    with pytest.raises(hairrecon.InputError) as e:
        hairrecon.write_strands(str(tmp_path / "a.hair"), *args)
    assert all(w in str(e.value) for w in words), str(e.value)
    assert list(tmp_path.iterdir()) == []


def test_eval_names_its_arguments_and_refuses_empty_sets():
    with pytest.raises(hairrecon.InputError, match=r"gt_points must be a float32 array .* \(N, 3\)"):
        hairrecon.eval(PTS, COUNTS, PTS[:, :2], COUNTS)
    with pytest.raises(hairrecon.InputError, match="pred_counts must be a uint32 array"):
        hairrecon.eval(PTS, COUNTS.astype(np.float32), PTS, COUNTS)
    empty = (np.zeros((0, 3), np.float32), np.zeros(0, np.uint32))
    with pytest.raises(hairrecon.InputError, match="pred_counts is empty: there are no predicted strands"):
        hairrecon.eval(*empty, PTS, COUNTS)
    with pytest.raises(hairrecon.InputError, match="gt_counts is empty: there are no ground-truth strands"):
        hairrecon.eval(PTS, COUNTS, [], [])


def test_empty_strands_write_a_file_of_no_strands(tmp_path):
    hairrecon.write_strands(str(tmp_path / "e.hair"), [], [])
    p, c = hairrecon.read_strands(str(tmp_path / "e.hair"))
    assert p.shape == (0, 3) and c.shape == (0,)
