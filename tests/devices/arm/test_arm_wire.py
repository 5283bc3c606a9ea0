"""Bytes on the wire: the recorded reference-library traces replayed against the simulator and
the client in all three variants, the ABB server's quirks, state decoding, bad peers."""

from __future__ import annotations

import math
import os
import struct

import numpy as np
import pytest

from robocli.devices.arm import Arm
from robocli.errors import DeviceError, TransportError
from robocli.kinematics import load_model
from robocli.kinematics.trajectory import circle
from robocli.protocols import simple_message as sm
from tests.devices.arm.conftest import VARIANTS, RawSM, exchange, vectors

IRB = load_model("irb120")


def _frames(raw: RawSM, n: int, timeout: float = 5.0) -> list[bytes]:
    out = []
    for _ in range(n):
        f = raw.frame(timeout)
        assert f is not None, f"only {len(out)} of {n} frames arrived"
        out.append(f)
    return out


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_exchange_replayed_against_generic_server(variant, make_sim) -> None:
    """Every client frame of the recorded library conversation, sent to the generic profile,
    gets the recorded server frames back, byte for byte (FAILURE replies included)."""
    order, real = VARIANTS[variant]
    sim, mp, _ = make_sim(profile="generic", byteorder=order, real=real)
    raw = RawSM(mp, order)
    lines = exchange(variant)
    for i, line in enumerate(lines):
        if line["dir"] != "client->server":
            continue
        raw.send(bytes.fromhex(line["hex"]))
        nxt = lines[i + 1] if i + 1 < len(lines) else None
        if nxt is not None and nxt["dir"] == "server->client":
            assert raw.frame() == bytes.fromhex(nxt["hex"]), f"frame {i + 1}"
    assert raw.frame(0.2) is None  # and nothing else (no reply to the TOPIC point)
    raw.close()


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_library_vectors_against_abb_server(variant, make_sim) -> None:
    """Each library JOINT_TRAJ_PT request gets the ABB's header-only SUCCESS ack (the library
    vector); the TOPIC point gets none; the state server's JOINT_POSITION equals the
    library's bytes for the same joints."""
    order, real = VARIANTS[variant]
    vec = vectors(variant)
    q0 = vec["joint_position_topic"]["fields"]["joints"][:6]
    sim, mp, sp = make_sim(byteorder=order, real=real, q0=q0)
    raw = RawSM(mp, order)
    ack = bytes.fromhex(vec["joint_traj_pt_reply_success_header_only"]["hex"])
    for name in ("seq_m1_start_download", "seq0", "seq1", "seq5", "seq_m4_stop"):
        raw.send(bytes.fromhex(vec[f"joint_traj_pt_request_{name}"]["hex"]))
        assert raw.frame() == ack, name
    raw.send(bytes.fromhex(vec["joint_traj_pt_topic_seq_m1"]["hex"]))
    assert raw.frame(0.2) is None
    assert sim.snapshot().points_received == 6
    state = RawSM(sp, order)
    assert state.frame() == bytes.fromhex(vec["joint_position_topic"]["hex"])
    status = sm.decode(state.frame(), byteorder=order, real=real)
    assert status.msg_type == sm.SimpleMessageType.STATUS and status.body["in_motion"] == 0
    raw.close()
    state.close()


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_client_sends_library_bytes(variant, make_sim, make_arm) -> None:
    """The client's STOP is byte-identical to the library's (all-zero point, seq -4), and a
    download works in every variant."""
    order, real = VARIANTS[variant]
    sim, mp, sp = make_sim(byteorder=order, real=real)
    sent: list[bytes] = []
    arm = make_arm(mp, sp, byte_order="big" if order == ">" else "little", real_size=real)
    arm.add_listener(lambda d, frame, t: sent.append(frame) if d == "tx" else None, "motion")
    arm.stop()
    assert sent == [bytes.fromhex(vectors(variant)["joint_traj_pt_request_seq_m4_stop"]["hex"])]
    arm.download(circle(IRB, 20, duration=1.0))
    arm.wait_until_idle(10)
    assert sim.snapshot().trajectories == 1


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_client_decodes_library_state_frames(variant, talking_server) -> None:
    """JOINT_POSITION, STATUS and JOINT_FEEDBACK exactly as the library serialises them."""
    order, real = VARIANTS[variant]
    vec = vectors(variant)
    names = ("joint_position_topic", "status_topic_manual_error", "joint_feedback_topic")
    server = talking_server(b"".join(bytes.fromhex(vec[n]["hex"]) for n in names))
    arm = Arm.connect(
        "127.0.0.1",
        state_port=server.port,
        motion=False,
        byte_order="big" if order == ">" else "little",
        real_size=real,
    )
    try:
        arm.wait_for_state()
        arm.wait_for_state()
        samples = list(arm.history)
        pos = next(s for s in samples if s.source == "joint_position")
        want = [struct.unpack(order + ("f" if real == 4 else "d"),
                              struct.pack(order + ("f" if real == 4 else "d"), v))[0]
                for v in vec["joint_position_topic"]["fields"]["joints"][:6]]  # fmt: skip
        assert list(pos.joints) == want and pos.robot_time is None
        fb = next(s for s in samples if s.source == "joint_feedback")
        fields = vec["joint_feedback_topic"]["fields"]
        assert fb.robot_time == pytest.approx(fields["time"], rel=1e-6)
        assert fb.joints == pytest.approx(fields["positions"][:6], rel=1e-6)
        st = arm.status
        f = vec["status_topic_manual_error"]["fields"]
        assert st is not None and st.mode == "MANUAL" and st.error_code == f["error_code"]
        assert st.in_error is (None if f["in_error"] < 0 else bool(f["in_error"]))
    finally:
        arm.close()


