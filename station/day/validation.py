"""``station capacity validate DAY_RUN``: a day's measured figures beside the capacity model's
prediction of that day (:mod:`station.capacity.validate`), with the service times the day
measured on calibration passes before its clock and after it (``service_day.json``,
:mod:`station.day.calibrate`), or measured now (``--sessions K``, or a day run with
``--no-calibrate``), or read from ``--service``.

Writes ``<DAY_RUN>/validation.json`` (the rows and the service times used), and
``<DAY_RUN>/service_validate.json`` when it measured them.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from station.errors import StationError

__all__ = ["SESSIONS", "machine_speed", "validate_day", "validation_text"]

#: Calibration sessions measured one after the other: the spread between them (this
#: machine's from one minute to the next, 10-25 % on a shared VM) is in the interval.
SESSIONS = 2
#: The model's own days (replications of seeds of their own) scored as the day is.
OWN_DAYS = 200
#: The service times measured by the validation itself (the day's own are kept).
MEASURED_FILE = "service_validate.json"


def _read_json(path: Path, what: str) -> dict:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise StationError(
            f"{path.parent}: not a station day's directory ({path.name} missing: {what})"
        ) from None
    except (OSError, ValueError) as exc:
        raise StationError(f"{path}: unreadable: {exc}") from None


def validate_day(
    run: Path,
    service_file: str | None = None,
    replications: int | None = None,
    say: bool = True,
    sessions: int | None = None,
) -> dict[str, object]:
    """The validation of the day in ``run`` (module docstring)."""
    from levels.files import write_json
    from station.capacity.plan import read_plan
    from station.capacity.validate import DayUnits, compare, own_days, predict
    from station.day.calibrate import SERVICE_FILE, SERVICE_FORMAT, day_service, read_service
    from station.day.config import load_day, with_workers
    from station.day.run import DAY_FILE, PLAN_FILE

    report = _read_json(run / "day.json", "the day's report")
    if report.get("format") != "spot-station-day":
        raise StationError(f"{run}/day.json: not a day's report ({report.get('format')!r})")
    plan = read_plan(run / PLAN_FILE)
    scn = with_workers(load_day(run / DAY_FILE), int(report["workers"]), float(report["clock"]))
    if service_file:
        service = read_service(Path(service_file))
    elif sessions is None and (run / SERVICE_FILE).is_file():  # measured at the day's time
        service = read_service(run / SERVICE_FILE)
    else:
        if say:
            print("measuring the day's stages on calibration passes ...", file=sys.stderr)
        k = SESSIONS if sessions is None else sessions
        if not 1 <= k <= 10:
            raise StationError(f"--sessions {k}: expected 1 to 10")
        service = {
            "format": SERVICE_FORMAT,
            "sessions": [{**day_service(scn), "when": "validate"} for _ in range(k)],
        }
        write_json(run / MEASURED_FILE, service)  # the day's own is kept
    res = scn.capacity.resources
    units = DayUnits(res.ingest_workers, res.geo_workers, scn.day.workers, scn.day.clock)
    n = replications or scn.capacity.simulation.replications
    if n < 2:
        raise StationError(f"--replications {n}: an interval needs at least 2")
    predicted = predict(plan, units, service, n, scn.capacity.seed)
    rows = compare(report, predicted)
    own = own_days(predicted, predict(plan, units, service, OWN_DAYS, scn.capacity.seed + n))
    inside = sum(bool(r["inside"]) for r in rows)
    result = {
        "day": report["day"],
        "workers": scn.day.workers,
        "clock": scn.day.clock,
        "replications": n,
        "rows": rows,
        "all_inside": all(r["inside"] for r in rows),
        "inside": inside,
        # what the model's own days score: the day is consistent with the model when at
        # least 5 % of them score as few figures inside as it does, or fewer
        "own_days": {
            "days": OWN_DAYS,
            "inside_mean": float(own.mean()),
            "inside_p5": float(np.percentile(own, 5, method="lower")),
            "all_inside_share": float(np.mean(own == len(rows))),
            # the share of the model's own days that score as few as the day, or fewer
            "as_few_share": float(np.mean(own <= inside)),
        },
        "consistent": bool(np.mean(own <= inside) >= 0.05),
        "machine_speed": machine_speed(run, service),
        "service": service,
    }
    write_json(run / "validation.json", result)
    return result


def validation_text(result: dict) -> str:
    """Measured beside predicted, one figure a line."""
    lines = [
        f"day {result['day']}: {result['workers']} workers, clock {result['clock']:g}x; the "
        f"model's mean and 95 % interval over {result['replications']} replications",
        f"{'stage/level':12s} {'figure':28s} {'measured':>9s} {'model':>9s}"
        "   interval            inside",
    ]
    for r in result["rows"]:
        what = r.get("stage", r.get("level"))
        lo, hi = r["interval"]
        note = f" ({100 * r['relative_error']:.1f} %)" if "relative_error" in r else ""

        def f(x: float) -> str:
            return "nan" if not math.isfinite(x) else f"{x:.4f}"

        lines.append(
            f"{what:12s} {r['figure']:28s} {f(r['measured']):>9s} {f(r['predicted']):>9s}"
            f"   [{f(lo)}, {f(hi)}]  {'yes' if r['inside'] else 'NO'}{note}"
        )
    n_in, n = sum(r["inside"] for r in result["rows"]), len(result["rows"])
    own = result["own_days"]
    lines += [
        f"{n_in} of {n} figures inside "
        "(utilisation: within 10 % of the model's mean, or inside its interval where wider)",
        f"the model's own {own['days']} days, scored the same way: {own['inside_mean']:.1f} of "
        f"{n} inside on average, {own['inside_p5']:.0f} or more in 95 % of them, all {n} in "
        f"{100 * own['all_inside_share']:.0f} %; {n_in} or fewer in "
        f"{100 * own['as_few_share']:.0f} %",
        "the day is "
        + ("consistent" if result["consistent"] else "NOT consistent")
        + " with the model (at least 5 % of its own days score as few figures inside, or fewer)",
    ]
    speed = result.get("machine_speed", {})
    if speed.get("jobs"):
        lines.append(
            f"the day's {speed['jobs']} jobs that shared the machine with nothing took "
            f"{speed['ratio_mean']:.2f} ± {speed['ratio_sem']:.2f} times their calibrated time "
            "(1: the machine ran the day as fast as it was calibrated)"
        )
    return "\n".join(lines)


def machine_speed(run: Path, service: dict) -> dict[str, float]:
    """How fast the machine ran the day against its calibration, from the jobs that shared
    it with nothing: each made while no other job ran and the front end neither ingested
    nor catalogued, its wall time (dispatch to its end) over its kind's calibrated time on
    an archive of its segment's scenes (the mean over the sessions). A diagnostic, never an
    input of the model: 1.0 says the day ran at the calibrated speed; where the model
    misses and this is well above 1, the machine itself was slower during the day than
    minutes before and after it (a shared VM's neighbours), which no calibration taken
    outside the day can see."""
    from station.capacity.plan import read_plan
    from station.capacity.validate import cor_mean_s
    from station.day.run import EVENTS_FILE, PLAN_FILE, read_events

    plan = read_plan(run / PLAN_FILE)
    events = read_events(run / EVENTS_FILE)
    seg = {(p.name, s.hrv): s for p in plan.passes for s in p.segments}
    orders = {o.name: o for o in plan.orders}
    front = [
        (c["started_unix"], c["started_unix"] + c["catalogued_s"])
        for e in events
        if e["event"] == "archived"
        for c in e["channels"]
    ]
    jobs = [(e["dispatched_unix"], e.get("finished_unix", e["returned_unix"]), e["order"])
            for e in events if e["event"] == "made"]  # fmt: skip
    sessions = service.get("sessions", [service])
    ratios = []
    for a, b, name in jobs:
        busy = front + [(x, y) for x, y, other in jobs if other != name]
        if any(min(b, y) > max(a, x) for x, y in busy):
            continue
        o = orders[name]
        s = seg[o.pass_name, o.hrv]
        calibrated = np.mean([cor_mean_s(t["cor_s"][s.mode][o.level], s.scenes) for t in sessions])
        ratios.append((b - a) / calibrated)
    r = np.asarray(ratios)
    return {
        "jobs": int(r.size),
        "ratio_mean": float(r.mean()) if r.size else math.nan,
        "ratio_sem": float(r.std(ddof=1) / np.sqrt(r.size)) if r.size > 1 else math.nan,
    }
