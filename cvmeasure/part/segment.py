"""The wire's mask in a photo of a part on a dark or light matte sheet.

Steel wire is neither darker nor brighter than the sheet everywhere: on a
light sheet its flanks are dark and its crest can be a specular highlight, on
a dark sheet it is bright with darker flanks; the wire also casts a soft
shadow. The mask therefore comes from the *absolute* difference between the
photo and its local background, a median filter a few wire widths wide (a
median keeps the sheet's and board's large step edges, so only thin structures
stand out). The threshold sits well above the noise (a shadow joined to the
wire does no harm: the mask is only a guide); the candidates are the connected
components outside the board no wider than a wire, longest path through the filled mask
first (of the longest skeletons: a stray disc's outline has a long skeleton, no long
path); the longest whose profiles are a wire's is the wire (:mod:`cvmeasure.part.locate`). The mask only
gives the wire's topology and a
first centre line: :mod:`cvmeasure.part.centreline` measures it sub-pixel.

Frame: image pixels (OpenCV: x right, y down, pixel centres at integers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from skimage.morphology import skeletonize

__all__ = ["WireMask", "segment_wire", "wire_candidates", "gray_float", "longest_skeleton_path"]

Sheet = Literal["dark", "light"]

#: The wire is chosen among this many components with the longest skeletons (by the
#: longest path through each once its holes are filled).
CANDIDATES = 6


@dataclass(frozen=True)
class WireMask:
    """The wire found in a photo.

    Attributes
    ----------
    mask : ndarray (H, W), bool; the wire's pixels (holes filled).
    path_px : ndarray (M, 2), float64; the mask's skeleton as one ordered path
        from one wire end to the other (x, y), pixels.
    sheet : ``"dark"`` or ``"light"``: the background is darker or lighter than the wire.
    background_level : median grey level of the background around the wire (0-255 scale).
    contrast : median absolute difference wire - background inside the mask.
    threshold : the difference level the mask was cut at.
    width_px : rough wire width (mask area / path length), pixels.
    passed_over : why each longer thin line was not taken for the wire (empty when this
        is the longest; set by :func:`cvmeasure.part.locate.measure_centreline_mm`).
    """

    mask: np.ndarray
    path_px: np.ndarray
    sheet: Sheet
    background_level: float
    contrast: float
    threshold: float
    width_px: float
    passed_over: tuple[str, ...] = ()

    @property
    def length_px(self) -> float:
        return float(np.sum(np.hypot(*np.diff(self.path_px, axis=0).T)))

    def to_dict(self) -> dict[str, Any]:
        return {
            "sheet": self.sheet,
            "background_level": self.background_level,
            "contrast": self.contrast,
            "threshold": self.threshold,
            "width_px": self.width_px,
            "length_px": self.length_px,
            "area_px": int(self.mask.sum()),
        }


def gray_float(image: np.ndarray) -> np.ndarray:
    """A float32 grey image on a 0-255 scale from BGR/grey, uint8/uint16/float input."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.dtype != np.float64 else img.mean(axis=2)
    out = img.astype(np.float32)
    if image.dtype == np.uint16:
        out *= 255.0 / 65535.0
    return out