def test_abb_buffer_drops_beyond_100_but_acks(make_sim) -> None:
    sim, mp, _ = make_sim()
    raw = RawSM(mp)
    q = [float(v) for v in IRB.work]

    def point(seq: int) -> bytes:
        body = {"sequence": seq, "joints": q, "velocity": 0.0, "duration": 0.01}
        return sm.encode(11, sm.CommType.SERVICE_REQUEST, 0, body)

    seqs = [-1, *range(1, 101), -3]  # 102 points
    for seq in seqs:
        raw.send(point(seq))
    replies = _frames(raw, len(seqs))
    assert all(sm.decode(r).reply_code == sm.ReplyCode.SUCCESS for r in replies)
    snap = sim.wait_until(lambda s: s.trajectories == 1, 30)
    assert snap.dropped_points == 2 and snap.points_received == 102
    raw.close()


def test_abb_motion_server_restarts_on_another_message(make_sim, make_arm) -> None:
    """PING stops the RAPID motion task: the link closes, the next client is served."""
    sim, mp, sp = make_sim()
    raw = RawSM(mp)
    raw.send(sm.encode(sm.SimpleMessageType.PING, sm.CommType.SERVICE_REQUEST))
    assert raw.closed_by_peer()
    assert sim.wait_until(lambda s: s.motion_clients == 0, 30).frames_refused == 1
    arm = make_arm(mp, sp)
    arm.download(circle(IRB, 10, duration=1.0))
    arm.wait_until_idle(10)


def test_garbage_on_both_ports_while_another_client_monitors(make_sim, make_arm) -> None:
    sim, mp, sp = make_sim()
    monitor = make_arm(mp, sp, motion=False)
    monitor.wait_for_state()
    rng = np.random.default_rng(7)
    for i in range(2):
        bad = RawSM(mp)
        bad.send(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
        bad.close()
        sim.wait_until(lambda s, n=i + 1: s.motion_accepted == n and s.motion_clients == 0, 30)
        busy = RawSM(sp)  # one client per port: refused, whatever it sends
        busy.send(os.urandom(512))
        assert busy.closed_by_peer()
        busy.close()
    before = len(monitor.history)
    worker = make_arm(mp, None, state=False)
    worker.download(circle(IRB, 10, duration=1.0), first_duration=1.0)
    monitor.wait_until_idle(10)
    assert len(monitor.history) > before and monitor.stats["state"]["decode_errors"] == 0
    assert sim.snapshot().trajectories == 1


def test_second_state_client_is_refused(make_sim, make_arm) -> None:
    sim, mp, sp = make_sim()
    make_arm(mp, sp, motion=False).wait_for_state()
    with pytest.raises(DeviceError, match="busy"):
        Arm.connect("127.0.0.1", state_port=sp, motion=False, timeout=3.0)


def test_port_answering_another_protocol(talking_server) -> None:
    server = talking_server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 3)
    with pytest.raises(TransportError, match="not in Simple Message"):
        Arm.connect("127.0.0.1", state_port=server.port, motion=False, timeout=0.5)


