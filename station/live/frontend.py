"""The SRRS front end as a server (``station serve``, ``docs/live.md``).

It listens on a TCP port and takes, per channel, the demodulator's stream as it arrives
(:mod:`station.live.wire`): frame sync, derandomisation, Reed–Solomon and CRC run on each
piece as it comes (:class:`station.srrs.stream.StreamDecoder`), and the pass's L0 archive
is written **on the fly**: every ``checkpoint_s`` of a channel's stream the archive of
what has arrived replaces the last one (a killed server leaves a readable archive of
everything received until then, its ``live`` attribute saying where it stopped); at the
stream's end the archive is the file route's, byte for byte. The front end's memory does
not grow with the pass: the frames go, as they are decoded, to an assembler that keeps
the lines and the image packets in the channel's spool (``<tag>.spool/``, removed once the
archive is written) and little else (:mod:`station.srrs.assembler`); an archive written
while the pass goes on is read from there, and the next one waits at least
:data:`CHECKPOINT_SHARE` times as long as that one took to write, so that rewriting a
growing archive never takes more than a fifth of the front end's time.

A connection dropped before its end is a stream cut there: the archive says so, nothing is
raised. A raw stream that no announced pass awaits is kept as it came (``unannounced/``)
with what its decoding found: nothing received is lost.

Each pass goes into a directory of its own under ``out`` (its name): one archive per
channel (``<tag>.l0.h5``, as ``station run`` names them) and ``live.json``, what each
channel brought (bytes, time, rate, frames and their accounting, whether it was cut).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import json
import logging
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from station.errors import StationError
from station.live.nrt import NearRealTime
from station.live.raf import RafConfig, RafProvider
from station.live.wire import (
    CHANNEL,
    MULTIPLEX,
    PASS,
    Announcement,
    ChannelInfo,
    WireError,
    read_channel_piece,
    read_header,
    read_piece,
)
from station.srrs.errors import ReceiverError
from station.srrs.receiver import DecodedPass
from station.srrs.recorder import write_l0
from station.srrs.stream import StreamDecoder

__all__ = ["FrontEnd", "serve", "warm_up"]

_log = logging.getLogger(__name__)

#: Seconds of a channel's stream between two archives written while it arrives.
CHECKPOINT_S = 2.0
#: The wait before the next archive, in multiples of the time the last one took to write.
CHECKPOINT_SHARE = 4.0
#: Bytes read from a raw stream at a time.
RAW_PIECE_BYTES = 64 << 10
#: Seconds between two progress lines of a channel (``-v``).
PROGRESS_S = 1.0
#: The piece of a stream decoded before the server listens (``tools/live_warmup.py``).
WARM_UP_STREAM = Path(__file__).resolve().parents[1] / "data" / "warmup.cadu"


def _give_back() -> None:
    """The heap's free memory returned to the system after an archive is written (glibc
    keeps what large transient arrays freed, and a front end's resident memory would be
    its high-water mark); nothing where the C library has no ``malloc_trim``."""
    trim = getattr(_LIBC, "malloc_trim", None)
    if trim is not None:
        trim(0)


_LIBC = ctypes.CDLL(ctypes.util.find_library("c") or None)


def warm_up() -> None:
    """Decode :data:`WARM_UP_STREAM` once: the receiver's kernels loaded (numba's cache)
    before the first pass arrives, not while it does."""
    decoder = StreamDecoder()
    decoder.feed(WARM_UP_STREAM.read_bytes())
    decoder.decoded()
    decoder.finish()


def _warm_geo() -> None:
    """GEO's placing of a pass's scenes (what the catalogue's entry of an archive needs) run
    once on the warm-up archive: its modules and kernels loaded before the first pass, not
    while its entry is written."""
    from levels.warmup import WARM_UP_ARCHIVE
    from station.archive_catalogue import archive_items

    t = time.perf_counter()
    try:
        archive_items(WARM_UP_ARCHIVE, WARM_UP_ARCHIVE.parent)
    except Exception as exc:  # a warm-up, never a reason not to serve
        _log.warning("GEO's warm-up failed: %s", exc)
    else:
        _log.info("GEO warm in %.2f s", time.perf_counter() - t)


@dataclass(eq=False)
class _Channel:
    """One channel of a pass at the front end: what it is, where its archive goes, and
    what has come."""

    info: ChannelInfo
    path: Path
    decoder: StreamDecoder = field(default_factory=StreamDecoder)
    spool: Path | None = None
    next_archive_s: float = 0.0  # when the next archive is written while the pass goes on
    connected: bool = False
    done: bool = False
    cut: bool = False
    started_s: float = 0.0
    said_s: float = 0.0  # its last progress line
    #: From its first byte to its last, to the pass decoded, to its archive written (s).
    seconds: float = 0.0
    decoded_s: float = 0.0
    archived_s: float = 0.0
    catalogued_s: float = 0.0  # its archive's entry (GEO's scenes) in the catalogue
    started_unix: float = 0.0  # its first byte, on the wall clock (a day's timeline)
    archives_written: int = 0
    #: The scenes' products made while the pass went on (``--levels``), with latencies.
    products: list[dict[str, object]] = field(default_factory=list)


@dataclass(eq=False)
class _Pass:
    announcement: Announcement
    where: Path
    channels: dict[str, _Channel]

    @property
    def done(self) -> bool:
        return all(c.done for c in self.channels.values())


class FrontEnd:
    """The server's state: the passes announced, the channels connected, what is done."""

    def __init__(
        self,
        out: Path,
        checkpoint_s: float = CHECKPOINT_S,
        sle: RafProvider | None = None,
        levels: tuple[str, ...] = (),
        catalogue: bool = True,
    ) -> None:
        self.out, self.checkpoint_s, self.sle = Path(out), checkpoint_s, sle
        self.catalogue = catalogue
        self.nrt = NearRealTime(levels) if levels else None
        self._lock = threading.Lock()
        self._passes: list[_Pass] = []
        self.passes_done: list[Path] = []
        self._unannounced = 0
        self.changed = threading.Condition(self._lock)

    # -- connections --------------------------------------------------------------
    def handle(self, sock: socket.socket, peer: str) -> None:
        """One connection, whatever it is (module docstring); never raises."""
        try:
            with sock:
                kind, header, first = read_header(sock)
                if kind == PASS:
                    self._announce(sock, Announcement.of_json(header or {}))
                elif kind == CHANNEL:
                    self._framed(sock, header or {}, peer)
                elif kind == MULTIPLEX:
                    self._multiplexed(sock, header or {}, peer)
                else:
                    self._raw(sock, first, peer)
        except (WireError, OSError) as exc:
            _log.warning("%s: %s", peer, exc)
        except Exception:  # a bug in one connection: said, the server goes on
            _log.exception("%s: the connection failed", peer)

    def _announce(self, sock: socket.socket, ann: Announcement) -> None:
        with self._lock:
            where = self._pass_dir(ann.name)
            channels = {c.tag: _Channel(c, where / f"{c.tag}.l0.h5") for c in ann.channels}
            self._passes.append(_Pass(ann, where, channels))
        _log.info("pass %s announced: %d channel(s), into %s", ann.name, len(channels), where)
        sock.sendall(b"OK")

    def _pass_dir(self, name: str) -> Path:
        """A directory of its own for a pass (its name; a second pass of that name gets
        ``<name>_2`` …)."""
        where, k = self.out / name, 1
        taken = {p.where for p in self._passes}
        while where in taken or where.exists():
            k += 1
            where = self.out / f"{name}_{k}"
        where.mkdir(parents=True)
        return where

    def _claim(self, pass_name: str | None, tag: str | None) -> tuple[_Pass, _Channel] | None:
        """The channel a stream is for: named (a framed stream), or the first one not yet
        connected of the passes announced (a raw stream)."""
        with self._lock:
            for p in self._passes:
                if pass_name is not None and p.announcement.name != pass_name:
                    continue
                for c in p.channels.values():
                    if (tag is None or c.info.tag == tag) and not c.connected and not c.done:
                        c.connected, c.started_s = True, time.perf_counter()
                        c.started_unix = time.time()
                        c.next_archive_s = c.started_s + self.checkpoint_s
                        c.spool = p.where / f"{c.info.tag}.spool"
                        c.spool.mkdir(exist_ok=True)
                        c.decoder = StreamDecoder(spool=c.spool)
                        if self.sle is not None:  # each CADU to the SLE users as it comes
                            c.decoder.on_frames = functools.partial(self.sle.offer, c.info.tag)
                        if self.nrt is not None:
                            cut = p.announcement.scene_cut
                            self.nrt.channel(c.info.tag, p.where, cut, c.started_s)
                        return p, c
        return None

    def _framed(self, sock: socket.socket, header: dict, peer: str) -> None:
        claimed = self._claim(str(header.get("pass")), str(header.get("tag")))
        if claimed is None:
            _log.warning(
                "%s: a stream for channel %s of pass %s, which no announced pass awaits "
                "(or another stream holds): refused",
                peer,
                header.get("tag"),
                header.get("pass"),
            )
            sock.sendall(b"NO")
            return
        p, c = claimed
        n_bits = None
        while True:
            data, n_bits = read_piece(sock)
            if data is None:
                break
            c.decoder.feed(data)
            self._checkpoint(p, c)
        self._finish(p, c, n_bits)
        with contextlib.suppress(OSError):
            sock.sendall(b"OK")

    def _multiplexed(self, sock: socket.socket, header: dict, peer: str) -> None:
        """A pass's channels on one connection (:mod:`station.live.wire`)."""
        tags = [str(t) for t in header.get("tags", [])]
        claimed = [self._claim(str(header.get("pass")), t) for t in tags]
        if not tags or any(got is None for got in claimed):
            for got in claimed:  # none taken: the connection is refused whole
                if got is not None:
                    self._unclaim(got[1])
            _log.warning(
                "%s: a connection for channels %s of pass %s, which no announced pass "
                "awaits (or other streams hold): refused", peer, tags, header.get("pass"),
            )  # fmt: skip
            sock.sendall(b"NO")
            return
        open_ = dict(enumerate(got for got in claimed if got is not None))
        try:
            while open_:
                index, data, n_bits = read_channel_piece(sock)
                if index is None:
                    break
                if index not in open_:
                    raise WireError(f"a piece for channel {index} of {len(tags)}, or one ended")
                p, c = open_[index]
                if data is not None:
                    c.decoder.feed(data)
                    self._checkpoint(p, c)
                else:
                    self._finish(p, c, n_bits)
                    del open_[index]
        finally:
            for p, c in open_.values():  # the connection closed before their ends
                self._finish(p, c, None)
        with contextlib.suppress(OSError):
            sock.sendall(b"OK")

    def _unclaim(self, c: _Channel) -> None:
        with self._lock:
            c.decoder.assembler.close()
            if c.spool is not None:
                c.spool.rmdir()
            c.connected = False

    def _raw(self, sock: socket.socket, first: bytes, peer: str) -> None:
        claimed = self._claim(None, None)
        if claimed is None:
            self._unannounced_stream(sock, first, peer)
            return
        p, c = claimed
        data = first
        while data:
            c.decoder.feed(data)
            self._checkpoint(p, c)
            data = sock.recv(RAW_PIECE_BYTES)
        self._finish(p, c, None, raw=True)

    def _unannounced_stream(self, sock: socket.socket, first: bytes, peer: str) -> None:
        """A raw stream no pass awaits: kept as it came, with what its decoding found."""
        with self._lock:
            self._unannounced += 1
            where = self.out / "unannounced"
            where.mkdir(parents=True, exist_ok=True)
            path = where / f"stream_{self._unannounced:03d}.cadu"
        spool = path.with_suffix(".spool")
        spool.mkdir()
        decoder = StreamDecoder(spool=spool)
        with path.open("wb") as f:
            data = first
            while data:
                f.write(data)
                decoder.feed(data)
                data = sock.recv(RAW_PIECE_BYTES)
        found: dict[str, object] = {"peer": peer, **decoder.counts()}
        try:
            found["status"] = decoder.finish().status_counts
        except ReceiverError as exc:
            found["status"] = str(exc)
        decoder.assembler.close()
        spool.rmdir()
        path.with_suffix(".json").write_text(json.dumps(found, indent=1, sort_keys=True))
        _log.warning(
            "%s: a stream no announced pass awaits (%d bytes): kept as %s",
            peer,
            decoder.n_bytes,
            path,
        )

    # -- the archives -------------------------------------------------------------
    def _checkpoint(self, p: _Pass, c: _Channel) -> None:
        """The archive of what has come, every ``checkpoint_s`` at least (module
        docstring); a progress line every second (``-v``)."""
        now = time.perf_counter()
        if now - c.said_s >= PROGRESS_S:
            c.said_s = now
            self._progress(c, now)
        if now < c.next_archive_s:
            return
        try:
            decoded = c.decoder.decoded()
        except ReceiverError:  # no data frame yet: nothing to archive
            c.next_archive_s = now + self.checkpoint_s
            return
        self._write(p, c, decoded, {"complete": False, **self._where(c)})
        took = time.perf_counter() - now
        c.next_archive_s = now + max(self.checkpoint_s, CHECKPOINT_SHARE * took)
        if self.nrt is not None:  # the scenes now complete, made meanwhile
            self.nrt.archived(c.info.tag, c.path, decoded)
        del decoded
        _give_back()

    @staticmethod
    def _progress(c: _Channel, now: float) -> None:
        """A channel's progress line: what has come, how fast, the frames and their
        errors (as ``station run``'s progress says its stages)."""
        counts = c.decoder.counts()
        rate = 8 * counts["bytes"] / max(now - c.started_s, 1e-9) / 1e6
        _log.info(
            "%s: %.1f MB at %.1f Mbit/s, %d frames (%d corrected, %d uncorrectable)",
            c.info.tag,
            counts["bytes"] / 1e6,
            rate,
            counts["frames"],
            counts["corrected"],
            counts["uncorrectable"],
        )

    @staticmethod
    def _where(c: _Channel) -> dict[str, object]:
        return {"bytes_received": c.decoder.n_bytes, "frames_found": c.decoder.n_frames}

    def _write(self, p: _Pass, c: _Channel, decoded: DecodedPass, live: dict | None) -> None:
        ann = p.announcement
        write_l0(
            c.path,
            decoded,
            c.info.bulletins,
            c.info.bulletin_epoch_utc,
            list(c.info.ancillary),
            scenario_name=ann.name,
            provenance=dict(ann.provenance),
            scene_cut=dict(ann.scene_cut) or None,
            live=live,
        )
        c.archives_written += 1

    def _finish(self, p: _Pass, c: _Channel, n_bits: int | None, raw: bool = False) -> None:
        """A channel's stream has ended (``n_bits`` said by the sender) or was cut (None,
        on a framed stream): its last archive, and the pass's report when it is done."""
        c.cut = n_bits is None and not raw
        c.seconds = time.perf_counter() - c.started_s
        try:
            decoded = c.decoder.finish(n_bits)
        except ReceiverError as exc:
            _log.warning("%s: %s: no archive", c.info.tag, exc)
            decoded = None
        c.decoded_s = time.perf_counter() - c.started_s
        if decoded is not None:
            live = {"complete": False, "cut": True, **self._where(c)} if c.cut else None
            self._write(p, c, decoded, live)
            if self.nrt is not None:
                self.nrt.archived(c.info.tag, c.path, decoded, final=True)
                c.products = self.nrt.finish(c.info.tag)
            if c.cut:
                _log.warning("%s: the stream was cut after %d bytes", c.info.tag, c.decoder.n_bytes)
        c.archived_s = time.perf_counter() - c.started_s
        if decoded is not None and self.catalogue:
            self._catalogue(p, c)
        c.catalogued_s = time.perf_counter() - c.started_s
        c.decoder.assembler.close()  # the spool, once archived
        _give_back()
        if c.spool is not None:
            c.spool.rmdir()
        if self.sle is not None:
            self.sle.flush()
        with self._lock:
            c.done = True
            if p.done:
                self._report(p)
                self.passes_done.append(p.where)
            self.changed.notify_all()

    def _catalogue(self, p: _Pass, c: _Channel) -> None:
        """The channel's archive (its pass and scenes, one transaction) and the products
        made while it went on (one each) in the station's catalogue
        (``<out>/catalogue.sqlite``); a failure is said, not raised."""
        from station.archive_catalogue import CATALOGUE_FILE, Catalogue, add_archive, add_products

        try:
            with Catalogue(self.out / CATALOGUE_FILE) as cat:
                add_archive(cat, c.path)
                add_products(cat, [p.where / str(m["file"]) for m in c.products])
        except Exception as exc:  # the archive is written; its entry is what failed
            _log.warning("%s: not catalogued: %s", c.info.tag, exc)

    def _report(self, p: _Pass) -> None:
        channels = []
        for c in p.channels.values():
            n = c.decoder.n_bytes
            channels.append(
                {
                    "tag": c.info.tag,
                    "hrv": c.info.hrv,
                    "archive": c.path.name if c.path.is_file() else None,
                    "bytes": n,
                    "seconds": round(c.seconds, 3),
                    "decoded_s": round(c.decoded_s, 3),
                    "archived_s": round(c.archived_s, 3),
                    "catalogued_s": round(c.catalogued_s, 3),
                    "started_unix": round(c.started_unix, 6),
                    "mbit_per_s": round(8 * n / max(c.decoded_s, 1e-9) / 1e6, 2),
                    "line_rate_mbps": c.info.bit_rate_bit_per_s / 1e6,
                    "cut": c.cut,
                    "archives_written": c.archives_written,
                    **c.decoder.counts(),
                    **({"products": c.products} if self.nrt is not None else {}),
                }
            )
        from station.reports import LIVE_PASS

        report = LIVE_PASS.header(**{"pass": p.announcement.name, "channels": channels})
        (p.where / "live.json").write_text(json.dumps(report, indent=1, sort_keys=True))
        _log.info("pass %s received: %s", p.announcement.name, p.where)


def _stop_at_eof(stop: threading.Event) -> None:
    """``stop`` set once standard input ends (whatever it carries is ignored)."""
    with contextlib.suppress(OSError, ValueError):
        while sys.stdin.buffer.read(4096):
            pass
    stop.set()


def _listen(host: str, port: int) -> socket.socket:
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        server.bind((host, port))
    except OSError as exc:
        server.close()
        raise StationError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    server.listen(8)
    server.settimeout(0.2)
    return server


def serve(
    out: Path,
    host: str = "127.0.0.1",
    port: int = 0,
    passes: int | None = None,
    port_file: Path | None = None,
    checkpoint_s: float = CHECKPOINT_S,
    sle: tuple[RafConfig, int, Path | None] | None = None,
    levels: tuple[str, ...] = (),
    warm_first: bool = False,
    until_stdin_closes: bool = False,
) -> list[Path]:
    """Listen on ``host:port`` (0: a free port, written to ``port_file``) and receive
    passes into ``out`` until ``passes`` of them are done (None: until interrupted);
    with ``sle = (config, port, port_file)``, be an SLE RAF provider on that port too
    (:mod:`station.live.raf`); with ``levels``, make each scene's products as soon as its
    lines are in (:mod:`station.live.nrt`); with ``warm_first``, GEO is warmed before the
    port is said (else beside the first pass); with ``until_stdin_closes``, it also stops
    when its standard input ends (the process that started it has closed the pipe, or
    died: a day's front end lives as long as its day). Returns the passes' directories."""
    if levels:
        from levels.options import ProcessingOptions

        ProcessingOptions(levels=levels)  # an unknown level refused before listening
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    provider = RafProvider(sle[0]) if sle is not None else None
    front = FrontEnd(out, checkpoint_s, provider, levels)
    server = _listen(host, port)
    stop = threading.Event()
    sle_server = _listen(host, sle[1]) if sle is not None else None
    warm_up()  # ready when the port is said
    if front.catalogue and warm_first:
        _warm_geo()
    elif front.catalogue:  # meanwhile: a pass's entry is written seconds after it begins
        threading.Thread(target=_warm_geo, daemon=True, name="warm-geo").start()
    if provider is not None and sle_server is not None and sle is not None:
        threading.Thread(
            target=provider.serve_forever, args=(sle_server, stop), daemon=True
        ).start()
        _port_file(sle[2], sle_server.getsockname()[1])
    bound = server.getsockname()[1]
    _port_file(port_file, bound)
    _log.info("station serve: listening on %s:%d, passes into %s", host, bound, out)
    try:
        if until_stdin_closes:
            threading.Thread(target=_stop_at_eof, args=(stop,), daemon=True).start()
        while (passes is None or len(front.passes_done) < passes) and not stop.is_set():
            try:
                sock, addr = server.accept()
            except TimeoutError:
                continue
            sock.settimeout(None)
            peer = f"{addr[0]}:{addr[1]}"
            threading.Thread(target=front.handle, args=(sock, peer), daemon=True).start()
        if provider is not None:
            provider.linger(LINGER_S)  # the users bound get what was received
    finally:
        stop.set()
        server.close()
        if front.nrt is not None:
            front.nrt.close()
        if sle_server is not None:
            sle_server.close()
    return list(front.passes_done)


#: Seconds the server waits, its passes done, for an SLE user still bound to unbind.
LINGER_S = 60.0


def _port_file(path: Path | None, port: int) -> None:
    if path is not None:
        tmp = Path(path).with_suffix(".tmp")
        tmp.write_text(f"{port}\n")
        tmp.replace(path)  # whole or not at all: a script reads it once it exists
