"""Moment-curvature of a round wire: a fibre model with kinematic hardening.

The cross-section is cut into fibres across the bending plane (Gauss-Legendre in
``t`` with ``y = a sin t``, so the chord width ``2 a cos t`` is integrated exactly).
Each fibre is a 1-D elastic-plastic bar with a fixed yield stress and two back
stresses: a linear one (Prager, modulus ``H``) and a saturating one
(Armstrong-Frederick, ``dX = C dp n - gamma X dp``), so reversed loading yields
early: the Bauschinger effect. Over a strain increment of one sign the 1-D
return mapping below is exact (the flow direction is constant and the
saturating back stress has a closed form along it), so coarse steps are exact too.

A section is loaded by pure bending from a symmetric state, so every field stays
antisymmetric in ``y`` and the neutral axis stays at the centroid (no axial solve).

Units: mm, MPa (N/mm^2), N mm, curvature in 1/mm. Bending is positive curvature
(fibres at ``y > 0`` in tension); a bend the other way is this one mirrored with
the initial back-stress field negated (:func:`section_table` ``direction``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

_N_FIBRES = 64
_NEWTON_ITERATIONS = 10


@dataclass(frozen=True)
class Material:
    """Elastic-plastic wire material with linear + saturating kinematic hardening.

    Attributes
    ----------
    name : str
    youngs_modulus_mpa, yield_stress_mpa : float
    linear_hardening_mpa : float
        Prager back-stress modulus ``H`` (MPa per unit plastic strain).
    saturating_hardening_mpa : float
        Armstrong-Frederick modulus ``C`` (MPa); the back stress saturates at ``C / gamma``.
    saturation_rate : float
        ``gamma`` (dimensionless).
    """

    name: str
    youngs_modulus_mpa: float
    yield_stress_mpa: float
    linear_hardening_mpa: float
    saturating_hardening_mpa: float
    saturation_rate: float

    def softened(self, factor: float) -> Material:
        """The material with its flow stresses (yield, both hardening moduli) times ``factor``."""
        return Material(
            name=self.name,
            youngs_modulus_mpa=self.youngs_modulus_mpa,
            yield_stress_mpa=self.yield_stress_mpa * factor,
            linear_hardening_mpa=self.linear_hardening_mpa * factor,
            saturating_hardening_mpa=self.saturating_hardening_mpa * factor,
            saturation_rate=self.saturation_rate,
        )


MATERIALS: dict[str, Material] = {
    # Cold-drawn low-carbon steel (welding rod class, yield ~280 MPa, flow ~450-550 MPa
    # at the strains of a tight bend).
    "low_carbon_steel": Material("low_carbon_steel", 200_000.0, 280.0, 250.0, 12_000.0, 100.0),
    # Austenitic stainless (304): low yield, strong and long hardening.
    "stainless_304": Material("stainless_304", 193_000.0, 310.0, 900.0, 30_000.0, 80.0),
    # Rebar B500: high yield, modest hardening.
    "rebar_b500": Material("rebar_b500", 200_000.0, 520.0, 300.0, 15_000.0, 150.0),
    # Half-hard copper (jewellery, electrical wire).
    "copper_h02": Material("copper_h02", 117_000.0, 200.0, 150.0, 6_000.0, 120.0),
    # Elastic-perfectly plastic steel: the textbook case (no hardening).
    "epp_steel": Material("epp_steel", 200_000.0, 280.0, 0.0, 0.0, 1.0),
}


@dataclass
class _FibreState:
    plastic_strain: np.ndarray
    linear_back_mpa: np.ndarray
    saturating_back_mpa: np.ndarray

    def copy(self) -> _FibreState:
        return _FibreState(
            self.plastic_strain.copy(), self.linear_back_mpa.copy(), self.saturating_back_mpa.copy()
        )


def _fibres(radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Fibre heights ``y`` (mm) and areas (mm^2) of a round section of this radius."""
    t, w = np.polynomial.legendre.leggauss(_N_FIBRES)
    t = t * np.pi / 2.0
    w = w * np.pi / 2.0
    y = radius_mm * np.sin(t)
    area = 2.0 * radius_mm**2 * np.cos(t) ** 2 * w
    return y, area


