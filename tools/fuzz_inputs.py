"""Fuzz what a user writes and is handed: scenarios, control-point files, DEMs, tolerance
files and command lines, and the files of outside producers (DIMAP zips, ERS frames in ESA's
format), mutated by hypothesis and handed to ``station`` as a user would.

    python tools/fuzz_inputs.py 10000              # 10 000 cases, every kind in turn
    python tools/fuzz_inputs.py 500 --kind gcps    # one kind
    python tools/fuzz_inputs.py 10000 --kind files # DIMAP zips, .E1 frames, control points

The files' cases mutate every count, size, offset and number field of each format: an .E1's
``KEY=value`` header fields (of the MPH, the SPH and every data set descriptor) and the
binary fields of its records (the main processing parameters, Doppler, SR/GR and
geolocation records, the image records' times), a DIMAP's numbers and elements, its zip
(members' declared sizes, truncation, a member inflating past the cap, its image's bytes),
a control-point file's cells and rows; then ``station locate`` or ``station process``.

Every case runs ``station.cli.main`` in this process, in a sandbox directory of its own
(the current directory while it runs), on inputs written there and with ``--out`` inside
it. What must hold, whatever the input (the issue's bar):

- the exit code is 0, 1 or 2 (never 3: a bug), or argparse's own 2 for a bad command line;
- stderr holds no traceback;
- no file appears outside ``--out`` other than the inputs the case wrote;
- no case runs past ``CASE_BOUND_S`` (a hang), nor raises the process's peak memory by
  more than ``CASE_MEMORY_BYTES``, nor runs out of the run's ``ADDRESS_SPACE_BYTES`` (a
  blow-up); the run's peak is printed.

Most cases ask for the checks only (``run --check``, ``process --check``: what a user's
input meets first); a share runs the real work where it is quick (one in ten mutated
scenarios that check out, when under 0.2 Mpx; a reduced scene's level 2 on mutated control
points, level 3 on a mutated DEM). The first case that breaks a rule
is shrunk by hypothesis to its smallest form and printed; the tool then exits 1. The
figures (cases per kind, exit codes) are printed at the end.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "scenarios" / "small_test.toml"
REFDATA = Path(os.environ.get("SPOT_REFDATA", ROOT.parent / "shared" / "refdata"))
DIMAP = REFDATA / "dimap" / "spot2_hrv1_P_19980220_izmit_METADATA.DIM"
KINDS = ("scenario", "gcps", "dem", "tolerances", "command", "dimap", "envisat")
#: ``--kind files``: the files of outside producers, and control points.
FILE_KINDS = ("dimap", "envisat", "gcps")
#: A case running longer than this is a hang (s): a refusal reads a header in a second.
CASE_BOUND_S = 30
#: A case raising the process's peak resident memory by more than this is a blow-up: a
#: small scene's processing takes a few hundred MB.
CASE_MEMORY_BYTES = 1.5 * 2**30
#: The run's address space (bytes): its interpreter, numba's compiler and a small scene's
#: processing take about 3 GB of it; a case past it fails "out of memory", counted a blow-up.
ADDRESS_SPACE_BYTES = 12 * 2**30

#: Values a user gets wrong: out of range, of the wrong type, not numbers, paths.
NASTY_TEXT = ["", "nan", "inf", "-inf", "-1", "0", "1e308", "-1e308", "x", "1,2", "../x", "/etc"]
NASTY_PATHS = ["../x", "/etc/passwd", "", ".", "a/b", "N00E010.hgt", "missing.tif", "nul\u0000"]


def nasty_scalars() -> st.SearchStrategy:
    return st.one_of(
        st.integers(min_value=-(2**70), max_value=2**70),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([0, 1, -1, 2**31, 10**6, 1e-300, 0.5]),
        st.text(max_size=12),
        st.sampled_from(NASTY_PATHS),
        st.booleans(),
    )


def nasty_values() -> st.SearchStrategy:
    return st.one_of(nasty_scalars(), st.lists(nasty_scalars(), max_size=4))


def toml_value(v: object) -> str:
    """``v`` as a TOML value (NaN and infinities as TOML spells them)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return json.dumps(str(v))  # a TOML basic string: JSON's escapes


