"""The DIMAP route against the L0 route on one emulated pass (``station.routes``): every
level made twice, from the L0 archive and from its 1A written as SPOT World Heritage's zip,
and how far apart they land, with both against the truth.

    python tools/dimap_route.py [SCENARIO] [--levels 1A,1B,2A,2,3] [--set SECTION.KEY=VALUE]
                                [--out DIR]

By default the full P scene at 27° near Cuiabá (``scenarios/cuiaba_p_27deg.toml``, 6000 ×
6000) to every level; level 3 over the scenario's exported DEM (a ``[dem]`` table of 3″ is
added when the scenario has none, and said). ``--set instrument.mode='"XS"'``: the XS
scene. Prints, per level: identical counts, the largest count difference, the largest
geometry difference (raw pixels), each route's checkpoint RMS against the truth; then each
route's time.

Measured (2026-11-27, 2 cores): see ``docs/dimap.md``.
"""

from __future__ import annotations

import argparse
import tempfile
import tomllib
from pathlib import Path

from overrides import scenario_changes  # tools/overrides.py

from levels.makers.base import Need
from levels.process import plan_levels
from station.routes import compare_routes
from station.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "cuiaba_p_27deg.toml"))
    ap.add_argument("--levels", default="1A,1B,2A,2,3")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--out", help="keep the runs here (default: a temporary directory)")
    args = ap.parse_args()
    path = Path(args.scenario)
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    for section, values in scenario_changes(args.set).items():
        data.setdefault(section, {}).update(values)
    levels = tuple(lv.strip() for lv in args.levels.split(",") if lv.strip())
    has_dem = "dem" in data or data.get("processing", {}).get("dem_path")
    needs_dem = any(Need.DEM in m.needs for m in plan_levels(levels))
    if needs_dem and not has_dem:
        data["dem"] = {"spacing_arcsec": 3.0}
        print("a level needs a DEM: the world's exported at 3″ ([dem] added)")
    scn = scenario_from_dict(data, base_dir=path.parent)
    with tempfile.TemporaryDirectory(prefix="dimap-route-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        r = compare_routes(scn, out, levels)
    print(f"{scn.name}: the L0 route and the DIMAP route ({Path(r['zip']).name})")
    print(
        "level  identical counts  max diff  valid in one  geometry max px  truth RMS m (L0 / DIMAP)"
    )
    for level, row in r["levels"].items():
        t0, t1 = row["truth_rms_m_l0"], row["truth_rms_m_dimap"]
        truth = "—" if t0 is None else f"{t0:.3f} / {t1:.3f}"
        print(
            f"{level:>5}  {row['counts_identical']:15.5f}  {row['counts_max_diff']:8d}  "
            f"{row['valid_in_one_only']:12d}  {row['geometry_max_px']:15.2e}  {truth}"
        )
    t = r["timings_s"]
    print(f"times: L0 route (emulated, received, processed) {t['l0_route']:.1f} s; "
          f"DIMAP route (read from the zip, processed) {t['dimap_route']:.1f} s")  # fmt: skip


if __name__ == "__main__":
    main()
