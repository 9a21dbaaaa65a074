"""The front end as an SLE Return All Frames provider (``station serve --sle-port``).

This is CCSDS 911.1 (RAF) over ISP1 (913.1), what control centres connect to a ground
station with.

- **The association.** The user connects over TCP and opens with the ISP1 context message
  (``ISP1``, its heartbeat interval and dead factor). Each PDU then travels in a TML
  message, and either side sends a heartbeat when it has sent nothing for the interval. A
  side that hears nothing for interval × dead factor aborts.
- **BIND.** The service type must be RAF, the version 1 to 5, and the service instance
  this provider's. With ``password`` set, the user's ISP1 credentials must hold: the
  SHA-1 or SHA-256 of the DER of (time, random number, user name, password), minted
  within the last 180 s. Anything else is refused with the diagnostic the standard names:
  ``serviceTypeNotSupported``, ``versionNotSupported``, ``noSuchServiceInstance``,
  ``accessDenied``, ``alreadyBound``.
- **START and STOP.** They open and close the delivery of the frames the front end
  receives, from then on: each CADU as received (1024 bytes), with its earth-receive time
  (the front end's clock when its piece arrived), the channel as the antenna, its quality
  (``good``: Reed–Solomon and CRC checked; else ``erred``) and the data-link continuity
  (frames missing before it on its virtual channel; −1 unknown). Frames go in transfer
  buffers of ``buffer_frames``, sent when full or after ``latency_s``.
- **Delivery modes.** In *online complete* (the default: ``…raf=onlc1``) nothing is ever
  discarded: a user that stops reading only grows the provider's queue. In *online timely*
  (``onlt``) the queue holds ``timely_frames`` at most; beyond that the oldest are
  discarded and an ``excessiveDataBacklog`` notification says so.
- **The rest.** SCHEDULE-STATUS-REPORT (immediately, periodically, stop) and its reports;
  GET-PARAMETER (buffer size, delivery mode, latency limit, others refused as unknown);
  UNBIND; PEER-ABORT either way.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import logging
import socket
import struct
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from station.live import ber
from station.live.ber import CONTEXT, BerError, Tlv, decode_one, integer, null, octets, sequence
from station.live.transfer import FrameQueue, Frames, transfer_buffer
from station.live.wire import read_exact
from station.srrs.receiver import Found
from station.telemetry import format as tf

__all__ = ["RafConfig", "RafProvider"]

_log = logging.getLogger(__name__)

#: The service instance attributes' object identifiers, by name (CCSDS 911.1 annex; the
#: heritage ones of version 1).
_OIDS = {
    "sagr": 52, "spack": 53, "fsl-fg": 14, "rsl-fg": 38, "cltu": 7, "fsp": 10, "raf": 22,
    "rcf": 46, "rcfsh": 44, "rocf": 49, "rsp": 40, "tcf": 12, "tcva": 16,
}  # fmt: skip
_NAMES: dict[tuple[int, ...], str] = {(1, 3, 112, 4, 3, 1, 2, n): k for k, n in _OIDS.items()}
_NAMES |= {(1, 2, 0, 9, 5, 2, n): k for k, n in _OIDS.items()}
#: TML message types (913.1): a PDU, the context, a heartbeat.
_PDU, _CONTEXT, _HEARTBEAT = 0x01000000, 0x02000000, 0x03000000
#: Seconds the user has to send the context message once connected (ISP1's TMS).
TMS_S = 30.0
#: How old a credential may be (s): ISP1's authentication delay.
AUTHENTICATION_DELAY_S = 180.0
CCSDS_EPOCH = dt.datetime(1958, 1, 1, tzinfo=dt.UTC)
RTN_ALL_FRAMES = 0
#: BIND diagnostics (911.1 §3.2).
ACCESS_DENIED, SERVICE_TYPE, VERSION, NO_SUCH_INSTANCE, ALREADY_BOUND = 0, 1, 2, 3, 4
GOOD, ERRED = 0, 1


@dataclass(frozen=True)
class RafConfig:
    """One RAF service instance of the front end (``station serve --sle-*``)."""

    instance: str = "sagr=1.spack=1.rsl-fg=1.raf=onlc1"
    provider: str = "station"
    user: str = "mcs"
    #: The user's password (its bytes), and the provider's, when credentials are checked.
    password: bytes | None = None
    provider_password: bytes | None = None
    buffer_frames: int = 100
    latency_s: float = 1.0
    timely_frames: int = 10_000

    @property
    def complete(self) -> bool:
        """Online complete (``onlc``), or online timely (``onlt``)."""
        return "onlt" not in self.instance.rsplit("=", 1)[-1]

    def attributes(self) -> list[tuple[str, str]]:
        return [tuple(p.split("=", 1)) for p in self.instance.split(".")]  # type: ignore[misc]


def _cds_time(when: dt.datetime) -> bytes:
    """CCSDS day segmented time: days since 1958 (16 bits), ms of the day, µs of the ms."""
    d = when - CCSDS_EPOCH
    ms, us = divmod(d.seconds * 1_000_000 + d.microseconds, 1000)
    return struct.pack("!HIH", d.days, ms, us)


def _credentials(user: str, password: bytes | None) -> bytes:
    """Invoker or performer credentials: unused ([0] NULL), or ISP1's (SHA-256)."""
    if password is None:
        return null(CONTEXT, 0)
    now = dt.datetime.now(dt.UTC)
    t, rnd = _cds_time(now), int.from_bytes(np.random.default_rng().bytes(4), "big") >> 1
    digest = hashlib.sha256(_hash_input(t, rnd, user, password)).digest()
    isp1 = sequence(octets(t), integer(rnd), octets(digest))
    return octets(isp1, CONTEXT, 1)


