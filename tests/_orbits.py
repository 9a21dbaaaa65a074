"""Analytic and numerically integrated orbits, and a synthetic HRV scene, for the tests.

The Keplerian orbit is exact (Kepler's equation solved to machine precision), so it is an
outside reference for the Lagrange interpolation; the J2 orbit is integrated by scipy's
DOP853 at tight tolerance.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from levels.geometry import (
    Ephemeris,
    Epoch,
    LineClock,
    LookAngleTable,
    PushbroomModel,
    SampledAttitude,
    mirror_angle_rad,
)
from levels.geometry.frames import eci_to_ecef

GM_M3_PER_S2 = 3.986004418e14  # WGS84 / IERS
J2 = 1.08262668e-3
RE_M = 6378137.0

#: SPOT-like mean elements: 822 km at the equator, near-circular, 98.7°.
SPOT_A_M = 7200.5e3
SPOT_E = 1.2e-3
SPOT_I_RAD = np.radians(98.7)

#: The HRV's P detector pitch (rad) and its 4 CCDs' along-track butting (rad), as the
#: emulator's defaults (DESIGN.md: SPOT facts).
P_PITCH_RAD = 1.1987e-5
BUTTING_RAD = np.array([0.0, 4.0, -3.0, 2.0]) * 1e-6

#: The mean anomaly at t = 0 that puts ``synthetic_pass``'s scene on a descending track at
#: about 15° S (argument of latitude ≈ 195° with ``kepler_eci``'s argument of perigee).
DESCENDING_M0_RAD = 2.79

EPOCH = Epoch(np.datetime64("1998-02-20T09:16:00", "ns"), name="test epoch")


def kepler_eci(
    t_s, a_m=SPOT_A_M, e=SPOT_E, i_rad=SPOT_I_RAD, raan_rad=1.2, argp_rad=0.4, m0_rad=0.3
):
    """Exact two-body position and velocity (ECI), shape (N, 3) each."""
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    n = np.sqrt(GM_M3_PER_S2 / a_m**3)
    mean = m0_rad + n * t
    ecc = mean.copy()
    for _ in range(30):  # Newton on Kepler's equation E − e sin E = M
        ecc -= (ecc - e * np.sin(ecc) - mean) / (1.0 - e * np.cos(ecc))
    cos_e, sin_e = np.cos(ecc), np.sin(ecc)
    r_pf = np.stack([a_m * (cos_e - e), a_m * np.sqrt(1 - e * e) * sin_e, 0 * t], axis=-1)
    edot = n / (1.0 - e * cos_e)
    v_pf = np.stack([-a_m * sin_e * edot, a_m * np.sqrt(1 - e * e) * cos_e * edot, 0 * t], axis=-1)
    cw, sw, ci, si, co, so = (
        np.cos(argp_rad),
        np.sin(argp_rad),
        np.cos(i_rad),
        np.sin(i_rad),
        np.cos(raan_rad),
        np.sin(raan_rad),
    )
    rot = np.array(
        [
            [co * cw - so * sw * ci, -co * sw - so * cw * ci, so * si],
            [so * cw + co * sw * ci, -so * sw + co * cw * ci, -co * si],
            [sw * si, cw * si, ci],
        ]
    )
    return r_pf @ rot.T, v_pf @ rot.T


def j2_eci(t_s, r0_m, v0_m_per_s):
    """Position and velocity under J2, integrated from (r0, v0) at t = 0 (DOP853, rtol 1e-13)."""

    def rhs(_t, y):
        r = y[:3]
        rn = np.linalg.norm(r)
        z2 = (r[2] / rn) ** 2
        k = 1.5 * J2 * GM_M3_PER_S2 * RE_M**2 / rn**5
        acc = -GM_M3_PER_S2 * r / rn**3 + k * r * np.array([5 * z2 - 1, 5 * z2 - 1, 5 * z2 - 3])
        return np.concatenate([y[3:], acc])

    t = np.asarray(t_s, dtype=np.float64)
    sol = solve_ivp(
        rhs,
        (0.0, float(t.max())),
        np.concatenate([r0_m, v0_m_per_s]),
        method="DOP853",
        t_eval=t,
        rtol=1e-13,
        atol=1e-7,
    )
    return sol.y[:3].T, sol.y[3:].T


def ecef_states(t_s, eci=kepler_eci):
    r, v = eci(t_s)
    return eci_to_ecef(r, v, EPOCH.era_rad(t_s))


def hrv_model(mirror_step=48, n_lines=6000, n_columns=6000, jitter=True, step_s=60.0):
    """A synthetic HRV P scene: Keplerian ephemeris every ``step_s``, attitude with offsets,
    a slow drift and jitter, and a look-angle table of ``n_columns`` detectors (10 m at nadir)."""
    t_eph = np.arange(0.0, 8 * step_s, step_s)  # 8 samples, like the SPOT 1–4 files
    r, v = ecef_states(t_eph)
    eph = Ephemeris(t_eph, r, v)
    t_centre = t_eph[3] + 0.37 * step_s
    clock = LineClock(t_centre, 0.5 * (n_lines - 1), 1.504e-3 * 6000 / n_lines)
    t_att = np.arange(t_centre - 6.0, t_centre + 6.0, 0.125)
    s = t_att - t_centre
    angles = np.stack(
        [
            2e-4 + 1e-6 * s + (3e-6 * np.sin(2 * np.pi * s / 0.9) if jitter else 0),  # roll
            -1.5e-4 + 2e-6 * s + (2e-6 * np.sin(2 * np.pi * s / 1.3) if jitter else 0),  # pitch
            3e-4 - 1e-6 * s,  # yaw
        ],
        axis=-1,
    )
    att = SampledAttitude(t_att, angles)
    half_swath_rad = 0.0361  # ±30 km from 830 km: 60 km at nadir, whatever n_columns is
    psi_y = np.array([-half_swath_rad, half_swath_rad]) + mirror_angle_rad(mirror_step)
    table = LookAngleTable(
        np.array([0.0, n_columns - 1.0]), np.array([1.07e-2, 1.11e-2]), psi_y, n_columns
    )
    return PushbroomModel(EPOCH, clock, eph, att, table, n_lines)


def synthetic_pass(n_lines=400, n_detectors=400, mirror_step=48, reference_height_m=450.0):
    """GEO of a synthetic pass (``levels.geo.scenes.pass_geometry``), without the emulator:
    the Keplerian ephemeris every 60 s, gyro records every 0.125 s of a slow steady drift,
    a look-angle table of ``n_detectors`` across the HRV's 60 km at nadir (its P pitch
    scaled to the detector count, its 4 CCDs butted by ``BUTTING_RAD``), ``n_lines`` lines
    of 1.504 ms × 6000 / ``n_detectors``.
    Returns the pass, its scene (all its lines) and the nominal pixel."""
    from levels.geo.scenes import cut_scenes, pass_geometry
    from levels.passes import nominal_pixel_size_m

    t_eph = np.arange(0.0, 8 * 60.0, 60.0)
    # descending over 15° S at the scene, as the station's passes over Brazil are
    r, v = ecef_states(t_eph, lambda t: kepler_eci(t, m0_rad=DESCENDING_M0_RAD))
    period = 1.504e-3 * 6000 / n_detectors
    t0 = t_eph[3] + 0.37 * 60.0 - 0.5 * (n_lines - 1) * period
    line_t = t0 + period * np.arange(n_lines)
    gyro_t = np.arange(line_t[0] - 1.0, line_t[-1] + 1.0, 0.125)
    rates = np.tile([1e-6, 2e-6, -1e-6], (gyro_t.size, 1))
    # the HRV's P pitch scaled to the detector count, its 4 CCDs butted along the track
    j = np.arange(n_detectors, dtype=np.float64)
    pitch = P_PITCH_RAD * 6000 / n_detectors
    psi_y = (j - (n_detectors - 1) / 2) * pitch + mirror_angle_rad(mirror_step)
    ccd = np.minimum((4 * (j + 0.5) / n_detectors).astype(int), 3)
    table = LookAngleTable(j, BUTTING_RAD[ccd], psi_y, n_detectors)
    pg = pass_geometry(EPOCH, line_t, period, Ephemeris(t_eph, r, v), gyro_t, rates, {"P": table})
    (cut,) = cut_scenes(n_lines, n_lines)
    return pg, pg.scene(cut, reference_height_m), nominal_pixel_size_m(table)


def synthetic_gcps(scene, n=40, seed=3, sigma_ground_m=8.0, sigma_h_m=5.0, sigma_px=0.3):
    """Control points of a synthetic scene: ``n`` image points drawn over it, located by
    its own model at heights of a few hundred metres (``levels.readers.gcp``'s set; their
    stated σ the emulator's defaults)."""
    from levels.readers.gcp import ControlPointSet

    rng = np.random.default_rng(seed)
    model = next(iter(scene.models.values()))
    line = rng.uniform(0.0, model.n_lines - 1.0, n)
    column = rng.uniform(0.0, model.look_angles.n_columns - 1.0, n)
    h = rng.uniform(200.0, 800.0, n)
    g = model.image_to_ground(line, column, h)
    return ControlPointSet(
        tuple(f"g{k}" for k in range(n)),
        g.lon_rad,
        g.lat_rad,
        g.h_m,
        line,
        column,
        np.full(n, sigma_ground_m),
        np.full(n, sigma_h_m),
        np.full(n, sigma_px),
        np.ones(n, dtype=np.int64),
    )


#: ERS-1's C-band wavelength (m), its pulse repetition frequency (Hz) and its slant-range
#: sample (m): the AMI's (the emulator's ``ERS1``).
ERS_WAVELENGTH_M = 0.05656
ERS_PRF_HZ = 1679.9
ERS_RANGE_SAMPLE_M = 7.905


def synthetic_frame(n_lines=120, n_samples=100, azimuth_looks=5, range_looks=2, seed=3):
    """A detected ERS-like slant-range frame without the emulator (``levels.sar``): five
    state vectors 10 s apart of ``kepler_eci``'s orbit on its descending track, zero
    Doppler, right-looking at 850 km of near range, and speckled intensity (three looks)
    over a smooth pattern."""
    from levels.sar import SarAnnotation, SarImage

    t = np.arange(5) * 10.0
    r, v = ecef_states(t, lambda tt: kepler_eci(tt, m0_rad=DESCENDING_M0_RAD))
    annotation = SarAnnotation(
        EPOCH,
        t,
        r,
        v,
        first_line_s=18.0,
        line_interval_s=azimuth_looks / ERS_PRF_HZ,
        near_range_m=850e3,
        range_spacing_m=range_looks * ERS_RANGE_SAMPLE_M,
        wavelength_m=ERS_WAVELENGTH_M,
        doppler_hz=(0.0,),
        shape=(n_lines, n_samples),
        looks=float(azimuth_looks),
    )
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:n_lines, 0:n_samples]
    pattern = 0.2 + 0.1 * np.sin(xx / 7.0) * np.cos(yy / 11.0)
    intensity = (pattern * rng.gamma(3.0, 1.0 / 3.0, pattern.shape)).astype(np.float32)
    return SarImage(annotation, intensity)


def smooth_table(table):
    """A look-angle table's smooth part: a cubic across the line, without the CCD
    buttings' steps."""
    c = np.asarray(table.column, dtype=np.float64)
    fit = (np.polyval(np.polyfit(c, a, 3), c) for a in (table.psi_x_rad, table.psi_y_rad))
    return LookAngleTable(c, *fit, table.n_columns)
