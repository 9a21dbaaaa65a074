"""``station serve`` and ``station transmit``: the station live (``docs/live.md``)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from station.cli._options import add_json, emit
from station.errors import StationError

if TYPE_CHECKING:
    from station.cli._options import Subparsers
    from station.live.raf import RafConfig

__all__ = ["register"]


def register(sub: Subparsers) -> None:
    s = sub.add_parser(
        "serve",
        help="the front end as a server: receive passes from a socket, archive them live",
        description="Listen on a TCP port for passes (station transmit, or any raw CADU "
        "stream) and receive them as they arrive: frame sync, derandomisation, "
        "Reed-Solomon, CRC and the accounting on each piece of the stream, each pass's L0 "
        "archive written on the fly into OUT/<pass>/ (a killed server leaves a readable "
        "archive of everything received), and the same archive as station run's at the "
        "stream's end.",
    )
    s.add_argument("--host", default="127.0.0.1", help="the address to listen on (127.0.0.1)")
    s.add_argument("--port", type=int, default=0, help="the port (0: a free one; --port-file)")
    s.add_argument("--port-file", metavar="F", help="write the port listened on to F")
    s.add_argument("--out", required=True, help="the directory that receives the passes")
    s.add_argument(
        "--passes", type=int, metavar="N", help="exit after N passes (default: until Ctrl-C)"
    )
    s.add_argument(
        "--checkpoint",
        type=float,
        default=2.0,
        metavar="S",
        help="seconds between two archives written while a stream arrives (2)",
    )
    s.add_argument(
        "--levels",
        help="comma-separated levels (e.g. 1A,2A) made of each scene as soon as its lines "
        "are in, while the pass goes on",
    )
    s.add_argument(
        "--warm-first",
        action="store_true",
        help="warm GEO (the catalogue's placing of scenes) before the port is said, not "
        "beside the first pass (a day's front end, whose first pass may come at once)",
    )
    s.add_argument(
        "--until-stdin-closes",
        action="store_true",
        help="also stop when standard input ends (a front end that lives as long as the "
        "process that started it, as a station day's does)",
    )
    _add_sle(s)
    add_json(s)
    s.set_defaults(func=_serve)

    t = sub.add_parser(
        "transmit",
        help="send a pass to a front end at its line rate (the emulator's sender)",
        description="Emulate a pass's scenario and send it through its downlink and "
        "channel, as station run does, to a front end (station serve) over TCP: each HRV "
        "on its channel, at --speed times its line rate (1: real time; max: as fast as "
        "the link takes). A .cadu file is replayed as it was recorded (a raw stream).",
    )
    t.add_argument("source", help="a pass's scenario (.toml) or a recorded stream (.cadu)")
    t.add_argument("--to", required=True, metavar="HOST:PORT", help="the front end's address")
    t.add_argument(
        "--speed", default="1", help="a multiple of the line rate (1: real time), or max"
    )
    t.add_argument(
        "--one-connection",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the pass's channels multiplexed on one connection, or each on its own "
        "(default: as the scenario's [downlink] one_connection says)",
    )
    add_json(t)
    t.set_defaults(func=_transmit, levels=None)


def _add_sle(s: argparse.ArgumentParser) -> None:
    """The SLE Return All Frames provider's options (``station.live.raf``)."""
    g = s.add_argument_group("SLE Return All Frames (CCSDS 911.1 over ISP1)")
    g.add_argument(
        "--sle-port", type=int, metavar="Q", help="be a RAF provider on port Q (0: free)"
    )
    g.add_argument("--sle-port-file", metavar="F", help="write the SLE port listened on to F")
    g.add_argument(
        "--sle-instance",
        default="sagr=1.spack=1.rsl-fg=1.raf=onlc1",
        help="the service instance (raf=onlc…: online complete; raf=onlt…: online timely)",
    )
    g.add_argument("--sle-provider", default="station", help="the provider's identifier")
    g.add_argument("--sle-user", default="mcs", help="the user's identifier")
    g.add_argument(
        "--sle-auth",
        metavar="USER_HEX[,PROVIDER_HEX]",
        help="check the user's ISP1 credentials against this password (hex), and sign the "
        "returns with the provider's (default: no authentication)",
    )
    g.add_argument(
        "--sle-buffer", type=int, default=100, metavar="N", help="frames per transfer buffer"
    )
    g.add_argument(
        "--sle-latency",
        type=float,
        default=1.0,
        metavar="S",
        help="seconds a frame may wait for its transfer buffer to fill (1)",
    )


def _sle_of(args: argparse.Namespace) -> tuple[RafConfig, int, Path | None] | None:
    from station.live.raf import RafConfig

    if args.sle_port is None:
        return None
    if not 0 <= args.sle_port < 65536:
        raise StationError(f"--sle-port {args.sle_port}: 0 (a free port) to 65535")
    if args.sle_buffer < 1 or not args.sle_latency > 0:
        raise StationError("--sle-buffer at least 1 frame, --sle-latency above 0 s")
    passwords: list[bytes | None] = [None, None]
    if args.sle_auth:
        try:
            for k, p in enumerate(args.sle_auth.split(",")[:2]):
                passwords[k] = bytes.fromhex(p)
        except ValueError:
            raise StationError(f"--sle-auth {args.sle_auth}: passwords in hex") from None
    parts = [p.split("=", 1) for p in args.sle_instance.split(".")]
    if not all(len(p) == 2 and p[0] and p[1] for p in parts):
        raise StationError(f"--sle-instance {args.sle_instance}: expected a=1.b=2…")
    config = RafConfig(
        args.sle_instance, args.sle_provider, args.sle_user, passwords[0], passwords[1],
        args.sle_buffer, args.sle_latency,
    )  # fmt: skip
    where = Path(args.sle_port_file) if args.sle_port_file else None
    return config, args.sle_port, where


def _address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise StationError(f"--to {text}: expected HOST:PORT (e.g. 127.0.0.1:5000)")
    return host, int(port)


def _speed(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not value > 0:
        raise StationError(f"--speed {text}: a positive multiple of the line rate, or max")
    return value


def _serve(args: argparse.Namespace) -> int:
    from station.live.frontend import serve

    if args.passes is not None and args.passes < 1:
        raise StationError(f"--passes {args.passes}: at least 1")
    if not 0 <= args.port < 65536:
        raise StationError(f"--port {args.port}: 0 (a free port) to 65535")
    done = serve(
        Path(args.out),
        args.host,
        args.port,
        args.passes,
        Path(args.port_file) if args.port_file else None,
        args.checkpoint,
        _sle_of(args),
        tuple(v.strip() for v in args.levels.split(",")) if args.levels else (),
        args.warm_first,
        args.until_stdin_closes,
    )
    emit(args, {"passes": [str(p) for p in done]}, lambda d: "\n".join(d["passes"]))
    return 0


def _transmit(args: argparse.Namespace) -> int:
    from station.live.sender import transmit

    host, port = _address(args.to)
    said = transmit(Path(args.source), host, port, _speed(args.speed), args.one_connection)
    emit(args, said, _transmit_text)
    return 0


def _transmit_text(said: dict) -> str:
    lines = [f"{said['pass']}: sent at {said['speed']}× the line rate"]
    for c in said["channels"]:
        rate = 8 * c["bytes"] / max(c["seconds"], 1e-9) / 1e6
        lines.append(
            f"  {c['tag']}: {c['bytes'] / 1e6:.1f} MB in {c['seconds']:.2f} s "
            f"({rate:.1f} Mbit/s; line rate {c['line_rate_mbps']:.1f})"
        )
    return "\n".join(lines)
