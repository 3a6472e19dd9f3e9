"""The design corpus: files as operators export them, each with its expected outcome.

``tests/cvmeasure/data/designs`` holds Inkscape (96 px per inch and mm documents),
Illustrator (72 pt), plain SVG in in/cm/pt and unitless, LibreCAD/QCAD/ezdxf DXF in mm,
cm and inches and unitless, arcs, splines, bulged polylines, lines drawn out of order,
tiny and real gaps, closed shapes, self-contact and too-short segments
(``make_corpus.py`` wrote them and ``expected.json`` from their construction). Every
file goes through ``cvmeasure gcode`` as an operator runs it: the job's bends and feeds
are the drawn ones, every change is printed, or the design is refused (exit 2) with
the element and the number, and nothing is written.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cvmeasure.cli import main

CORPUS = Path(__file__).parent / "data" / "designs"
EXPECTED = json.loads((CORPUS / "expected.json").read_text(encoding="utf-8"))


def test_the_corpus_is_large_and_mixed():
    assert len(EXPECTED) >= 30
    outcomes = [e["outcome"] for e in EXPECTED.values()]
    assert outcomes.count("ok") >= 12 and outcomes.count("refused") >= 12
    assert {p.suffix for p in CORPUS.iterdir()} >= {".svg", ".dxf"}


def _turns(steps):
    return -np.array([s["bend_deg"] for s in steps[:-1]])


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus_design(name, tmp_path, capsys):
    want = EXPECTED[name]
    out = tmp_path / "job.gcode"
    code = main(["gcode", str(CORPUS / name), "-o", str(out), "--json"])
    printed = capsys.readouterr()
    if want["outcome"] == "refused":
        assert code == 2, printed.out
        assert printed.err.count("\n") == 1  # one line
        for word in want["message"]:
            assert word in printed.err, printed.err
        assert not out.exists()
        return
    assert code == 0, printed.err
    job = json.loads(printed.out)
    steps = job["bend_list"]
    feeds = np.array([s["feed_mm"] for s in steps])
    turns = _turns(steps)
    # every change the planner made is printed (JSON) and kept in the job's header
    made = [c["what"] for c in job["plan"]["changes"]]
    assert sorted(made) == sorted(want["changes"])
    header = out.read_text(encoding="utf-8")
    for what in made:
        assert f"; {what}:" in header
    if "chords_mm" in want:
        c, t = np.array(want["chords_mm"]), np.array(want["turns_deg"])
        if want.get("either_end") and not np.allclose(feeds, c, atol=0.01):
            c, t = c[::-1], -t[::-1]  # drawn from the other end
        np.testing.assert_allclose(feeds, c, atol=0.01)
        np.testing.assert_allclose(turns, t, atol=0.01)
    if "arc_chords" in want and "arc_chord_mm" in want:
        n, chord, turn = want["arc_chords"], want["arc_chord_mm"], want["arc_turn_deg"]
        straight = want["straight_mm"]
        assert len(feeds) == n + len(straight)
        np.testing.assert_allclose(
            sorted(feeds)[-len(straight) :] if straight else [], sorted(straight), atol=0.01
        )
        arc_feeds = feeds[1 : 1 + n] if straight else feeds
        np.testing.assert_allclose(arc_feeds, chord, atol=0.01)
        inner = turns[1:-1] if straight else turns
        if not straight:
            np.testing.assert_allclose(inner, turn, atol=0.01)
        else:
            np.testing.assert_allclose(inner, turn, atol=0.01)
            # at the tangent points half a chord's turn
            np.testing.assert_allclose(turns[[0, -1]], turn / 2, atol=0.01)
    if want.get("equal_chords"):
        assert np.ptp(feeds) < 0.01 and np.all(feeds >= 12.0)
        if "arc_chords" in want:
            assert len(feeds) == want["arc_chords"]
        verts = np.array(job["plan"]["vertices_mm"])
        assert np.hypot(*(verts[-1] - verts[0])) == pytest.approx(want["end_to_end_mm"], abs=0.01)
    if "bends" in want:
        assert len(turns) == want["bends"]


def test_no_corpus_design_is_changed_silently(tmp_path, capsys):
    """Over the corpus: every accepted design is bent as drawn, or each change is printed."""
    silent = []
    for name, want in EXPECTED.items():
        if want["outcome"] != "ok":
            continue
        out = tmp_path / "job.gcode"
        assert main(["gcode", str(CORPUS / name), "-o", str(out), "--json"]) == 0
        job = json.loads(capsys.readouterr().out)
        assert main(["gcode", str(CORPUS / name), "-o", str(out)]) == 0
        printed = capsys.readouterr().out
        steps = job["bend_list"]
        feeds = np.array([s["feed_mm"] for s in steps])
        as_drawn = "chords_mm" in want and (
            np.allclose(feeds, want["chords_mm"], atol=0.01)
            or np.allclose(feeds[::-1], want["chords_mm"], atol=0.01)
        )
        changes = job["plan"]["changes"]
        told = all(f"{c['what']}: " in printed and "largest deviation" in printed for c in changes)
        if not (as_drawn or (changes and told)):
            silent.append(name)
    assert silent == []