def _hash_input(t: bytes, rnd: int, user: str, password: bytes) -> bytes:
    return sequence(octets(t), integer(rnd), ber.visible(user), octets(password))


def _check_credentials(cred: Tlv, user: str, password: bytes | None) -> bool:
    """Whether an invoker's credentials are good for ``user`` (always, unchecked)."""
    if password is None:
        return True
    if cred.number != 1 or cred.constructed:
        return False
    try:
        t, rnd, protected = decode_one(cred.content)[0].children()
        days, ms, us = struct.unpack("!HIH", t.content)
    except (BerError, ValueError, struct.error):
        return False
    minted = CCSDS_EPOCH + dt.timedelta(days=days, milliseconds=ms, microseconds=us)
    if abs((dt.datetime.now(dt.UTC) - minted).total_seconds()) > AUTHENTICATION_DELAY_S:
        return False
    data = _hash_input(t.content, rnd.integer(), user, password)
    return protected.content in (hashlib.sha1(data).digest(), hashlib.sha256(data).digest())


@dataclass(eq=False)
class _Association:
    """One user's association: its socket, what it agreed, its state."""

    sock: socket.socket
    peer: str
    heartbeat_s: float = 25.0
    dead_factor: int = 5
    bound: bool = False
    active: bool = False
    quality: int = 2  # allFrames
    #: ``lock`` guards the queue, ``send_lock`` the socket: a user slow to read holds up
    #: the sending, never the front end that queues frames
    lock: threading.Lock = field(default_factory=threading.Lock)
    send_lock: threading.Lock = field(default_factory=threading.Lock)
    last_sent: float = field(default_factory=time.monotonic)
    queue: FrameQueue = field(default_factory=FrameQueue)
    wake: threading.Event = field(default_factory=threading.Event)
    closed: bool = False
    delivered: int = 0
    error_free: int = 0
    report_every_s: float | None = None
    backlog_said: bool = False

    def send_pdu(self, pdu: bytes) -> None:
        self._send(struct.pack("!II", _PDU, len(pdu)) + pdu)

    def _send(self, message: bytes) -> None:
        with self.send_lock:
            if self.closed:
                return
            try:
                self.sock.sendall(message)
            except OSError:
                self.closed = True
            self.last_sent = time.monotonic()


