"""SLE Return All Frames (issue 59 §5): ``station serve --sle-port`` as a RAF provider, the
``sle`` package (LibreCube's SLE user API, protocol version 5) as the user. The user binds,
starts and receives a whole pass: every CADU the front end found, byte for byte and in
order, with its quality; it stops and unbinds. A wrong service instance, a wrong password
and a wrong user are refused as the standard says; a user that stops reading for 10 s
loses nothing in online complete mode.

Every server here is a ``station serve`` this module starts on 127.0.0.1 and free ports,
stopped by its id (``tests/test_live.py``'s ``serving``)."""

from __future__ import annotations

import atexit
import contextlib
import logging
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from test_live import NOISY, serving

sle = pytest.importorskip("sle")
from sle.constants import SleState  # noqa: E402

INSTANCE = "sagr=1.spack=1.rsl-fg=1.raf=onlc1"
#: The sockets the closed users' readers wait on (:meth:`_User.close`), closed on exit.
_QUIET: list[tuple[socket.socket, socket.socket]] = []
atexit.register(lambda: [s.close() for pair in _QUIET for s in pair])
#: How long a user may take to bind, start, stop or unbind, and to receive a pass.
STEP_S, PASS_S = 15.0, 90.0
#: Frames per transfer buffer: few messages a pass (the ``sle`` user reads one TML message
#: each time its socket has data; the provider's heartbeats bring it the rest).
BUFFER = "1000"
logging.getLogger("sle").setLevel(logging.ERROR)


@pytest.fixture(scope="module")
def expected() -> tuple[list[bytes], list[int]]:
    """The CADUs of the poor channel's pass as the front end finds them (the receiver on
    the recorded stream), and their quality: 0 good (Reed–Solomon and CRC), 1 erred."""
    from station.chain.session import downlink
    from station.loader import load_scenario
    from station.spacecraft.emulator import emulate_pass
    from station.srrs.receiver import receive
    from station.srrs.stream import _cadus_at

    rx = downlink(emulate_pass(load_scenario(NOISY))[0]).reception
    d = receive(rx.stream, rx.n_bits)
    cadus = _cadus_at(np.asarray(rx.stream), d.frame_bit_offset)
    good = np.isin(d.frame_status, [0, 1, 3, 4, 5])  # ok, corrected, duplicate, late, fill
    return [bytes(c) for c in cadus], [0 if g else 1 for g in good]


class _User(sle.RafServiceUser):
    """A RAF user that keeps what it is given."""

    made: list[_User] = []  # noqa: RUF012 - every user, closed after its test

    def __init__(self, port: int, instance: str = INSTANCE, **kw: object) -> None:
        args = {"auth_level": "none", "local_identifier": "mcs", "peer_identifier": "station"}
        args |= {"heartbeat_interval": 1, "heartbeat_deadfactor": 5, **kw}
        super().__init__(
            service_instance_identifier=instance,
            responder_host="127.0.0.1",
            responder_port=port,
            **args,
        )
        self.frames: list[tuple[bytes, int]] = []
        _User.made.append(self)

    def close(self) -> None:
        """Its transport's timers stopped (threads that would hold the interpreter up), and
        its reader given a socket that never has data: once its own is gone, ``sle`` 0.3's
        reader loops on ``select`` of nothing without waiting, a core's worth of CPU for
        the rest of the session."""
        transport = self._proxy.transport
        for timer in ("_tms_timer", "_hbt_timer", "_hbr_timer", "_cpa_timer"):
            getattr(transport, timer).stop()
        if transport._socket is not None:
            with contextlib.suppress(OSError):
                transport._socket.close()
        quiet = socket.socketpair()
        _QUIET.append(quiet)  # both ends kept open: never readable, never closed
        transport._socket = quiet[0]

    def frame_indication(self, pdu: object) -> None:
        self.frames.append((bytes(pdu["data"]), int(pdu["deliveredFrameQuality"])))  # type: ignore[index]


@pytest.fixture(autouse=True)
def _closed_users() -> Iterator[None]:
    """The users a test made have their timers stopped when it ends, whatever happened."""
    yield
    while _User.made:
        _User.made.pop().close()


def _sle_port(where: Path) -> int:
    path, deadline = where / "sleport", time.monotonic() + STEP_S
    while not path.is_file():
        assert time.monotonic() < deadline
        time.sleep(0.05)
    return int(path.read_text())


