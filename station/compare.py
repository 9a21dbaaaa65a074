"""Regression comparison of two run directories: their products (:mod:`levels.compare`)
and what only the station knows, the decode statistics of their ``report.json``.

``levels`` compares products and directories of products; a run directory is the station's
(``station run``), so reading its report is the station's business.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from levels.compare import (
    CompareError,
    Comparison,
    Finding,
    compare_directories,
    compare_paths,
    load_tolerances,
)
from levels.readers.l0 import read_l0

__all__ = ["compare_inputs", "compare_runs"]


#: The report naming what wrote a directory: a run, a reprocessing, a campaign.
_REPORTS = {"report.json": "run", "process.json": "process", "campaign.json": "campaign"}


def _kind(d: Path) -> str:
    """What wrote directory ``d``: ``run``, ``process``, ``campaign``, or ``products`` (no
    report: a directory of products)."""
    return next((kind for name, kind in _REPORTS.items() if (d / name).is_file()), "products")


def compare_inputs(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Two products (:func:`levels.compare.compare_paths`), or two directories of the same
    kind: run directories (:func:`compare_runs`), ``station process`` directories, campaign
    directories (:func:`compare_campaigns`), or directories of products."""
    pa, pb = Path(a), Path(b)
    if not (pa.is_dir() and pb.is_dir()):
        return compare_paths(pa, pb, tolerances)
    ka, kb = _kind(pa), _kind(pb)
    if ka != kb:
        out = Comparison(str(pa), str(pb), {"": []})
        out.findings[""].append(Finding("files", "what wrote the directory", ok=False, a=ka, b=kb))
        return out
    if ka == "campaign":
        return compare_campaigns(pa, pb, tolerances)
    if ka == "process":
        out = compare_directories(pa, pb, tolerances or load_tolerances(None))
        out.findings[""] += _compare_made(
            _read_report(pa / "process.json"), _read_report(pb / "process.json")
        )
        if list(pa.glob("*.l0.h5")) or list(pb.glob("*.l0.h5")):  # a scenario's pass
            out.findings[""] += _compare_l0s(pa, pb)
        return out
    if ka == "products":
        return compare_directories(pa, pb, tolerances or load_tolerances(None))
    return compare_runs(pa, pb, tolerances)


