"""Scenes, archives and capacity replications as tasks (``levels.tasks``): on a real Dask
cluster (a scheduler and two workers started here as separate processes by the ``dask``
command line, bound to 127.0.0.1), on a local cluster (``--workers 2``) and in process,
the products are the same bit for bit; a failed task is named and the others finished."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest

from levels.products import is_product_file, product_name
from levels.tasks import scheduler_address
from station.cli import EXIT_BAD_INPUT, EXIT_INTERNAL, main

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "scenarios" / "small_test.toml"
#: The small scene's 300 lines cut into 4 scenes of 75 lines: four tasks per archive.
SCENE_LINES = 75
#: How long the cluster may take to start (a worker imports numpy, numba and h5py), and
#: how long it may take to stop before it is killed.
START_S, STOP_S = 90.0, 10.0

dask_cli = shutil.which("dask", path=str(Path(sys.executable).parent)) or shutil.which("dask")
distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")  # a dependency of distributed


@pytest.fixture(scope="module")
def archives(run_dir, tmp_path_factory) -> Path:
    """Two archives of one small pass (as a campaign has) and the options cutting them
    into four scenes."""
    d = tmp_path_factory.mktemp("archives")
    for name in ("pass_a", "pass_b"):
        shutil.copy(run_dir / "small_test.l0.h5", d / f"{name}.l0.h5")
    (d / "options.toml").write_text(f"[processing]\nscene_lines = {SCENE_LINES}\n")
    return d


@pytest.fixture(scope="module")
def cluster(tmp_path_factory) -> Iterator[str]:
    """A Dask scheduler and two one-thread workers, each its own process, on 127.0.0.1;
    stopped (these processes only, by their ids) when the module's tests end."""
    if dask_cli is None:
        pytest.fail("the dask command line is not installed (the test extra installs it)")
    d = tmp_path_factory.mktemp("cluster")
    file = d / "scheduler.json"
    # one core per worker for numba and for BLAS, as Dask's nanny would set (without it,
    # OpenBLAS threads of two workers spin against each other: 3× slower)
    threads = {k: "1" for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
    env = {**os.environ, **threads, "PYTHONUNBUFFERED": "1"}
    env.pop("DASK_SCHEDULER_ADDRESS", None)
    logs = [open(d / f"{k}.log", "w") for k in ("scheduler", "worker0", "worker1")]
    common = ["--host", "127.0.0.1", "--no-dashboard", "--dashboard-address", "127.0.0.1:0"]
    procs = [
        subprocess.Popen(
            [dask_cli, "scheduler", "--port", "0", "--scheduler-file", str(file), *common],
            env=env,
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        )
    ]
    try:
        deadline = time.monotonic() + START_S
        while not file.is_file() and time.monotonic() < deadline:
            assert procs[0].poll() is None, (d / "scheduler.log").read_text()
            time.sleep(0.2)
        assert file.is_file(), "the scheduler did not start in time"
        for k in (1, 2):
            procs.append(
                subprocess.Popen(
                    [
                        dask_cli,
                        "worker",
                        "--scheduler-file",
                        str(file),
                        "--nthreads",
                        "1",
                        "--no-nanny",
                        "--name",
                        f"worker{k - 1}",
                        *common,
                    ],
                    env=env,
                    stdout=logs[k],
                    stderr=subprocess.STDOUT,
                )
            )
        address = json.loads(file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        with distributed.Client(address, timeout=START_S) as client:
            client.wait_for_workers(2, timeout=START_S)
        for p in procs:  # every port these processes listen on is this machine's only
            listening = [
                c.laddr.ip
                for c in psutil.Process(p.pid).net_connections("inet")
                if c.status == psutil.CONN_LISTEN
            ]
            assert listening and set(listening) == {"127.0.0.1"}, listening
        yield address
    finally:
        # only the processes started here, by their ids: the workers, then the scheduler
        # (a worker whose scheduler left first may hang in its farewell)
        for group in (procs[1:], procs[:1]):
            for p in group:
                p.terminate()
            for p in group:
                try:
                    p.wait(timeout=STOP_S)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(timeout=STOP_S)
        for f in logs:
            f.close()


def _campaign(archives: Path, out: Path, *extra: str) -> tuple[int, dict]:
    code = main(
        [
            "campaign",
            str(archives),
            "--options",
            str(archives / "options.toml"),
            "--out",
            str(out),
            "--quiet",
            *extra,
        ]
    )
    return code, json.loads((out / "campaign.json").read_text())


def _products(out: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(out)): p.read_bytes()
        for p in sorted(out.rglob("*"))
        if is_product_file(p)
    }


def test_products_are_bit_for_bit_the_same_wherever_they_are_made(
    run_dir, archives, cluster, tmp_path, capsys, monkeypatch
) -> None:
    code, alone = _campaign(archives, tmp_path / "in_process")
    assert code == 0 and alone["workers"] == 1
    reference = _products(tmp_path / "in_process")
    # 2 archives × 4 scenes × 3 levels (1A, 1B, 2A)
    assert len(reference) == 24 and alone["summary"]["scenes"] == 8

    code, remote = _campaign(archives, tmp_path / "cluster", "--scheduler", cluster)
    assert code == 0 and remote["workers"] == 2
    assert _products(tmp_path / "cluster") == reference

    # the usual Dask environment variable instead of --scheduler: the address every
    # command's runner asks for (levels.tasks.dask_runner) is the variable's
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster)
    assert scheduler_address() == cluster and scheduler_address("tcp://x:1") == "tcp://x:1"
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")

    # a local cluster of two worker processes, started and stopped by the command: on one
    # of the archives (the same code path, half the work: the suite's time)
    one = tmp_path / "one_archive"
    one.mkdir()
    for name in ("options.toml", "pass_a.l0.h5"):
        shutil.copy(archives / name, one / name)
    first = {k: v for k, v in reference.items() if "pass_a" in k}
    assert len(first) == 12

    code, local = _campaign(one, tmp_path / "local", "--workers", "2")
    assert code == 0 and local["workers"] == 2
    assert _products(tmp_path / "local") == first

    # and a whole run through the cluster: station compare finds nothing, nor does cmp
    run = tmp_path / "run"
    argv = ["run", str(SMALL), "--out", str(run), "--quiet", "--no-quicklooks"]
    assert main([*argv, "--scheduler", cluster]) == 0
    assert main(["compare", str(run_dir), str(run)]) == 0
    assert _products(run) == _products(run_dir)
    capsys.readouterr()


