"""C ring buffer (robocli.core.Ring) against the pure-Python reference."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.core import Ring
from tests import reference


def _rec(i: int, size: int) -> bytes:
    return bytes((i + k) & 0xFF for k in range(size))


def test_known_answers() -> None:
    r = Ring(4, 8)
    assert (r.record_size, r.capacity, r.pushed) == (4, 8, 0)
    a = r.add_reader()
    b = r.add_reader(limit=3)
    for i in range(5):
        r.push(float(i), _rec(i, 4))
    assert r.pushed == 5
    assert (r.available(a), r.lost(a)) == (5, 0)
    assert (r.available(b), r.lost(b)) == (3, 2)
    t, rec = r.read(b)
    assert t.dtype == np.float64 and rec.dtype == np.uint8
    assert t.tolist() == [2.0, 3.0, 4.0]
    assert rec.shape == (3, 4) and bytes(rec[0]) == _rec(2, 4)
    t, rec = r.read(a, 2)
    assert t.tolist() == [0.0, 1.0]
    r.push_many(np.arange(5, 15, dtype=np.float64), b"".join(_rec(i, 4) for i in range(5, 15)))
    assert (r.available(a), r.lost(a)) == (8, 5)
    t, rec = r.read(a)
    assert t.tolist() == [float(i) for i in range(7, 15)]
    assert [bytes(x) for x in rec] == [_rec(i, 4) for i in range(7, 15)]
    t, rec = r.read(a)
    assert t.shape == (0,) and rec.shape == (0, 4)
    r.remove_reader(b)
    assert r.add_reader(2) == b


def test_push_numpy_records_and_structured() -> None:
    r = Ring(12, 16)
    a = r.add_reader()
    r.push(1.5, np.arange(3, dtype=np.int32))
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<i4")])
    recs = np.zeros(3, dtype=dt)
    recs["z"] = [7, 8, 9]
    r.push_many([2.0, 3.0, 4.0], recs)
    r.push_many(np.zeros(0), np.zeros((0, 12), dtype=np.uint8))
    t, rec = r.read(a)
    assert t.tolist() == [1.5, 2.0, 3.0, 4.0]
    assert rec[0].view(np.int32).tolist() == [0, 1, 2]
    assert rec[1:].copy().view(dt)["z"].ravel().tolist() == [7, 8, 9]


def test_errors() -> None:
    with pytest.raises(ValueError):
        Ring(0, 4)
    with pytest.raises(ValueError):
        Ring(4, -1)
    r = Ring(4, 4)
    with pytest.raises(ValueError):
        r.push(0.0, b"abc")
    with pytest.raises(ValueError):
        r.push_many([0.0, 1.0], b"abcd")
    with pytest.raises(ValueError):
        r.push_many(np.zeros((2, 2)), bytes(16))
    with pytest.raises(ValueError):
        r.add_reader(0)
    with pytest.raises(ValueError):
        r.available(3)
    with pytest.raises(ValueError):
        r.read(0)
    a = r.add_reader()
    r.remove_reader(a)
    with pytest.raises(ValueError):
        r.lost(a)
    with pytest.raises(ValueError):
        r.remove_reader(a)


def test_concurrent_push_and_read() -> None:
    r = Ring(8, 1 << 16)
    a = r.add_reader()
    n = 20_000
    got: list[np.ndarray] = []

    def reader() -> None:
        total = 0
        while total < n:
            t, _ = r.read(a)
            got.append(t)
            total += t.shape[0]

    th = threading.Thread(target=reader)
    th.start()
    for i in range(0, n, 100):
        r.push_many(np.arange(i, i + 100, dtype=np.float64), np.zeros((100, 8), np.uint8))
    th.join(10)
    assert np.concatenate(got).tolist() == [float(i) for i in range(n)]
    assert r.lost(a) == 0


def test_one_writer_many_readers_without_a_caller_lock() -> None:
    """The C ring locks itself: readers with small limits race one writer (the C calls run
    truly concurrently, without the GIL) and readers come and go; every record read is
    whole (its bytes match its timestamp), in order, and read + lost == pushed."""
    size, n, batch = 16384, 12000, 3
    r = Ring(size, 64)
    readers = [r.add_reader(limit) for limit in (3, 10, None)]
    errors: list[str] = []
    done = threading.Event()

    def reader(rid: int) -> None:
        seen, last = 0, -1.0
        while True:
            finished = done.is_set()
            t, rec = r.read(rid)
            for ti, row in zip(t.tolist(), rec, strict=True):
                if ti <= last or not np.all(row == int(ti) & 0xFF):
                    errors.append(f"reader {rid}: record {ti} after {last}, torn or out of order")
                    return
                last = ti
            seen += len(t)
            if finished:
                break
        if seen + r.lost(rid) != n:
            errors.append(f"reader {rid}: {seen} read + {r.lost(rid)} lost != {n}")

    def churn() -> None:
        while not done.is_set():
            r.remove_reader(r.add_reader(2))
            r.available(readers[0])

    threads = [threading.Thread(target=reader, args=(rid,)) for rid in readers]
    threads.append(threading.Thread(target=churn))
    for th in threads:
        th.start()
    for i in range(0, n, batch):
        k = min(batch, n - i)
        ts = np.arange(i, i + k, dtype=np.float64)
        r.push_many(ts, np.repeat((ts.astype(np.int64) & 0xFF).astype(np.uint8), size))
    done.set()
    for th in threads:
        th.join(10)
    assert not any(th.is_alive() for th in threads)
    assert errors == []
    assert r.pushed == n


OPS = st.lists(
    st.one_of(
        st.tuples(st.just("push"), st.integers(0, 3)),
        st.tuples(st.just("many"), st.integers(0, 25)),
        st.tuples(st.just("add"), st.one_of(st.none(), st.integers(1, 12))),
        st.tuples(st.just("remove"), st.integers(0, 5)),
        st.tuples(st.just("read"), st.one_of(st.none(), st.integers(0, 6))),
    ),
    max_size=60,
)


@settings(max_examples=200, deadline=None)
@given(ops=OPS, capacity=st.integers(1, 9), size=st.integers(1, 5))
def test_random_ops_match_reference(
    ops: list[tuple[str, int | None]], capacity: int, size: int
) -> None:
    c = Ring(size, capacity)
    r = reference.RefRing(size, capacity)
    counter = 0
    for op, arg in ops:
        if op == "push":
            c.push(float(counter), _rec(counter, size))
            r.push(float(counter), _rec(counter, size))
            counter += 1
        elif op == "many":
            assert arg is not None
            ts = [float(counter + i) for i in range(arg)]
            recs = b"".join(_rec(counter + i, size) for i in range(arg))
            c.push_many(np.array(ts), np.frombuffer(recs, np.uint8).reshape(arg, size))
            r.push_many(ts, recs)
            counter += arg
        elif op == "add":
            assert c.add_reader(arg) == r.add_reader(arg)
        elif r.readers:
            rid = sorted(r.readers)[(arg or 0) % len(r.readers)]
            if op == "remove":
                c.remove_reader(rid)
                r.remove_reader(rid)
            else:
                t, rec = c.read(rid, arg)
                want = r.read(rid, arg)
                assert t.tolist() == [x[0] for x in want]
                assert [bytes(x) for x in rec] == [x[1] for x in want]
        assert c.pushed == r.pushed
        for rid in r.readers:
            assert c.available(rid) == r.available(rid)
            assert c.lost(rid) == r.lost(rid)