def compare_campaigns(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Two campaign directories: the same archives, each with the same status, and each
    archive's products compared (findings keyed ``<archive>/<product>``)."""
    pa, pb = Path(a), Path(b)
    tol = tolerances or load_tolerances(None)
    ra, rb = _read_report(pa / "campaign.json"), _read_report(pb / "campaign.json")
    ea = {e.get("name"): e for e in ra.get("archives", [])}
    eb = {e.get("name"): e for e in rb.get("archives", [])}
    out = Comparison(str(pa), str(pb), {"": []})
    for name in sorted(set(ea) | set(eb), key=str):
        sa, sb = (
            ea.get(name, {}).get("status", "missing"),
            eb.get(name, {}).get("status", "missing"),
        )
        if sa != sb:
            out.findings[""].append(Finding("files", f"archive {name}", ok=False, a=sa, b=sb))
        elif sa == "ok":
            sub = compare_directories(pa / str(name), pb / str(name), tol)
            for key, found in sub.findings.items():
                out.findings[f"{name}/{key}" if key else str(name)] = found
    if not ea and not eb:
        out.findings[""].append(Finding("files", "archives", ok=False, a="none", b="none"))
    return out


def _compare_made(a: dict[str, Any], b: dict[str, Any]) -> list[Finding]:
    """What two ``process.json`` say was made: per archive its products (scene, level,
    file), the scenes skipped and why, the tail of lines left; not where, nor how long."""

    def made(report: dict[str, Any]) -> list[Any]:
        return [
            {
                "products": sorted(
                    (p.get("scene"), p.get("level"), Path(str(p.get("path"))).name)
                    for p in d.get("products", [])
                ),
                "skipped": d.get("skipped"),
                "tail_lines": d.get("tail_lines"),
            }
            for d in report.get("archives", [report])
        ]

    ma, mb = made(a), made(b)
    if ma != mb:
        return [Finding("files", "process.json: what was made", ok=False, a=ma, b=mb)]
    return [Finding("files", "process.json", value="the same products, skips and tails")]


def compare_runs(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Two run directories: their products, and their reports' decode statistics when both
    have one (counts: exact)."""
    pa, pb = Path(a), Path(b)
    out = compare_directories(pa, pb, tolerances or load_tolerances(None))
    ra, rb = pa / "report.json", pb / "report.json"
    if ra.is_file() and rb.is_file():
        out.findings[""] += _compare_reports(_read_report(ra), _read_report(rb))
    else:  # a run that did not finish (or not a run): never compared as if it were whole
        out.findings[""].append(
            Finding(
                "files",
                "report.json",
                ok=False,
                a="present" if ra.is_file() else "missing (the run did not finish)",
                b="present" if rb.is_file() else "missing (the run did not finish)",
            )
        )
    out.findings[""] += _compare_l0s(pa, pb)
    return out


def _is_sar_run(d: Path) -> bool:
    """Whether ``d`` is the run of a SAR frame (``station.run_sar``)."""
    from station.run_sar import SAR_REPORT_FORMAT

    try:
        return _read_report(d / "report.json").get("format") == SAR_REPORT_FORMAT
    except (OSError, CompareError):  # no report, or not one: compared as a pass's run
        return False


def _compare_l0s(a: Path, b: Path) -> list[Finding]:
    """The L0 archives of two runs: present in both, and their data equal (counts, masks,
    line times, ephemeris, gyro rates: a rerun of a scenario records the same bytes of
    data). A damaged archive is bad input (its checksums, ``levels.readers.l0``)."""
    la = {p.name: p for p in sorted(a.glob("*.l0.h5"))}
    lb = {p.name: p for p in sorted(b.glob("*.l0.h5"))}
    out = [
        Finding(
            "files",
            f"L0 {n}",
            ok=False,
            a="present" if n in la else "missing",
            b="present" if n in lb else "missing",
        )
        for n in sorted(set(la) ^ set(lb))
    ]
    if not la and not lb and not _is_sar_run(a):  # a SAR frame's run records none
        out.append(Finding("files", "L0 archives", ok=False, a="none", b="none"))
    for name in sorted(set(la) & set(lb)):
        x, y = read_l0(la[name]), read_l0(lb[name])
        pairs = {
            "lines/t_s": (x.line_t_s, y.line_t_s),
            "lines/line_counter": (x.line_counter, y.line_counter),
            "ephemeris/r_ecef_m": (x.ephemeris.r_ecef_m, y.ephemeris.r_ecef_m),
            "ephemeris/v_ecef_m_per_s": (x.ephemeris.v_ecef_m_per_s, y.ephemeris.v_ecef_m_per_s),
            "aux/gyro_rates_rad_per_s": (x.gyro_rates_rad_per_s, y.gyro_rates_rad_per_s),
        }
        if set(x.bands) != set(y.bands):
            out.append(
                Finding("l0", f"{name}: bands", ok=False, a=sorted(x.bands), b=sorted(y.bands))
            )
        for band in sorted(set(x.bands) & set(y.bands)):
            pairs[f"bands/{band}/counts"] = (x.bands[band].counts, y.bands[band].counts)
            pairs[f"bands/{band}/valid"] = (x.bands[band].valid, y.bands[band].valid)
        differ = [
            k
            for k, (u, v) in pairs.items()
            if np.shape(u) != np.shape(v) or not np.array_equal(u, v)
        ]
        for k in differ:
            out.append(
                Finding(
                    "l0",
                    f"{name}: {k}",
                    ok=False,
                    a=f"shape {np.shape(pairs[k][0])}",
                    b=f"shape {np.shape(pairs[k][1])}, values differ",
                )
            )
        if not differ:
            out.append(Finding("l0", f"{name}", value="identical data"))
    return out


def _read_report(path: Path) -> dict[str, Any]:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CompareError(f"{path}: not a readable run report ({exc})") from None


def _compare_reports(a: dict[str, Any], b: dict[str, Any]) -> list[Finding]:
    """The decode statistics of two run reports, HRV by HRV: counts, exactly."""
    out = []
    ha, hb = _decode_by_hrv(a), _decode_by_hrv(b)
    if set(ha) != set(hb):
        out.append(Finding("decode", "HRVs received", ok=False, a=sorted(ha), b=sorted(hb)))
    for hrv in sorted(set(ha) & set(hb)):
        da, db = ha[hrv], hb[hrv]
        where = f"decode/HRV{hrv}"
        for key in ("link", "cadus", "truth_check"):
            for k in sorted(set(da.get(key, {})) | set(db.get(key, {}))):
                va, vb = da.get(key, {}).get(k), db.get(key, {}).get(k)
                if va != vb:
                    out.append(Finding("decode", f"{where}/{key}/{k}", ok=False, a=va, b=vb))
        ba = {x["name"]: x for x in da.get("bands", [])}
        bb = {x["name"]: x for x in db.get("bands", [])}
        for name in sorted(set(ba) | set(bb)):
            for k in ("lines_complete", "lines_partial", "lines_missing"):
                va, vb = ba.get(name, {}).get(k), bb.get(name, {}).get(k)
                if va != vb:
                    out.append(Finding("decode", f"{where}/bands/{name}/{k}", ok=False, a=va, b=vb))
    if not out:
        out.append(Finding("decode", "decode statistics", value="identical"))
    return out


def _decode_by_hrv(report: dict[str, Any]) -> dict[Any, dict[str, Any]]:
    """A run report's decode statistics per HRV number (format 1 had one HRV, at the top)."""
    if "hrvs" in report:
        return {h.get("hrv"): h.get("decode", {}) for h in report["hrvs"]}
    if "decode" in report:
        return {report.get("instrument", {}).get("hrv"): report["decode"]}
    return {}
