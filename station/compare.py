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


def compare_inputs(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Two products (:func:`levels.compare.compare_paths`) or two run directories
    (:func:`compare_runs`)."""
    pa, pb = Path(a), Path(b)
    if pa.is_dir() and pb.is_dir():
        return compare_runs(pa, pb, tolerances)
    return compare_paths(pa, pb, tolerances)


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
    if not la and not lb:
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
