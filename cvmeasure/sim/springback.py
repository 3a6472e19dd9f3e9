"""Springback of a round wire: moment-curvature, hardening laws and the affine law.

Moment of a circular section of radius a at curvature kappa, for any
stress-strain law sigma(eps) (substituting y = a sin t)::

    M(kappa) = 4 a^3  integral_0^{pi/2} sigma(kappa a sin t) sin t cos^2 t dt

evaluated by Gauss-Legendre quadrature split at the elastic-plastic boundary
``t* = asin(eps_y / (kappa a))``. For elastic-perfectly-plastic material it
reproduces the closed form (``beta = kappa_y / kappa``)::

    M = (sigma_y a^3 / 6) [ (5 - 2 beta^2) sqrt(1 - beta^2) + 3 asin(beta) / beta ]

Unloading is elastic (``delta kappa = M / EI``). In pin-and-die bending the
wrapped zone (curvature 1 / rho, arc rho * theta) and the free span of length
l between die and pin (moment falling linearly to zero) give the affine law::

    springback = b * theta + a,   b = M rho / EI,   a = c M l / EI

Reference: /work/shared/reference/springback-discrepancy.md, sections 1.2-1.4;
F. J. Gardiner, "The Spring Back of Metals", Trans. ASME 79 (1957) 1-9.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cvmeasure.sim.params import SimParams

__all__ = [
    "flow_stress_mpa",
    "moment_nmm",
    "epp_moment_nmm",
    "curvature_ratio_epp",
    "SpringbackLaw",
    "springback_law",
    "springback_deg",
]

_GL_T, _GL_W = np.polynomial.legendre.leggauss(48)
_GL_W2 = np.concatenate((_GL_W, _GL_W))  # the weights of two intervals' nodes side by side


def _swift_constants(params: SimParams) -> tuple[float, float]:
    """(K, eps0) of the Swift law: UTS at necking (true strain n) and sigma(0) = yield."""
    n = params.hardening_exponent
    if n <= 0:
        return params.yield_mpa, 1.0
    k = params.uts_mpa / (n**n * math.exp(-n))
    k = max(k, params.yield_mpa)
    eps0 = (params.yield_mpa / k) ** (1.0 / n)
    return k, eps0


def flow_stress_mpa(params: SimParams, strain: ArrayLike) -> NDArray[np.float64]:
    """Uniaxial stress (MPa) at total strain(s) ``strain`` (>= 0) for the params' law."""
    eps = np.abs(np.asarray(strain, dtype=np.float64))
    e_mod = params.youngs_modulus_mpa
    eps_y = params.yield_mpa / e_mod
    plastic = np.maximum(eps - eps_y, 0.0)
    if params.hardening == "epp":
        flow = np.full_like(eps, params.yield_mpa)
    elif params.hardening == "bilinear":
        flow = params.yield_mpa + params.tangent_modulus_mpa * plastic
    else:
        k, eps0 = _swift_constants(params)
        flow = k * (eps0 + plastic) ** params.hardening_exponent
    return np.where(eps <= eps_y, e_mod * eps, flow)


def _integrate(fun, lo: float, hi: float) -> float:
    if hi <= lo:
        return 0.0
    t = 0.5 * (hi - lo) * _GL_T + 0.5 * (hi + lo)
    return float(0.5 * (hi - lo) * np.sum(_GL_W * fun(t)))


def moment_nmm(params: SimParams, curvature_per_mm: float) -> float:
    """Bending moment M (N mm) of the round wire at curvature kappa (1/mm), loading."""
    a = params.wire_radius_mm
    kappa = abs(float(curvature_per_mm))
    if kappa == 0.0:
        return 0.0
    eps_y = params.yield_mpa / params.youngs_modulus_mpa
    t_star = math.asin(min(1.0, eps_y / (kappa * a)))

    def integrand(t: np.ndarray) -> np.ndarray:
        return flow_stress_mpa(params, kappa * a * np.sin(t)) * np.sin(t) * np.cos(t) ** 2

    half_pi = math.pi / 2
    if not 0.0 < t_star < half_pi:
        return (
            4.0
            * a**3
            * (_integrate(integrand, 0.0, t_star) + _integrate(integrand, t_star, half_pi))
        )
    # both parts' nodes in one evaluation of the integrand (elementwise: the same number at
    # every node), each part summed over its own nodes as _integrate sums them
    n = _GL_T.size
    t = np.concatenate(
        (
            0.5 * t_star * _GL_T + 0.5 * t_star,
            0.5 * (half_pi - t_star) * _GL_T + 0.5 * (t_star + half_pi),
        )
    )
    f = _GL_W2 * integrand(t)
    elastic = float(0.5 * (t_star - 0.0) * np.sum(f[:n]))
    plastic = float(0.5 * (half_pi - t_star) * np.sum(f[n:]))
    return 4.0 * a**3 * (elastic + plastic)


