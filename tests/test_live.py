"""The station live (issue 59): the receiver on a stream as it arrives is the receiver on
the recorded pass, array for array, wherever the stream is cut into pieces; ``station
serve`` fed by ``station transmit`` writes the archive ``station run`` writes, byte for
byte, for a poor channel and for a twin pass's two channels; a server killed mid-pass
leaves a readable archive saying where it stopped; bad streams are said and kept.

Every server here is a ``station serve`` this module starts, on 127.0.0.1 and a free port
(``--port 0 --port-file``), bounded in time and stopped by its process id."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
NOISY = ROOT / "scenarios" / "noisy_channel.toml"
#: How long a server may take to start (a fresh interpreter imports numpy, h5py, numba),
#: and how long a whole pass may take to arrive here.
START_S, PASS_S = 60.0, 120.0
#: A twin pass's two channels, reduced: HRV1 in P and HRV2 in XS on a poor channel.
TWIN = """
name = "twin_live"
seed = 5
[[instrument]]
hrv = 1
mode = "P"
twin = true
n_detectors = 200
n_lines = 400
[[instrument]]
hrv = 2
mode = "XS"
twin = true
n_detectors = 100
n_lines = 200
[downlink]
bit_rate_mbps = 1.0
preamble_s = 0.1
postamble_s = 0.1
[channel]
ber = 1e-5
reorder_fraction = 0.01
[processing]
levels = ["1A"]
"""


@contextlib.contextmanager
def serving(where: Path, *extra: str) -> Iterator[tuple[subprocess.Popen, int]]:
    """``station serve`` in a process of its own on a free port of 127.0.0.1; stopped
    (by its id) when the block ends, whatever happened."""
    port_file = where / "port"
    cmd = [sys.executable, "-m", "station.cli", "serve", "--port", "0"]
    cmd += ["--port-file", str(port_file), "--out", str(where / "served"), *extra]
    log = (where / "serve.log").open("w")
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=where)
    try:
        deadline = time.monotonic() + START_S
        while not port_file.is_file():
            assert proc.poll() is None, (where / "serve.log").read_text()
            assert time.monotonic() < deadline, "the server did not start"
            time.sleep(0.05)
        yield proc, int(port_file.read_text())
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
        log.close()


def _transmit(
    scenario: Path, port: int, speed: str = "max", *more: str
) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "station.cli", "transmit", str(scenario)]
    cmd += ["--to", f"127.0.0.1:{port}", "--speed", speed, "--json", *more]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=PASS_S, check=False)


def _run(scenario: Path, out: Path) -> Path:
    from station.cli import main

    assert main(["run", str(scenario), "--out", str(out), "-q", "--no-quicklooks"]) == 0
    return out


@pytest.fixture(scope="module")
def noisy_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``station run`` of the poor channel: the file route's archive."""
    return _run(NOISY, tmp_path_factory.mktemp("noisy") / "run")


def test_the_stream_decoder_is_the_receiver_wherever_the_stream_is_cut() -> None:
    """The poor channel's stream (BER 1e-4, bursts, fades that drop the lock, a replay
    overlap, reordering) fed in pieces of 1 byte to 200 kB (its first 4 kB byte by byte,
    markers cut anywhere): every array of the pass the
    receiver makes of the whole recording, and a pass so far at any point before."""
    from station.chain.session import downlink
    from station.loader import load_scenario
    from station.spacecraft.emulator import emulate_pass
    from station.srrs.receiver import receive
    from station.srrs.stream import StreamDecoder

    rx = downlink(emulate_pass(load_scenario(NOISY))[0]).reception
    whole = receive(rx.stream, rx.n_bits)
    rng = np.random.default_rng(59)
    for sizes in ((1, 7), (1, 200_000), (65_536, 65_537)):
        d = StreamDecoder()
        i, looked = 0, False
        while i < rx.stream.size:
            # byte by byte at first, then pieces of the sizes (past 20 kB: at least 1 kB)
            low, high = sizes if i < 20_000 else (max(sizes[0], 1000), max(sizes[1], 1001))
            n = 1 if i < 4096 else int(rng.integers(low, high))
            d.feed(rx.stream[i : i + n])
            i += n
            if i > rx.stream.size // 2 and not looked:  # a pass so far: its first frames
                looked = True
                early = d.decoded()
                assert 0 < early.frame_status.size < whole.frame_status.size
                head = early.frame_bit_offset.size
                assert np.array_equal(early.frame_bit_offset, whole.frame_bit_offset[:head])
        got = d.finish(rx.n_bits)
        for f in dataclasses.fields(whole):
            a, b = getattr(whole, f.name), getattr(got, f.name)
            if isinstance(a, tuple):
                assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)), f.name
            elif isinstance(a, np.ndarray):
                assert np.array_equal(a, b), f.name
            else:
                assert a == b, f.name
        assert d.counts()["frames"] == whole.frame_status.size


