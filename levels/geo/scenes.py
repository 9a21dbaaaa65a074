"""GEO, once per pass: the pass's geometry and its cutting into scenes.

INPE's GEO (paper ``004_…`` §2.1) takes, for all scenes of a pass:

* the **attitude** from the gyro rates, integrated "assuming a null attitude for the first
  received attitude rate record" and, per scene, with "the attitude at scene center time ...
  subtracted ... thus zeroing the scene center attitude" (:func:`integrate_rates`,
  :meth:`SampledAttitude.zeroed_at`). The absolute attitude is never known to the system
  levels: the constant offsets ω0, ρ0, κ0 of the truth are what 1B and 2A are off by;
* the **ephemeris** of the bulletins, by 8-point ("seventh order") Lagrange
  (:class:`~levels.geometry.ephemeris.Ephemeris`);
* the **line clock** from the recorded line times;
* the photogrammetric model of the geometry core, one per scene and band, with the scene's
  own line numbering (line 0 is the scene's first line);
* the scene centre and corners, located on the reference surface: the ellipsoid raised by the
  scene's reference height (the mean altitude a producer takes from a global DEM).

Scenes are cut along the pass every ``length − overlap`` lines; a tail shorter than a
scene is not a scene (it is reported, not silently dropped: :attr:`PassGeometry.tail_lines`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from levels.errors import GeometryError
from levels.geometry.attitude import GAP_FACTOR, SampledAttitude, integrate_rates
from levels.geometry.ephemeris import Ephemeris
from levels.geometry.model import LineClock, PushbroomModel
from levels.geometry.sensor import LookAngleTable
from levels.geometry.times import Epoch
from levels.threads import one_blas_thread

__all__ = [
    "PassGeometry",
    "SceneCut",
    "SceneGeometry",
    "cut_scenes",
    "models_of_tree",
    "pass_geometry",
]


@dataclass(frozen=True)
class SceneCut:
    """One scene of a pass: its first line among the pass's rows, its number of lines."""

    index: int
    first_line: int
    n_lines: int

    @property
    def centre_line(self) -> float:
        """The scene's centre line, in the scene's own numbering."""
        return 0.5 * (self.n_lines - 1)


def cut_scenes(
    n_lines: int, scene_lines: int, overlap_lines: int = 0, partial: bool = False
) -> list[SceneCut]:
    """Scenes of ``scene_lines`` lines every ``scene_lines − overlap_lines`` along a pass;
    with ``partial``, the lines after the last whole scene as a last, shorter scene (from
    where the next scene would start), so that no line is left out.

    A pass shorter than one scene gives one scene of the whole pass.
    """
    if scene_lines < 2 or not 0 <= overlap_lines < scene_lines:
        raise GeometryError(
            f"scene_lines={scene_lines}, overlap_lines={overlap_lines}: need scene_lines >= 2 "
            "and 0 <= overlap_lines < scene_lines"
        )
    if n_lines < 2:
        raise GeometryError(f"a pass of {n_lines} lines cannot be cut into scenes")
    if n_lines <= scene_lines:
        return [SceneCut(0, 0, n_lines)]
    step = scene_lines - overlap_lines
    starts = np.arange(0, n_lines - scene_lines + 1, step)
    cuts = [SceneCut(k, int(s), scene_lines) for k, s in enumerate(starts)]
    end = int(starts[-1]) + scene_lines
    if partial and end < n_lines:
        first = int(starts[-1]) + step
        if n_lines - first >= 2:
            cuts.append(SceneCut(len(cuts), first, n_lines - first))
    return cuts


@dataclass(frozen=True, eq=False)
class SceneGeometry:
    """GEO's result for one scene: the model of each band, centre and corners.

    ``corners_lat_rad`` / ``corners_lon_rad`` are in the order first line first column,
    first line last column, last line last column, last line first column (clockwise on a
    descending pass).
    """

    cut: SceneCut
    t_centre_s: float
    models: dict[str, PushbroomModel]
    attitude_at_centre_rad: NDArray[np.float64]
    reference_height_m: float
    centre_lat_rad: float
    centre_lon_rad: float
    corners_lat_rad: NDArray[np.float64]
    corners_lon_rad: NDArray[np.float64]

    def attitude_lines(self) -> NDArray[np.float64]:
        """Scene lines at the attitude samples, with the first and last line: where the
        model's attitude (linear between samples) changes slope."""
        model = self.model
        att = model.attitude
        inner = model.clock.line(att.t_s)  # type: ignore[attr-defined]
        last = self.cut.n_lines - 1.0
        inner = inner[(inner > 1.0) & (inner < last - 1.0)]
        return np.concatenate([[0.0], inner, [last]])

    @property
    def model(self) -> PushbroomModel:
        """The model of the first band (the scene's geometry for level 1B/2A grids)."""
        return next(iter(self.models.values()))