def toml_text(table: dict) -> str:
    """A two-level table (scalars, then sections) as TOML text."""
    lines = [f"{k} = {toml_value(v)}" for k, v in table.items() if not isinstance(v, dict)]
    for section, values in table.items():
        if isinstance(values, dict):
            lines.append(f"[{section}]")
            lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in values.items()]
    return "\n".join(lines) + "\n"


def mutated_text(draw, text: str) -> str:
    """Text with a few byte-level mutations: a cut, a flipped character, an insertion."""
    chars = list(text)
    for _ in range(draw(st.integers(1, 3))):
        if not chars:
            break
        k = draw(st.integers(0, len(chars) - 1))
        op = draw(st.sampled_from(["cut", "flip", "insert", "delete"]))
        if op == "cut":
            chars = chars[:k]
        elif op == "flip":
            chars[k] = chr(draw(st.integers(0, 0x2FF)))
        elif op == "insert":
            chars.insert(k, draw(st.sampled_from(["\n", "=", "[", '"', ",", "\x00", "é"])))
        else:
            del chars[k]
    return "".join(chars)


class Fixture:
    """What every case starts from, made once: the small scenario's run (its L0 archive,
    control points, products) and a real DIMAP."""

    def __init__(self, root: Path) -> None:
        from station.cli import main

        self.run = root / "base_run"
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            code = main(["run", str(SMALL), "--out", str(self.run), "-q", "--no-quicklooks"])
        if code != 0:
            raise SystemExit(f"the base run of {SMALL} failed ({code})")
        self.l0 = self.run / "small_test.l0.h5"
        self.gcps = self.run / "small_test.gcp.csv"
        self.product = self.run / "small_test_s000_1A.h5"
        self.scenario = tomllib.loads(SMALL.read_text())
        self.dimap_zip = root / "scene.zip"  # the small run's 1A as SWH's zip
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            main(["export", str(self.product), "--dimap", str(self.dimap_zip), "-q"])
        self.e1 = root / "frame.E1"  # an emulated ERS frame in ESA's format
        self.e1_ground = root / "ground.E1"  # the same on ground range (an SR/GR polynomial)
        from levels.writers.envisat import write_envisat
        from station.spacecraft.sar import ErsFrame, emulate_frame
        from station.spacecraft.world import World

        world = World(lon0_rad=np.radians(-56.1), base_height_m=200.0, relief_m=300.0, seed=3)
        image, _ = emulate_frame(ErsFrame(n_lines=120, n_samples=100), world)
        write_envisat(self.e1, image)
        write_envisat(self.e1_ground, image, ground_range=True)


def scenario_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    from station.scenario import _SECTIONS

    table = json.loads(json.dumps(fx.scenario))
    how = draw(st.sampled_from(["set", "set", "set", "delete", "text", "unknown"]))
    if how in ("set", "delete"):
        section = draw(st.sampled_from([*_SECTIONS, ""]))
        if section:
            from dataclasses import fields

            keys = [f.metadata["key"] for f in fields(_SECTIONS[section]) if "key" in f.metadata]
            keys = keys or ["x"]
            key = draw(st.sampled_from(keys))
            sec = table.setdefault(section, {})
            if how == "set":
                sec[key] = draw(nasty_values())
            else:
                sec.pop(key, None)
        else:
            table[draw(st.sampled_from(["name", "seed"]))] = draw(nasty_values())
        text = toml_text(table)
    elif how == "unknown":
        table[draw(st.sampled_from(["extra", "processing"]))] = {
            draw(st.text(min_size=1, max_size=8)): draw(nasty_values())
        }
        text = toml_text(table)
    else:
        text = mutated_text(draw, SMALL.read_text())
    path = box / "s.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return ["run", str(path), "--out", str(out), "-q", "--no-quicklooks", "--check"]


