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
    only_in_one,
)
from levels.readers.l0 import read_l0
from station.errors import StationError
from station.reports import (
    BLOCK_RUN,
    CAMPAIGN,
    LIVE_PASS,
    PASS_RUN,
    PROCESS,
    SAR_RUN,
    ReportFormat,
    report_of,
)

__all__ = [
    "compare_campaigns",
    "compare_inputs",
    "compare_runs",
    "directory_kind",
    "tolerances_of",
]


#: A directory with no report (:mod:`station.reports`): products alone.
_PRODUCTS = "a directory of products"
#: Sub-directories of a run that hold no results: compared through what they are made from.
_DERIVED = ("stac", "quicklooks")


def directory_kind(d: Path) -> str:
    """What wrote directory ``d``, in words (its report's, :mod:`station.reports`): the run
    of a pass, of a block (a stereo pair is one), of a SAR frame; a reprocessing
    (``station process``); a campaign; or, with no report, a directory of products."""
    report = _report(d)
    return report.what if report is not None else _PRODUCTS


def _report(d: Path) -> ReportFormat | None:
    try:
        return report_of(d)
    except StationError as exc:
        raise CompareError(str(exc)) from None


def compare_inputs(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Two products (:func:`levels.compare.compare_paths`), or two directories of the same
    kind (:func:`directory_kind`): runs of a pass (:func:`compare_runs`), of a block (every
    pass's run, the tie points, the block's and the pair's products), of a SAR frame,
    reprocessings, campaigns (:func:`compare_campaigns`), directories of products; a pass
    served live (``station serve``) with another or with the pass's run, by their L0
    archives. Two directories of other different kinds are refused
    (:class:`CompareError`): there is nothing to compare them by."""
    pa, pb = Path(a), Path(b)
    if not (pa.is_dir() and pb.is_dir()):
        return compare_paths(pa, pb, tolerances)
    ra, rb = _report(pa), _report(pb)
    if LIVE_PASS in (ra, rb) and {ra, rb} <= {LIVE_PASS, PASS_RUN}:  # a pass served live:
        return Comparison(str(pa), str(pb), {"": _compare_l0s(pa, pb)})  # its archives
    if ra != rb:
        raise CompareError(
            f"{pa} is {directory_kind(pa)} and {pb} {directory_kind(pb)}: different kinds of "
            "directory, nothing to compare them by; compare two of one kind"
        )
    return _compare_directory(pa, pb, ra, tolerances or load_tolerances(None))


def _compare_directory(
    a: Path,
    b: Path,
    report: ReportFormat | None,
    tol: dict[str, dict[str, float]],
    top: bool = True,
) -> Comparison:
    """Two directories of one kind (their ``report``), compared as that kind is."""
    if report is CAMPAIGN:
        return compare_campaigns(a, b, tol)
    if report is BLOCK_RUN:
        return _compare_blocks(a, b, tol)
    if report is PROCESS:
        out = compare_directories(a, b, tol)
        out.findings[""] += _compare_made(
            _read_report(a / PROCESS.file), _read_report(b / PROCESS.file)
        )
        if list(a.glob("*.l0.h5")) or list(b.glob("*.l0.h5")):  # a scenario's pass
            out.findings[""] += _compare_l0s(a, b)
        return out
    if report is None:
        return compare_directories(a, b, tol, require_products=top)
    return compare_runs(a, b, tol)


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


def _compare_made(a: dict[str, object], b: dict[str, object]) -> list[Finding]:
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


def _compare_blocks(a: Path, b: Path, tol: dict[str, dict[str, float]]) -> Comparison:
    """Two runs of a block: every sub-directory by its own kind (each pass's run, the
    block's level 2 and 3, the pair's DEM, the tie points), findings keyed
    ``<sub-directory>/<product>``; and what the reports say was tied and made."""
    out = Comparison(str(a), str(b), {"": []})
    ra, rb = _read_report(a / "report.json"), _read_report(b / "report.json")
    for key in ("passes", "ties"):
        made = [_block_made(r, key) for r in (ra, rb)]
        if made[0] != made[1]:
            out.findings[""].append(
                Finding("files", f"report.json: {key}", ok=False, a=made[0], b=made[1])
            )
    subs = {
        side: {p.name for p in d.iterdir() if p.is_dir() and p.name not in _DERIVED}
        for side, d in (("a", a), ("b", b))
    }
    out.findings[""] += only_in_one("files", "directory ", subs["a"], subs["b"])
    for name in sorted(subs["a"] & subs["b"]):
        sa, sb = _report(a / name), _report(b / name)
        if sa != sb:
            out.findings[""].append(
                Finding(
                    "files",
                    f"{name}/",
                    ok=False,
                    a=directory_kind(a / name),
                    b=directory_kind(b / name),
                )
            )
            continue
        sub = _compare_directory(a / name, b / name, sa, tol, top=False)
        for key, found in sub.findings.items():
            out.findings[f"{name}/{key}" if key else f"{name}/"] = found
    return out


def _block_made(report: dict[str, Any], key: str) -> Any:
    """What a block's report says of its passes (their names) or its ties (the pairs of
    scenes tied and the points found), without its timings."""
    if key == "passes":
        return [r.get("scenario", {}).get("name") for r in report.get("passes", [])]
    return [
        (p.get("a"), p.get("b"), p.get("scene_a"), p.get("scene_b"), p.get("points"))
        for p in report.get("ties", {}).get("pairs", [])
    ]


def _is_sar_run(d: Path) -> bool:
    """Whether ``d`` is the run of a SAR frame (``station.run_sar``), which records no L0."""
    try:
        return _report(d) is SAR_RUN
    except (OSError, CompareError):  # no report, or not one: compared as a pass's run
        return False


def _compare_l0s(a: Path, b: Path) -> list[Finding]:
    """The L0 archives of two runs: present in both, and their data equal (counts, masks,
    line times, ephemeris, gyro rates: a rerun of a scenario records the same bytes of
    data). A damaged archive is bad input (its checksums, ``levels.readers.l0``)."""
    la = {p.name: p for p in sorted(a.glob("*.l0.h5"))}
    lb = {p.name: p for p in sorted(b.glob("*.l0.h5"))}
    out = only_in_one("files", "L0 ", la, lb)
    if not la and not lb and not _is_sar_run(a):  # a SAR frame's run records none
        out.append(Finding("files", "L0 archives", ok=False, a="none", b="none"))
    for name in sorted(set(la) & set(lb)):
        x, y = read_l0(la[name]), read_l0(lb[name])
        pairs: dict[str, tuple[Any, Any]] = {
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


def _compare_reports(a: dict[str, object], b: dict[str, object]) -> list[Finding]:
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


def tolerances_of(path: str | Path | None) -> dict[str, dict[str, float]]:
    """``compare``'s tolerances: the defaults, overridden by a TOML file's
    (:func:`levels.compare.load_tolerances`)."""
    from levels.compare import load_tolerances

    return load_tolerances(path)