def test_a_served_pass_is_the_runs_archive_byte_for_byte(noisy_run: Path, tmp_path: Path) -> None:
    """``station serve --passes 1`` and ``station transmit --speed max``: the archive is
    the file route's, byte for byte; the pass's report says what came."""
    with serving(tmp_path, "--passes", "1") as (proc, port):
        sent = _transmit(NOISY, port)
        assert sent.returncode == 0, sent.stderr
        assert proc.wait(PASS_S) == 0, (tmp_path / "serve.log").read_text()
    served = tmp_path / "served" / "noisy_channel"
    a = (noisy_run / "noisy_channel.l0.h5").read_bytes()
    assert (served / "noisy_channel.l0.h5").read_bytes() == a
    report = json.loads((served / "live.json").read_text())
    (channel,) = report["channels"]
    said = json.loads(sent.stdout)["channels"][0]
    assert channel["bytes"] == said["bytes"] and not channel["cut"]
    assert channel["frames"] > 0 and channel["uncorrectable"] > 0  # a poor channel
    from station.archive_catalogue import CATALOGUE_FILE, Catalogue, Query
    from station.cli import main

    assert main(["compare", str(noisy_run), str(served), "-q"]) == 0  # by their archives
    with Catalogue(tmp_path / "served" / CATALOGUE_FILE) as cat:  # the pass catalogued
        assert cat.has("spot-passes", "noisy_channel")
        assert cat.count(Query(levels=("0",))) >= 1  # and its scenes


def test_a_twin_pass_on_its_two_channels(tmp_path: Path) -> None:
    """Both HRVs of a twin pass, each on its channel at once, then both multiplexed on one
    connection (``[downlink] one_connection``): both archives are the run's, each time."""
    scenario = tmp_path / "twin_live.toml"
    scenario.write_text(TWIN)
    run = _run(scenario, tmp_path / "run")
    with serving(tmp_path, "--passes", "2") as (proc, port):
        sent = _transmit(scenario, port)
        assert sent.returncode == 0, sent.stderr
        assert json.loads(sent.stdout)["connections"] == 2
        together = _transmit(scenario, port, "max", "--one-connection")
        assert together.returncode == 0, together.stderr
        assert json.loads(together.stdout)["connections"] == 1
        assert proc.wait(PASS_S) == 0, (tmp_path / "serve.log").read_text()
    for where in ("twin_live", "twin_live_2"):
        for tag in ("twin_live_hrv1", "twin_live_hrv2"):
            served = tmp_path / "served" / where / f"{tag}.l0.h5"
            assert served.read_bytes() == (run / f"{tag}.l0.h5").read_bytes(), (where, tag)
        assert not list((tmp_path / "served" / where).glob("*.spool"))  # let go once archived


