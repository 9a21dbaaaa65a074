"""Reference frames and rotations: every convention of the geometry core, stated once.

Vectors
    Arrays of vectors have shape ``(N, 3)``: one vector per row, components on the last
    axis. A single vector may be passed as shape ``(3,)``. Names give the frame before the
    unit: ``r_ecef_m``, ``v_eci_m_per_s``, ``los_sensor``.

Rotations
    A rotation matrix maps components from one frame to another and is named
    ``<to>_from_<from>``, so that ``v_to = to_from_from @ v_from`` and chains read right to
    left: ``ecef_from_sensor = ecef_from_orbital @ orbital_from_sensor``. Stacks of matrices
    have shape ``(N, 3, 3)``. The elementary rotations :func:`rot_x`, :func:`rot_y`,
    :func:`rot_z` are *active* and right-handed: ``rot_z(a) @ [1, 0, 0]`` is the x unit vector
    turned by ``a`` towards +y. Used as a change of frame, ``rot_z(a)`` gives the components,
    in the old frame, of a vector known in a frame turned by ``+a`` about z.

Frames
    ECEF
        WGS84 Earth-centred Earth-fixed (ITRF-like): origin at the Earth's centre of mass,
        z to the conventional pole, x to the Greenwich meridian, right-handed. Polar motion
        is neglected (< 15 m at the pole, the same in the emulator and the model).
    ECI
        The intermediate celestial frame obtained from ECEF by the Earth rotation angle
        alone (IERS 2010 CIRS ↔ TIRS, eq. 5.15): z along the ECEF z axis, x towards the
        Celestial Intermediate Origin. Precession–nutation is not applied: the frame is
        quasi-inertial over a pass, which is all the emulator and the model need.
    Local orbital (SPOT Geometry Handbook, S-NT-73-12-SI)
        Origin at the satellite, ``Z = P/|P|`` (radial, up), ``X = (V × Z)/|V × Z|`` (across
        track), ``Y = Z × X`` (along track, forward for a prograde velocity). ``P`` and ``V``
        are taken as given: SPOT 1–4 metadata carry the inertial velocity in ECEF axes and
        SPOT 5 the Earth-fixed one; using each as given is what the producer does.
    Satellite body (after attitude)
        The orbital frame turned by the attitude angles: roll about the along-track axis Y,
        pitch about the across-track axis X, yaw about the radial axis Z. SPOT gives the
        angles in a frame whose X and Y axes are inverted, so roll and pitch enter with the
        opposite sign to the right-handed rotations (:func:`orbital_from_body`).
    Local east, north, up (ENU)
        At a geodetic latitude and longitude: east, north and the ellipsoid normal
        (:func:`enu_from_ecef`); ground errors are stated in it.
    Sensor
        The HRV/HRG viewing frame, aligned with the body frame; a detector looks along
        ``normalise(-tan psi_y, tan psi_x, -1)`` (``levels.geometry.sensor``), with ``psi_y``
        across track (mirror included) and ``psi_x`` along track.

Every rotation here is checked by the round-trip and real-scene tests; a wrong sign shows
up as hundreds of metres at the corners of a real scene.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "REFERENCE_VELOCITIES",
    "apply",
    "apply_inverse",
    "ecef_from_eci",
    "ecef_from_orbital",
    "ecef_to_eci",
    "eci_to_ecef",
    "enu_from_ecef",
    "inertial_velocity_ecef",
    "normalize",
    "orbital_from_body",
    "rot_x",
    "rot_y",
    "rot_z",
]

#: Earth rotation rate of WGS84 (rad/s), as in IERS 2010 ERA rate x 2π / 86400 s.
EARTH_ROTATION_RATE_RAD_PER_S = 7.292115146706979e-5


def normalize(v: ArrayLike) -> NDArray[np.float64]:
    """Unit vectors along ``v`` (shape ``(..., 3)``); zero vectors become NaN."""
    v = np.asarray(v, dtype=np.float64)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / norm


def _rotation(angle_rad: ArrayLike, axis: int) -> NDArray[np.float64]:
    a = np.asarray(angle_rad, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_x(angle_rad: ArrayLike) -> NDArray[np.float64]:
    """Active right-handed rotation about x; shape ``(*angle.shape, 3, 3)``."""
    return _rotation(angle_rad, 0)


def rot_y(angle_rad: ArrayLike) -> NDArray[np.float64]:
    """Active right-handed rotation about y; shape ``(*angle.shape, 3, 3)``."""
    return _rotation(angle_rad, 1)


def rot_z(angle_rad: ArrayLike) -> NDArray[np.float64]:
    """Active right-handed rotation about z; shape ``(*angle.shape, 3, 3)``."""
    return _rotation(angle_rad, 2)


def ecef_from_orbital(r_ecef_m: ArrayLike, v_ecef_m_per_s: ArrayLike) -> NDArray[np.float64]:
    """Rotation from the local orbital frame to ECEF (columns are X, Y, Z of the orbital frame).

    Parameters
    ----------
    r_ecef_m, v_ecef_m_per_s
        Satellite position and velocity, shape ``(N, 3)`` or ``(3,)``.

    Returns
    -------
    ndarray, shape ``(N, 3, 3)`` or ``(3, 3)``
        ``ecef_from_orbital``; its columns are the orbital axes in ECEF.

    References
    ----------
    SPOT Geometry Handbook (S-NT-73-12-SI): Z = P/|P|, X = (V × Z)/|V × Z|, Y = Z × X.
    """
    z = normalize(r_ecef_m)
    x = normalize(_cross(np.asarray(v_ecef_m_per_s, dtype=np.float64), z))
    y = _cross(z, x)
    return np.stack([x, y, z], axis=-1)


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a × b`` of stacks ``(..., 3)``, component by component: ``np.cross`` costs ten
    times more on the few hundred vectors of a scene."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def orbital_from_body(
    roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike
) -> NDArray[np.float64]:
    """Rotation from the satellite body frame to the local orbital frame.

    ``orbital_from_body = rot_x(-pitch) @ rot_y(-roll) @ rot_z(yaw)``: yaw about the radial
    axis first, then roll about the along-track axis, then pitch about the across-track axis,
    roll and pitch with the sign inverted as SPOT defines them.

    The order and signs were established on the SPOT 5 scene of the reference data, whose
    attitude (up to 0.9 mrad, about 750 m on the ground) is the only one large enough to
    tell them apart: with them the producer's frame corners are reproduced to 0.05 m; with
    any other sign choice they miss by 23 m to 1.2 km. At SPOT attitudes (< 1e-2 rad) the
    order changes the result by less than 1e-4 rad times the angles.
    """
    # The product written out (9 vector expressions instead of three stacks and two
    # matrix products): a = −pitch, b = −roll, c = yaw.
    a = -np.asarray(pitch_rad, dtype=np.float64)
    b = -np.asarray(roll_rad, dtype=np.float64)
    c = np.asarray(yaw_rad, dtype=np.float64)
    a, b, c = np.broadcast_arrays(a, b, c)
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    out = np.empty((*a.shape, 3, 3))
    out[..., 0, 0] = cb * cc
    out[..., 0, 1] = -cb * sc
    out[..., 0, 2] = sb
    out[..., 1, 0] = ca * sc + sa * sb * cc
    out[..., 1, 1] = ca * cc - sa * sb * sc
    out[..., 1, 2] = -sa * cb
    out[..., 2, 0] = sa * sc - ca * sb * cc
    out[..., 2, 1] = sa * cc + ca * sb * sc
    out[..., 2, 2] = ca * cb
    return out


def ecef_from_eci(era_rad: ArrayLike) -> NDArray[np.float64]:
    """Rotation ECI → ECEF by the Earth rotation angle (IERS 2010 eq. 5.15, ``R3(-ERA)``).

    As a change of frame the ECEF axes are the ECI axes turned by ``+ERA`` about z, so the
    matrix is ``rot_z(-ERA)``.
    """
    return rot_z(-np.asarray(era_rad, dtype=np.float64))


def apply(rot: ArrayLike, vec: ArrayLike) -> NDArray[np.float64]:
    """``rot @ vec`` for stacks: rotations ``(N, 3, 3)`` or ``(3, 3)`` applied to vectors
    ``(N, 3)`` or ``(3,)``, one matrix per vector or one for all (the module's convention:
    ``v_to = apply(to_from_from, v_from)``)."""
    return np.einsum(
        "...ij,...j->...i", np.asarray(rot, dtype=np.float64), np.asarray(vec, dtype=np.float64)
    )


def apply_inverse(rot: ArrayLike, vec: ArrayLike) -> NDArray[np.float64]:
    """``rotᵀ @ vec`` for stacks, as :func:`apply`: the inverse rotation, without forming
    the transpose (``v_from = apply_inverse(to_from_from, v_to)``)."""
    return np.einsum(
        "...ji,...j->...i", np.asarray(rot, dtype=np.float64), np.asarray(vec, dtype=np.float64)
    )


def enu_from_ecef(lat_rad: ArrayLike, lon_rad: ArrayLike) -> NDArray[np.float64]:
    """Rotations ECEF → local east, north, up at geodetic ``lat_rad``, ``lon_rad``,
    ``(N, 3, 3)``: their rows are the east, north and up unit vectors in ECEF."""
    lat = np.asarray(lat_rad, dtype=np.float64)
    lon = np.asarray(lon_rad, dtype=np.float64)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    east = np.stack([-so, co, np.zeros_like(so)], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([east, north, up], axis=-2)


#: The velocities a local orbital frame may be built on (module docstring): SPOT 1–4's
#: inertial velocity in ECEF axes, SPOT 5's Earth-fixed one.
REFERENCE_VELOCITIES = ("inertial", "earth_fixed")


def inertial_velocity_ecef(r_ecef_m: ArrayLike, v_ecef_m_per_s: ArrayLike) -> NDArray[np.float64]:
    """The inertial velocity in ECEF axes, ``v + ω × r``, from the Earth-fixed one: what
    SPOT 1–4 ephemerides carry and their attitude's orbital frame follows."""
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RATE_RAD_PER_S])
    r = np.asarray(r_ecef_m, dtype=np.float64)
    return np.asarray(v_ecef_m_per_s, dtype=np.float64) + np.cross(omega, r)


