"""The vertex bends from each chord's whole cross-profile
(:func:`cvmeasure.part.chord_profiles.profile_polyline`), against a known bent wire drawn with a
side-lit profile (dark flanks, a highlight off the axis, a cast shadow on one side)."""

from __future__ import annotations

import cv2
import numpy as np

from cvmeasure.part.chord_profiles import chord_profile_centres, profile_polyline
from cvmeasure.part.fit import fit_polyline

WIDTH_PX = 38.0  # the wire's width at full size (3 mm at 550 mm)
MM_PER_PX = 0.08
BENDS_DEG = (17.0, 15.0)  # two vertices, three chords of about 200 px
NOISE = 1.5  # grey levels, as the ray tracer's


def _profile(v: np.ndarray, shadow_sign: float) -> np.ndarray:
    """Grey level at a signed distance ``v`` (px) across the wire: a dark sheet, the shadow
    beyond the wire on ``shadow_sign``'s side, the highlight on the lit flank."""
    hw = 0.5 * WIDTH_PX
    lit = -shadow_sign * v / hw
    body = 45.0 + 25.0 * np.clip(lit, -1, 1) + 120.0 * np.exp(-0.5 * ((lit - 0.45) / 0.1) ** 2)
    shadow = (shadow_sign * v > hw) & (shadow_sign * v < hw + 16.0)
    plate = 30.0 - 20.0 * shadow
    return np.where(np.abs(v) < hw, body, plate)


def _photo(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The image (a 3 x 3 supersampled, blurred, noisy polyline), its vertices (px) and
    true bends."""
    heads = np.radians(np.concatenate(([4.0], 4.0 + np.cumsum(BENDS_DEG))))
    verts = [np.array([60.0, 60.0])]
    for h in heads:
        verts.append(verts[-1] + 200.0 * np.array([np.cos(h), np.sin(h)]))
    verts = np.array(verts)
    h, w = 400, 680
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    acc = np.zeros((h, w))
    for ox in (-1 / 3, 0.0, 1 / 3):
        for oy in (-1 / 3, 0.0, 1 / 3):
            p = np.stack((xx + ox, yy + oy), axis=-1)
            best_d = np.full((h, w), np.inf)
            best_v = np.zeros((h, w))
            for a, b in zip(verts[:-1], verts[1:], strict=True):
                e = (b - a) / np.linalg.norm(b - a)
                n = np.array([-e[1], e[0]])
                t = np.clip((p - a) @ e, 0.0, np.linalg.norm(b - a))
                d = np.linalg.norm(p - (a + t[..., None] * e), axis=-1)
                closer = d < best_d
                best_d = np.where(closer, d, best_d)
                best_v = np.where(closer, (p - a) @ n, best_v)
            acc += _profile(best_v, 1.0)
    img = cv2.GaussianBlur(acc / 9.0, (0, 0), 0.7)
    img = img + np.random.default_rng(seed).normal(0.0, NOISE, img.shape)
    return img.astype(np.float32), verts, np.array(BENDS_DEG)


def _centres(verts: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Edge-like input centres (px): 0.3 px of noise, and on the last chord a 0.5 px drift
    (the shadow side's edge moving with a lifted part's shadow)."""
    out = []
    for k, (a, b) in enumerate(zip(verts[:-1], verts[1:], strict=True)):
        length = float(np.linalg.norm(b - a))
        e = (b - a) / length
        n = np.array([-e[1], e[0]])
        t = np.arange(0.0, length, 1.0)
        off = rng.normal(0.0, 0.3, len(t)) + (0.5 * t / length if k == len(verts) - 2 else 0.0)
        out.append(a + t[:, None] * e + off[:, None] * n)
    return np.vstack(out)


def test_chord_profile_centres_follow_a_straight_wire():
    """One straight chord: the re-measured centres lie on the true axis' line (direction
    within 0.01 deg) although the input centres drift 0.5 px along it (0.14 deg)."""
    img, verts, _ = _photo(3)
    pts = _centres(verts[:2], np.random.default_rng(4))
    truth = np.degrees(np.arctan2(*(verts[1] - verts[0])[::-1]))
    new = chord_profile_centres(img, pts, [(20, len(pts) - 20)], width_px=WIDTH_PX)
    ok = np.isfinite(new[:, 0])
    assert ok.sum() > 150

    def direction(q: np.ndarray) -> float:
        _, _, vt = np.linalg.svd(q - q.mean(axis=0), full_matrices=False)
        return float(np.degrees(np.arctan2(vt[0][1], vt[0][0]))) % 180.0

    assert abs(direction(pts[20:-20]) - truth) > 0.1
    assert abs(direction(new[ok]) - truth) < 0.01


def test_profile_polyline_bends_and_their_sigma():
    """Three chords, eight noise seeds: every vertex bend within 0.01 deg of the truth
    (the input centres' own fit is 0.1 deg off at the drifting chord), and at least 13 of
    16 within 2 stated sigma (the sigma from the re-measured centres' scatter)."""
    errors, sigmas, edge_errors = [], [], []
    for seed in range(8):
        img, verts, bends = _photo(10 + seed)
        pts = _centres(verts, np.random.default_rng(100 + seed))
        to_mm = lambda q: np.asarray(q) * MM_PER_PX  # noqa: E731
        edges = fit_polyline(to_mm(pts), len(bends) + 1)
        got = profile_polyline(img, pts, to_mm, edges, width_px=WIDTH_PX)
        assert got is not None and got.bend_sigma_deg is not None
        errors.append(got.bend_deg - bends)
        sigmas.append(got.bend_sigma_deg)
        edge_errors.append(edges.bend_deg - bends)
    err, sig = np.concatenate(errors), np.concatenate(sigmas)
    assert np.max(np.abs(np.concatenate(edge_errors))) > 0.1
    assert np.max(np.abs(err)) < 0.01
    assert np.sum(np.abs(err) < 2.0 * sig) >= 13