def test_a_server_killed_mid_pass_leaves_a_readable_archive(
    noisy_run: Path, tmp_path: Path
) -> None:
    """Killed while the pass arrives (4× its line rate: about 3 s), the server leaves the
    archive of what had come, readable, its ``live`` attribute saying so; the pass sent
    again to a fresh server is the whole pass again."""
    import h5py

    from levels.readers.l0 import read_l0

    first = tmp_path / "first"
    first.mkdir()
    with serving(first, "--checkpoint", "0.2") as (proc, port):
        cmd = [sys.executable, "-m", "station.cli", "transmit", str(NOISY)]
        sender = subprocess.Popen([*cmd, "--to", f"127.0.0.1:{port}", "--speed", "4"])
        archive = first / "served" / "noisy_channel" / "noisy_channel.l0.h5"
        deadline = time.monotonic() + PASS_S
        while not archive.is_file():
            assert time.monotonic() < deadline and sender.poll() is None
            time.sleep(0.05)
        time.sleep(0.5)
        os.kill(proc.pid, signal.SIGKILL)  # the server this test started, by its id
        proc.wait(10)
        sender.wait(PASS_S)  # the link broke under it: it says so and ends
    assert sender.returncode == 2
    partial = read_l0(archive)
    with h5py.File(archive) as f:
        live = json.loads(f.attrs["live"])
    assert live["complete"] is False and 0 < live["bytes_received"]
    whole = read_l0(noisy_run / "noisy_channel.l0.h5")
    # the lines not yet arrived are there, and not valid: nothing missing presented as data
    got, all_ = (a.bands["P"].pixel_valid().sum() for a in (partial, whole))
    assert 0 < got < all_
    again = tmp_path / "again"
    again.mkdir()
    with serving(again, "--passes", "1") as (proc, port):
        assert _transmit(NOISY, port).returncode == 0
        assert proc.wait(PASS_S) == 0
    served = again / "served" / "noisy_channel" / "noisy_channel.l0.h5"
    assert served.read_bytes() == (noisy_run / "noisy_channel.l0.h5").read_bytes()


def test_bad_streams_are_said_and_kept(tmp_path: Path) -> None:
    """Garbage with no marker, and a stream cut mid-frame, on raw connections no pass
    awaits: each kept as it came with what its decoding found; a stream for a channel no
    pass announced refused, and so is a connection for several; the server goes on."""
    from station.live.wire import CHANNEL, MULTIPLEX, pack_header

    rng = np.random.default_rng(3)
    with serving(tmp_path) as (proc, port):
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(rng.integers(0, 256, 300_000, dtype=np.uint8).tobytes())
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(pack_header(CHANNEL, {"pass": "nobody", "tag": "x"}))
            assert s.recv(2) == b"NO"
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(pack_header(MULTIPLEX, {"pass": "nobody", "tags": ["x", "y"]}))
            assert s.recv(2) == b"NO"
        kept = tmp_path / "served" / "unannounced" / "stream_001.json"
        deadline = time.monotonic() + 30
        while not kept.is_file():
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert proc.poll() is None  # still serving
    found = json.loads(kept.read_text())
    # random bits hold a false marker every 770 000 bits or so (3 errors allowed in 32):
    # found, none decoded
    assert found["bytes"] == 300_000 and found["uncorrectable"] == found["frames"] < 10
    assert "no data frame" in found["status"]
    assert kept.with_suffix(".cadu").stat().st_size == 300_000  # nothing received lost
    log = (tmp_path / "serve.log").read_text()
    assert "no announced pass awaits" in log