class RafProvider:
    """The RAF service instance of a front end (module docstring)."""

    def __init__(self, config: RafConfig) -> None:
        self.config = config
        self._association: _Association | None = None
        self._lock = threading.Lock()
        self._continuity: dict[tuple[str, int], int] = {}
        self.frames_offered = 0

    # -- frames from the front end ---------------------------------------------------
    def offer(self, tag: str, cadus: NDArray[np.uint8], found: Found) -> None:
        """A piece's CADUs as received and what their decoding found (the front end's
        :class:`station.srrs.stream.StreamDecoder` hook)."""
        now = _cds_time(dt.datetime.now(dt.UTC))
        good = found.rs_ok & found.crc_ok
        head = found.frames[:, :6].astype(np.int64)
        word = (head[:, 0] << 8) | head[:, 1]
        vc = word & 0x3F
        count = tf.from_u24(found.frames[:, 2:5])
        self.frames_offered += len(cadus)
        continuity = self._continuity_of(tag, good, vc, count)
        quality = np.where(good, GOOD, ERRED)
        a = self._association
        if a is None or not a.active:
            return
        keep = (
            np.ones(len(cadus), bool) if a.quality == 2 else (quality == GOOD) == (a.quality == 0)
        )
        frames = Frames(
            now, tag.encode()[:16] or b"-", continuity[keep], quality[keep], cadus[keep]
        )
        with a.lock:
            a.queue.put(frames)
            if not self.config.complete and a.queue.keep_newest(self.config.timely_frames):
                a.backlog_said = False  # timely: the oldest went
        a.wake.set()

    def _continuity_of(
        self, tag: str, good: NDArray[np.bool_], vc: NDArray[np.int64], count: NDArray[np.int64]
    ) -> NDArray[np.int64]:
        """Each frame's data-link continuity: the frames missing just before it on its
        virtual channel (from their counts, across pieces); −1 where unknown (a frame
        that did not decode, the first of a channel, one that came back in time)."""
        out = np.full(vc.size, -1, np.int64)
        for v in np.unique(vc[good]):  # a channel's few virtual channels
            rows = np.flatnonzero(good & (vc == v))
            before = np.r_[self._continuity.get((tag, int(v)), -1), count[rows][:-1]]
            gap = count[rows] - before - 1
            out[rows] = np.where((before >= 0) & (gap >= 0), gap, -1)
            self._continuity[(tag, int(v))] = int(count[rows][-1])
        return out

    # -- the server ----------------------------------------------------------------
    def serve_forever(self, server: socket.socket, stop: threading.Event) -> None:
        """Accept users on ``server`` until ``stop``; one association at a time."""
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                sock, addr = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            t = threading.Thread(
                target=self._associate, args=(sock, f"{addr[0]}:{addr[1]}"), daemon=True
            )
            t.start()

    def _associate(self, sock: socket.socket, peer: str) -> None:
        a = _Association(sock, peer)
        try:
            with sock:
                self._context(a)
                threading.Thread(target=self._deliver, args=(a,), daemon=True).start()
                self._read(a)
        except (OSError, BerError, ValueError) as exc:
            _log.warning("SLE %s: %s", peer, exc)
        finally:
            a.closed = True
            a.wake.set()
            with self._lock:
                if self._association is a:
                    self._association = None

    def _context(self, a: _Association) -> None:
        a.sock.settimeout(TMS_S)
        head = read_exact(a.sock, 20)
        mtype, length = struct.unpack("!II", head[:8])
        if mtype != _CONTEXT or length != 12 or head[8:12] != b"ISP1":
            raise ValueError("no ISP1 context message: not an SLE user")
        hb, dead = struct.unpack("!HH", head[16:20])
        a.heartbeat_s, a.dead_factor = float(hb or 25), max(dead, 2)
        a.sock.settimeout(a.heartbeat_s * a.dead_factor if hb else None)

    def _read(self, a: _Association) -> None:
        while not a.closed:
            head = read_exact(a.sock, 8)
            if len(head) < 8:
                return  # the user closed
            mtype, length = struct.unpack("!II", head)
            if mtype == _HEARTBEAT:
                continue
            if mtype != _PDU:
                raise ValueError(f"a TML message of type {mtype:#x}")
            pdu, _ = decode_one(read_exact(a.sock, length))
            if self._invocation(a, pdu) is False:
                return

    def _invocation(self, a: _Association, pdu: Tlv) -> bool:
        """One PDU of the user; False when the association ends."""
        number = pdu.number
        if number == 104:  # peer abort
            _log.info("SLE %s: peer abort (%d)", a.peer, pdu.integer())
            return False
        parts = pdu.children()
        cred = parts[0]
        if number == 100:
            return self._bind(a, parts)
        if not a.bound:
            raise ValueError(f"[{number}] before BIND")
        # authentication at BIND (ISP1's "bind" level): later credentials, when sent,
        # must hold too
        if cred.number == 1 and not _check_credentials(
            cred, self.config.user, self.config.password
        ):
            self._abort(a, 0)  # accessDenied
            return False
        me = _credentials(self.config.provider, self.config.provider_password)
        if number == 102:  # unbind
            a.send_pdu(sequence(me, null(CONTEXT, 0), cls=CONTEXT, number=103))
            return False
        invoke = parts[1].integer()
        if number == 0:  # start
            a.quality = parts[4].integer()
            a.active = True
            a.send_pdu(sequence(me, integer(invoke), null(CONTEXT, 0), cls=CONTEXT, number=1))
        elif number == 2:  # stop
            self._flush(a)
            a.active = False
            a.send_pdu(sequence(me, integer(invoke), null(CONTEXT, 0), cls=CONTEXT, number=3))
        elif number == 4:  # schedule status report
            kind = parts[2]
            a.report_every_s = float(kind.integer()) if kind.number == 1 else None
            a.send_pdu(sequence(me, integer(invoke), null(CONTEXT, 0), cls=CONTEXT, number=5))
            if kind.number == 0:
                self._status_report(a)
        elif number == 6:  # get parameter
            a.send_pdu(self._parameter(me, invoke, parts[2].integer(), a))
        return True

    def _bind(self, a: _Association, parts: list[Tlv]) -> bool:
        cred, initiator, _port, service, version, instance = parts
        c = self.config
        diagnostic = None
        if service.integer() != RTN_ALL_FRAMES:
            diagnostic = SERVICE_TYPE
        elif not 1 <= version.integer() <= 5:
            diagnostic = VERSION
        elif _instance_of(instance) != c.attributes():
            diagnostic = NO_SUCH_INSTANCE
        elif initiator.text() != c.user or not _check_credentials(cred, c.user, c.password):
            diagnostic = ACCESS_DENIED
        else:
            with self._lock:
                if self._association is not None and self._association is not a:
                    diagnostic = ALREADY_BOUND
                else:
                    self._association = a
        me = _credentials(c.provider, c.provider_password)
        result = (
            integer(version.integer(), CONTEXT, 0)
            if diagnostic is None
            else integer(diagnostic, CONTEXT, 1)
        )
        a.send_pdu(sequence(me, ber.visible(c.provider), result, cls=CONTEXT, number=101))
        if diagnostic is not None:
            _log.warning("SLE %s: BIND refused (diagnostic %d)", a.peer, diagnostic)
            return False
        a.bound = True
        _log.info("SLE %s: bound to %s", a.peer, c.instance)
        return True

    def _parameter(self, me: bytes, invoke: int, name: int, a: _Association) -> bytes:
        c = self.config
        values = {4: (0, c.buffer_frames), 6: (1, 1 if c.complete else 0)}
        if name in values:
            alt, value = values[name]
            par = sequence(integer(name), integer(value), cls=CONTEXT, number=alt)
            result = ber.tlv(CONTEXT, True, 0, par)
        elif name == 15:  # latency limit: online (seconds)
            par = sequence(integer(name), ber.tlv(CONTEXT, True, 0, integer(
                max(1, round(c.latency_s)), CONTEXT, 0)), cls=CONTEXT, number=2)  # fmt: skip
            result = ber.tlv(CONTEXT, True, 0, par)
        else:  # unknownParameter
            result = ber.tlv(CONTEXT, True, 1, integer(0, CONTEXT, 1))
        return sequence(me, integer(invoke), result, cls=CONTEXT, number=7)

    def _status_report(self, a: _Association) -> None:
        me = _credentials(self.config.provider, self.config.provider_password)
        locked = 0 if a.delivered else 3
        body = [integer(a.error_free), integer(a.delivered)]
        body += [integer(locked), integer(locked), integer(2), integer(locked), integer(0)]
        a.send_pdu(sequence(me, *body, cls=CONTEXT, number=9))

    def _abort(self, a: _Association, diagnostic: int) -> None:
        a.send_pdu(integer(diagnostic, CONTEXT, 104))

    # -- delivery ------------------------------------------------------------------
    def _deliver(self, a: _Association) -> None:
        """Transfer buffers as frames come (full, or after the latency limit), heartbeats
        when nothing else is sent, status reports when scheduled."""
        last_report = time.monotonic()
        oldest: float | None = None
        while not a.closed:
            a.wake.wait(0.2)
            a.wake.clear()
            now = time.monotonic()
            with a.lock:
                n = len(a.queue)
            if n and oldest is None:
                oldest = now
            if n >= self.config.buffer_frames or (
                n and oldest is not None and now - oldest >= self.config.latency_s
            ):
                self._flush(a)
                oldest = None
            if a.report_every_s and now - last_report >= a.report_every_s:
                self._status_report(a)
                last_report = now
            if now - a.last_sent >= a.heartbeat_s:
                a._send(struct.pack("!II", _HEARTBEAT, 0))

    def _flush(self, a: _Association) -> None:
        """Every queued frame, in transfer buffers of ``buffer_frames``."""
        me = _credentials(self.config.provider, self.config.provider_password)
        while True:
            with a.lock:
                pieces = a.queue.take(self.config.buffer_frames)
            if not pieces:
                return
            a.send_pdu(transfer_buffer(me, pieces))
            a.delivered += sum(len(f) for f in pieces)
            a.error_free += sum(int((f.quality == GOOD).sum()) for f in pieces)

    def linger(self, timeout_s: float) -> None:
        """Wait (at most ``timeout_s``) for the user bound, if any, to end its association."""
        deadline = time.monotonic() + timeout_s
        while self._association is not None and time.monotonic() < deadline:
            time.sleep(0.1)

    def flush(self) -> None:
        """Send what is queued now (a pass has ended)."""
        a = self._association
        if a is not None and a.active:
            self._flush(a)


def _instance_of(sii: Tlv) -> list[tuple[str, str]]:
    """A BIND's service instance identifier as (attribute name, value) pairs."""
    out = []
    for attribute in sii.children():
        for element in attribute.children():
            ident, value = element.children()
            out.append((_NAMES.get(ident.oid(), str(ident.oid())), value.text()))
    return out
