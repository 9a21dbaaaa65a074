"""The emulator's sender (``station transmit``): a pass emulated and sent through its
downlink and channel as ``station run`` sends it (the same random draws), then replayed
to a front end over TCP at its line rate, at a multiple of it, or as fast as the link
takes; or a recorded CADU file replayed as it is (``docs/live.md``)."""

from __future__ import annotations

import logging
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from station.errors import StationError
from station.live.wire import (
    CHANNEL,
    MULTIPLEX,
    Announcement,
    ChannelInfo,
    end_of_stream,
    pack_header,
    piece,
    read_exact,
)

__all__ = ["Stream", "emulated_streams", "send_streams", "transmit"]

_log = logging.getLogger(__name__)

#: Bytes a piece of a channel carries: 21 ms of a 25 Mbit/s channel.
PIECE_BYTES = 64 << 10
#: Seconds a connection to the front end may take to open.
CONNECT_TIMEOUT_S = 10.0


@dataclass(frozen=True, eq=False)
class Stream:
    """One channel's bytes as the demodulator gives them, its length in bits and its rate."""

    tag: str
    data: NDArray[np.uint8]
    n_bits: int
    bit_rate_bit_per_s: float


def emulated_streams(scenario: Path) -> tuple[Announcement, list[Stream], bool]:
    """A pass's scenario emulated and sent through its downlink and channel, each HRV on
    its channel, as ``station run`` does (its tags, its random draws): the announcement of
    the pass, each channel's stream, and whether they share one connection
    (``[downlink] one_connection``)."""
    from station.chain.session import ancillary_of, downlink
    from station.loader import load_scenario
    from station.spacecraft.emulator import emulate_pass

    scn = load_scenario(scenario)
    acqs = emulate_pass(scn)
    n_hrv = len(acqs)
    channels, streams = [], []
    for acq in acqs:
        tag = scn.name if n_hrv == 1 else f"{scn.name}_hrv{acq.hrv.number}"
        result = downlink(acq)
        rate = result.transmission.bit_rate_bit_per_s
        rx = result.reception
        channels.append(
            ChannelInfo(
                tag, acq.hrv.number, rate, acq.bulletins, acq.epoch.t0_utc, tuple(ancillary_of(acq))
            )
        )
        streams.append(Stream(tag, rx.stream[: -(-rx.n_bits // 8)], int(rx.n_bits), rate))
    cut = {"scene_lines": scn.processing.scene_lines, "overlap_lines": scn.processing.overlap_lines}
    ann = Announcement(scn.name, tuple(channels), scn.provenance(), cut)
    return ann, streams, scn.downlink.one_connection


def _connect(host: str, port: int) -> socket.socket:
    try:
        sock = socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S)
    except OSError as exc:
        raise StationError(
            f"no front end answers at {host}:{port} ({exc.strerror or exc})"
        ) from None
    sock.settimeout(None)
    return sock


def _announce(host: str, port: int, announcement: Announcement) -> None:
    with _connect(host, port) as sock:
        sock.sendall(announcement.message())
        if read_exact(sock, 2) != b"OK":
            raise StationError(f"the front end at {host}:{port} refused the pass announcement")


def _send(
    host: str, port: int, stream: Stream, pass_name: str | None, speed: float | None, said: dict
) -> None:
    """One channel's connection: its header (none for a raw replay), its pieces paced at
    ``speed`` times its line rate (None: as fast as the link takes), its end."""
    t0 = time.perf_counter()
    with _connect(host, port) as sock:
        if pass_name is not None:
            sock.sendall(pack_header(CHANNEL, {"pass": pass_name, "tag": stream.tag}))
        data = stream.data.tobytes()
        rate = None if speed is None else stream.bit_rate_bit_per_s / 8.0 * speed
        for start in range(0, len(data), PIECE_BYTES):
            chunk = data[start : start + PIECE_BYTES]
            sock.sendall(piece(chunk) if pass_name is not None else chunk)
            if rate is not None:  # paced: the line rate's schedule, not sleeps summed
                ahead = t0 + (start + len(chunk)) / rate - time.perf_counter()
                if ahead > 0:
                    time.sleep(ahead)
        if pass_name is not None:
            sock.sendall(end_of_stream(stream.n_bits))
        sock.shutdown(socket.SHUT_WR)
        read_exact(sock, 2)  # the front end's "OK" once it has the whole stream
    said[stream.tag] = {"bytes": len(data), "seconds": time.perf_counter() - t0}


def _send_multiplexed(
    host: str, port: int, streams: list[Stream], pass_name: str, speed: float | None, said: dict
) -> None:
    """Every channel on one connection: each channel's pieces in the order their line
    rates make them (``speed`` times; None: as fast as the link takes), interleaved."""
    t0 = time.perf_counter()
    due = []  # (when the piece is whole, channel, start)
    for k, st in enumerate(streams):
        per_s = st.bit_rate_bit_per_s / 8.0 * (speed or 1.0)
        for start in range(0, st.data.size, PIECE_BYTES):
            due.append((min(start + PIECE_BYTES, st.data.size) / per_s, k, start))
    due.sort()
    with _connect(host, port) as sock:
        sock.sendall(pack_header(MULTIPLEX, {"pass": pass_name, "tags": [s.tag for s in streams]}))
        ends = [(streams[k].data.size, k) for k in range(len(streams))]
        for when, k, start in due:
            if speed is not None and (ahead := t0 + when - time.perf_counter()) > 0:
                time.sleep(ahead)
            chunk = streams[k].data[start : start + PIECE_BYTES].tobytes()
            sock.sendall(bytes([k]) + piece(chunk))
            if start + PIECE_BYTES >= ends[k][0]:
                sock.sendall(bytes([k]) + end_of_stream(streams[k].n_bits))
        sock.shutdown(socket.SHUT_WR)
        read_exact(sock, 2)  # the front end's "OK" once it has every stream
    for st in streams:
        said[st.tag] = {"bytes": int(st.data.size), "seconds": time.perf_counter() - t0}


def transmit(
    source: Path,
    host: str,
    port: int,
    speed: float | None = 1.0,
    one_connection: bool | None = None,
) -> dict[str, object]:
    """Send ``source`` (a pass's scenario, or a recorded ``.cadu`` file) to the front end
    at ``host:port``, every channel at once, at ``speed`` times the line rate (None: as
    fast as the link takes), each on its connection or all on one (``one_connection``;
    None: as the scenario's downlink says); returns what was sent and how fast."""
    if speed is not None and not speed > 0:
        raise StationError(f"--speed {speed}: a positive multiple of the line rate, or max")
    source = Path(source)
    if not source.is_file():
        raise StationError(f"{source}: no such file")
    if source.suffix == ".toml":
        announcement, streams, shared = emulated_streams(source)
        name: str | None = announcement.name
        one_connection = shared if one_connection is None else one_connection
        _announce(host, port, announcement)
    else:  # a recorded stream, replayed as it is (a raw connection)
        data = np.fromfile(source, np.uint8)
        streams, name = [Stream(source.stem, data, 8 * data.size, 25e6)], None
        if one_connection:
            raise StationError(f"{source}: a recorded stream is one channel, not several")
    said = _send_all(host, port, streams, name, speed, bool(one_connection))
    return {
        "pass": name or source.name,
        "speed": "max" if speed is None else speed,
        "connections": 1 if one_connection else len(streams),
        "channels": [
            {"tag": s.tag, **said[s.tag], "line_rate_mbps": s.bit_rate_bit_per_s / 1e6}
            for s in streams
        ],
    }


def send_streams(
    announcement: Announcement,
    streams: list[Stream],
    host: str,
    port: int,
    speed: float | None,
    one_connection: bool,
) -> dict[str, dict[str, float]]:
    """A pass emulated already (:func:`emulated_streams`) announced and sent to the front
    end at ``host:port`` (a day's passes, emulated before its clock starts): per channel,
    what was sent and how fast."""
    _announce(host, port, announcement)
    return _send_all(host, port, streams, announcement.name, speed, one_connection)


def _send_all(
    host: str,
    port: int,
    streams: list[Stream],
    name: str | None,
    speed: float | None,
    one_connection: bool,
) -> dict[str, dict[str, float]]:
    """Every stream at once, each on its connection or all on one; per channel, what was
    sent and how fast."""
    said: dict[str, dict[str, float]] = {}
    failures: list[BaseException] = []

    def one(s: Stream) -> None:
        try:
            _send(host, port, s, name, speed, said)
        except BaseException as exc:
            failures.append(exc)

    def together() -> None:
        try:
            _send_multiplexed(host, port, streams, str(name), speed, said)
        except BaseException as exc:
            failures.append(exc)

    threads = (
        [threading.Thread(target=together, daemon=True)]
        if one_connection
        else [threading.Thread(target=one, args=(s,), daemon=True) for s in streams]
    )
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failures:
        exc = failures[0]
        if isinstance(exc, OSError):
            raise StationError(f"the link to {host}:{port} broke: {exc}") from None
        raise exc
    return said