def _gray8(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The photo's grey levels rounded to uint8, and the grey levels themselves (0-255).

    A uint8 photo's grey levels are whole already: both are the one uint8 image (no
    full-size float copy).
    """
    img = np.asarray(image)
    if img.dtype == np.uint8:
        g8 = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        return g8, g8
    gray = gray_float(img)
    return np.clip(gray + 0.5, 0, 255).astype(np.uint8), gray


def _odd(n: float) -> int:
    k = max(3, int(math.ceil(n)))
    return k if k % 2 else k + 1


def longest_skeleton_path(skeleton: np.ndarray) -> np.ndarray:
    """The longest shortest-path through a skeleton's 8-connected pixels, ordered (M, 2) x, y.

    Two breadth-first sweeps (farthest pixel from any pixel, then farthest from
    that) give the diameter of the skeleton graph, which drops spurs.
    """
    ys, xs = np.nonzero(skeleton)
    n = len(xs)
    if n < 2:
        return np.column_stack((xs, ys)).astype(np.float64)
    index = -np.ones(skeleton.shape, dtype=np.int64)
    index[ys, xs] = np.arange(n)
    rows, cols, weights = [], [], []
    h, w = skeleton.shape
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        y2, x2 = ys + dy, xs + dx
        ok = (y2 >= 0) & (y2 < h) & (x2 >= 0) & (x2 < w)
        j = np.full(n, -1)
        j[ok] = index[y2[ok], x2[ok]]
        ok &= j >= 0
        rows.append(np.arange(n)[ok])
        cols.append(j[ok])
        weights.append(np.full(int(ok.sum()), math.hypot(dx, dy)))
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    wgt = np.concatenate(weights)
    graph = coo_matrix((wgt, (r, c)), shape=(n, n)).tocsr()
    d0 = dijkstra(graph, directed=False, indices=0)
    a = int(np.argmax(np.where(np.isfinite(d0), d0, -1)))
    da, pred = dijkstra(graph, directed=False, indices=a, return_predecessors=True)
    b = int(np.argmax(np.where(np.isfinite(da), da, -1)))
    order = [b]
    while order[-1] != a:
        order.append(int(pred[order[-1]]))
    order.reverse()
    return np.column_stack((xs[order], ys[order])).astype(np.float64)


def _wire_like(
    count: int, labels: np.ndarray, stats: np.ndarray, min_extent: float, wide: float
) -> list[tuple[float, int]]:
    """(skeleton length, label) of the components long enough and no wider than a wire."""
    found: list[tuple[float, int]] = []
    for lab in range(1, count):
        x, y, w, h, area = stats[lab]
        if max(w, h) < min_extent:
            continue
        comp = labels[y : y + h, x : x + w] == lab
        skel = skeletonize(comp)
        length = float(skel.sum())
        if area / max(length, 1.0) > wide:
            continue  # wider than any wire: a strip of table, a sheet's edge
        found.append((length, lab))
    return found


def _filled_paths(
    found: list[tuple[float, int]], labels: np.ndarray, stats: np.ndarray, wide: float
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Of the longest skeletons, those no wider than a wire once their holes are filled,
    longest path first (a stray disc's or ring's outline has a long skeleton but, filled,
    no long path; a sheet's grainy margin around the left-out board passes the skeleton
    test, as its speckle has a long skeleton, but filled it is a band tens of wires wide,
    more than ``wide`` as filled area over path length): (path length, its filled mask,
    the path), in the reduced image's pixels."""
    kept: list[tuple[float, np.ndarray, np.ndarray]] = []
    for _, lab in sorted(found, reverse=True):
        if len(kept) == CANDIDATES:
            break
        x, y, w, h, _ = stats[lab]
        comp_box = (labels[y : y + h, x : x + w] == lab).astype(np.uint8)
        # fill holes (a specular crest can split the mask along the wire)
        contours, _ = cv2.findContours(comp_box, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        filled_box = np.zeros_like(comp_box)
        cv2.drawContours(filled_box, contours, -1, 1, thickness=cv2.FILLED)
        path_box = longest_skeleton_path(skeletonize(filled_box.astype(bool)))
        plen = float(np.sum(np.hypot(*np.diff(path_box, axis=0).T)))
        if float(filled_box.sum()) / max(plen, 1.0) > wide:
            continue
        filled = np.zeros(labels.shape, dtype=np.uint8)
        filled[y : y + h, x : x + w] = filled_box
        kept.append((plen, filled, path_box + np.array([x, y], dtype=np.float64)))
    return sorted(kept, key=lambda k: -k[0])


def segment_wire(
    image: np.ndarray,
    *,
    exclude: np.ndarray | None = None,
    max_wire_width_px: float,
    min_length_px: float,
) -> WireMask | None:
    """The wire in a photo: the longest of :func:`wire_candidates`, or None."""
    found = wire_candidates(
        image, exclude=exclude, max_wire_width_px=max_wire_width_px, min_length_px=min_length_px
    )
    return found[0] if found else None


def wire_candidates(
    image: np.ndarray,
    *,
    exclude: np.ndarray | None = None,
    max_wire_width_px: float,
    min_length_px: float,
) -> list[WireMask]:
    """The thin lines in a photo that could be the wire, longest first.

    Parameters
    ----------
    image : ndarray (H, W, 3) BGR or (H, W) grey, uint8 or uint16.
    exclude : ndarray (H, W) bool, optional; pixels that cannot be wire (the
        board and its margin).
    max_wire_width_px : the widest the wire can appear, pixels (sets the
        background filter's size).
    min_length_px : a wire shorter than this is "no wire".

    Returns
    -------
    list of WireMask, longest path first (at most ``CANDIDATES``); empty when no
    wire-like structure is found. Which one is a wire is for its profiles to tell
    (:func:`cvmeasure.part.locate.measure_centreline_mm`).
    """
    g8, levels = _gray8(image)
    # Work at a reduced size when the wire is wide: the mask is only a guide.
    factor = min(1.0, 10.0 / max(max_wire_width_px, 1e-9))
    small = (
        cv2.resize(g8, None, fx=factor, fy=factor, interpolation=cv2.INTER_AREA)
        if factor < 1.0
        else g8
    )
    wide = max_wire_width_px * factor
    background = cv2.medianBlur(small, _odd(2.0 * wide + 1))
    diff = np.abs(small.astype(np.float32) - background.astype(np.float32))
    valid = np.ones(small.shape, dtype=bool)
    if exclude is not None:
        ex = cv2.resize(
            exclude.astype(np.uint8),
            (small.shape[1], small.shape[0]),
            interpolation=cv2.INTER_NEAREST,
        ).astype(bool)
        valid &= ~ex
    # ignore a frame at the image border (filter edge effects)
    border = _odd(2 * wide)
    valid[:border] = valid[-border:] = False
    valid[:, :border] = valid[:, -border:] = False
    values = diff[valid]
    if values.size == 0:
        return None
    noise = 1.4826 * float(np.median(np.abs(values - np.median(values)))) + 0.5
    threshold = max(6.0 * noise, 10.0)
    cand = (diff > threshold) & valid
    close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (_odd(wide / 2),) * 2)
    cand = cv2.morphologyEx(cand.astype(np.uint8), cv2.MORPH_CLOSE, close).astype(bool)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        cand.astype(np.uint8), connectivity=8
    )
    found = _wire_like(count, labels, stats, min_length_px * factor * 0.5, wide)
    if not found:
        return []
    return [
        _wire_mask(filled, path_small, path_len / factor, factor, g8, levels, threshold,
                   max_wire_width_px)
        for path_len, filled, path_small in _filled_paths(found, labels, stats, wide)
        if path_len / factor >= min_length_px
    ]  # fmt: skip


