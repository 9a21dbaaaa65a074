"""Regression comparison of level products: two products, or two run directories.

What is compared, and how (each check is a :class:`Finding`, inside or outside its
tolerance):

- **metadata**: the product attributes (level, sizes, instrument, pixel size) and the map
  CRS must be equal;
- **pixels**, per band, over the pixels valid in both: max |Δ| and RMS in counts, PSNR
  (peak 255), the fraction of pixels changed; and the fraction whose validity changed; a
  band of a quantity (a DEM's heights, their σ, the points per cell) in its own units:
  max |Δ|, RMS and mean difference, the fraction changed reported;
- **geometry**: the shift of the scene centre and corners on the ellipsoid (m); for 2A the
  shift of the map grid's origin (m) and, per band, the difference of the inverse grids
  (raw pixels); for 1B the difference of the polynomials f, g, h over the image (pixels);
  and every other number of the geometry tree (ephemeris, attitude, look angles, DEM…)
  within ``rel`` of its dataset's largest magnitude;
- **as stored**: every variable and attribute outside the trees, as GDAL, xarray and CF
  tools read them: the ``x`` and ``y`` coordinates (within ``corner_shift_m``), the grid
  mapping (``crs``: its WKT and ``GeoTransform``), the attributes of every band variable;
- **quality**: every scalar figure of the ``quality`` group, within ``abs + rel·|a|``;
- **provenance**: reported, never a failure (a new software version is why one compares),
  with the processing parameters that differ named one by one;
- for two directories of products, also the products present in one only (the station
  adds, for its run directories, the decode statistics of their reports:
  ``station.compare``).

The default tolerances (:data:`DEFAULT_TOLERANCES`, documented in ``docs/compare.md``) let
through only what a different CPU's floating point can change (a few pixels by one count
under numba's fastmath); reruns on one machine are bit-identical. A TOML file with the same
sections overrides any of them.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
from numpy.typing import NDArray

from levels.errors import ProductError
from levels.geo.level1b import Level1BGeometry
from levels.geo.level2a import Level2AGeometry
from levels.products import Product, band_spec, is_product_file, read_product
from levels.quality import scalar_figures
from levels.registry import kind_of

__all__ = [
    "DEFAULT_TOLERANCES",
    "CompareError",
    "Comparison",
    "Finding",
    "compare_directories",
    "compare_paths",
    "compare_products",
    "compare_stored",
    "load_tolerances",
    "only_in_one",
]

DEFAULT_TOLERANCES: dict[str, dict[str, float]] = {
    "pixels": {
        "max_abs_counts": 1.0,
        "rms_counts": 0.01,
        "fraction_changed": 1e-4,
        "mask_fraction_changed": 0.0,
        "quantity_max_abs": 0.01,
        "quantity_rms": 0.001,
    },
    "geometry": {"corner_shift_m": 0.01, "grid_px": 1e-4, "rel": 1e-9},
    "quality": {"abs": 1e-6, "rel": 1e-4},
}


#: Root attributes that say how a product is stored, not what it holds.
_STORAGE_ATTRS = ("format_version", "Conventions", "history")


class CompareError(ProductError):
    """Bad input to a comparison (not products, an unknown tolerance, …)."""


@dataclass(frozen=True)
class Finding:
    """One check: ``what`` was ``a`` in the first input and ``b`` in the second, or a figure
    ``value`` of their difference; ``ok`` if within ``tolerance`` (None: reported only)."""

    kind: str
    what: str
    value: Any = None
    tolerance: float | None = None
    ok: bool = True
    a: Any = None
    b: Any = None

    def text(self) -> str:
        if self.a is not None or self.b is not None:
            s = f"{self.what}: {self.a!r} → {self.b!r}"
        else:
            s = f"{self.what} = {_num(self.value)}"
        if self.tolerance is not None:
            s += f" (tolerance {_num(self.tolerance)})"
        return s


def only_in_one(kind: str, label: str, a: Collection[str], b: Collection[str]) -> list[Finding]:
    """A difference for each name in ``a`` or ``b`` but not both: ``<label><name>``,
    present in one and missing in the other."""
    return [
        Finding(
            kind,
            f"{label}{n}",
            ok=False,
            a="present" if n in a else "missing",
            b="present" if n in b else "missing",
        )
        for n in sorted(set(a) ^ set(b))
    ]


def _num(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


@dataclass
class Comparison:
    """All findings of a comparison, per pair of products (``""`` for the run itself)."""

    a: str
    b: str
    findings: dict[str, list[Finding]] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return all(f.ok for fs in self.findings.values() for f in fs)

    def failures(self) -> list[tuple[str, Finding]]:
        return [(k, f) for k, fs in self.findings.items() for f in fs if not f.ok]

    def as_dict(self) -> dict[str, object]:
        return {
            "a": self.a,
            "b": self.b,
            "ok": self.ok,
            "outside_tolerance": sum(1 for _ in self.failures()),
            "findings": {
                k: [{key: _jsonable(v) for key, v in f.__dict__.items()} for f in fs]
                for k, fs in self.findings.items()
            },
        }

    def text(self) -> str:
        n = sum(len(fs) for fs in self.findings.values())
        bad = self.failures()
        lines = [f"compare {self.a} with {self.b}: {n} checks, {len(bad)} outside tolerance"]
        for k, f in bad:
            lines.append(f"  DIFFERS  {k + ': ' if k else ''}{f.text()}")
        notes: dict[str, list[str]] = {}  # the same note of many products, said once
        for k, fs in self.findings.items():
            for f in fs:
                if f.ok and f.kind == "provenance":
                    notes.setdefault(f.text(), []).append(k)
        for text, where in sorted(notes.items(), key=lambda t: not t[0].startswith("proc")):
            whose = where[0] if len(where) == 1 else f"{len(where)} products"
            lines.append(f"  note     {text} ({whose})")
        return "\n".join(lines)


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return x


def load_tolerances(path: str | Path | None) -> dict[str, dict[str, float]]:
    """The default tolerances, overridden by a TOML file's sections and keys."""
    tol = {k: dict(v) for k, v in DEFAULT_TOLERANCES.items()}
    if path is None:
        return tol
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CompareError(f"tolerance file {p} not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CompareError(f"{p}: not valid TOML ({exc})") from None
    for section, values in data.items():
        if section not in tol or not isinstance(values, dict):
            raise CompareError(
                f"{p}: unknown section [{section}]; expected one of {', '.join(tol)}"
            )
        for key, v in values.items():
            if key not in tol[section]:
                raise CompareError(
                    f"{p}: unknown key {key!r} in [{section}]; expected one of "
                    f"{', '.join(tol[section])}"
                )
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v < math.inf:
                raise CompareError(f"{p}: [{section}] {key} = {v!r}: expected a finite number >= 0")
            tol[section][key] = float(v)
    return tol


def compare_paths(
    a: str | Path, b: str | Path, tolerances: dict[str, dict[str, float]] | None = None
) -> Comparison:
    """Compare two products, or two directories of products (matched by name)."""
    pa, pb = Path(a), Path(b)
    tol = tolerances or load_tolerances(None)
    for p in (pa, pb):
        if not p.exists():
            raise CompareError(f"{p}: no such product or run directory")
    if pa.is_dir() != pb.is_dir():
        raise CompareError(f"cannot compare a directory with a file ({pa}, {pb})")
    if not pa.is_dir():
        x, y = read_product(pa), read_product(pb)
        kx, ky = (str(p.attrs.get("level", "?")) for p in (x, y))
        if kx != ky:
            raise CompareError(
                f"{pa} is a level {kx} product and {pb} a level {ky}: different kinds, nothing "
                "to compare them by; compare two of one kind"
            )
        out = Comparison(str(pa), str(pb))
        out.findings[""] = compare_products(x, y, tol)
        out.findings[""] += compare_stored(pa, pb, tol)
        return out
    return compare_directories(pa, pb, tol)


def _products_in(d: Path) -> dict[str, Path]:
    return {p.name: p for p in sorted(d.iterdir()) if p.is_file() and is_product_file(p)}


#: Files of control and tie points (``docs/gcp.md``) a directory of products may hold.
POINT_FILES = ("*.gcp.csv", "*.tie.csv")
#: What a point file can tell apart: image positions written to 1e-3 px, heights to 1 mm
#: (longitudes and latitudes to 1e-9°, 0.1 mm): a tolerance finer than that is this.
POINT_FILE_PX, POINT_FILE_M = 1e-3, 1e-3


def compare_directories(
    a: Path, b: Path, tol: dict[str, dict[str, float]], require_products: bool = True
) -> Comparison:
    """Two directories of products, matched by file name: every pair compared, and the
    products present in one directory only reported as differences; their control and tie
    point files too (:func:`compare_point_files`). ``require_products``: a directory pair
    with no product is bad input (:class:`CompareError`)."""
    out = Comparison(str(a), str(b))
    pa, pb = _products_in(a), _products_in(b)
    if require_products and not pa and not pb:
        raise CompareError(f"no level products (*.nc, *.h5) in {a} or {b}")
    out.findings[""] = only_in_one("files", "product ", pa, pb)
    out.findings[""] += compare_point_files(a, b, tol)
    for name in sorted(set(pa) & set(pb)):
        out.findings[name] = compare_products(read_product(pa[name]), read_product(pb[name]), tol)
        out.findings[name] += compare_stored(pa[name], pb[name], tol)
    return out


def compare_point_files(a: Path, b: Path, tol: dict[str, dict[str, float]]) -> list[Finding]:
    """The control and tie point files of two directories (:data:`POINT_FILES`), matched by
    name: the same points (ids, kinds, HRVs), their image positions within ``grid_px``,
    their ground within ``corner_shift_m`` and their σ within ``rel``."""
    from levels.readers.gcp import read_gcps

    names = {
        side: {p.name: p for pattern in POINT_FILES for p in sorted(d.glob(pattern))}
        for side, d in (("a", a), ("b", b))
    }
    fa, fb = names["a"], names["b"]
    out = only_in_one("files", "points ", fa, fb)
    g = tol["geometry"]
    for n in sorted(set(fa) & set(fb)):
        x, y = read_gcps(fa[n]), read_gcps(fb[n])
        same_kinds = np.array_equal(np.asarray(x.tie), np.asarray(y.tie))
        if x.id != y.id or not same_kinds or not np.array_equal(x.hrv, y.hrv):
            moved = sorted(set(x.id) ^ set(y.id))
            out.append(
                Finding(
                    "points",
                    f"{n}: points",
                    ok=False,
                    a=len(x),
                    b=len(y) if not moved else f"{len(y)}, {len(moved)} not in both",
                )
            )
            continue
        ground = _ground_shift_m(x, y)
        checks = {
            "image position (px)": (
                np.hypot(x.line - y.line, x.column - y.column),
                max(g["grid_px"], POINT_FILE_PX),
            ),
            "ground (m)": (ground, max(g["corner_shift_m"], POINT_FILE_M)),
        }
        for what, (d, bound) in checks.items():
            bad = ~(d <= bound)
            if bad.any():
                worst = int(np.argmax(np.where(np.isfinite(d), d, np.inf)))
                out.append(
                    Finding(
                        "points",
                        f"{n}: {what} of {int(bad.sum())} point(s), worst {x.id[worst]}",
                        float(d[worst]),
                        bound,
                        ok=False,
                    )
                )
        for field_ in ("sigma_ground_m", "sigma_h_m", "sigma_px"):
            diff, scale = _finite_difference(getattr(x, field_), getattr(y, field_))
            if not diff <= g["rel"] * scale:
                out.append(Finding("points", f"{n}: {field_}", diff, g["rel"] * scale, ok=False))
        if not any(f.what.startswith(f"{n}:") for f in out):
            out.append(Finding("points", n, value=f"{len(x)} points within tolerance"))
    return out


def _ground_shift_m(x: Any, y: Any) -> NDArray[np.float64]:
    """How far each point's ground lies from the other file's, in metres (tie points,
    which have none: 0 when both lack it, infinite when one has it)."""
    _, _, flat = _GEOD.inv(
        np.degrees(x.lon_rad), np.degrees(x.lat_rad), np.degrees(y.lon_rad), np.degrees(y.lat_rad)
    )
    d = np.hypot(np.nan_to_num(np.asarray(flat), nan=0.0), np.nan_to_num(x.h_m - y.h_m, nan=0.0))
    known = np.isfinite(x.lat_rad) & np.isfinite(y.lat_rad)
    both_unknown = ~np.isfinite(x.lat_rad) & ~np.isfinite(y.lat_rad)
    return np.where(known, d, np.where(both_unknown, 0.0, np.inf))


def compare_products(
    a: Product, b: Product, tol: dict[str, dict[str, float]] | None = None
) -> list[Finding]:
    """Every check of two products (module docstring)."""
    tol = _of_kind(a, tol or load_tolerances(None))
    out = _metadata(a, b)
    out += _schema(a, b)
    out += _pixels(a, b, tol["pixels"])
    out += _geometry(a, b, tol["geometry"])
    out += _geometry_leaves(a, b, tol["geometry"])
    out += _quality(a, b, tol["quality"])
    out += _provenance(a, b)
    return out


def _of_kind(product: Product, tol: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """The tolerances for a product of its kind: the defaults, the kind's own over them
    (:attr:`levels.kinds.ProductKind.tolerances`), and whatever ``tol`` sets apart from
    the defaults (a tolerance file's) over both."""
    known = kind_of(product)
    if known is None or not known.tolerances:
        return tol
    out = {k: dict(v) for k, v in DEFAULT_TOLERANCES.items()}
    for section, values in known.tolerances.items():
        out[section].update(values)
    for section, values in tol.items():
        for key, v in values.items():
            if v != DEFAULT_TOLERANCES[section][key]:
                out[section][key] = v
    return out


def _metadata(a: Product, b: Product) -> list[Finding]:
    out = []
    for k in sorted(set(a.attrs) | set(b.attrs)):
        va, vb = a.attrs.get(k), b.attrs.get(k)
        if _differs(va, vb):
            # how a product is stored is not what it holds: a note, as provenance is
            stored = k in _STORAGE_ATTRS
            out.append(
                Finding(
                    "provenance" if stored else "metadata",
                    f"attrs/{k}",
                    ok=stored,
                    a=_plain(va),
                    b=_plain(vb),
                )
            )
    if set(a.bands) != set(b.bands):
        out.append(Finding("metadata", "bands", ok=False, a=sorted(a.bands), b=sorted(b.bands)))
    ga, gb = a.map_grid, b.map_grid
    if (ga is None) != (gb is None):
        out.append(
            Finding(
                "metadata",
                "map grid",
                ok=False,
                a="present" if ga else "missing",
                b="present" if gb else "missing",
            )
        )
    elif ga is not None and gb is not None:
        ca, cb = pyproj.CRS.from_wkt(ga.crs_wkt), pyproj.CRS.from_wkt(gb.crs_wkt)
        if not ca.equals(cb):
            out.append(Finding("metadata", "map CRS", ok=False, a=ca.name, b=cb.name))
    return out


def _paths(tree: dict[str, object], prefix: str = "") -> set[str]:
    out = set()
    for k, v in tree.items():
        out.add(prefix + k)
        if isinstance(v, dict):
            out |= _paths(v, f"{prefix}{k}/")
    return out


def _schema(a: Product, b: Product) -> list[Finding]:
    """What one product holds and the other lacks, in any tree: a missing part is a
    difference, never an absence of checks (provenance excepted: a new version may say
    more of itself)."""
    out = []
    for tree in ("geometry", "quality"):
        pa, pb = _paths(getattr(a, tree)), _paths(getattr(b, tree))
        out += only_in_one("schema", f"{tree}/", pa, pb)
    return out


def _plain(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    return _jsonable(x)


def _differs(x: Any, y: Any) -> bool:
    """Whether two stored values differ (NaN equals NaN: a float band's fill value)."""
    if isinstance(x, np.ndarray | np.floating) or isinstance(y, np.ndarray | np.floating):
        ax, ay = np.asarray(x), np.asarray(y)
        floats = ax.dtype.kind == "f" and ay.dtype.kind == "f"
        return not np.array_equal(ax, ay, equal_nan=floats)
    return bool(x != y)


def _pixels(a: Product, b: Product, tol: dict[str, float]) -> list[Finding]:
    out = []
    for name in sorted(set(a.bands) & set(b.bands)):
        ia, ib = a.bands[name], b.bands[name]
        if ia.image.shape != ib.image.shape:
            out.append(
                Finding(
                    "pixels", f"bands/{name}/shape", ok=False, a=ia.image.shape, b=ib.image.shape
                )
            )
            continue
        both = ia.valid & ib.valid
        if band_spec(a, name, ia.image.dtype).quantity or ia.image.dtype != ib.image.dtype:
            out += _quantities(name, ia, ib, both, tol)
            continue
        d = ia.image[both].astype(np.int16) - ib.image[both].astype(np.int16)
        n = max(int(both.sum()), 1)
        max_abs = float(np.abs(d).max()) if d.size else 0.0
        rms = float(np.sqrt(np.mean(d.astype(np.float64) ** 2))) if d.size else 0.0
        changed = float(np.count_nonzero(d)) / n
        mask = float(np.count_nonzero(ia.valid != ib.valid)) / ia.valid.size
        psnr = math.inf if rms == 0 else 20.0 * math.log10(255.0 / rms)
        p = f"bands/{name}"
        out += [
            _within(f"{p}/max_abs_counts", max_abs, tol["max_abs_counts"]),
            _within(f"{p}/rms_counts", rms, tol["rms_counts"]),
            _within(f"{p}/fraction_changed", changed, tol["fraction_changed"]),
            _within(f"{p}/mask_fraction_changed", mask, tol["mask_fraction_changed"]),
            Finding("pixels", f"{p}/psnr_db", psnr),
        ]
    return out


def _quantities(name: str, ia: Any, ib: Any, both: Any, tol: dict[str, float]) -> list[Finding]:
    """A band of a quantity in its own units (a DEM's heights, σ and counts, as its kind
    declares it: :class:`levels.kinds.BandSpec`), compared as numbers, not counts: max |Δ| and
    RMS in the band's units within ``quantity_max_abs`` and ``quantity_rms``; the share
    of pixels changed at all is reported (another CPU changes the last bits of many)."""
    a = ia.image[both].astype(np.float64)
    b = ib.image[both].astype(np.float64)
    d = a - b
    max_abs = float(np.max(np.abs(d))) if d.size else 0.0
    rms = float(np.sqrt(np.mean(d**2))) if d.size else 0.0
    changed = float(np.count_nonzero(d)) / max(int(both.sum()), 1)
    mask = float(np.count_nonzero(ia.valid != ib.valid)) / ia.valid.size
    p = f"bands/{name}"
    return [
        _within(f"{p}/max_abs", max_abs, tol["quantity_max_abs"]),
        _within(f"{p}/rms", rms, tol["quantity_rms"]),
        Finding("pixels", f"{p}/mean_difference", float(np.mean(d)) if d.size else 0.0),
        Finding("pixels", f"{p}/fraction_changed", changed),
        _within(f"{p}/mask_fraction_changed", mask, tol["mask_fraction_changed"]),
    ]


def _within(what: str, value: float, bound: float) -> Finding:
    """A pixel figure against its tolerance."""
    return Finding("pixels", what, value, bound, value <= bound)


_GEOD = pyproj.Geod(ellps="WGS84")


def _geometry(a: Product, b: Product, tol: dict[str, float]) -> list[Finding]:
    out = []
    sa, sb = a.geometry.get("scene"), b.geometry.get("scene")
    if sa and sb:
        lat_a = np.append(sa["corners_lat_deg"], sa["centre_lat_deg"])
        lon_a = np.append(sa["corners_lon_deg"], sa["centre_lon_deg"])
        lat_b = np.append(sb["corners_lat_deg"], sb["centre_lat_deg"])
        lon_b = np.append(sb["corners_lon_deg"], sb["centre_lon_deg"])
        _, _, dist = _GEOD.inv(lon_a, lat_a, lon_b, lat_b)
        shift = float(np.max(dist))
        out.append(
            Finding(
                "geometry",
                "scene/corner_shift_m",
                shift,
                tol["corner_shift_m"],
                shift <= tol["corner_shift_m"],
            )
        )
    if a.map_grid is not None and b.map_grid is not None:
        ta, tb = a.map_grid.geotransform, b.map_grid.geotransform
        shift = float(np.hypot(ta[0] - tb[0], ta[3] - tb[3]))
        out.append(
            Finding(
                "geometry",
                "level_2a/origin_shift_m",
                shift,
                tol["corner_shift_m"],
                shift <= tol["corner_shift_m"],
            )
        )
    bands = sorted(set(a.bands) & set(b.bands))
    if "level_2a" in a.geometry and "level_2a" in b.geometry:
        for band in bands:
            ga = Level2AGeometry.from_tree(a.geometry["level_2a"], band)
            gb = Level2AGeometry.from_tree(b.geometry["level_2a"], band)
            what = f"level_2a/bands/{band}/inverse_grid_px"
            if ga.inverse_line.shape != gb.inverse_line.shape:
                out.append(
                    Finding(
                        "geometry", what, ok=False, a=ga.inverse_line.shape, b=gb.inverse_line.shape
                    )
                )
                continue
            d = float(
                max(
                    np.abs(ga.inverse_line - gb.inverse_line).max(),
                    np.abs(ga.inverse_column - gb.inverse_column).max(),
                )
            )
            out.append(Finding("geometry", what, d, tol["grid_px"], d <= tol["grid_px"]))
    if "level_1b" in a.geometry and "level_1b" in b.geometry:
        for band in bands:
            pa = Level1BGeometry.from_tree(a.geometry["level_1b"], band)
            pb = Level1BGeometry.from_tree(b.geometry["level_1b"], band)
            rows = np.linspace(0.0, pa.n_rows - 1.0, 101)
            cols = np.linspace(0.0, pa.n_cols - 1.0, 101)
            d = max(
                float(np.abs(fa(x) - fb(x)).max())
                for fa, fb, x in ((pa.f, pb.f, rows), (pa.g, pb.g, cols), (pa.h, pb.h, rows))
            )
            out.append(
                Finding(
                    "geometry",
                    f"level_1b/bands/{band}/polynomials_px",
                    d,
                    tol["grid_px"],
                    d <= tol["grid_px"],
                )
            )
    return out


#: The trees' groups, compared as trees (``compare_products``), and the attributes HDF5
#: dimension scales keep as object references (their targets are compared instead).
_TREES = ("geometry", "quality", "provenance", "bands")
_REFERENCE_ATTRS = ("DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME")


def compare_stored(
    a: str | Path, b: str | Path, tol: dict[str, dict[str, float]] | None = None
) -> list[Finding]:
    """Two product files as stored, outside their trees: every root variable and its
    attributes (coordinates, grid mapping, bands' and masks' attributes), and their values
    but the images' (``_pixels``): the coordinates within ``corner_shift_m``, numbers of the
    grid mapping (``GeoTransform``) within it too, everything else exactly. Products of
    two format versions store differently: noted, not compared."""
    import h5py

    limit = (tol or load_tolerances(None))["geometry"]["corner_shift_m"]
    out: list[Finding] = []
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        fv = [int(f.attrs.get("format_version", 0)) for f in (fa, fb)]
        if fv[0] != fv[1]:  # two layouts: what they hold is compared above, not how kept
            return [Finding("provenance", "stored layout: format_version", a=fv[0], b=fv[1])]
        names = sorted((set(fa) | set(fb)) - set(_TREES))
        images = {n for n in names if f"{n}_valid" in names}
        for n in names:
            if n not in fa or n not in fb:
                out.append(
                    Finding(
                        "schema",
                        n,
                        ok=False,
                        a="present" if n in fa else "missing",
                        b="present" if n in fb else "missing",
                    )
                )
                continue
            out += _stored_attrs(n, fa[n].attrs, fb[n].attrs, limit)
            if n in images or n.endswith("_valid") or not isinstance(fa[n], h5py.Dataset):
                continue
            va, vb = np.asarray(fa[n][()]), np.asarray(fb[n][()])
            if va.shape != vb.shape:
                out.append(Finding("stored", f"{n} shape", ok=False, a=va.shape, b=vb.shape))
            elif va.dtype.kind == "f" and vb.dtype.kind == "f":
                d = float(np.max(np.abs(va - vb))) if va.size else 0.0
                out.append(Finding("stored", f"{n} (m)", d, limit, d <= limit))
            elif not np.array_equal(va, vb):
                out.append(Finding("stored", n, ok=False, a="…", b="values differ"))
    if not any(not f.ok for f in out):
        out.append(Finding("stored", "variables and attributes", value="identical"))
    return out


def _stored_attrs(name: str, a: Any, b: Any, limit: float) -> list[Finding]:
    """The attributes of one variable: present in both and equal; ``GeoTransform``'s
    numbers within ``limit``."""
    out = []
    for k in sorted((set(a) | set(b)) - set(_REFERENCE_ATTRS)):
        what = f"{name}@{k}"
        if k not in a or k not in b:
            out.append(
                Finding(
                    "schema",
                    what,
                    ok=False,
                    a="present" if k in a else "missing",
                    b="present" if k in b else "missing",
                )
            )
            continue
        va, vb = a[k], b[k]
        if k == "GeoTransform":
            try:
                ga = np.array(str(va).split(), dtype=np.float64)
                gb = np.array(str(vb).split(), dtype=np.float64)
                d = float(np.max(np.abs(ga - gb))) if ga.shape == gb.shape else math.inf
            except ValueError:
                d = math.inf
            out.append(Finding("stored", what, d, limit, d <= limit))
        elif _differs(va, vb):
            out.append(Finding("stored", what, ok=False, a=_plain(va), b=_plain(vb)))
    return out


def _tree_numbers(tree: dict[str, object], prefix: str = "") -> dict[str, object]:
    """Every leaf of a tree by its path."""
    out: dict[str, object] = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            out.update(_tree_numbers(v, f"{prefix}{k}/"))
        else:
            out[prefix + k] = v
    return out


def _geometry_leaves(a: Product, b: Product, tol: dict[str, float]) -> list[Finding]:
    """Every number of the two geometry trees: image coordinates (inverse grids,
    polynomials: ``inverse_`` or ``level_1b/`` in the path) within ``grid_px``, the scene's
    corners by ``_geometry`` (skipped), every other within ``rel`` of its dataset's largest
    magnitude; every other leaf equal (paths present in one only: ``_schema``)."""
    la, lb = _tree_numbers(a.geometry), _tree_numbers(b.geometry)
    out = []
    for k in sorted(set(la) & set(lb)):
        if k.startswith("scene/"):
            continue
        in_pixels = "inverse_" in k or k.startswith("level_1b/")
        va, vb = la[k], lb[k]
        xa, xb = np.asarray(va), np.asarray(vb)
        if xa.dtype.kind in "fiu" and xb.dtype.kind in "fiu":
            if xa.shape != xb.shape:
                out.append(Finding("geometry", f"geometry/{k}", ok=False, a=xa.shape, b=xb.shape))
                continue
            d, scale = _finite_difference(xa, xb)
            bound = tol["grid_px"] if in_pixels else tol["rel"] * scale
            if not d <= bound:
                out.append(Finding("geometry", f"geometry/{k}", d, bound, ok=False))
        elif _differs(va, vb):
            out.append(Finding("geometry", f"geometry/{k}", ok=False, a=_plain(va), b=_plain(vb)))
    n = len(set(la) & set(lb))
    if not out:
        out.append(Finding("geometry", f"geometry ({n} values)", value="within tolerance"))
    return out


def _finite_difference(xa: NDArray[Any], xb: NDArray[Any]) -> tuple[float, float]:
    """The largest difference of two arrays of numbers of one shape, and the largest finite
    magnitude of the first. A value that is not finite must be the same in both (NaN for
    NaN, +inf for +inf: a level 2's unbounded σ of what it does not estimate), else the
    difference is infinite; two equal non-finite values differ by nothing."""
    fa, fb = xa.astype(np.float64), xb.astype(np.float64)
    same = (fa == fb) | (np.isnan(fa) & np.isnan(fb))
    if same.all():
        d = 0.0
    elif not (np.isfinite(fa) | same).all() or not (np.isfinite(fb) | same).all():
        d = math.inf
    else:
        diff = np.subtract(fa, fb, out=np.zeros_like(fa), where=~same)
        d = float(np.max(np.abs(diff)))
    finite = np.isfinite(fa)
    scale = float(np.max(np.abs(fa), where=finite, initial=0.0))
    return d, scale


def _same_figure(va: float, vb: float, bound: float) -> bool:
    """Two quality figures within ``bound``; equal non-finite figures (NaN and NaN, an
    unbounded σ and another) are the same figure."""
    if va == vb or (math.isnan(va) and math.isnan(vb)):
        return True
    return abs(va - vb) <= bound


def _quality(a: Product, b: Product, tol: dict[str, float]) -> list[Finding]:
    qa, qb = scalar_figures(a.quality), scalar_figures(b.quality)
    out = []
    for k in sorted(set(qa) | set(qb)):
        what = f"quality/{k}"
        if k not in qa or k not in qb:
            out.append(
                Finding("quality", what, ok=False, a=qa.get(k, "missing"), b=qb.get(k, "missing"))
            )
            continue
        va, vb = qa[k], qb[k]
        if isinstance(va, int | float) and isinstance(vb, int | float) and not isinstance(va, bool):
            bound = tol["abs"] + tol["rel"] * (abs(va) if math.isfinite(va) else 0.0)
            if not _same_figure(va, vb, bound):
                out.append(Finding("quality", what, ok=False, a=va, b=vb, tolerance=bound))
        elif va != vb:
            out.append(Finding("quality", what, ok=False, a=va, b=vb))
    n = len(set(qa) | set(qb))
    if not out:
        out.append(Finding("quality", f"quality ({n} figures)", value="within tolerance"))
    return out


def _provenance(a: Product, b: Product) -> list[Finding]:
    out = []
    pa, pb = a.provenance, b.provenance
    for k in sorted(set(pa) | set(pb)):
        va, vb = pa.get(k), pb.get(k)
        if va == vb:
            continue
        if k == "processing":
            try:
                ca, cb = json.loads(va or "{}"), json.loads(vb or "{}")
            except (json.JSONDecodeError, TypeError):
                ca, cb = va, vb
            if not isinstance(ca, dict) or not isinstance(cb, dict):
                ca, cb = {"processing": va}, {"processing": vb}
            for key in sorted(set(ca) | set(cb)):
                if ca.get(key) != cb.get(key):
                    out.append(
                        Finding("provenance", f"processing/{key}", a=ca.get(key), b=cb.get(key))
                    )
        else:
            out.append(Finding("provenance", f"provenance/{k}", a=va, b=vb))
    return out