@dataclass(frozen=True, eq=False)
class PassGeometry:
    """GEO's inputs for a whole pass, from the L0 archive.

    Parameters
    ----------
    epoch
        Origin of every ``t_s``.
    line_t_s
        Time of each row of the pass (s), from the line clock.
    line_period_s
        Nominal line period (s).
    ephemeris
        The bulletins (positions and velocities in ECEF).
    attitude
        Attitude integrated from the gyro rates, null at the first record.
    look_angles
        Nominal look-angle table of each band (mirror included).
    """

    epoch: Epoch
    line_t_s: NDArray[np.float64]
    line_period_s: float
    ephemeris: Ephemeris
    attitude: SampledAttitude
    look_angles: dict[str, LookAngleTable]

    def __post_init__(self) -> None:
        t = np.asarray(self.line_t_s, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
            raise GeometryError("line times must be a 1-D increasing array of at least 2 lines")
        object.__setattr__(self, "line_t_s", t)
        # one straight line through the recorded times of the whole pass (they come from
        # one fitted clock already), fitted once for every scene
        period, t0 = np.polyfit(np.arange(t.size, dtype=np.float64), t, 1)
        object.__setattr__(self, "_clock_fit", (float(t0), float(period)))

    @property
    def n_lines(self) -> int:
        return int(self.line_t_s.size)

    def clock(self, first_line: int) -> LineClock:
        """Line clock of a scene starting at row ``first_line``, from the pass's fit."""
        t0, period = self._clock_fit  # type: ignore[attr-defined]
        return LineClock(t0 + period * first_line, 0.0, period)

    @one_blas_thread
    def scene(
        self,
        cut: SceneCut,
        reference_height_m: float = 0.0,
        *,
        ephemeris: Ephemeris | None = None,
        attitude: SampledAttitude | None = None,
    ) -> SceneGeometry:
        """GEO for one scene: models with the attitude zeroed at the scene centre, centre
        and corners on the reference surface.

        Level 2 gives its refined ``ephemeris`` and ``attitude`` (absolute: used as given,
        not zeroed; :meth:`levels.adjust.Adjustment.refine`).
        """
        clock = self.clock(cut.first_line)
        t_c = float(clock.time_s(cut.centre_line))
        if attitude is None:
            att = self.attitude.zeroed_at(t_c)  # INPE §2.1: null attitude at scene centre
            at_centre = self.attitude.angles_rad(np.array([t_c]))[0]
        else:
            att, at_centre = attitude, attitude.angles_rad(np.array([t_c]))[0]
        eph = self.ephemeris if ephemeris is None else ephemeris
        models = {
            name: PushbroomModel(self.epoch, clock, eph, att, look, cut.n_lines)
            for name, look in self.look_angles.items()
        }
        model = next(iter(models.values()))
        nl, nc = cut.n_lines - 1, model.n_columns - 1
        line = np.array([cut.centre_line, 0, 0, nl, nl], dtype=np.float64)
        col = np.array([0.5 * nc, 0, nc, nc, 0], dtype=np.float64)
        g = model.image_to_ground(line, col, reference_height_m)
        if not np.all(g.ok):
            t_att = self.attitude.t_s
            t_end = float(clock.time_s(nl))
            raise GeometryError(
                f"scene {cut.index}: centre or corners not located (its lines "
                f"{clock.time_s(0):.2f}–{t_end:.2f} s; attitude known over "
                f"{t_att[0]:.2f}–{t_att[-1]:.2f} s, ephemeris over "
                f"{self.ephemeris.span_s[0]:.0f}–{self.ephemeris.span_s[1]:.0f} s)"
            )
        return SceneGeometry(
            cut,
            t_c,
            models,
            at_centre,
            reference_height_m,
            float(g.lat_rad[0]),
            float(g.lon_rad[0]),
            g.lat_rad[1:],
            g.lon_rad[1:],
        )

    def product_tree(self, scene: SceneGeometry) -> dict[str, object]:
        """The part of a product's ``geometry`` tree every level shares: the epoch, the
        scene, its clock, the ephemeris and attitude used (the attitude records within 2 s
        of the scene), the look angles of each band (``docs/products.md``)."""
        att, eph = scene.model.attitude, scene.model.ephemeris
        t = att.t_s  # type: ignore[attr-defined]
        margin_s = 2.0
        keep = (t >= scene.model.clock.time_s(0) - margin_s) & (
            t <= scene.model.clock.time_s(scene.cut.n_lines - 1) + margin_s
        )
        return {
            "epoch_utc": str(self.epoch.t0_utc),
            "reference_height_m": scene.reference_height_m,
            "scene": {
                "first_line": scene.cut.first_line,
                "n_lines": scene.cut.n_lines,
                "t_centre_s": scene.t_centre_s,
                "centre_lat_deg": float(np.degrees(scene.centre_lat_rad)),
                "centre_lon_deg": float(np.degrees(scene.centre_lon_rad)),
                "corners_lat_deg": np.degrees(scene.corners_lat_rad),
                "corners_lon_deg": np.degrees(scene.corners_lon_rad),
            },
            "clock": {
                "t_first_line_s": float(scene.model.clock.time_s(0)),
                "line_period_s": scene.model.clock.period_s,
            },
            "ephemeris": {
                "t_s": eph.t_s,
                "r_ecef_m": eph.r_ecef_m,
                "v_ecef_m_per_s": eph.v_ecef_m_per_s,
                "lagrange_points": eph.n_points,
                **(
                    {"reference_velocity": eph.reference_velocity} if eph.reference_velocity else {}
                ),
            },
            "attitude": {
                "t_s": t[keep],
                "angles_rad": att.angles_rad_samples[keep],  # type: ignore
                "integrated_at_centre_rad": scene.attitude_at_centre_rad,
                "note": "gyro rates integrated from a null first record, zeroed at "
                "the scene centre (INPE)",
            },
            "look_angles": {
                name: {
                    "column": m.look_angles.column,
                    "psi_x_rad": m.look_angles.psi_x_rad,
                    "psi_y_rad": m.look_angles.psi_y_rad,
                }
                for name, m in scene.models.items()
            },
        }

    def scenes(
        self, scene_lines: int, overlap_lines: int = 0, reference_height_m: float = 0.0
    ) -> list[SceneGeometry]:
        """GEO for every scene of the pass (:func:`cut_scenes`)."""
        return [
            self.scene(c, reference_height_m)
            for c in cut_scenes(self.n_lines, scene_lines, overlap_lines)
        ]

    def tail_lines(self, scene_lines: int, overlap_lines: int = 0) -> int:
        """Rows after the last whole scene (made as a partial scene, or skipped and said)."""
        cuts = cut_scenes(self.n_lines, scene_lines, overlap_lines)
        return self.n_lines - (cuts[-1].first_line + cuts[-1].n_lines)


def models_of_tree(tree: dict[str, Any]) -> tuple[Epoch, dict[str, PushbroomModel]]:
    """The epoch and each band's model of a product's ``geometry`` tree, as
    :meth:`PassGeometry.product_tree` wrote them (scene line 0 is the product's row 0): the
    model the product was made with, rebuilt from the product alone."""
    from levels.geometry.times import parse_utc

    try:
        epoch = Epoch(parse_utc(str(tree["epoch_utc"])), name="the product's epoch")
        clock = LineClock(
            float(tree["clock"]["t_first_line_s"]), 0.0, float(tree["clock"]["line_period_s"])
        )
        e = tree["ephemeris"]
        eph = Ephemeris(
            np.asarray(e["t_s"]),
            np.asarray(e["r_ecef_m"]),
            np.asarray(e["v_ecef_m_per_s"]),
            int(e.get("lagrange_points", 8)),
            e.get("reference_velocity") or None,
        )
        a = tree["attitude"]
        att = SampledAttitude(np.asarray(a["t_s"]), np.asarray(a["angles_rad"]))
        n_lines = int(tree["scene"]["n_lines"])
        looks = {
            band: LookAngleTable(
                np.asarray(t["column"]),
                np.asarray(t["psi_x_rad"]),
                np.asarray(t["psi_y_rad"]),
                int(np.asarray(t["column"])[-1]) + 1,
            )
            for band, t in tree["look_angles"].items()
        }
    except KeyError as exc:
        raise GeometryError(f"product geometry tree without {exc}: no model to rebuild") from None
    return epoch, {
        band: PushbroomModel(epoch, clock, eph, att, look, n_lines) for band, look in looks.items()
    }


@one_blas_thread
def pass_geometry(
    epoch: Epoch,
    line_t_s: NDArray[np.float64],
    line_period_s: float,
    ephemeris: Ephemeris,
    gyro_t_s: NDArray[np.float64],
    gyro_rates_rad_per_s: NDArray[np.float64],
    look_angles: dict[str, LookAngleTable],
) -> PassGeometry:
    """GEO's pass set-up: integrate the gyro rates from a null attitude at the first record,
    holding the attitude across records lost in the downlink
    (:func:`~levels.geometry.attitude.integrate_rates`)."""
    order = np.argsort(gyro_t_s, kind="stable")
    t, keep = np.unique(np.asarray(gyro_t_s)[order], return_index=True)
    rates = np.asarray(gyro_rates_rad_per_s)[order][keep]
    # INPE §2.1: null attitude at the first record; held across lost records (Westin)
    gap = GAP_FACTOR * float(np.median(np.diff(t))) if t.size > 2 else None
    attitude = integrate_rates(t, rates, max_gap_s=gap)
    return PassGeometry(
        epoch,
        np.asarray(line_t_s, float),
        float(line_period_s),
        ephemeris,
        attitude,
        dict(look_angles),
    )