def _wire_mask(
    filled: np.ndarray,
    path_small: np.ndarray,
    length_px: float,
    factor: float,
    g8: np.ndarray,
    levels: np.ndarray,
    threshold: float,
    max_wire_width_px: float,
) -> WireMask:
    """One candidate at full size: its mask, path, sheet, levels and rough width."""
    if factor < 1.0:
        mask = cv2.resize(filled, (g8.shape[1], g8.shape[0]), interpolation=cv2.INTER_NEAREST)
        path = (path_small + 0.5) / factor - 0.5
    else:
        mask, path = filled, path_small
    mask_b = mask.astype(bool)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (_odd(max_wire_width_px),) * 2)
    # the wire's levels and the ring about it read within the mask's bounding box grown by
    # the ring's kernel, where every pixel of both lies (the same pixels, in the same order,
    # as reading the whole photo: a candidate is a few percent of it)
    box = _grown_box(mask_b, kernel.shape)
    mask_in, levels_in = mask_b[box], levels[box]
    inside = levels_in[mask_in].astype(np.float32)
    around = cv2.dilate(mask_in.astype(np.uint8), kernel).astype(bool) & ~mask_in
    bg_level = float(np.median(levels_in[around])) if around.any() else float(np.median(levels))
    # which way the wire stands out: compare its mean absolute deviation sides
    dev = inside - bg_level
    sheet: Sheet = (
        "light" if np.mean(np.minimum(dev, 0) ** 2) > np.mean(np.maximum(dev, 0) ** 2) else "dark"
    )
    return WireMask(
        mask=mask_b,
        path_px=path,
        sheet=sheet,
        background_level=bg_level,
        contrast=float(np.median(np.abs(dev))),
        threshold=threshold,
        width_px=float(mask_in.sum()) / max(length_px, 1.0),
    )


def _grown_box(mask: np.ndarray, kernel_shape: tuple[int, int]) -> tuple[slice, slice]:
    """Rows and columns of ``mask``'s bounding box grown by half an odd kernel either side
    (clipped to the image): what a dilation by that kernel can reach. The whole image when
    the mask is empty."""
    ys = np.nonzero(mask.any(axis=1))[0]
    if not len(ys):
        return slice(None), slice(None)
    xs = np.nonzero(mask[ys[0] : ys[-1] + 1].any(axis=0))[0]
    ay, ax = kernel_shape[0] // 2, kernel_shape[1] // 2
    h, w = mask.shape
    return (
        slice(max(0, ys[0] - ay), min(h, ys[-1] + ay + 1)),
        slice(max(0, xs[0] - ax), min(w, xs[-1] + ax + 1)),
    )
