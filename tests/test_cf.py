"""Every level's product against the CF conventions it declares (CF-1.11), by the IOOS
compliance-checker: no high- or medium-priority failure, full score."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from levels.products import product_name
from station.cli import main

LEVELS = ("1A", "1B", "2A", "2", "3")
#: Checks of compliance-checker 6.1 that raise on any file with groups and no ``time``
#: dimension (a KeyError 'time' inside the checker, whatever the file holds): reported by
#: the checker as its own exception, not as a finding about the product.
CHECKER_EXCEPTIONS = {"check_invalid_same_named_dimension_across_groups"}
SCENARIO = """
name = "cf"
seed = 4
[instrument]
n_detectors = 300
n_lines = 300
[downlink]
bit_rate_mbps = 0.2
preamble_s = 0.1
postamble_s = 0.1
[dem]
spacing_arcsec = 10.0
[processing]
levels = ["1A", "1B", "2A", "2", "3"]
"""


@pytest.fixture(scope="module")
def every_level(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cf")
    (d / "cf.toml").write_text(SCENARIO)
    out = d / "run"
    assert main(["run", str(d / "cf.toml"), "--out", str(out), "-q", "--no-quicklooks"]) == 0
    return out


@pytest.mark.parametrize("level", LEVELS)
def test_cf_1_11_without_a_failure(level, every_level, tmp_path, capsys) -> None:
    """CF §2.1 asks for the ``.nc`` name, which the map levels have; the image-geometry
    levels keep ``.h5`` (for GDAL's sake: ``levels.products.MAP_SUFFIX``) and are checked
    under a ``.nc`` copy: their content is what is checked."""
    import warnings

    from compliance_checker.runner import CheckSuite, ComplianceChecker

    nc = tmp_path / f"cf_{level}.nc"
    shutil.copy(every_level / product_name("cf", 0, level, level in ("2A", "2", "3")), nc)
    CheckSuite.load_all_available_checkers()
    report = tmp_path / "report.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        passed, raised = ComplianceChecker.run_checker(
            str(nc), ["cf:1.11"], 0, "normal", output_filename=str(report), output_format="json"
        )
    said = capsys.readouterr()
    own = {
        ln.split(":", 2)[1].rsplit(".", 1)[-1]
        for ln in (said.out + said.err).splitlines()
        if ln.startswith("cf:1.11.")
    }
    result = json.loads(report.read_text())["cf:1.11"]
    failures = [
        m for k in ("high_priorities", "medium_priorities") for c in result[k] for m in c["msgs"]
    ]
    assert passed and not failures, failures
    assert own <= CHECKER_EXCEPTIONS and (own or not raised), own
    assert result["scored_points"] == result["possible_points"]