def _serve_sle(where: Path, *extra: str):
    return serving(
        where, "--passes", "1", "--sle-port", "0", "--sle-port-file", str(where / "sleport"),
        "--sle-buffer", BUFFER, *extra,
    )  # fmt: skip


def _transmit(port: int) -> None:
    import subprocess

    cmd = [sys.executable, "-m", "station.cli", "transmit", str(NOISY), "--speed", "max"]
    done = subprocess.run([*cmd, "--to", f"127.0.0.1:{port}"], timeout=PASS_S, check=False)
    assert done.returncode == 0


def _until(check, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline
        time.sleep(0.1)


def test_a_raf_user_receives_the_pass_frame_for_frame(expected, tmp_path: Path) -> None:
    cadus, quality = expected
    with _serve_sle(tmp_path) as (proc, port):
        user = _User(_sle_port(tmp_path))
        user.bind()
        assert user.wait_for_state(SleState.READY, STEP_S)
        user.start()
        assert user.wait_for_state(SleState.ACTIVE, STEP_S)
        _transmit(port)
        _until(lambda: len(user.frames) >= len(cadus), PASS_S)
        user.stop()
        assert user.wait_for_state(SleState.READY, STEP_S)
        user.unbind()
        assert user.wait_for_state(SleState.UNBOUND, STEP_S)
        assert proc.wait(STEP_S) == 0  # the user gone, the pass done: the server ends
    assert [f for f, _ in user.frames] == cadus  # byte for byte, in order
    assert [q for _, q in user.frames] == quality
    assert 0 < quality.count(1) < len(quality)  # good and erred frames, a poor channel


#: The provider's passwords (``--sle-auth``): the user's, and its own.
AUTH = {"auth_level": "bind", "local_password": "0a0b0c", "peer_password": "0102"}


@pytest.mark.parametrize(
    "instance, user_kw, refused",
    [
        ("sagr=1.spack=1.rsl-fg=1.raf=onlc9", AUTH, "noSuchServiceInstance"),
        (INSTANCE, AUTH | {"local_identifier": "intruder"}, "accessDenied"),
        (INSTANCE, AUTH | {"local_password": "00ff"}, "accessDenied"),
    ],
    ids=["instance", "user", "password"],
)
def test_wrong_identifiers_and_credentials_are_refused(
    instance: str, user_kw: dict, refused: str, auth_server: tuple[Path, int]
) -> None:
    where, port = auth_server
    user = _User(port, instance, **user_kw)
    user.bind()
    assert user.wait_for_state(SleState.UNBOUND, STEP_S)  # refused, not bound
    code = {"noSuchServiceInstance": 3, "accessDenied": 0}[refused]
    _until(lambda: f"BIND refused (diagnostic {code})" in (where / "serve.log").read_text(), 5)
    good = _User(port, **AUTH)
    good.bind()  # the right credentials are taken: the refusal was the wrong ones'
    assert good.wait_for_state(SleState.READY, STEP_S)
    good.unbind()
    assert good.wait_for_state(SleState.UNBOUND, STEP_S)


@pytest.fixture(scope="module")
def auth_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, int]]:
    """A provider checking credentials (``--sle-auth``), serving every refusal case."""
    where = tmp_path_factory.mktemp("sle_auth")
    sle_file = str(where / "sleport")
    with serving(
        where, "--sle-port", "0", "--sle-port-file", sle_file, "--sle-auth", "0a0b0c,0102"
    ):
        yield where, _sle_port(where)


