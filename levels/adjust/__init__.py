"""Level 2: control points refine the sensor model, from one scene to a whole pass.

Westin's pass adjustment (paper ``000_…``), on this project's rigorous model
(:class:`~levels.geometry.model.PushbroomModel`) instead of his plane circular orbit:

Parameters (eqs. 1–3)
    For the **pass**: a bias of the ephemeris along track, across track and radial, and its
    growth per second (six; Westin's ΔΩ, Δi, Δr0 are the same freedoms of a plane orbit).
    For **each scene** ``j``: offsets of roll, pitch, yaw (Westin's Δω0, Δρ0, Δκ0) and their
    rates over the scene. The corrections are applied to the pass's attitude integrated from
    the gyros (:func:`~levels.geometry.attitude.integrate_rates`: Westin's "start values
    calculated from the preceding scene"), so that with attitude records all the way every
    scene needs the same correction. Westin's per-scene time Δt0 is not needed: every row of
    a pass comes from one fitted line clock (:class:`~levels.geo.scenes.PassGeometry`), so
    the scenes' relative timing is known; the clock's absolute error is an along-track bias.

Observations
    Each control point gives the collinearity condition (eqs. 7–9) as two angles: the
    direction to the point seen from the projection centre of its measured line, in the
    sensor frame, minus the look-angle table's at its measured column, expressed in pixels
    (the table's pitch). Its weight is ``(A Q Aᵀ)⁻¹`` (eq. 20): ``A`` the partials of the
    condition with respect to the point's line, column, east, north and height (numerical),
    ``Q`` their a priori variances from the control-point file. The pass parameters are
    observed as zero with the error budget's σ (eq. 4, 10), the first scene's attitude as
    zero (eq. 5, 11), and each following scene's attitude *difference* with the previous
    one (eqs. 6, 12) with the variance of its increment: the gyros' random walk,
    ``σ_g² T Δt``, where records are continuous, and Westin's variogram (eqs. 24–26,
    ``levels.geometry.attitude.westin_variogram_rad2``) over the records lost in a gap.
    Rates are observed as zero with the gyro noise averaged over a scene.

Solution
    Weighted nonlinear least squares in parameters scaled by their a priori σ:
    Gauss–Newton on the sparse normal equations (``scipy``), the first fit with a robust
    loss by iteratively reweighted least squares; then Baarda's data
    snooping: normalised residuals ``v / σ_v`` (``σ_v² = 1 − h``, ``h`` the leverage),
    points beyond the threshold rejected and reported, and a plain least-squares fit on the
    rest. Its covariance (a priori: the error budget is trusted, the unit-weight σ0 is
    reported beside it) propagates to a **predicted accuracy** of every scene, with or
    without control points: the ground displacement (east, north on the reference surface)
    that the parameters' covariance makes at a lattice of the scene's pixels.

The package, by stage: :mod:`~levels.adjust.model` (parameters, observations, the
result), :mod:`~levels.adjust.solve` (Gauss–Newton, snooping, prediction),
:mod:`~levels.adjust.passes` (a pass, a twin pass), :mod:`~levels.adjust.block` (a block of
passes tied by tie points).

Modes: ``pass`` (all scenes together, Westin) and ``scene`` (each alone: its six pass
parameters its own). One control point, or none, is handled by the same equations: what the
points cannot determine is held by the priors, and the predicted σ says so.
"""

from levels.adjust.block import adjust_block
from levels.adjust.model import PASS_PARAMETERS, SCENE_PARAMETERS, Adjustment, Strip
from levels.adjust.passes import adjust, adjust_strips

__all__ = [
    "PASS_PARAMETERS",
    "SCENE_PARAMETERS",
    "Adjustment",
    "Strip",
    "adjust",
    "adjust_block",
    "adjust_strips",
]
