"""Regression comparison of two run directories: their products (:mod:`levels.compare`)
and what only the station knows, the decode statistics of their ``report.json``.

``levels`` compares products and directories of products; a run directory is the station's
(``station run``), so reading its report is the station's business.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from levels.compare import (
    CompareError,
    Comparison,
    Finding,
    compare_directories,
    compare_paths,
    load_tolerances,
)

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