def _return_map(
    strain: np.ndarray, state: _FibreState, mat: Material
) -> tuple[np.ndarray, _FibreState]:
    """Stress (MPa) at total ``strain`` from ``state`` (exact for a one-signed increment)."""
    e, h, c = mat.youngs_modulus_mpa, mat.linear_hardening_mpa, mat.saturating_hardening_mpa
    gamma = mat.saturation_rate
    x_sat = c / gamma if c > 0.0 else 0.0
    trial = e * (strain - state.plastic_strain)
    xi = trial - state.linear_back_mpa - state.saturating_back_mpa
    n = np.where(xi >= 0.0, 1.0, -1.0)
    f = np.abs(xi) - mat.yield_stress_mpa
    room = np.maximum(x_sat - n * state.saturating_back_mpa, 0.0)
    dp = np.zeros_like(strain)
    active = f > 0.0
    if np.any(active):
        fa, ra = f[active], room[active]
        d = np.zeros_like(fa)
        for _ in range(_NEWTON_ITERATIONS):
            ex = np.exp(-gamma * d)
            g = fa - (e + h) * d - ra * (1.0 - ex)
            dg = -(e + h) - ra * gamma * ex
            d = np.maximum(d - g / dg, 0.0)
        dp[active] = d
    new_sat = n * x_sat + (state.saturating_back_mpa - n * x_sat) * np.exp(-gamma * dp)
    new = _FibreState(
        state.plastic_strain + n * dp,
        state.linear_back_mpa + h * n * dp,
        np.where(dp > 0.0, new_sat, state.saturating_back_mpa),
    )
    return trial - e * n * dp, new


@dataclass(frozen=True)
class SectionTable:
    """Monotonic moment-curvature and unloading of one section, one bend direction.

    Attributes
    ----------
    curvature_per_mm : numpy.ndarray
        Increasing curvature grid, first entry the wire's own (residual) curvature.
    moment_nmm : numpy.ndarray
        Bending moment on the monotonic loading path at each grid curvature.
    residual_curvature_per_mm : numpy.ndarray
        Curvature left after unloading to zero moment from each grid curvature.
    flexural_rigidity_nmm2 : float
        ``E I`` of the section.
    """

    curvature_per_mm: np.ndarray
    moment_nmm: np.ndarray
    residual_curvature_per_mm: np.ndarray
    flexural_rigidity_nmm2: float

    @property
    def natural_curvature_per_mm(self) -> float:
        """Curvature of the unloaded wire (its coil set; 0 for a straight wire)."""
        return float(self.curvature_per_mm[0])

    def moment(self, curvature_per_mm: np.ndarray | float) -> np.ndarray:
        """Moment (N mm) at a curvature on the loading path."""
        return np.interp(curvature_per_mm, self.curvature_per_mm, self.moment_nmm)

    def curvature(self, moment_nmm: np.ndarray | float) -> np.ndarray:
        """Curvature (1/mm) at a moment on the loading path (moment >= 0)."""
        return np.interp(moment_nmm, self.moment_nmm, self.curvature_per_mm)

    def residual(self, curvature_per_mm: np.ndarray | float) -> np.ndarray:
        """Curvature left after loading to ``curvature_per_mm`` and releasing."""
        return np.interp(curvature_per_mm, self.curvature_per_mm, self.residual_curvature_per_mm)


def _moment(curv: np.ndarray | float, state: _FibreState, y, area, mat):
    """Moments of a batch of states (rows) at curvatures ``curv`` (one per row)."""
    strain = np.asarray(curv)[..., None] * y
    stress, new = _return_map(strain, state, mat)
    return (stress * y * area).sum(axis=-1), new


def _release(curv, state: _FibreState, y, area, mat) -> tuple[np.ndarray, _FibreState]:
    """Curvatures where the moment returns to zero unloading from ``curv`` (one per state row)."""
    curv = np.asarray(curv, dtype=float)
    m0, loaded = _moment(curv, state, y, area, mat)
    ei = mat.youngs_modulus_mpa * float((y**2 * area).sum())
    same, other = curv.copy(), curv - 4.0 * m0 / ei  # m0's sign at `same`, the other at `other`
    for _ in range(55):
        mid = 0.5 * (same + other)
        m, _ = _moment(mid, loaded, y, area, mat)
        keep = (m > 0.0) == (m0 > 0.0)
        same = np.where(keep, mid, same)
        other = np.where(keep, other, mid)
    final = 0.5 * (same + other)
    final = np.where(m0 == 0.0, curv, final)
    return final, _moment(final, loaded, y, area, mat)[1]


