"""``station day``: a day's passes sent to a front end on a clock, archived and catalogued,
and its orders processed by a pool of workers, urgent first.

The day's processes, all started and ended by it:

- a front end, ``station serve`` in a process of its own on a free port of 127.0.0.1: it
  receives each pass, archives its channels (ingest) and catalogues their scenes as GEO
  places them (:mod:`station.archive_catalogue`);
- ``workers`` processing workers (``concurrent.futures``, spawned): they emulate the passes
  before the clock starts (the spacecraft is not the station's load), then make the
  ordered products, each from its pass's archive, and catalogue them;
- this process: the clock (station time = ``clock`` × wall time), a sender thread per
  pass at its AOS (:func:`station.live.sender.send_streams`, at ``clock`` times the line
  rate), and the orders: each, at its time, waits for its scene in the catalogue (its
  pass's GEO), then for a worker (urgent first, then by when it became ready).

What happened is kept in ``<out>/events.jsonl`` (one line per event, flushed): a killed day
goes on with ``--resume`` from the catalogue and these events, without sending a pass
archived or making a product catalogued again; the report (:mod:`station.day.report`) is
written at the end. Before the clock and after it, the station's service times are measured
on calibration passes of their own (``service_day.json``): the model is checked with the
machine of the day's own minutes.
"""

from __future__ import annotations

import heapq
import json
import logging
import shutil
import sys
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from station.archive_catalogue import CATALOGUE_FILE, Catalogue
from station.capacity.plan import DayPlan, PlannedOrder, PlannedPass, draw_plan, read_plan
from station.day import work
from station.day.config import DayScenario, with_workers
from station.day.front import launch_front_end, port_of, stop_front_end
from station.day.pool import DayPool, day_pool
from station.errors import StationError

if TYPE_CHECKING:
    from station.live.wire import Announcement

__all__ = ["DAY_FILE", "EVENTS_FILE", "PLAN_FILE", "run_day"]

_log = logging.getLogger(__name__)
PLAN_FILE = "plan.json"
#: The day file, copied into the day's directory.
DAY_FILE = "day.toml"
EVENTS_FILE = "events.jsonl"
#: How often the clock looks at what happened (wall s).
TICK_S = 0.02


@dataclass
class _Order:
    order: PlannedOrder
    l0: Path | None = None
    ready_unix: float | None = None
    state: str = "planned"  # planned, ordered, ready, running, made, not_held, failed


@dataclass
class _State:
    """What the day has done, rebuilt from the events on ``--resume``."""

    sent: set[str] = field(default_factory=set)
    archived: set[str] = field(default_factory=set)
    made: set[str] = field(default_factory=set)
    station_s: float = 0.0


