"""RPC evaluation across the antimeridian on GDAL's own transformer test vectors
(``autotest/gcore/transformer.py``), and the longitude wrap it relies on."""

from __future__ import annotations

import numpy as np
import pytest

from levels.geo.rpc import Rpc, wrap_degrees

#: GDAL's test asks its reverse transform to land within 0.1 px of where it started.
GDAL_TEST_PX = 0.1


def _coefficients(text: str) -> np.ndarray:
    return np.array(text.split(), dtype=np.float64)


#: GDAL autotest ``gcore/transformer.py``, ``test_transformer_15``: an RPC of a 6600 × 4400
#: image with LONG_OFF 179.9, whose pixel (0, 0) GDAL's forward transform (DEM at 50 m)
#: places at (180.0228° E, 0.0611° N); the reverse transform, from that longitude or the
#: same minus 360°, must come back within 0.1 px.
GDAL_TEST_15 = {
    "line_off": 2191.17012189569,
    "samp_off": 3300.0420831968,
    "lat_off": 0.0,
    "lon_off": 179.9,
    "height_off": 50.0,
    "line_scale": 2197.23749680132,
    "samp_scale": 3295.90302088781,
    "lat_scale": -0.105215174097221,
    "lon_scale": 0.124705315627701,
    "height_scale": 10.0,
    "line_num": _coefficients(
        "0.00673418095252569 -1.38985626744028 -0.645141238074041 1.4661564574111e-05 "
        "0.00022202101663831 -4.32910472926433e-06 -1.90048143949724e-06 "
        "-0.00374486341484218 -0.00041396053769863 1.14148334846788e-09 "
        "-1.20458144309064e-07 -0.00618122456017927 -0.00783023711720404 "
        "1.32704635552568e-09 -0.0032532225011433 -0.00355239507036451 "
        "6.20315160857432e-10 -4.75170167074672e-07 1.37652348819162e-07 "
        "9.53393990126859e-12"
    ),
    "line_den": _coefficients(
        "1 0.000113241782375585 -7.43522609681362e-05 3.71535308900828e-08 "
        "0.000338102551252493 4.57912749279076e-07 -7.00823537484445e-08 "
        "9.01275640119332e-05 -0.000209723741981335 4.74972505083506e-09 "
        "7.2855438070338e-10 -3.16688523275456e-05 -4.49211037453489e-05 "
        "8.29706981496464e-12 7.58128162744879e-06 6.82536481272507e-07 "
        "2.58661007069147e-11 -3.9697791887986e-08 -5.06502821928986e-08 "
        "4.66978771069271e-11"
    ),
    "samp_num": _coefficients(
        "-0.000776008179693209 -0.380692820465227 1.0647540743599 1.72660888229082e-06 "
        "0.0028311896140173 -1.0466632896253e-06 3.17728359468736e-06 "
        "-0.000150466834838251 0.000566231304705376 -7.34786296240808e-11 "
        "5.90340934437437e-07 -0.00169917056998316 -0.00231193494979752 "
        "-2.71280972480264e-09 0.00482224415396017 0.00596164573794891 "
        "7.58464598771136e-09 -1.46075167736497e-07 -4.64652272450397e-07 "
        "-5.59268858101854e-13"
    ),
    "samp_den": _coefficients(
        "1 2.1759243891474e-05 -5.96367842636917e-06 6.03714873685079e-09 "
        "-0.000109764869260479 4.67786228725161e-07 -4.22013004308237e-07 "
        "0.000110379633112327 -0.00011679427405351 9.30515192365439e-09 "
        "1.09243100743555e-09 -3.29956656106618e-05 -4.1918167733603e-05 "
        "2.78076356769406e-11 -4.57011012884097e-06 -1.01453844685279e-05 "
        "2.60244039950836e-11 -3.52960090220746e-08 -4.49975439524006e-08 "
        "1.80641651820794e-11"
    ),
}


@pytest.mark.parametrize(
    "lon_off, lon, lat, pixel, line",
    [
        (179.9, 180.02280735469199, 0.061069145746997976, 0.0, 0.0),
        (-179.9, -180.02313813793387, -0.061398913932229765, 6600.0, 4400.0),
    ],
    ids=["east", "west"],
)
def test_gdal_transformer_test_15(lon_off, lon, lat, pixel, line) -> None:
    """GDAL's vectors, each longitude given on both turns (``± 360°``): the same image
    position, GDAL's pixel corners half a pixel from RPC00B's centres."""
    rpc = Rpc(**{**GDAL_TEST_15, "lon_off": lon_off}, fit_error_px={})
    got_line, got_samp = rpc.image_of(lat, [lon, lon - 360.0, lon + 360.0], 50.0)
    assert np.max(np.abs(got_samp + 0.5 - pixel)) <= GDAL_TEST_PX
    assert np.max(np.abs(got_line + 0.5 - line)) <= GDAL_TEST_PX


def test_wrap_degrees() -> None:
    assert wrap_degrees([180.0, -180.0, 179.99, 540.5, -190.0]) == pytest.approx(
        [-180.0, -180.0, 179.99, -179.5, 170.0]
    )
