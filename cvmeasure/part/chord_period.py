"""The chord count of an arc bent in equal chords, from the scallop its vertices leave.

A wire bent in ``N`` equal chords whose vertices lie on a circle of radius ``R`` departs
from that circle by a scallop: at angle ``u`` from a chord's middle (``|u| <= D/2``,
``D`` the chord's angle at the centre) the chord lies at ``R cos(D/2) / cos(u)`` from the
centre. Its peak-to-peak size is the chord's sagitta (``c^2 / 8R`` for a chord ``c``:
0.16 mm for 10 mm chords at R 80 mm), a few times the centreline's noise in a photo, too
little for vertices to stand out one by one but plain when the whole arc is tested at
once: the radial residual about a smooth curve is regressed on the scallop of each
candidate count, vertices spread evenly between the wire's ends (each end allowed to lie a
quarter chord from a vertex: a cut end, an end cap).

The models are compared with a likelihood ratio: the residual sum of squares each leaves,
over the centreline's noise variance (the larger of the best model's residual scatter and
the scatter at scales below a chord, :func:`centreline_noise_mm`) times how many centres
make one independent sample (their correlation along the wire). A count is reported only
when its scallop is significant against the smooth curve after allowing for every count
and end offset tried, and clearly better than every other count.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.special import chdtri

from cvmeasure.geometry import fit_circle_robust
from cvmeasure.warning import StageWarning

__all__ = [
    "PeriodicChords",
    "centreline_noise_mm",
    "chord_spacing_warning",
    "periodic_chords",
    "spacing_disagreement_deg",
]

#: Degree of the smooth curve (Legendre in the angle about the centre) the scallop is
#: tested against: large-scale departures from a circle (a tilted or lifted part, a lens
#: left over) are not vertices. Counts below ``MIN_DIVISIONS`` it could absorb are left
#: to the vertex search.
SMOOTH_DEGREE = 3
MIN_DIVISIONS = 3
#: False-alarm probability of the count against a smooth curve, all counts tried.
FALSE_ALARM = 1e-4
#: Likelihood ratio the best count must have over every other (2 ln 100).
MIN_MARGIN = 2.0 * math.log(100.0)
#: The scallop's size over an inscribed polygon's that equal chords on a circle can have
#: (vertices rounded by the pin, a centreline biased at the kinks): outside it the
#: periodic structure is something else (a harmonic of other chords, steps in the
#: centreline).
AMPLITUDE_RANGE = (0.5, 2.0)
#: How far the bend per chord from the wire's ends may lie from the vertices' spacing, in
#: the spacing's sigmas, before it is called into doubt (as stated sigmas are read: 2).
SPACING_SIGMAS = 2.0
#: The most the arc model may leave of the centreline's scatter, over its scatter at
#: scales below a chord, for its verdict to stand: beyond it the wire has structure at a
#: chord's scale the model does not describe (an S-curve, unequal chords, steps in the
#: centreline), and its vertices are searched one by one.
MAX_MISFIT = 3.0
#: Each wire end may lie this share of a chord from a vertex (searched in END_STEPS steps).
END_SLACK = 0.25
END_STEPS = 5
#: Centres the test uses at most (every k-th of a longer centreline: neighbouring centres
#: are correlated, and the scallop needs a few per chord: 8 per shortest chord are kept).
MAX_POINTS = 400


@dataclass(frozen=True)
class PeriodicChords:
    """The equal-chord count an arc's scallop shows, and how sure it is.

    Attributes
    ----------
    divisions : the count N, or None when no count is significant or one is not clearly
        better than the others.
    best_divisions : the count that fitted best (whether significant or not).
    chord_mm : its chord length, mm.
    chord_angle_deg : its chords' angle at the circle's centre, from the vertices' spacing
        (the wire's ends left out): for vertices on the circle, each vertex's bend;
        ``chord_angle_sigma_deg`` its one sigma (the noise's, with its correlation).
    amplitude : the scallop's size over an inscribed polygon's (1 for vertices on the
        circle; a shape that is not one reads far from 1).
    significance : twice the log-likelihood ratio of the best count over the smooth
        curve; ``threshold`` what it must reach.
    margin : twice the log-likelihood ratio of the best count over the next best count.
    noise_mm : the centreline noise used (1 sigma, mm); ``correlation``: centres per
        independent sample.
    reason : the decision in words.
    applies : the wire looks like an arc of equal chords: the best scallop's amplitude is
        one such chords can have (``AMPLITUDE_RANGE``) and the model leaves at most
        ``MAX_MISFIT`` times the centreline's noise below a chord. A count this test then
        cannot find is not to be found vertex by vertex either.
    """

    divisions: int | None
    best_divisions: int | None
    chord_mm: float
    chord_angle_deg: float
    chord_angle_sigma_deg: float
    amplitude: float
    significance: float
    threshold: float
    margin: float
    noise_mm: float
    correlation: float
    reason: str
    applies: bool


def centreline_noise_mm(points_mm: np.ndarray, window_mm: float = 1.5) -> float:
    """The centreline's noise at scales below a chord (1 sigma, mm).

    Around every centre, a quadratic across the wire is fitted to the centres within
    about ``window_mm`` along it (a chord's curvature and a vertex's kink mostly
    absorbed); the robust scatter (1.4826 MAD) of the middle centres' residuals, scaled
    for the fit's degrees of freedom, is the noise.
    """
    pts = np.asarray(points_mm, dtype=np.float64)
    step = float(np.median(np.hypot(*np.diff(pts, axis=0).T)))
    half = max(3, round(window_mm / max(step, 1e-9)))
    if len(pts) < 2 * half + 2:
        return math.nan
    idx = np.arange(half, len(pts) - half)
    win = pts[idx[:, None] + np.arange(-half, half + 1)[None, :]]  # (m, 2h+1, 2)
    along = win[:, -1] - win[:, 0]
    along /= np.maximum(np.hypot(along[:, 0], along[:, 1]), 1e-12)[:, None]
    rel = win - win[:, half : half + 1]
    t = rel[..., 0] * along[:, None, 0] + rel[..., 1] * along[:, None, 1]
    off = rel[..., 1] * along[:, None, 0] - rel[..., 0] * along[:, None, 1]
    a = np.stack((np.ones_like(t), t, t * t), axis=-1)  # (m, 2h+1, 3)
    at = a.transpose(0, 2, 1)
    coef = np.linalg.solve(at @ a, at @ off[..., None])[..., 0]
    res = off[:, half] - np.einsum("mk,mk->m", a[:, half], coef)
    m = 2 * half + 1
    return 1.4826 * float(np.median(np.abs(res))) * math.sqrt(m / (m - 3))


def _correlation(residuals: np.ndarray) -> float:
    """Centres per independent sample: ``1 + 2 sum rho_k`` up to the first rho <= 0."""
    r = residuals - residuals.mean()
    power = float(r @ r)
    total = 1.0
    if power <= 0.0:
        return total
    for lag in range(1, max(2, len(r) // 4)):
        rho = float(r[:-lag] @ r[lag:]) / power
        if rho <= 0.0:
            break
        total += 2.0 * rho
    return total


def _scallops(
    phi: np.ndarray, radius: float, n: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Scallops (rows) of ``n`` chords, vertices from ``phi0 + a D`` to ``phi1 + b D``.

    Returns the rows and each one's chord angle ``D`` at the centre (rad).
    """
    d = (phi[-1] - phi[0]) / (n + a - b)
    u = np.mod(phi[None, :] - (phi[0] + a * d)[:, None], d[:, None]) - 0.5 * d[:, None]
    return radius * (np.cos(0.5 * d)[:, None] / np.cos(u) - 1.0), d


def _fit(g: np.ndarray, q: np.ndarray, r0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each scallop's amplitude and the squares it removes from ``r0`` (0 when inward)."""
    g = g - (g @ q) @ q.T  # what the smooth curve cannot explain of each scallop
    gg = np.einsum("ij,ij->i", g, g)
    amp = (g @ r0) / np.maximum(gg, 1e-300)
    return amp, np.where(amp > 0.0, amp * amp * gg, 0.0)  # vertices bulge outwards only


def _refine(
    phi: np.ndarray, radius: float, q: np.ndarray, r0: np.ndarray, n: int, ab: np.ndarray
) -> tuple[np.ndarray, float, float, np.ndarray]:
    """The best count's end offsets refined (Nelder-Mead).

    Returns ``(a, b)``, the amplitude, the chord angle ``D`` (rad) and the Hessian of the
    squares the scallop removes with respect to ``(a, b)`` there (its curvature: how
    sharply the data fix the vertices' spacing).
    """

    def gain(x: np.ndarray) -> float:
        x = np.clip(x, -2 * END_SLACK, 2 * END_SLACK)
        g, _ = _scallops(phi, radius, np.array([n]), x[:1], x[1:])
        return float(_fit(g, q, r0)[1][0])

    x = minimize(lambda v: -gain(v), ab, method="Nelder-Mead", options={"xatol": 1e-3}).x
    x = np.clip(x, -2 * END_SLACK, 2 * END_SLACK)
    g, d = _scallops(phi, radius, np.array([n]), x[:1], x[1:])
    amp, _ = _fit(g, q, r0)
    return x, float(amp[0]), float(d[0]), _hessian(gain, x, 0.02)


def _hessian(f: Callable[[np.ndarray], float], x: np.ndarray, h: float) -> np.ndarray:
    """Central-difference Hessian of ``f`` at ``x`` (2 variables), step ``h``."""
    e = h * np.eye(2)
    out = np.empty((2, 2))
    for i in range(2):
        out[i, i] = (f(x + e[i]) - 2.0 * f(x) + f(x - e[i])) / (h * h)
    out[0, 1] = out[1, 0] = (
        f(x + e[0] + e[1]) - f(x + e[0] - e[1]) - f(x - e[0] + e[1]) + f(x - e[0] - e[1])
    ) / (4.0 * h * h)
    return out


def _angle_sigma(hess: np.ndarray, var: float, angle: float, span: float) -> float:
    """One sigma of the chord angle (rad) from the gain's curvature in the end offsets.

    In units of the noise the gain is a log-likelihood (times 2): the offsets' covariance
    is ``2 var (-H)^-1``, and ``D = span / (n + a - b)`` moves by ``D^2 / span`` per unit
    of ``a`` and of ``-b``.
    """
    try:
        cov = 2.0 * var * np.linalg.inv(-hess)
    except np.linalg.LinAlgError:
        return math.inf
    j = np.array([1.0, -1.0]) * angle * angle / span
    v = float(j @ cov @ j)
    return math.sqrt(v) if v > 0 else math.inf


def _arc(pts: np.ndarray, min_chord_mm: float) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Angles about the circle's centre (increasing), radial residuals and the radius.

    None when the centreline is no arc of at least ``MIN_DIVISIONS`` chords.
    """
    circle = fit_circle_robust(pts)
    centre, radius = np.asarray(circle.centre), float(circle.radius)
    if not math.isfinite(radius):
        return None
    phi = np.unwrap(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]))
    phi = -phi if phi[-1] < phi[0] else phi
    if np.any(np.diff(phi) < -0.01):
        return None  # not an arc about this centre (an S-curve, a loop back)
    most = int((phi[-1] - phi[0]) * radius // min_chord_mm)
    if most < MIN_DIVISIONS or len(pts) < 8 * most:
        return None
    return phi, np.hypot(*(pts - centre).T) - radius, radius


def periodic_chords(
    ordered_points_mm: np.ndarray, *, min_chord_mm: float = 6.0
) -> PeriodicChords | None:
    """The equal-chord count of an arc from its scallop (see the module notes).

    Returns None when the centreline is no arc of at least ``MIN_DIVISIONS`` chords of
    ``min_chord_mm`` (too short, turning the other way): the caller then looks for
    vertices one by one.
    """
    pts = np.asarray(ordered_points_mm, dtype=np.float64)
    noise_local = centreline_noise_mm(pts)
    length_mm = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    keep = max(MAX_POINTS, int(8 * length_mm / min_chord_mm) + 2)  # 8 per shortest chord
    every = max(1, len(pts) // keep)
    pts = np.vstack((pts[:-1:every], pts[-1:])) if every > 1 else pts
    arc = _arc(pts, min_chord_mm)
    if arc is None:
        return None
    phi, rho, radius = arc
    span = float(phi[-1] - phi[0])
    x = 2.0 * (phi - phi[0]) / span - 1.0
    base = np.column_stack(
        (np.polynomial.legendre.legvander(x, SMOOTH_DEGREE), np.cos(phi), np.sin(phi))
    )
    q, _ = np.linalg.qr(base)
    r0 = rho - q @ (q.T @ rho)
    counts = np.arange(MIN_DIVISIONS, int(span * radius // min_chord_mm) + 1)
    shifts = np.linspace(-END_SLACK, END_SLACK, END_STEPS)
    n, a, b = (g.ravel() for g in np.meshgrid(counts, shifts, shifts, indexing="ij"))
    amp, gain = _fit(_scallops(phi, radius, n, a, b)[0], q, r0)
    best = int(np.argmax(gain))
    n_best = int(n[best])
    ab, amplitude, angle, hess = _refine(phi, radius, q, r0, n_best, np.r_[a[best], b[best]])
    g, _ = _scallops(phi, radius, np.array([n_best]), ab[:1], ab[1:])
    resid = r0 - amplitude * (g[0] - q @ (q.T @ g[0]))
    misfit = math.sqrt(float(resid @ resid) / max(len(pts) - q.shape[1] - 3, 1))
    noise = max(misfit, noise_local)
    corr = _correlation(resid)
    var = noise * noise * corr
    others = gain[n != n_best]
    # decided on the grid's values (every count searched alike); refined: the angle
    margin = (float(gain[best] - others.max())) / var if others.size else math.inf
    angle_sigma = _angle_sigma(hess, var, angle, span)
    threshold = float(chdtri(1, FALSE_ALARM / len(gain)))  # chi-square isf, no scipy.stats
    return _decide(
        n_best, radius, (angle, angle_sigma), amplitude, float(gain[best]) / var, threshold,
        margin, noise, corr, misfit <= MAX_MISFIT * noise_local,
    )  # fmt: skip


def _decide(
    n_best: int,
    radius: float,
    angle: tuple[float, float],
    amplitude: float,
    sig: float,
    threshold: float,
    margin: float,
    noise: float,
    corr: float,
    described: bool,
) -> PeriodicChords:
    """The count kept or withheld, and why in words; ``angle``: D and its sigma (rad)."""
    chord = 2.0 * radius * math.sin(0.5 * angle[0])
    consistent = AMPLITUDE_RANGE[0] <= amplitude <= AMPLITUDE_RANGE[1]
    found = n_best if sig >= threshold and margin >= MIN_MARGIN and consistent else None
    if found is not None:
        why = (
            f"{n_best} equal chords of {chord:.1f} mm: their vertices' scallop stands "
            f"{math.sqrt(sig):.1f} sigma out of the centreline's noise ({noise:.3f} mm), "
            f"{math.sqrt(margin):.1f} sigma clearer than any other count"
        )
    elif sig < threshold:
        why = (
            f"no chord count is significant: the best, {n_best} chords of {chord:.1f} mm, "
            f"leaves a scallop of {math.sqrt(sig):.1f} sigma (needed {math.sqrt(threshold):.1f}) "
            f"in the centreline's noise ({noise:.3f} mm)"
        )
    elif not consistent:
        why = (
            f"{n_best} chords fit best, but their scallop is {amplitude:.2f} times that of "
            "equal chords with vertices on the circle: not a polygon of equal chords"
        )
    else:
        why = (
            f"{n_best} chords fit best but only {math.sqrt(max(margin, 0.0)):.1f} sigma better "
            f"than another count (needed {math.sqrt(MIN_MARGIN):.1f}): the count is ambiguous"
        )
    return PeriodicChords(
        found, n_best, chord, math.degrees(angle[0]), math.degrees(angle[1]), amplitude, sig, threshold, margin, noise,
        corr, why, consistent and described,
    )  # fmt: skip


def spacing_disagreement_deg(
    segment_bend_deg: float | None, divisions: int | None, periodic: PeriodicChords | None
) -> float:
    """How far the bend per chord from the wire's ends lies from its vertices' spacing
    (signed, deg) where :func:`chord_spacing_warning` warns about it, else 0."""
    if segment_bend_deg is None or periodic is None or periodic.best_divisions != divisions:
        return 0.0
    if not periodic.applies or periodic.significance < periodic.threshold:
        return 0.0
    sigma = periodic.chord_angle_sigma_deg
    diff = abs(segment_bend_deg) - periodic.chord_angle_deg
    if not math.isfinite(sigma) or abs(diff) <= SPACING_SIGMAS * sigma:
        return 0.0
    return float(diff)


def chord_spacing_warning(
    segment_bend_deg: float | None, divisions: int | None, periodic: PeriodicChords | None
) -> StageWarning | None:
    """A warning when the bend per chord disagrees with the spacing of the vertices.

    The bend per chord (the arc angle over N) rests on the wire's two ends; an arc of
    equal chords also gives it from where its vertices lie (``chord_angle_deg``, the ends
    left out). Beyond ``SPACING_SIGMAS`` of the spacing's sigma apart, an end is cut
    short, hidden or extended (a shadow, a cap), or the count's spacing is off: the bend
    per chord is not measured to better than their difference. Checked only where the
    equal-chord test found this count significant.
    """
    diff = spacing_disagreement_deg(segment_bend_deg, divisions, periodic)
    if diff == 0.0 or segment_bend_deg is None or periodic is None:
        return None
    sigma = periodic.chord_angle_sigma_deg
    return StageWarning(
        "part_chord_spacing",
        f"the bend per chord from the wire's ends ({abs(segment_bend_deg):.3f} deg, the arc "
        f"over {divisions}) differs from the spacing of its vertices ({periodic.chord_angle_deg:.3f} "
        f"+- {sigma:.3f} deg) by {diff:+.3f} deg: an end may be cut short, hidden or extended; "
        "the bend per chord is uncertain by that much",
    )