@functools.lru_cache(maxsize=256)
def section_table(
    mat: Material,
    radius_mm: float,
    max_curvature_per_mm: float,
    direction: int = 1,
    initial_back_share: float = 0.0,
    coil_curvature_per_mm: float = 0.0,
    coil_set_per_mm: float = 0.0,
) -> SectionTable:
    """Loading and unloading curves of a round wire bent in one direction.

    Parameters
    ----------
    mat : Material
    radius_mm : float
        Wire radius.
    max_curvature_per_mm : float
        Largest curvature the table must cover (the die's, with margin).
    direction : {1, -1}
        Bend direction relative to the fields below (-1 negates them: the mirror image).
    initial_back_share : float
        A residual linear back stress ``share * yield * sign(y)`` left in the wire
        (e.g. by drawing or a straightener), which makes bends one way yield later
        than the other: the flow stress is ``(1 + direction * share)`` times the yield.
    coil_curvature_per_mm, coil_set_per_mm : float
        Prehistory of coiled wire: bent to the spool's curvature, then straightened by
        a reverse bend chosen so that ``coil_set_per_mm`` of curvature remains (signed,
        positive in ``direction`` +1). Zero curvature: virgin straight wire.
    """
    y, area = _fibres(radius_mm)
    sign = float(direction)
    zeros = np.zeros_like(y)
    state = _FibreState(
        zeros.copy(), sign * initial_back_share * mat.yield_stress_mpa * np.sign(y), zeros.copy()
    )
    natural = 0.0
    if coil_curvature_per_mm > 0.0:
        state, natural = _coil_prehistory(
            state, sign, coil_curvature_per_mm, coil_set_per_mm, y, area, mat
        )
    ei = mat.youngs_modulus_mpa * float((y**2 * area).sum())
    k_y = mat.yield_stress_mpa / (mat.youngs_modulus_mpa * radius_mm)
    top = max(max_curvature_per_mm, 4.0 * k_y) * 1.05
    grid = natural + np.concatenate(([0.0], np.geomspace(0.05 * k_y, top, 220)))
    moments = np.empty_like(grid)
    rows = []
    snapshot = state
    for i, curv in enumerate(grid):
        m, snapshot = _moment(curv, snapshot, y, area, mat)
        moments[i] = m
        rows.append(snapshot)
    stacked = _FibreState(
        *(np.stack([getattr(r, f) for r in rows]) for f in _FibreState.__dataclass_fields__)
    )
    residual = _release(grid, stacked, y, area, mat)[0]
    residual = np.where(moments <= 1e-9 * ei * k_y, natural, residual)
    moments[0] = 0.0
    moments = np.maximum.accumulate(np.maximum(moments, 0.0))
    # A strictly increasing moment keeps the inverse interpolation well defined.
    moments = moments + np.arange(moments.size) * 1e-12 * max(moments[-1], 1.0)
    return SectionTable(grid, moments, residual, ei)


def _coil_prehistory(state, sign, coil_curvature, coil_set, y, area, mat):
    """Bend to the spool's curvature, straighten by a reverse bend leaving ``coil_set``."""
    k_coil = sign * coil_curvature
    _, coiled = _moment(k_coil, state, y, area, mat)
    target = sign * coil_set
    # Depth of the reverse bend (curvature -sign * depth) whose release leaves `target`.
    lo, hi = 0.0, 3.0 * coil_curvature
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        _, reversed_state = _moment(-sign * mid, coiled, y, area, mat)
        left = float(_release(-sign * mid, reversed_state, y, area, mat)[0])
        if sign * left > sign * target:
            lo = mid
        else:
            hi = mid
    lo, hi = -sign * lo, -sign * hi
    _, reversed_state = _moment(0.5 * (lo + hi), coiled, y, area, mat)
    left, released = _release(0.5 * (lo + hi), reversed_state, y, area, mat)
    return released, float(left)


def epp_moment_closed_form(mat: Material, radius_mm: float, curvature_per_mm: float) -> float:
    """Textbook moment of an elastic-perfectly plastic round section (N mm).

    With the elastic core half-depth ``c = a beta``, ``beta = kappa_y / kappa``:
    ``M = 4 sigma_y a^3 [ int_0^{asin beta} sin^2 t cos^2 t / beta dt + int_{asin beta}^{pi/2} sin t cos^2 t dt ]``,
    i.e. ``M = sigma_y a^3 / 6 [(5 - 2 beta^2) sqrt(1 - beta^2) + 3 asin(beta) / beta]``.
    """
    a, sy = radius_mm, mat.yield_stress_mpa
    k_y = sy / (mat.youngs_modulus_mpa * a)
    if curvature_per_mm <= k_y:
        return mat.youngs_modulus_mpa * np.pi * a**4 / 4.0 * curvature_per_mm
    b = k_y / curvature_per_mm
    return sy * a**3 / 6.0 * ((5.0 - 2.0 * b * b) * np.sqrt(1.0 - b * b) + 3.0 * np.arcsin(b) / b)