def test_a_failed_scene_is_named_and_the_others_are_finished(
    archives, cluster, tmp_path, capsys
) -> None:
    """A flipped bit in the counts' second chunk (rows 256–299): only scene 3 (rows
    225–299) of that archive reads it; the campaign names it and makes everything else."""
    d = tmp_path / "archives"
    d.mkdir()
    shutil.copy(archives / "options.toml", d)
    shutil.copy(archives / "pass_a.l0.h5", d)
    bad = d / "pass_z.l0.h5"
    shutil.copy(archives / "pass_a.l0.h5", bad)
    with h5py.File(bad) as f:
        ds = f["bands/P/counts"]
        assert ds.chunks[0] == 256, "the damage below is placed for 256-row chunks"
        info = ds.id.get_chunk_info(1)
    data = bytearray(bad.read_bytes())
    data[info.byte_offset + 11] ^= 0x10
    bad.write_bytes(bytes(data))

    code, report = _campaign(d, tmp_path / "out", "--scheduler", cluster)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == EXIT_BAD_INPUT
    assert len(err) == 1 and "pass_z-s003" in err[0] and "checksum" in err[0]
    entries = {a["name"]: a for a in report["archives"]}
    assert entries["pass_a"]["status"] == "ok" and entries["pass_a"]["scenes"] == 4
    z = entries["pass_z"]
    assert z["status"] == "failed" and z["kind"] == "bad input"
    assert z["failed_scenes"] == ["pass_z-s003"] and z["scenes"] == 3
    made = sorted(p.name for p in (tmp_path / "out" / "pass_z").iterdir() if is_product_file(p))
    assert made == sorted(
        product_name("pass_z", k, lv, on_map=lv == "2A")
        for k in range(3)
        for lv in ("1A", "1B", "2A")
    )


