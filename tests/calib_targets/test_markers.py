"""The printable marker-kit sheet: exact scale, every role, its CLI."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.kit import default_kit
from cvmeasure_calib_targets.markers import (
    KIT_PAGE_MM,
    kit_sheet_positions_mm,
    naive_cmyk,
    render_kit_sheet,
    write_kit_sheet,
)

DPI = 200.0


def test_png_sheet_has_every_disc_at_exact_size_and_place():
    kit = default_kit()
    data = render_kit_sheet(kit, "png", dpi=DPI)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    px_per_mm = DPI / 25.4
    assert img.shape[1] == pytest.approx(KIT_PAGE_MM[0] * px_per_mm, abs=1)
    assert img.shape[0] == pytest.approx(KIT_PAGE_MM[1] * px_per_mm, abs=1)
    positions = kit_sheet_positions_mm(kit)
    for marker in kit.markers:
        r, g, b = marker.srgb
        # half-way between the disc's colour and the white ring: the anti-aliased edge
        d_disc = np.linalg.norm(img.astype(float) - (b, g, r), axis=2)
        d_white = np.linalg.norm(img.astype(float) - 255.0, axis=2)
        mask = ((d_disc < d_white) & (d_disc < 60)).astype(np.uint8)
        n, _, stats, centroids = cv2.connectedComponentsWithStats(mask)
        discs = [i for i in range(1, n) if stats[i, 4] > 100]
        expected = [(x, y) for role, x, y in positions if role == marker.role]
        assert len(discs) == len(expected), marker.role
        for i in discs:
            diameter_mm = 2 * np.sqrt(stats[i, 4] / np.pi) / px_per_mm
            assert diameter_mm == pytest.approx(marker.diameter_mm, abs=0.13), marker.role  # 1 px
            cx, cy = (centroids[i] + 0.5) / px_per_mm
            assert min(np.hypot(cx - x, cy - y) for x, y in expected) < 0.1


def test_svg_and_pdf_are_a4_at_exact_scale(tmp_path):
    kit = default_kit()
    svg = write_kit_sheet(kit, tmp_path / "kit.svg").read_text()
    w = float(re.search(r'width="([\d.]+)pt"', svg).group(1))
    h = float(re.search(r'height="([\d.]+)pt"', svg).group(1))
    assert (w * 25.4 / 72, h * 25.4 / 72) == pytest.approx(KIT_PAGE_MM, abs=0.05)
    assert "seed-5" in svg
    pdf = write_kit_sheet(kit, tmp_path / "kit.pdf").read_bytes()
    assert pdf.startswith(b"%PDF")
    box = re.search(rb"/MediaBox \[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", pdf)
    assert (float(box.group(1)) * 25.4 / 72, float(box.group(2)) * 25.4 / 72) == pytest.approx(
        KIT_PAGE_MM, abs=0.05
    )
    with pytest.raises(ValueError, match="unsupported sheet format"):
        write_kit_sheet(kit, tmp_path / "kit.gif")
    with pytest.raises(ValueError, match="copies"):
        kit_sheet_positions_mm(kit, copies=9)


def test_naive_cmyk():
    assert naive_cmyk((255, 255, 255)) == (0.0, 0.0, 0.0, 0.0)
    assert naive_cmyk((0, 0, 0)) == (0.0, 0.0, 0.0, 100.0)
    assert naive_cmyk((255, 0, 0)) == (0.0, 100.0, 100.0, 0.0)


def test_targets_markers_cli(tmp_path, capsys):
    assert main(["targets", "markers", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == default_kit().to_dict()
    out = tmp_path / "sheet.pdf"
    assert main(["targets", "markers", "-o", str(out)]) == 0
    assert out.read_bytes().startswith(b"%PDF")
