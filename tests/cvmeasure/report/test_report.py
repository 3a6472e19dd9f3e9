"""The HTML report: strict HTML parse, everything embedded, overlays where the measurements are,
and a real headless Chromium rendering it (skipped, saying why, when Chromium is absent)."""

import base64
import re
import shutil
import subprocess

import cv2
import html5lib
import numpy as np
import pytest

from cvmeasure.agreement import ManualReading, agreement
from cvmeasure.cli import main
from cvmeasure.fileio import append_jsonl
from cvmeasure.report import build_report, overlay_thumbnail

PLOT_BLUE_BGR = (159, 95, 31)  # matplotlib points of the angle plot (#1f5f9f)


def grey_photo(path, size=(1600, 1200)):
    rng = np.random.default_rng(2)
    img = np.clip(128 + rng.normal(0, 3, (size[1], size[0], 3)), 0, 255).astype(np.uint8)
    cv2.imwrite(str(path), img, [cv2.IMWRITE_JPEG_QUALITY, 95])


def red_centroid(jpeg: bytes) -> tuple[float, float, tuple[int, int]]:
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    b, g, r = (img[..., i].astype(int) for i in range(3))
    ys, xs = np.nonzero((r > 160) & (g < 100) & (b < 100))
    assert xs.size > 100
    # centre of the drawn circle's extent
    return (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2, (img.shape[1], img.shape[0])


def test_disc_overlay_is_drawn_where_the_disc_was_measured(tmp_path):
    photo = tmp_path / "g.jpg"
    grey_photo(photo)
    rec = {"photo": str(photo), "x_px": 1000.0, "y_px": 300.0, "r_px": 120.0}
    x, y, size = red_centroid(overlay_thumbnail(rec, photo, width_px=400))
    assert size == (400, 300)
    assert abs(x - 250) < 2 and abs(y - 75) < 2  # scale 0.25


def test_marker_overlay_crops_to_the_markers(tmp_path):
    photo = tmp_path / "m.jpg"
    grey_photo(photo)
    centres = {
        "origin": (800, 600),
        "axis": (600, 600),
        "pin": (860, 560),
        "wire_a": (880, 620),
        "wire_b": (950, 650),
    }
    rec = {"markers": {k: {"x_px": x, "y_px": y, "r_px": 10.0} for k, (x, y) in centres.items()}}
    img = cv2.imdecode(
        np.frombuffer(overlay_thumbnail(rec, photo, width_px=360), np.uint8), cv2.IMREAD_COLOR
    )
    # the crop spans the markers (350 px wide) plus margins, magnified to 360 px
    assert img.shape[1] == 360 and img.shape[0] < 360
    # the pin circle (yellow, BGR 0,220,255) is drawn inside the crop
    yellow = (img[..., 0] < 90) & (img[..., 1] > 170) & (img[..., 2] > 200)
    assert yellow.sum() > 10


def records_and_files(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    records = []
    rng = np.random.default_rng(8)
    for i in range(6):
        name = f"m{i}.jpg"
        grey_photo(photos / name, size=(800, 600))
        bend = float(rng.uniform(10, 120))
        markers = {
            role: {"x_px": 300 + 40 * j, "y_px": 300 + 5 * j, "r_px": 8.0}
            for j, role in enumerate(("axis", "origin", "pin", "wire_a", "wire_b"))
        }
        records.append(
            {
                "photo": f"photos/{name}",
                "file_name": name,
                "kind": "machine",
                "ok": True,
                "bend_angle_deg": bend,
                "pin_angle_deg": bend + 5,
                "markers": markers,
                "uncertainty_deg": {"bend_angle_deg": 0.02, "pin_angle_deg": 0.03},
                "warnings": ["a <b>bold</b> warning"] if i == 0 else [],
            }
        )
    records.append(
        {
            "photo": "photos/broken.jpg",
            "kind": "machine",
            "ok": False,
            "error": "photos/broken.jpg: unreadable",
        }
    )
    records.append(
        {"trial": 1, "loaded_bend_deg": 47.0, "unloaded_bend_deg": 45.2, "springback_deg": 1.8}
    )
    return records


def check_self_contained(text: str, n_rows: int) -> None:
    parser = html5lib.HTMLParser(strict=True, namespaceHTMLElements=False)
    doc = parser.parse(text)  # raises on any parse error
    imgs = doc.findall(".//img")
    assert imgs, "no images"
    for img in imgs:
        src = img.get("src")
        m = re.fullmatch(r"data:image/(png|jpeg);base64,([A-Za-z0-9+/=]+)", src)
        assert m, src[:60]
        decoded = cv2.imdecode(
            np.frombuffer(base64.b64decode(m.group(2)), np.uint8), cv2.IMREAD_COLOR
        )
        assert decoded is not None and decoded.shape[0] > 20
    for el in doc.iter():
        for name, value in el.attrib.items():
            assert not re.search(r"(https?:|ftp:|//[a-z0-9])", value, re.I) or value.startswith(
                "data:"
            ), (name, value[:80])
    assert doc.find(".//script") is None and doc.find(".//link") is None
    assert len(doc.findall(".//div[@class='wide']/table/tbody/tr")) == n_rows
    assert "<b>bold</b>" not in text and "&lt;b&gt;bold&lt;/b&gt;" in text  # escaped


def test_report_is_valid_self_contained_html(tmp_path):
    records = records_and_files(tmp_path)
    manual = [
        ManualReading(r["file_name"], r["bend_angle_deg"] - 0.2 + 0.05 * i, "a", "1")
        for i, r in enumerate(records[:6])
    ]
    result = agreement(manual, {r["file_name"]: r["bend_angle_deg"] for r in records[:6]})
    text = build_report(records, source="results.jsonl", photo_roots=[tmp_path], agreement=result)
    check_self_contained(text, n_rows=len(records))
    # 6 thumbnails, the failed photo named as missing, plots of angles/springback/residuals + Bland-Altman
    assert text.count("class=thumb") == 6 and "photo not found" in text
    assert text.count("data:image/png") == 4
    assert "Agreement with manual readings" in text


def test_cli_report_and_chromium_renders_it(tmp_path):
    records = records_and_files(tmp_path)
    long_name = "bender_" + "x" * 120 + ".jpg"  # one unbreakable token, as real paths are
    records.append(
        {"photo": f"/data/{long_name}", "file_name": long_name, "kind": "machine", "ok": False}
        | {"error": f"/data/{'very_long_folder_' * 8}/{long_name}: marker 'pin' not found"}
    )
    results = tmp_path / "results.jsonl"
    for r in records:
        append_jsonl(results, r)
    out = tmp_path / "out" / "report.html"
    assert main(["report", str(results), "-o", str(out), "--quiet"]) == 0
    text = out.read_text()
    check_self_contained(text, n_rows=len(records))
    assert text.count("class=thumb") == 6  # photos found beside the results file
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip(
            "Debian's chromium is not installed (apt-get install chromium): HTML checked by html5lib only"
        )
    shot = tmp_path / "shot.png"
    proc = subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--proxy-server=127.0.0.1:9",
            "--window-size=1200,3000",
            f"--screenshot={shot}",
            out.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=90,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-500:]
    img = cv2.imread(str(shot))
    assert img.shape[:2] == (3000, 1200)
    # the embedded angle plot was decoded and painted: its blue points are on screen
    near_blue = np.all(np.abs(img.astype(int) - PLOT_BLUE_BGR) < 30, axis=2)
    assert near_blue.sum() > 50
    # and the thumbnails (mid-grey photos) too
    grey = np.all(np.abs(img.astype(int) - 128) < 12, axis=2)
    assert grey.sum() > 5000
    # nothing runs off the side of a 1400 px window: a copy of the page that reports its
    # width (the report itself has no script)
    probe = tmp_path / "probe.html"
    probe.write_text(
        text.replace(
            "</body>",
            "<script>document.body.setAttribute('data-overflow-px', "
            "document.documentElement.scrollWidth - window.innerWidth)</script></body>",
        )
    )
    dom = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--proxy-server=127.0.0.1:9"]
        + ["--window-size=1400,900", "--dump-dom", probe.as_uri()],
        capture_output=True,
        text=True,
        timeout=90,
        check=False,
    )
    m = re.search(r'data-overflow-px="(-?\d+)"', dom.stdout)
    assert m, dom.stderr[-300:]
    assert int(m.group(1)) <= 0, f"the page is {m.group(1)} px wider than a 1400 px window"


def test_cli_report_bad_input(tmp_path, capsys):
    empty = tmp_path / "e.jsonl"
    empty.write_text("")
    assert main(["report", str(empty), "-o", str(tmp_path / "r.html")]) == 2
    assert "e.jsonl: no records" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "missing.jsonl"), "-o", str(tmp_path / "r.html")]) == 2
    assert not (tmp_path / "r.html").exists()