class _Events:
    """``events.jsonl``: one JSON line per event, flushed as it happens."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._f = path.open("a")
        self._lock = threading.Lock()

    def __call__(self, kind: str, **fields: object) -> None:
        with self._lock:
            self._f.write(json.dumps({"event": kind, "unix": time.time(), **fields}) + "\n")
            self._f.flush()

    def close(self) -> None:
        self._f.close()


def read_events(path: Path) -> list[dict]:
    """The events of a day so far (a line cut by a kill is dropped)."""
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def _state_of(events: list[dict]) -> _State:
    st = _State()
    for e in events:
        if e["event"] == "sent":
            st.sent.add(e["pass"])
        elif e["event"] == "archived":
            st.archived.add(e["pass"])
        elif e["event"] == "made":
            st.made.add(e["order"])
        if "station_s" in e:
            st.station_s = max(st.station_s, float(e["station_s"]))
    return st


class Clock:
    """Station time (s from the window's start) on the wall clock, ``rate`` times faster,
    from ``station_s`` now."""

    def __init__(self, rate: float, station_s: float = 0.0) -> None:
        self.rate, self.station0, self.wall0 = rate, station_s, time.time()

    def now(self) -> float:
        return self.station0 + (time.time() - self.wall0) * self.rate

    def wall(self, station_s: float) -> float:
        return self.wall0 + (station_s - self.station0) / self.rate


def prepare(scn: DayScenario, out: Path, resume: bool, local_workers: bool = True) -> DayPlan:
    """The output directory and the day's plan (drawn, or the one a killed day drew); the
    machine's room checked first (the workers' too when they are local)."""
    plan_path = out / PLAN_FILE
    from station.day.preflight import check_room

    if resume:
        if not plan_path.is_file():
            raise StationError(f"--resume: {out} holds no day ({PLAN_FILE} missing)")
        plan = read_plan(plan_path)
        check_room(scn, plan, out, local_workers)
        return plan
    if plan_path.exists():
        raise StationError(
            f"{out} holds a day already: --resume to go on with it, or another --out"
        )
    plan = draw_plan(scn.capacity, scn.day.start_s, scn.day.hours)
    if not plan.passes:
        raise StationError(
            f"no pass images in the window ({scn.day.hours} h from day {scn.day.start_day}, "
            f"{scn.day.start_h} h UTC): move [day] start_day or start_h"
        )
    check_room(scn, plan, out, local_workers)  # before anything is written
    out.mkdir(parents=True, exist_ok=True)
    if scn.source:
        shutil.copyfile(scn.source, out / DAY_FILE)  # what validate reads back
    (out / "passes").mkdir(exist_ok=True)
    for k, p in enumerate(plan.passes):
        text = work.pass_scenario(
            p,
            scn.capacity.seed + scn.day.seed + k,
            scn.day.start_s,
            scn.day.p_detectors,
            scn.day.bit_rate_mbps,
        )
        (out / "passes" / f"{p.name}.toml").write_text(text)
    plan.write(plan_path)
    return plan


class Day:
    """One day on the clock (module docstring)."""

    def __init__(
        self, scn: DayScenario, out: Path, plan: DayPlan, resume: bool, say: bool = True
    ) -> None:
        self.scn, self.out, self.plan, self.say = scn, out, plan, say
        self.state = _state_of(read_events(out / EVENTS_FILE)) if resume else _State()
        self.events = _Events(out / EVENTS_FILE)
        self.catalogue = out / "archive" / CATALOGUE_FILE
        self.passes = {p.name: p for p in plan.passes}
        self.orders = [_Order(o) for o in plan.orders]
        self._ready: list[tuple[int, float, int, _Order]] = []
        self._done: list[tuple[_Order, float, Future, float]] = []
        self._lock = threading.Lock()
        self.failures: list[str] = []
        self.unsent: set[str] = set()  # passes the sender could not send
        self.made_now = 0

    def tell(self, text: str) -> None:
        if self.say:
            print(f"[{self.clock.now() / 3600.0:6.2f} h] {text}", file=sys.stderr, flush=True)

    def run(self, pool: DayPool) -> None:
        day = self.scn.day
        if self.out.joinpath("archive").is_dir():  # a pass cut by a kill is sent again
            for d in (self.out / "archive").iterdir():
                if d.is_dir() and d.name in self.passes and d.name not in self.state.archived:
                    shutil.rmtree(d)
        to_send = [p for p in self.plan.passes if p.name not in self.state.archived]
        end_s = self.plan.hours * 3600.0
        left = [o for o in self.plan.orders if o.order_s < end_s and o.name not in self.state.made]
        if not to_send and not left:  # a whole day resumed: nothing to start
            self.clock = Clock(day.clock, self.state.station_s)
            self.events.close()
            return
        proc = launch_front_end(self.out) if to_send else None
        sent = False  # until the clock runs, the front end has no pass to wait for
        try:
            streams = self._emulate(pool, to_send)
            port = port_of(proc, self.out) if proc is not None else 0
            sent = True
            self.clock = Clock(day.clock, self.state.station_s)
            self.events(
                "start",
                station_s=self.state.station_s,
                resumed=bool(self.state.sent),
                workers=day.workers,
                clock=day.clock,
            )
            self._loop(pool, streams, port)
        finally:
            stop_front_end(proc, 30.0 if sent else 0.0)
        self.events("end", station_s=self.clock.now())
        self.events.close()

    def _emulate(self, pool: DayPool, passes: list[PlannedPass]) -> dict:
        """Each pass to send emulated on the workers, before the clock starts (and every
        worker started and warm)."""
        t0 = time.time()
        futures = {
            p.name: pool.submit(work.emulate, str(self.out / "passes" / f"{p.name}.toml"))
            for p in passes
        }
        for _ in range(self.scn.day.workers):
            pool.submit(time.sleep, 0.2)  # every worker spawned and warm before the clock
        streams = {name: f.result() for name, f in futures.items()}
        if self.say:
            print(
                f"station day: {len(passes)} pass(es) emulated in {time.time() - t0:.1f} s; "
                f"the clock starts ({self.scn.day.clock:g}x)",
                file=sys.stderr,
                flush=True,
            )
        return streams

    def _loop(self, pool: DayPool, streams: dict, port: int) -> None:
        end_s = self.plan.hours * 3600.0
        senders: list[threading.Thread] = []
        pending = [p for p in self.plan.passes if p.name not in self.state.archived]
        waiting = list(self.orders)
        for o in waiting:
            if o.order.name in self.state.made:
                o.state = "made"
        running = 0
        while True:
            now = self.clock.now()
            for p in [p for p in pending if p.aos_s <= now and p.name in streams]:
                ann, chans, one = streams.pop(p.name)
                t = threading.Thread(
                    target=self._send, args=(p, ann, chans, one, port), daemon=True
                )
                t.start()
                senders.append(t)
            for p in list(pending):
                if p.name in self.unsent or self._archived(p):
                    pending.remove(p)
            running -= self._collect()
            self._order_due(now)
            while running < self.scn.day.workers and self._ready:
                _, _, _, o = heapq.heappop(self._ready)
                self._submit(pool, o)
                running += 1
            open_orders = [
                o
                for o in self.orders
                if o.state not in ("made", "not_held", "failed") and o.order.order_s < end_s
            ]
            if now >= end_s and not pending and not open_orders and running == 0:
                break
            time.sleep(TICK_S)
        for t in senders:
            t.join(60.0)

    def _send(self, p: PlannedPass, ann: Announcement, chans: list, one: bool, port: int) -> None:
        from station.live.sender import send_streams

        self.events("sent", **{"pass": p.name}, station_s=self.clock.now())
        self.tell(f"{p.name}: AOS, {len(p.segments)} channel(s) to the front end")
        try:
            send_streams(ann, chans, "127.0.0.1", port, self.scn.day.clock, one)
        except Exception as exc:  # said; its orders are listed as not held
            self.failures.append(f"{p.name}: not sent: {exc}")
            self.unsent.add(p.name)

    def _archived(self, p: PlannedPass) -> bool:
        """Whether the front end has archived and catalogued the pass (its report is
        written once every channel's archive is catalogued)."""
        report = self.out / "archive" / p.name / "live.json"
        if not report.is_file():
            return False
        try:
            live = json.loads(report.read_text())
        except json.JSONDecodeError:
            return False  # being written
        self.state.archived.add(p.name)
        self.events(
            "archived", **{"pass": p.name}, station_s=self.clock.now(), channels=live["channels"]
        )
        self.tell(f"{p.name}: archived and catalogued")
        return True

    def _order_due(self, now: float) -> None:
        """Orders whose time has come: ordered, then ready once their scene is in the
        catalogue (its pass's GEO done), or listed when the catalogue does not hold it."""
        ids: set[str] | None = None
        for o in self.orders:
            if o.state == "planned" and o.order.order_s <= now:
                o.state = "ordered"
                self.events("ordered", order=o.order.name, station_s=now)
            if o.state == "ordered" and o.order.pass_name in self.unsent:
                o.state = "not_held"
                self.events("not_held", order=o.order.name, scene=None, station_s=now)
                continue
            if o.state != "ordered" or o.order.pass_name not in self.state.archived:
                continue
            if ids is None:
                with Catalogue(self.catalogue) as cat:
                    ids = cat.ids()
            p = self.passes[o.order.pass_name]
            sid = work.scene_id(p, o.order.hrv, o.order.scene)
            if sid not in ids:
                o.state = "not_held"
                self.events("not_held", order=o.order.name, scene=sid, station_s=now)
                self.tell(f"{o.order.name}: scene {sid} is not in the catalogue; listed")
                continue
            o.state, o.ready_unix = "ready", time.time()
            tag = work.channel_tag(p, o.order.hrv)
            o.l0 = self.out / "archive" / p.name / f"{tag}.l0.h5"
            self.events("ready", order=o.order.name, station_s=now)
            heapq.heappush(
                self._ready, (0 if o.order.urgent else 1, o.ready_unix, self.orders.index(o), o)
            )

    def _submit(self, pool: DayPool, o: _Order) -> None:
        o.state = "running"
        p = self.passes[o.order.pass_name]
        out = self.out / "products" / p.name
        t = time.time()
        self.events("dispatched", order=o.order.name, station_s=self.clock.now())
        f = pool.submit(
            work.make_order, str(o.l0), o.order.scene, o.order.level, str(out), str(self.catalogue)
        )
        f.add_done_callback(lambda fut: self._finished(o, t, fut))

    def _finished(self, o: _Order, dispatched: float, fut: Future) -> None:
        with self._lock:  # when the worker's job ended (the loop sees it at its next look)
            self._done.append((o, dispatched, fut, time.time()))

    def _collect(self) -> int:
        """Finished jobs recorded; how many."""
        with self._lock:
            done, self._done = self._done, []
        for o, dispatched, fut, finished in done:
            now = self.clock.now()
            try:
                r = fut.result()
            except Exception as exc:  # said, the day goes on
                o.state = "failed"
                self.failures.append(f"{o.order.name}: {exc}")
                self.events("failed", order=o.order.name, error=str(exc), station_s=now)
                self.tell(f"{o.order.name}: failed: {exc}")
                continue
            o.state = "made"
            self.made_now += 1
            self.events(
                "made",
                order=o.order.name,
                station_s=now,
                dispatched_unix=dispatched,
                finished_unix=finished,  # the worker free again
                returned_unix=time.time(),  # seen by the loop: the product's latency
                **r,
            )
            self.tell(
                f"{o.order.name}: {o.order.level}{' (urgent)' * o.order.urgent} made: "
                f"{', '.join(map(str, r['files']))}"
            )
        return len(done)


def run_day(
    scn: DayScenario,
    out: Path,
    resume: bool = False,
    say: bool = True,
    calibrate: bool = True,
    scheduler: str | None = None,
) -> dict:
    """Run the day into ``out`` (module docstring); its report
    (:func:`station.day.report.day_report`), also written to ``<out>/day.json``. With
    ``calibrate``, the station's service times are measured on calibration passes of their
    own just before the clock and just after it (:func:`station.day.calibrate.bracket`):
    what ``station capacity validate`` gives the model. With ``scheduler``, the workers are
    those of the Dask cluster there (:mod:`station.day.pool`), as many as its threads."""
    from station.day.calibrate import bracket
    from station.day.report import day_report, write_report

    out = Path(out)
    with day_pool(scn.day.workers, scheduler) as pool:
        if scheduler is not None:  # the cluster's workers, checked for room by it
            scn = with_workers(scn, pool.workers, None)
        plan = prepare(scn, out, resume, local_workers=scheduler is None)
        if say:
            print(f"station day: the workers are {pool.where}", file=sys.stderr, flush=True)
        if calibrate:
            bracket(scn, out, "before", pool, say)
        day = Day(scn, out, plan, resume, say)
        day.run(pool)
        if calibrate:
            bracket(scn, out, "after", pool, say)
    report = day_report(scn, plan, read_events(out / EVENTS_FILE), day.failures)
    write_report(out, report)
    return report