def test_a_port_in_use_and_bad_addresses_are_one_line(tmp_path: Path, capsys) -> None:
    from station.cli import EXIT_BAD_INPUT, main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        code = main(["serve", "--port", str(port), "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and f"127.0.0.1:{port}" in err and err.count("\n") == 1
    for to, said in (("nowhere", "HOST:PORT"), ("127.0.0.1:1", "no front end answers")):
        assert main(["transmit", str(NOISY), "--to", to, "--speed", "max"]) == EXIT_BAD_INPUT
        assert said in capsys.readouterr().err
    assert main(["transmit", str(NOISY), "--to", "127.0.0.1:1", "--speed", "0"]) == 2
    assert "--speed 0" in capsys.readouterr().err


def test_the_warm_up_stream_decodes() -> None:
    """The piece of a stream the front end decodes before it listens
    (``station/data/warmup.cadu``) holds fill and data frames that decode clean."""
    from station.live.frontend import WARM_UP_STREAM
    from station.srrs.stream import StreamDecoder

    d = StreamDecoder()
    d.feed(WARM_UP_STREAM.read_bytes())
    counts = d.finish().status_counts
    assert counts["ok"] >= 5 and counts["fill"] >= 100 and counts["uncorrectable"] == 0


#: A pass of four scenes (300 detectors, 1200 lines of 30 ms: 36 s of imaging).
FOUR = """
name = "four_scenes"
seed = 7
[instrument]
n_detectors = 300
n_lines = 1200
[downlink]
bit_rate_mbps = 1.25
preamble_s = 0.5
postamble_s = 0.5
[processing]
levels = ["1A", "2A"]
"""
#: A scene made while the pass arrives, against the archive route's: its line clock and
#: attitude fitted over the lines in so far, so a count may differ by one where the
#: resampling falls on the other side of a rounding (measured 99.6–100 % equal, 1 at most).
NRT_SAME_SHARE, NRT_MAX_COUNTS = 0.99, 1


def test_products_while_the_pass_goes_on(tmp_path: Path) -> None:
    """``station serve --levels 1A,2A``, a four-scene pass at 4× its line rate: every
    scene's 1A and 2A made as its lines come in, the first scene's 2A before the stream
    ends (LOS), each with its latency; each on the archive route's grid, its counts
    within one of that route's."""
    from levels.products import read_product

    scenario = tmp_path / "four_scenes.toml"
    scenario.write_text(FOUR)
    run = _run(scenario, tmp_path / "run")
    with serving(tmp_path, "--passes", "1", "--levels", "1A,2A", "--checkpoint", "0.3") as (
        proc,
        port,
    ):
        assert _transmit(scenario, port, "4").returncode == 0
        assert proc.wait(PASS_S) == 0, (tmp_path / "serve.log").read_text()
    served = tmp_path / "served" / "four_scenes"
    (channel,) = json.loads((served / "live.json").read_text())["channels"]
    made = {(p["scene"], p["level"]): p for p in channel["products"]}
    assert set(made) == {(k, lv) for k in range(4) for lv in ("1A", "2A")}
    assert made[(0, "2A")]["before_los"] and made[(1, "2A")]["before_los"]
    assert all(p["latency_s"] is not None and p["latency_s"] >= 0 for p in made.values())
    for k in range(4):
        a, b = (read_product(d / f"four_scenes_s{k:03d}_2A.nc") for d in (run, served))
        assert a.map_grid == b.map_grid
        valid = a.bands["P"].valid & b.bands["P"].valid
        diff = np.abs(a.bands["P"].image.astype(int) - b.bands["P"].image.astype(int))[valid]
        assert (diff == 0).mean() >= NRT_SAME_SHARE and diff.max() <= NRT_MAX_COUNTS, k


def test_a_stream_cut_mid_frame_is_archived_as_cut(tmp_path: Path) -> None:
    """A pass announced, its channel's stream closed half way, mid-frame, without its end:
    the archive of what came is written, its ``live`` attribute saying the stream was cut;
    the pass is done and the server ends as asked."""
    import h5py

    from levels.readers.l0 import read_l0
    from station.live.sender import emulated_streams
    from station.live.wire import CHANNEL, pack_header, piece

    announcement, (stream,), _ = emulated_streams(NOISY)
    half = stream.data[: stream.data.size // 2 + 517].tobytes()  # mid-frame
    with serving(tmp_path, "--passes", "1") as (proc, port):
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(announcement.message())
            assert s.recv(2) == b"OK"
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(pack_header(CHANNEL, {"pass": announcement.name, "tag": stream.tag}))
            s.sendall(piece(half))
        assert proc.wait(PASS_S) == 0
    archive = tmp_path / "served" / "noisy_channel" / "noisy_channel.l0.h5"
    with h5py.File(archive) as f:
        live = json.loads(f.attrs["live"])
    assert live["cut"] is True and live["bytes_received"] == len(half)
    assert 0 < read_l0(archive).bands["P"].pixel_valid().mean() < 0.75
    report = json.loads((archive.parent / "live.json").read_text())
    assert report["channels"][0]["cut"] is True