def test_a_bug_in_one_scene_is_raised_after_the_others(archives, tmp_path, monkeypatch) -> None:
    """In process: the bug is raised as itself, its task named, once the other scenes are
    made; the campaign reports it as an internal error (exit 3)."""
    import levels.process

    real = levels.process.make_scene

    def buggy(ctx, scene):
        if scene.cut.index == 1:
            raise ZeroDivisionError("a bug")
        return real(ctx, scene)

    monkeypatch.setattr(levels.process, "make_scene", buggy)
    code, report = _campaign(archives, tmp_path / "out")
    assert code == EXIT_INTERNAL
    entry = report["archives"][0]
    assert entry["kind"] == "internal error" and entry["failed_scenes"] == ["pass_a-s001"]
    assert "ZeroDivisionError" in entry["reason"] and "ZeroDivisionError" in entry["traceback"]
    assert entry["scenes"] == 3


def _stamp() -> int:
    return time.perf_counter_ns()


def test_a_task_submitted_again_runs_again(cluster) -> None:
    """A runner that makes the same pass twice (a benchmark, a library caller) submits the
    same task names twice: each submission must run, not stand for the one before (whose
    release is still on its way to the scheduler when the next is submitted)."""
    from levels.tasks import DaskRunner

    with distributed.Client(cluster, timeout=START_S) as client:
        runner = DaskRunner(client)
        stamps = []
        for _ in range(5):
            [(_, stamp)] = runner.completed([runner.submit("pass-s000", _stamp)])
            stamps.append(stamp)
    assert len(set(stamps)) == len(stamps), stamps


def test_no_scheduler_answering_is_bad_input(archives, monkeypatch, tmp_path, capsys) -> None:
    import levels.tasks

    monkeypatch.setattr(levels.tasks, "CONNECT_TIMEOUT_S", 1.0)
    nobody = "tcp://127.0.0.1:9"  # the discard port: nothing listens there
    code = main(["campaign", str(archives), "--out", str(tmp_path), "--scheduler", nobody])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and err.count("\n") == 1 and nobody in err
    assert not (tmp_path / "campaign.json").exists()


def test_capacity_sweeps_on_the_cluster_are_those_in_process(cluster, tmp_path, capsys) -> None:
    """Every replication of every sweep value is a task; each draws its own streams."""
    cuiaba = ROOT / "scenarios" / "capacity" / "cuiaba.toml"
    scn = tmp_path / "short.toml"
    text = cuiaba.read_text().replace("days = 365.0", "days = 20.0")
    scn.write_text(
        text.replace(
            'file = "service_times.json"', f'file = "{cuiaba.parent / "service_times.json"}"'
        )
    )
    base = ["capacity", str(scn), "--replications", "2", "--no-plots", "--json"]
    base += ["--sweep", "resources.cor_workers=1,2"]
    assert main([*base, "--out", str(tmp_path / "a")]) == 0
    assert main([*base, "--out", str(tmp_path / "b"), "--scheduler", cluster]) == 0
    capsys.readouterr()
    a = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert [r["value"] for r in a["runs"]] == ["1", "2"]
    assert (tmp_path / "a" / "summary.json").read_bytes() == (
        tmp_path / "b" / "summary.json"
    ).read_bytes()


def test_a_day_runs_its_orders_on_the_clusters_workers(cluster, tmp_path, monkeypatch, capsys):
    """``station day --scheduler``: the reduced day's passes emulated and its orders made by
    the cluster's two workers (their process ids), each product
    catalogued; a scheduler that does not answer is refused in one line, before any work."""
    from _tiny_day import tiny_day_file
    from distributed import Client

    import station.day.pool
    from station.day.run import read_events

    path = tiny_day_file(tmp_path)
    out = tmp_path / "day"
    argv = ["day", str(path), "--no-calibrate", "-q", "--json"]
    assert main([*argv, "--scheduler", cluster, "--out", str(out)]) == 0
    report = json.loads(capsys.readouterr().out)
    c = report["counts"]
    assert c["made"] == c["orders_in_window"] > 0 and c["failed"] == c["made_twice"] == 0
    assert report["workers"] == 2  # the cluster's threads
    with Client(cluster, timeout=30) as client:
        workers = set(client.run(os.getpid).values())
    made_by = {e["pid"] for e in read_events(out / "events.jsonl") if e["event"] == "made"}
    assert made_by and made_by <= workers  # no local pool: every product the cluster's
    monkeypatch.setattr(station.day.pool, "CONNECT_TIMEOUT_S", 1.0)
    nobody = "tcp://127.0.0.1:9"  # the discard port: nothing listens there
    assert main([*argv, "--scheduler", nobody, "--out", str(tmp_path / "no")]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and nobody in err and not (tmp_path / "no").exists()