def gcps_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    lines = fx.gcps.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    header, rows = lines[len(head)], [r.split(",") for r in lines[len(head) + 1 :]]
    how = draw(st.sampled_from(["cell", "cell", "rows", "header", "text"]))
    if how == "cell":
        for _ in range(draw(st.integers(1, 4))):
            r = draw(st.integers(0, len(rows) - 1))
            c = draw(st.integers(0, len(rows[r]) - 1))
            rows[r][c] = draw(st.one_of(st.sampled_from(NASTY_TEXT), st.text(max_size=6)))
    elif how == "rows":
        keep = draw(st.lists(st.integers(0, len(rows) - 1), max_size=20))
        rows = [rows[k] for k in keep]
    elif how == "header":
        cols = header.split(",")
        k = draw(st.integers(0, len(cols) - 1))
        cols[k] = draw(st.sampled_from(["", "lon_deg", "x", cols[k].upper()]))
        header = ",".join(cols)
    text = "\n".join([*head, header, *(",".join(r) for r in rows)]) + "\n"
    if how == "text":
        text = mutated_text(draw, text)
    path = box / "p.gcp.csv"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    target = draw(st.sampled_from(["process", "process", "check", "locate"]))
    if target == "locate":
        return ["locate", str(DIMAP), "--gcps", str(path)]
    argv = ["process", str(fx.l0), "--levels", "2", "--gcps", str(path), "--out", str(out), "-q"]
    return [*argv, "--check"] if target == "check" else argv