def epp_moment_nmm(params: SimParams, curvature_per_mm: float) -> float:
    """Closed-form elastic-perfectly-plastic moment (N mm) of a circular section."""
    a = params.wire_radius_mm
    ei = params.youngs_modulus_mpa * math.pi * a**4 / 4.0
    kappa = abs(float(curvature_per_mm))
    kappa_y = params.yield_mpa / (params.youngs_modulus_mpa * a)
    if kappa <= kappa_y:
        return ei * kappa
    beta = kappa_y / kappa
    return (
        params.yield_mpa
        * a**3
        / 6.0
        * ((5 - 2 * beta**2) * math.sqrt(1 - beta**2) + 3 * math.asin(beta) / beta)
    )


def curvature_ratio_epp(params: SimParams, radius_mm: float) -> float:
    """Gardiner-type ratio K = R / R_final = kappa_final / kappa for a round EPP wire.

    ``radius_mm`` is the neutral-axis bend radius R.
    """
    a = params.wire_radius_mm
    beta = min(1.0, params.yield_mpa * radius_mm / (params.youngs_modulus_mpa * a))
    return 1.0 - (2.0 / (3.0 * math.pi)) * (
        beta * (5 - 2 * beta**2) * math.sqrt(1 - beta**2) + 3 * math.asin(beta)
    )


@dataclass(frozen=True)
class SpringbackLaw:
    """The affine springback law of one wire on one die edge.

    ``springback = wrap_slope * theta + curvature_per_mm_m * span_factor * lever_mm``
    in radians; :meth:`springback_deg` evaluates it.
    """

    moment_nmm: float  # M at the die edge (loaded)
    bending_stiffness_nmm2: float  # EI
    bend_radius_mm: float  # rho, neutral-axis radius on the die edge
    span_factor: float  # c

    @property
    def unload_curvature_per_mm(self) -> float:
        """Elastic curvature recovery M / EI (1/mm)."""
        return self.moment_nmm / self.bending_stiffness_nmm2

    @property
    def wrap_slope(self) -> float:
        """b = M rho / EI: springback per unit loaded angle from the wrapped zone."""
        return self.unload_curvature_per_mm * self.bend_radius_mm

    def intercept_deg(self, lever_mm: ArrayLike) -> NDArray[np.float64]:
        """a = c M l / EI (deg): springback of the free span of length l (mm)."""
        return np.degrees(
            self.span_factor * self.unload_curvature_per_mm * np.asarray(lever_mm, np.float64)
        )

    def span_bow_deg(self, chord_deg: ArrayLike, lever_mm: ArrayLike) -> NDArray[np.float64]:
        """Elastic bow of the loaded span (deg, >= 0): how far the leg beyond the pin
        leads the chord of the tangent construction, ``min(M l / (6 EI), theta / 2)``.

        The span's curvature ``M (1 - s / l) / EI`` (s from the die tangent point) bows
        it off its chord; the tangent at the pin leads the chord by
        ``(1 / l) int_0^l s kappa ds = M l / (6 EI)`` rad. Below the elastic threshold
        the span is a cantilever whose tip leads its chord by half the chord angle.
        ``chord_deg``: the chord's bend angle (deg, >= 0); ``lever_mm``: the span l (mm).
        """
        chord = np.asarray(chord_deg, dtype=np.float64)
        full = np.degrees(self.unload_curvature_per_mm / 6.0) * np.asarray(lever_mm, np.float64)
        return np.minimum(full, 0.5 * np.maximum(chord, 0.0))

    def springback_deg(self, loaded_deg: ArrayLike, lever_mm: ArrayLike) -> NDArray[np.float64]:
        """Springback (deg, >= 0) of a bend loaded to ``loaded_deg`` (>= 0) with lever l.

        Below the elastic threshold the wire springs back straight (springback = loaded).
        """
        theta = np.asarray(loaded_deg, dtype=np.float64)
        affine = self.wrap_slope * theta + self.intercept_deg(lever_mm)
        return np.minimum(theta, affine)

    def to_dict(self) -> dict[str, Any]:
        return {
            "moment_nmm": self.moment_nmm,
            "bending_stiffness_nmm2": self.bending_stiffness_nmm2,
            "bend_radius_mm": self.bend_radius_mm,
            "span_factor": self.span_factor,
            "wrap_slope": self.wrap_slope,
        }


@functools.lru_cache(maxsize=512)
def springback_law(params: SimParams) -> SpringbackLaw:
    """The affine springback law for the params' wire bent on its die edge (cached)."""
    a = params.wire_radius_mm
    rho = params.die_radius_mm + a
    ei = params.youngs_modulus_mpa * math.pi * a**4 / 4.0
    return SpringbackLaw(
        moment_nmm=moment_nmm(params, 1.0 / rho),
        bending_stiffness_nmm2=ei,
        bend_radius_mm=rho,
        span_factor=params.span_factor,
    )


def springback_deg(
    params: SimParams, loaded_deg: ArrayLike, lever_mm: ArrayLike
) -> NDArray[np.float64]:
    """Springback (deg) for loaded angle(s) (deg, >= 0) and lever arm(s) (mm)."""
    return springback_law(params).springback_deg(loaded_deg, lever_mm)