def test_state_decoding_from_simulator(make_sim, make_arm) -> None:
    q0 = IRB.work + np.radians([5, -5, 5, -5, 5, -5])
    sim, mp, sp = make_sim(q0=q0)
    arm = make_arm(mp, sp, motion=False)
    s = arm.wait_for_state()
    assert s.joints == pytest.approx(q0, abs=1e-6)
    assert s.degrees() == pytest.approx([math.degrees(v) for v in q0], abs=1e-4)
    st = arm.status
    assert st is not None and st.drives_powered and st.motion_possible and st.mode == "AUTO"
    assert st.in_motion is False and st.e_stopped is False and st.error_code == 0


def test_abb_aborts_a_trajectory_it_cannot_reach(make_sim) -> None:
    """A point beyond a joint limit (or NaN) makes MoveAbsJ fail: acked, never executed."""
    sim, mp, _ = make_sim()
    raw = RawSM(mp)
    q = [float(v) for v in IRB.work]
    far = [*q[:2], math.radians(90), *q[3:]]  # joint 3 stops at 70 deg
    for seq, joints in ((-1, q), (1, far), (2, [math.nan] * 6), (-3, q)):
        body = {"sequence": seq, "joints": joints, "velocity": 0.0, "duration": 0.5}
        raw.send(sm.encode(11, sm.CommType.SERVICE_REQUEST, 0, body))
    assert all(sm.decode(f).reply_code == sm.ReplyCode.SUCCESS for f in _frames(raw, 4))
    snap = sim.wait_until(lambda s: s.rejected_points == 1, 30)
    assert not snap.in_motion and np.allclose(snap.joints, IRB.work)
    raw.close()


def _connect_motion(sim, port: int, order: str) -> RawSM:
    sim.wait_until(lambda s: s.motion_clients == 0, 30)
    accepted = sim.snapshot().motion_accepted
    raw = RawSM(port, order)
    sim.wait_until(lambda s: s.motion_accepted == accepted + 1, 30)
    return raw


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_library_vector_against_both_profiles(variant, make_sim) -> None:
    """Each of the library's 25 vectors on the motion port, by the rules of each server:
    ABB: a JOINT_TRAJ_PT with a whole point is taken (acked if a request), anything else
    stops the RAPID task (link closed); generic: PING answered, requests answered (echo or
    header-only FAILURE), topics and replies ignored. A trailing STOP request proves that
    nothing else was sent back."""
    order, real = VARIANTS[variant]
    vec = vectors(variant)
    stop = bytes.fromhex(vec["joint_traj_pt_request_seq_m4_stop"]["hex"])
    point_size = sm.messages(order, real).JointTrajPt.sizeof()  # type: ignore[arg-type]
    for profile in ("abb", "generic"):
        sim, mp, _ = make_sim(profile=profile, byteorder=order, real=real)
        raw = RawSM(mp, order)
        for name, v in vec.items():
            frame = bytes.fromhex(v["hex"])
            body = len(frame) - 16
            mt, comm = v["msg_type"], v["comm_type"]
            request = comm == sm.CommType.SERVICE_REQUEST
            raw.send(frame + stop)
            got = raw.frame()
            if profile == "abb":
                if mt != 11 or body < point_size:
                    assert raw.closed_by_peer(), name
                    raw.close()
                    raw = _connect_motion(sim, mp, order)
                    continue
                if request:
                    assert sm.decode(got, byteorder=order, real=real).comm_type == 3, name
                    got = raw.frame()
            elif comm != sm.CommType.SERVICE_REPLY and (mt == 1 or request):
                reply = sm.decode(got, byteorder=order, real=real)
                assert reply.msg_type == mt and reply.comm_type == 3, name
                assert reply.reply_code in (1, 2), name
                if mt == 11 and body:
                    assert got[16:] == frame[16:], name  # echo of the point
                got = raw.frame()
            ack = sm.decode(got, byteorder=order, real=real)  # the STOP's reply, nothing else
            assert (ack.msg_type, ack.comm_type, ack.reply_code) == (11, 3, 1), name
        raw.close()


@pytest.mark.parametrize(("server", "client"), [((">", 4), ("little", 4)),
                                               (("<", 4), ("big", 4)),
                                               (("<", 8), ("little", 4))])  # fmt: skip
def test_wrong_byte_order_or_real_size_is_refused(server, client, make_sim) -> None:
    """The other byte order frames 3 bytes late, and small ints even decode; float64 bodies
    do not fit float32 messages: refused at connect, never garbage joints."""
    sim, mp, sp = make_sim(byteorder=server[0], real=server[1])
    with pytest.raises(TransportError, match="wrong byte order or real size"):
        Arm.connect("127.0.0.1", state_port=sp, motion=False, byte_order=client[0],
                    real_size=client[1], timeout=1.0)  # fmt: skip