def dem_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    import warnings

    import rasterio
    from rasterio.transform import Affine

    path = box / "d.tif"
    if draw(st.integers(0, 9)) == 0:  # not a raster at all
        path.write_bytes(draw(st.binary(max_size=64)))
    else:
        rows, cols = draw(st.integers(1, 24)), draw(st.integers(1, 24))
        base = draw(st.sampled_from([450.0, 0.0, -9000.0, 29000.0, 0.45, float("nan")]))
        noise = draw(st.floats(0, 5000, allow_nan=False))
        rng = np.random.default_rng(draw(st.integers(0, 2**31)))
        heights = (base + noise * rng.standard_normal((rows, cols))).astype(np.float32)
        if draw(st.booleans()):
            heights[rng.random((rows, cols)) < 0.3] = np.nan
        crs = draw(st.sampled_from([None, "EPSG:4326", "EPSG:32721", "EPSG:3857", "EPSG:4978"]))
        step = draw(st.sampled_from([0.02, -0.02, 1e-9, 10.0, 30.0]))
        x0 = draw(st.sampled_from([-56.4, -56.3, 10.0, 179.9, 560000.0]))
        y0 = draw(st.sampled_from([-15.3, 0.0, 8270000.0, 91.0]))
        flip = draw(st.booleans())
        gt = Affine(step, 0.0, x0, 0.0, step if flip else -abs(step), y0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(
                path,
                "w",
                driver="GTiff",
                width=cols,
                height=rows,
                count=1,
                dtype="float32",
                crs=crs,
                transform=gt,
            ) as d:
                d.write(heights[None])
    opts = box / "o.toml"
    vertical = draw(st.sampled_from(["ellipsoid", "egm96", "moon"]))
    opts.write_text(
        f'[processing]\nlevels = ["3"]\ndem_path = "{path.name}"\ndem_vertical = "{vertical}"\n'
    )
    argv = ["process", str(fx.l0), "--options", str(opts), "--out", str(out), "-q"]
    return argv if draw(st.integers(0, 3)) == 0 else [*argv, "--check"]


def tolerances_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    from levels.compare import DEFAULT_TOLERANCES

    table: dict = {}
    for _ in range(draw(st.integers(1, 3))):
        section = draw(st.sampled_from([*DEFAULT_TOLERANCES, "other"]))
        keys = [*DEFAULT_TOLERANCES.get(section, {"x": 0}), "unknown"]
        table.setdefault(section, {})[draw(st.sampled_from(keys))] = draw(nasty_values())
    text = toml_text(table)
    if draw(st.integers(0, 4)) == 0:
        text = mutated_text(draw, text)
    path = box / "t.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return ["compare", str(fx.product), str(fx.product), "--tolerances", str(path)]


#: Numbers a field of a file gets wrong: huge, negative, zero, tiny, not finite, not numbers.
NASTY_NUMBERS = ["+0999999999", "-000000001", "+0000000000", "9" * 20, "-1", "0", "1e308",
                 "-1e308", "1e-300", "nan", "inf", "-inf", "", "x", "0x10", "1,5"]  # fmt: skip


def _nasty_number(draw) -> str:
    return draw(st.one_of(st.sampled_from(NASTY_NUMBERS), st.integers(-(2**40), 2**40).map(str)))


def envisat_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    """An .E1 frame with one of its counts, sizes, offsets or numbers forged, or its bytes
    damaged (module docstring)."""
    from levels.readers.envisat import (
        DOPPLER_ADSR,
        GEOLOCATION_ADSR,
        MDS_PREFIX,
        MPH_SIZE,
        MPP_ADSR,
        SRGR_ADSR,
        _headers,
    )

    src = draw(st.sampled_from([fx.e1, fx.e1_ground]))
    raw = bytearray(src.read_bytes())
    how = draw(st.sampled_from(["header", "header", "header", "record", "record", "bytes"]))
    _, _, datasets = _headers(src, bytes(raw))
    if how == "header":  # a KEY=value field of the MPH, the SPH or a descriptor
        head = MPH_SIZE + int(re.search(rb"SPH_SIZE=\+?(\d+)", raw).group(1))
        fields = list(re.finditer(rb"\n([A-Z_0-9]+)=([^\n]*)", bytes(raw[:head])))
        m = draw(st.sampled_from(fields))
        a, b = m.span(2)
        value = _nasty_number(draw).encode()
        if draw(st.booleans()):  # the same width, as an editor leaves it
            value = value[: b - a].ljust(b - a)
        raw[a:b] = value
    elif how == "record":  # a binary field of a record, in its own type
        name, dtype = draw(
            st.sampled_from(
                [
                    ("MAIN PROCESSING PARAMS ADS", MPP_ADSR),
                    ("DOP CENTROID COEFFS ADS", DOPPLER_ADSR),
                    ("SR GR ADS", SRGR_ADSR),
                    ("GEOLOCATION GRID ADS", GEOLOCATION_ADSR),
                    ("MDS1", None),
                ]
            )
        )
        ds = datasets.get(name)
        if ds is None:
            return ["locate", str(src)]
        rec = draw(st.integers(0, max(ds.num_dsr - 1, 0)))
        at = ds.offset + rec * ds.dsr_size
        if dtype is None:  # an image record's zero-Doppler time and line number
            at += draw(st.integers(0, MDS_PREFIX - 4))
            kind = ">i4"
        else:
            field = draw(st.sampled_from(list(dtype.fields)))
            sub, off = dtype.fields[field][:2]
            at += off + (draw(st.integers(0, max(sub.itemsize // 4 - 1, 0))) * 4)
            kind = (
                ">f4" if sub.base.kind == "f" or (sub.fields is None and "f" in sub.str) else ">i4"
            )
        value = draw(
            st.sampled_from([0.0, -1.0, 1e-30, 3e38, float("nan"), float("inf"), -float("inf")])
            if kind == ">f4"
            else st.sampled_from([0, 1, -1, 2**31 - 1, -(2**31), 123456789])
        )
        raw[at : at + 4] = np.array(value, kind).tobytes()
    else:  # bytes flipped, or the file cut
        if draw(st.booleans()):
            for _ in range(draw(st.integers(1, 20))):
                raw[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 255))
        else:
            raw = raw[: draw(st.integers(0, len(raw)))]
    path = box / "f.E1"
    path.write_bytes(bytes(raw))
    if draw(st.integers(0, 2)) == 0:
        return ["process", str(path), "--levels", "GEC", "--out", str(out), "-q"]
    return ["locate", str(path)]


def dimap_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    """A DIMAP scene's zip with a number or an element of its METADATA.DIM forged, or the
    zip itself damaged (module docstring)."""
    import zipfile

    with zipfile.ZipFile(fx.dimap_zip) as z:
        members = {i.filename: z.read(i) for i in z.infolist() if "truth/" not in i.filename}
    dim_name = next(n for n in members if n.endswith("METADATA.DIM"))
    tif_name = next(n for n in members if n.endswith("IMAGERY.TIF"))
    how = draw(st.sampled_from(["number"] * 4 + ["element", "image", "bomb", "zip"]))
    dim = members[dim_name].decode()
    if how == "number":  # any element holding a number
        spots = [m.span(1) for m in re.finditer(r">([-+]?[0-9][0-9.eE+-]*)<", dim)]
        a, b = draw(st.sampled_from(spots))
        dim = dim[:a] + _nasty_number(draw) + dim[b:]
    elif how == "element":  # an element removed, or given twice
        tags = [m for m in re.finditer(r"<([A-Za-z_]+)>[^<]*</\1>", dim)]
        m = draw(st.sampled_from(tags))
        dim = dim[: m.start()] + (m.group(0) * 2 if draw(st.booleans()) else "") + dim[m.end() :]
    members[dim_name] = dim.encode()
    if how == "image":  # the image's bytes: its header, or the file cut
        tif = bytearray(members[tif_name])
        if draw(st.booleans()):
            for _ in range(draw(st.integers(1, 12))):
                tif[draw(st.integers(0, min(len(tif) - 1, 4096)))] = draw(st.integers(0, 255))
        else:
            tif = tif[: draw(st.integers(0, len(tif)))]
        members[tif_name] = bytes(tif)
    if how == "bomb":  # a member that inflates past the metadata cap
        from levels.readers.bounded import MAX_METADATA_BYTES

        head = dim.index("?>") + 2
        members[dim_name] = (
            dim[:head] + "<!--" + " " * int(1.2 * MAX_METADATA_BYTES) + "-->" + dim[head:]
        ).encode()
    path = box / "s.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    if how == "zip":  # the zip's own structure: a declared size forged, or the zip cut
        raw = bytearray(path.read_bytes())
        if draw(st.booleans()):
            sizes = [m.start() + 22 for m in re.finditer(rb"PK\x03\x04", raw)]
            sizes += [m.start() + 24 for m in re.finditer(rb"PK\x01\x02", raw)]
            at = draw(st.sampled_from(sizes))
            raw[at : at + 4] = np.array(
                draw(st.sampled_from([0, 1, 2**31, 2**32 - 1])), "<u4"
            ).tobytes()
        else:
            raw = raw[: draw(st.integers(0, len(raw)))]
        path.write_bytes(bytes(raw))
    target = draw(st.sampled_from(["locate", "locate", "check", "process"]))
    if target == "locate":
        return ["locate", str(path)]
    argv = ["process", str(path), "--levels", "1A", "--out", str(out), "-q"]
    return [*argv, "--check"] if target == "check" else argv


#: Command-line words: the commands fuzzed, their options, and values good and bad.
_COMMANDS = ("run", "process", "compare", "inspect", "export", "locate")
_OPTIONS = (
    "--json",
    "--levels",
    "--name",
    "--gcps",
    "--options",
    "--scenario",
    "--tolerances",
    "--workers",
    "--scheduler",
    "--attitude",
    "--model",
    "--heights",
    "--rpc",
    "--geotiff",
    "--no-quicklooks",
    "-v",
    "-q",
    "--help",
    "--bogus",
)


def command_case(draw, fx: Fixture, box: Path, out: Path) -> list[str]:
    cmd = draw(st.sampled_from(_COMMANDS))
    values = st.sampled_from(
        [
            str(fx.l0),
            str(fx.product),
            str(fx.gcps),
            str(SMALL),
            str(DIMAP),
            str(fx.run),
            "1A,2A",
            "3",
            "2,2",
            "4096",
            "-1",
            "0",
            "nonsense",
            "rpc",
            "0,1e9",
            "5,1",
            "../evil",
            "/tmp",
            "",
            "x" * 300,
            str(out / "x_RPC.TXT"),
        ]
    )
    words = draw(st.lists(st.one_of(st.sampled_from(_OPTIONS), values), max_size=6))
    argv = [cmd, *words]
    if cmd in ("run", "process"):
        argv += ["--out", str(out), "--check"]
    elif cmd == "export":
        argv += ["--out", str(out / "x.tif")]
    elif cmd == "locate" and "--rpc" in words:
        argv += ["--rpc", str(out / "y_RPC.TXT")]
    return argv


CASES = {
    "scenario": scenario_case,
    "gcps": gcps_case,
    "dem": dem_case,
    "tolerances": tolerances_case,
    "command": command_case,
    "dimap": dimap_case,
    "envisat": envisat_case,
}


#: A mutated scenario runs for real when it checks out and is this small (pixels).
FULL_RUN_PIXELS = 2e5


def full_run(argv: list[str]) -> list[str] | None:
    """``argv`` (a ``run --check``) without ``--check`` when its scenario is small."""
    from station.loader import load_scenario
    from station.preflight import run_needs

    if run_needs(load_scenario(argv[1])).pixels > FULL_RUN_PIXELS:
        return None
    return [a for a in argv if a != "--check"]


class Hang(BaseException):
    """A case past ``CASE_BOUND_S``: raised by the alarm, out of ``station``'s reach (its
    ``main`` says every ``Exception`` as exit 3)."""


def _alarm(signum: int, frame: object) -> None:
    raise Hang(f"still running after {CASE_BOUND_S} s")


def peak_rss_bytes() -> float:
    """The process's peak resident memory so far (Linux's ``ru_maxrss``, in KiB)."""
    return float(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024.0


def run_case(argv: list[str]) -> tuple[int, str]:
    """``station`` on ``argv`` in this process: its exit code and stderr; a case past
    ``CASE_BOUND_S`` is stopped, as exit ``HANG``."""
    from station.cli import main

    err = io.StringIO()
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CASE_BOUND_S)
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse: usage error (2) or --help (0)
            code = exc.code if isinstance(exc.code, int) else 2
        except Hang:
            code = HANG
        finally:
            signal.alarm(0)
    return code, err.getvalue()


#: The code a case stopped as a hang is counted under.
HANG = -1


def files_under(d: Path) -> set[Path]:
    return {p for p in d.rglob("*") if p.is_file() or p.is_symlink()}


def _bound(case, kind: str):
    """``case`` with its kind given: a function of its data, as hypothesis takes one."""

    def one(data: st.DataObject) -> None:
        case(kind, data)

    one.__name__ = f"case_{kind}"
    return one


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("n", type=int, nargs="?", default=1000, help="cases (default 1000)")
    parser.add_argument(
        "--kind",
        choices=[*KINDS, "files"],
        help="one kind of input only (files: " + ", ".join(FILE_KINDS) + ")",
    )
    parser.add_argument("--seed", type=int, default=0, help="hypothesis seed (default 0)")
    args = parser.parse_args(argv)
    kinds = FILE_KINDS if args.kind == "files" else (args.kind,) if args.kind else KINDS
    # a case that asks for the machine's memory fails as "out of memory", not by the kernel's
    # OOM killer taking the run (and the machine's other work) with it
    resource.setrlimit(resource.RLIMIT_AS, (int(ADDRESS_SPACE_BYTES), resource.RLIM_INFINITY))
    counts: Counter = Counter()
    slowest = [0.0, ""]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="fuzz_inputs_") as tmp:
        root = Path(tmp)
        fx = Fixture(root)
        here = os.getcwd()
        serial = iter(range(10**9))

        def case(kind: str, data: st.DataObject) -> None:
            box = root / f"case{next(serial)}"
            box.mkdir()
            out = box / "out"
            argv = CASES[kind](data.draw, fx, box, out)
            before = files_under(box)
            os.chdir(box)
            peak0, t_case = peak_rss_bytes(), time.perf_counter()
            try:
                code, err = run_case(argv)
                if kind == "scenario" and code == 0 and data.draw(st.integers(0, 9)) == 0:
                    argv = full_run(argv)  # a share of the valid ones run for real
                    if argv:
                        code, err = run_case(argv)
            finally:
                os.chdir(here)
            took = time.perf_counter() - t_case
            if took > slowest[0]:
                slowest[:] = [took, f"{kind}: {' '.join(argv[:2])}"]
            counts[(kind, code)] += 1
            strays = [p for p in files_under(box) - before if out not in p.parents]
            problems = []
            grew = peak_rss_bytes() - peak0
            if grew > CASE_MEMORY_BYTES:
                problems.append(f"the peak memory grew by {grew / 2**30:.1f} GiB")
            if "out of memory" in err:  # the address-space cap (main) reached: a blow-up
                problems.append("out of memory")
            if code == HANG:
                problems.append(f"a hang (stopped after {CASE_BOUND_S} s)")
            elif code not in (0, 1, 2):
                problems.append(f"exit {code}")
            if "Traceback" in err:
                problems.append("a traceback")
            if strays:
                problems.append(f"files outside --out: {sorted(map(str, strays))[:3]}")
            if problems:
                counts[("violations", kind)] += 1
                keep = Path(here) / "fuzz_failure"  # the inputs, to reproduce it
                shutil.rmtree(keep, ignore_errors=True)
                shutil.copytree(box, keep, ignore=shutil.ignore_patterns("out"))
                raise AssertionError(
                    f"{kind}: {', '.join(problems)}\n  argv: {argv}\n  stderr: {err.strip()}"
                )

        failed = None
        for k, kind in enumerate(kinds):  # each kind its share (one draw of them all: uneven)
            share = args.n // len(kinds) + (k < args.n % len(kinds))
            run = settings(
                max_examples=share,
                deadline=None,
                database=None,
                derandomize=False,
                suppress_health_check=list(HealthCheck),
                phases=[Phase.generate, Phase.shrink],
            )(given(st.data())(_bound(case, kind)))
            try:
                seed(args.seed)(run)()
            except AssertionError as exc:
                failed = str(exc)
                break
    elapsed = time.perf_counter() - t0
    total = sum(v for (k, _), v in counts.items() if k != "violations")
    print(f"{total} cases in {elapsed:.0f} s ({1e3 * elapsed / max(total, 1):.0f} ms each)")
    for kind in kinds:
        codes = {c: v for (k, c), v in sorted(counts.items(), key=str) if k == kind}
        print(f"  {kind:<11} {sum(codes.values()):6d} cases, exit codes {codes}")
    exit3 = sum(v for (k, c), v in counts.items() if c == 3 and k != "violations")
    hangs = sum(v for (k, c), v in counts.items() if c == HANG and k != "violations")
    print(
        f"exit 3: {exit3}; hangs (past {CASE_BOUND_S} s): {hangs}; the slowest case "
        f"{slowest[0]:.1f} s ({slowest[1]}); peak memory {peak_rss_bytes() / 2**30:.2f} GiB"
    )
    print(f"cases breaking a rule: {0 if failed is None else 'see below'}")
    if failed is not None:
        print(f"FIRST FAILURE (shrunk; its inputs in ./fuzz_failure/):\n{failed}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
