"""A day's front end: ``station serve`` in a process of its own on a free port of 127.0.0.1,
warm before it says its port (``--warm-first``), living until the process that started it
closes its input (``--until-stdin-closes``): the day's, or a calibration's."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from pathlib import Path

from station.errors import StationError

__all__ = ["FRONT_END_START_S", "launch_front_end", "port_of", "stop_front_end"]

#: Wall seconds the front end has to say its port.
FRONT_END_START_S = 120.0


def launch_front_end(out: Path) -> subprocess.Popen:
    """The day's front end started (``station serve --warm-first``): it warms while the
    passes are emulated, and says its port once warm (:func:`port_of`)."""
    port_file = out / "serve.port"
    port_file.unlink(missing_ok=True)
    log = (out / "serve.log").open("a")
    cmd = [
        sys.executable,
        "-m",
        "station.cli",
        "serve",
        "--out",
        str(out / "archive"),
        "--port",
        "0",
        "--port-file",
        str(port_file),
        "--warm-first",
        "--until-stdin-closes",
    ]
    # it lives until the day closes its input (or dies): its exit, which frees a process
    # of several hundred MB, must not fall beside the day's last jobs
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.PIPE)
    log.close()
    return proc


def port_of(proc: subprocess.Popen, out: Path) -> int:
    """The port the front end :func:`launch_front_end` started listens on, once said."""
    port_file = out / "serve.port"
    deadline = time.time() + FRONT_END_START_S
    while not port_file.is_file():
        if proc.poll() is not None:
            raise StationError(f"the front end exited ({proc.returncode}); see {out}/serve.log")
        if time.time() > deadline:
            proc.kill()
            proc.wait()
            raise StationError(f"the front end said no port in {FRONT_END_START_S:.0f} s")
        time.sleep(0.05)
    return int(port_file.read_text())


def stop_front_end(proc: subprocess.Popen | None, timeout_s: float = 30.0) -> None:
    """The front end this day started, ended: told by its input closed, then waited for
    (its last archive written), then ended by signal if it has not gone in ``timeout_s``."""
    if proc is None:
        return
    if proc.stdin is not None:
        with contextlib.suppress(OSError):
            proc.stdin.close()
    try:
        proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        proc.terminate()
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
