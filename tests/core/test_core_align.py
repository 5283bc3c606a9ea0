"""C timestamp alignment (robocli.core) against the pure-Python reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.core import align_linear, align_nearest
from tests import reference

TS = np.array([0.0, 1.0, 2.0, 2.0, 3.0, 5.0])
REF = np.array([-1.0, -0.2, 0.5, 1.4, 1.6, 2.0, 2.5, 4.0, 5.0, 5.2, 7.0])


def test_nearest_known_answers() -> None:
    got = align_nearest(TS, REF, 0.5)
    assert got.dtype == np.int64 and got.shape == (11,)
    assert got.tolist() == [-1, 0, 0, 1, 2, 2, 2, -1, 5, 5, -1]
    assert align_nearest(TS, REF, -1.0).tolist() == [-1] * 11
    assert align_nearest(TS, REF, np.inf).tolist() == [0, 0, 0, 1, 2, 2, 2, 4, 5, 5, 5]


def test_linear_known_answers() -> None:
    idx, w = align_linear(TS, REF)
    assert idx.dtype == np.int64 and w.dtype == np.float64
    assert idx.tolist() == [-1, -1, 0, 1, 1, 3, 3, 4, 4, -1, -1]
    np.testing.assert_allclose(w, [0, 0, 0.5, 0.4, 0.6, 0, 0.5, 0.5, 1.0, 0, 0], atol=1e-12)
    idx, w = align_linear(np.array([1.0]), np.array([0.0, 1.0, 2.0]))
    assert idx.tolist() == [-1, 0, -1] and w.tolist() == [0.0, 0.0, 0.0]


def test_shapes() -> None:
    streams = [TS, TS[:3], np.zeros(0)]
    got = align_nearest(streams, REF, 0.5)
    assert got.shape == (3, 11)
    assert got[0].tolist() == align_nearest(TS, REF, 0.5).tolist()
    assert got[2].tolist() == [-1] * 11
    assert align_nearest(np.vstack([TS, TS]), REF, 0.5).shape == (2, 11)
    idx, w = align_linear(streams, REF)
    assert idx.shape == w.shape == (3, 11)
    assert align_nearest([], REF, 1.0).shape == (0, 11)
    assert align_nearest(TS, np.zeros(0), 1.0).shape == (0,)
    with pytest.raises(ValueError):
        align_nearest(np.zeros((2, 2, 2)), REF, 1.0)
    with pytest.raises(ValueError):
        align_linear(TS, np.zeros((2, 2)))


def test_linear_reconstructs_interp() -> None:
    rng = np.random.default_rng(1)
    ts = np.cumsum(rng.uniform(0.01, 1.0, 200))
    x = rng.normal(size=200)
    ref = np.sort(rng.uniform(ts[0], ts[-1], 500))
    idx, w = align_linear(ts, ref)
    assert (idx >= 0).all()
    np.testing.assert_allclose((1 - w) * x[idx] + w * x[idx + 1], np.interp(ref, ts, x))


# Times on a coarse grid so that duplicates and exact ties are common.
times = st.lists(st.integers(-20, 20), max_size=30).map(lambda v: sorted(x / 4 for x in v))


@settings(max_examples=300, deadline=None)
@given(ts=times, ref=times, tol=st.sampled_from([-0.25, 0.0, 0.25, 0.5, 0.3, 10.0]))
def test_nearest_matches_reference(ts: list[float], ref: list[float], tol: float) -> None:
    got = align_nearest(np.array(ts), np.array(ref), tol)
    assert got.tolist() == reference.align_nearest(ts, ref, tol)


@settings(max_examples=300, deadline=None)
@given(ts=times, ref=times)
def test_linear_matches_reference(ts: list[float], ref: list[float]) -> None:
    idx, w = align_linear(np.array(ts), np.array(ref))
    ridx, rw = reference.align_linear(ts, ref)
    assert idx.tolist() == ridx
    assert w.tolist() == rw


@settings(max_examples=100, deadline=None)
@given(
    ts=st.lists(st.floats(-1e3, 1e3), max_size=40).map(sorted),
    ref=st.lists(st.floats(-1e3, 1e3), max_size=40).map(sorted),
    tol=st.floats(0, 100),
)
def test_random_floats_match_reference(ts: list[float], ref: list[float], tol: float) -> None:
    assert align_nearest(np.array(ts), np.array(ref), tol).tolist() == reference.align_nearest(
        ts, ref, tol
    )
    idx, w = align_linear([np.array(ts)], np.array(ref))
    ridx, rw = reference.align_linear(ts, ref)
    assert idx[0].tolist() == ridx and w[0].tolist() == rw