def test_a_user_that_stops_reading_loses_nothing_in_complete_mode(expected, tmp_path: Path) -> None:
    """The user's reader stalls 10 s on its first frames while the pass arrives at full
    speed: the provider queues, the front end never waits, and every frame comes after."""
    cadus, _ = expected
    with _serve_sle(tmp_path) as (_, port):
        # its heartbeat's dead time (3 s × 5) longer than the stall: it does not abort
        user = _User(_sle_port(tmp_path), heartbeat_interval=3)
        transport = user._proxy.transport
        deliver = transport._tcp_data_indication
        stalled: list[float] = []

        def slow(data: bytes) -> None:
            if not stalled and len(data) > 100_000:  # its first transfer buffer
                stalled.append(time.monotonic())
                time.sleep(10.0)
            deliver(data)

        transport._tcp_data_indication = slow
        user.bind()
        assert user.wait_for_state(SleState.READY, STEP_S)
        user.start()
        assert user.wait_for_state(SleState.ACTIVE, STEP_S)
        t0 = time.monotonic()
        _transmit(port)
        sent_s = time.monotonic() - t0
        _until(lambda: len(user.frames) >= len(cadus), PASS_S)
        user.stop()
        user.wait_for_state(SleState.READY, STEP_S)
        user.unbind()
        user.wait_for_state(SleState.UNBOUND, STEP_S)
    assert stalled and sent_s < 10.0  # the pass was in before the user read again
    assert [f for f, _ in user.frames] == cadus


def test_timely_delivery_keeps_the_newest_frames_when_the_user_falls_behind() -> None:
    """Online timely (``raf=onlt…``): past ``timely_frames`` queued, the oldest go and the
    newest are kept; online complete keeps every one."""
    import socket as sockets

    from station.live.raf import RafConfig, RafProvider, _Association
    from station.srrs.receiver import Found

    n = 25
    frames = np.zeros((n, 892), np.uint8)
    found = Found(
        np.arange(n) * 8192, np.ones(n, bool), frames, np.zeros((n, 4), np.int64),
        np.ones(n, bool), np.ones(n, bool),
    )  # fmt: skip
    cadus = np.repeat(np.arange(n, dtype=np.uint8)[:, None], 1024, axis=1)
    for instance, kept in (("sagr=1.spack=1.rsl-fg=1.raf=onlt1", 10), (INSTANCE, n)):
        provider = RafProvider(RafConfig(instance, timely_frames=10))
        a, b = sockets.socketpair()
        with a, b:
            association = _Association(a, "test", bound=True, active=True)
            provider._association = association
            provider.offer("ch1", cadus, found)
            pieces = association.queue.take(len(association.queue))
            queued = [int(c[0]) for f in pieces for c in f.cadus]
        assert queued == list(range(n - kept, n)), instance


def test_a_transfer_buffer_is_each_frame_encoded_on_its_own() -> None:
    """The transfer buffer laid a piece at a time (``station.live.transfer``) is, byte for
    byte, each annotated frame encoded by itself through the BER module, whatever the
    continuities' widths (−1, 0, 127, 128, 2¹⁵, 2³¹ …) and the credentials."""
    from station.live.ber import CONTEXT, integer, null, octets, sequence
    from station.live.transfer import FrameQueue, Frames, transfer_buffer

    rng = np.random.default_rng(911)
    cont = np.array([-1, 0, 1, 127, 128, 255, 256, 32767, 32768, 2**23, 2**31, 2**40, -129])
    cadus = rng.integers(0, 256, (cont.size, 1024), dtype=np.uint8)
    quality = rng.integers(0, 3, cont.size)
    pieces = [
        Frames(b"\x01" * 8, b"hrv1", cont[:5], quality[:5], cadus[:5]),
        Frames(b"\x02" * 8, b"a-longer-tag", cont[5:], quality[5:], cadus[5:]),
    ]
    for me in (null(CONTEXT, 0), sequence(octets(b"x" * 8), integer(7), octets(b"y" * 20))):
        want = sequence(
            *(
                sequence(
                    me,
                    octets(f.ert, CONTEXT, 0),
                    octets(f.tag, CONTEXT, 1),
                    integer(int(c)),
                    integer(int(q)),
                    null(CONTEXT, 0),
                    octets(bytes(d)),
                    cls=CONTEXT,
                    number=0,
                )
                for f in pieces
                for c, q, d in zip(f.continuity, f.quality, f.cadus, strict=True)
            ),
            cls=CONTEXT,
            number=8,
        )
        assert transfer_buffer(me, pieces) == want
    queue = FrameQueue()  # pieces split where a buffer ends, the oldest dropped first
    for f in pieces:
        queue.put(f)
    assert [len(f) for f in queue.take(7)] == [5, 2] and len(queue) == cont.size - 7
    assert queue.keep_newest(3) == cont.size - 10 and len(queue) == 3
    assert np.array_equal(queue.take(10)[0].continuity, cont[-3:])