def eci_to_ecef(
    r_eci_m: ArrayLike, v_eci_m_per_s: ArrayLike, era_rad: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and velocity from ECI to ECEF: ``r' = R r``, ``v' = R v − ω × r'``.

    Parameters
    ----------
    r_eci_m, v_eci_m_per_s
        Shape ``(N, 3)``.
    era_rad
        Earth rotation angle at each instant, shape ``(N,)`` (``levels.geometry.times``).
    """
    rot = ecef_from_eci(era_rad)
    r = apply(rot, r_eci_m)
    v = apply(rot, v_eci_m_per_s)
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RATE_RAD_PER_S])
    return r, v - np.cross(omega, r)


def ecef_to_eci(
    r_ecef_m: ArrayLike, v_ecef_m_per_s: ArrayLike, era_rad: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Inverse of :func:`eci_to_ecef`: ``r = Rᵀ r'``, ``v = Rᵀ (v' + ω × r')``."""
    rot = ecef_from_eci(era_rad)
    r_ecef = np.asarray(r_ecef_m, dtype=np.float64)
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RATE_RAD_PER_S])
    v_inertial = np.asarray(v_ecef_m_per_s, dtype=np.float64) + np.cross(omega, r_ecef)
    return apply_inverse(rot, r_ecef), apply_inverse(rot, v_inertial)
