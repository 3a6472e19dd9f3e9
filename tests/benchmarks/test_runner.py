"""The benchmark runner's contract: result JSON, RESULTS.md sections, hand-written sections kept."""

import json
import subprocess
import sys

import pytest

import benchmarks
from benchmarks import Metric, Table, finish, write_results_md
from benchmarks.__main__ import _declared_section, discover


@pytest.fixture
def bench_dirs(tmp_path, monkeypatch):
    results = tmp_path / "results"
    monkeypatch.setattr(benchmarks, "RESULTS_DIR", results)
    monkeypatch.setattr(benchmarks, "RESULTS_MD", tmp_path / "RESULTS.md")
    return tmp_path


def _stand_in(folder, sleep_s):
    """A benchmark command stand-in: the child sleeps, then writes ``folder/<name>``:
    its core count, start and end times and the schedule it was told."""

    def command(name, quick):
        script = (
            f"import os, time; t0 = time.time(); time.sleep({sleep_s}); "
            f"open({str(folder)!r} + '/{name}', 'w').write("
            "f'{len(os.sched_getaffinity(0))} {t0} {time.time()} ' "
            "+ os.environ.get('BENCHMARKS_SCHEDULE', '-'))"
        )
        return [sys.executable, "-c", script]

    return command


def test_finish_writes_json_and_only_its_section(bench_dirs, capsys):
    md = bench_dirs / "RESULTS.md"
    md.write_text("# Benchmark results\n\n## Hand-written lens notes\n\nrms 0.12 px, by hand.\n")
    result = finish(
        str(bench_dirs / "speed.py"),
        "Speed per photo",
        ["--quick"],
        quick=True,
        metrics=[
            Metric("ours per photo", 0.25, "s", target="<= 0.5", met=True),
            Metric("seed ratio", 7.5, "x", target=">= 10", met=False),
            Metric("note only", float("nan"), "s"),
        ],
        tables=[Table("sizes", ["MP", "seconds"], [[4, 0.1], [24, 0.6]])],
        notes=["a note"],
        seconds=1.5,
    )
    saved = json.loads((bench_dirs / "results" / "speed.json").read_text())
    assert saved == result
    assert saved["name"] == "speed" and saved["command"] == "python -m benchmarks.speed --quick"
    assert saved["metrics"][2]["value"] is None and saved["machine"]["cores"] >= 1
    text = md.read_text()
    assert "## Hand-written lens notes\n\nrms 0.12 px, by hand." in text
    assert "## Speed per photo" in text and "| ours per photo | 0.25 | s | <= 0.5 | yes |" in text
    assert "| seed ratio | 7.5 | x | >= 10 | **NO** |" in text
    assert "1 of 2 targets met." in text  # the summary counts metrics with a target
    assert "ours per photo" in capsys.readouterr().out

    # a second run replaces the section in place, keeps the others and their order
    finish(
        str(bench_dirs / "speed.py"),
        "Speed per photo",
        [],
        quick=False,
        metrics=[Metric("ours per photo", 0.2, "s", target="<= 0.5", met=True)],
        seconds=2.0,
    )
    text2 = md.read_text()
    assert text2.count("## Speed per photo") == 1 and "| 0.25 |" not in text2
    assert text2.index("Hand-written lens notes") < text2.index("## Speed per photo")
    assert "1 of 1 targets met." in text2


def test_render_only_regenerates_preamble_and_sections(bench_dirs):
    (bench_dirs / "results").mkdir()
    (bench_dirs / "results" / "x.json").write_text(
        json.dumps(
            {
                "name": "x",
                "section": "X bench",
                "command": "python -m benchmarks.x",
                "quick": False,
                "date_utc": "2026-11-21T00:00:00+00:00",
                "seconds": 3.0,
                "machine": {"cores": 2},
                "metrics": [{"name": "m", "value": 1, "unit": "", "target": None, "met": None}],
                "tables": [],
                "plots": [],
                "notes": [],
            }
        )
    )
    (bench_dirs / "results" / "broken.json").write_text("{not json")
    write_results_md(command="python -m benchmarks --quick")
    text = (bench_dirs / "RESULTS.md").read_text()
    assert text.startswith("# Benchmark results")
    assert "Last full run: `python -m benchmarks --quick`" in text
    assert "## X bench" in text and "## Targets at a glance" in text


def test_discover_and_declared_section():
    names = discover()
    assert "batch" in names and "__main__" not in names and "__init__" not in names
    assert _declared_section("batch") == "Batch throughput and resume (issue 9)"
    assert _declared_section("no_such_benchmark") == "no_such_benchmark (benchmark)"


def test_runner_cli_list_and_unknown():
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks", "--list"], capture_output=True, text=True, check=False
    )
    assert out.returncode == 0 and "batch" in out.stdout.split()
    bad = subprocess.run(
        [sys.executable, "-m", "benchmarks", "nope"], capture_output=True, text=True, check=False
    )
    assert bad.returncode == 2 and "unknown benchmark(s) nope" in bad.stderr


def test_metric_at_most_target_and_met():
    assert Metric.at_most("p95", 0.05, "deg", 0.1) == Metric(
        "p95", 0.05, "deg", target="<= 0.1", met=True
    )
    assert Metric.at_most("p95", 0.1, "deg", 0.1).met is True  # the limit itself is met
    assert Metric.at_most("p95", 0.11, "deg", 0.1).met is False
    assert Metric.at_most("p95", None, "deg", 0.1).to_dict()["met"] is False  # nothing measured


def test_shared_real_boards_and_random_photo():
    from benchmarks._photos import CHARUCO_5X7, LIFECAM, random_bender_photo
    from cvmeasure.board import board_from_dict

    assert board_from_dict(CHARUCO_5X7).size_mm == pytest.approx((200.0, 280.0))
    assert board_from_dict(LIFECAM).size_mm == pytest.approx((203.2, 203.2))
    jpeg = random_bender_photo((240, 160), 5)
    plain = random_bender_photo((240, 160), 5, jpeg=False)
    assert jpeg.bgr.shape == plain.bgr.shape == (160, 240, 3)
    assert jpeg.jpeg_bytes is not None and plain.jpeg_bytes is None
    # same seed, same scene: only the compression differs
    assert jpeg.truth["requested"] == plain.truth["requested"]
    assert abs(jpeg.truth["requested"]["pin_angle_deg"]) <= 120.0


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_pinned_runs_each_on_a_core_of_its_own(tmp_path, monkeypatch):
    """--cores N: every child is pinned to one core, at most N at once, exit codes kept."""
    import os

    import benchmarks.__main__ as runner

    cores = sorted(os.sched_getaffinity(0))[:2]

    def command(name, quick):
        code = 3 if name == "bad" else 0
        script = (
            "import os, sys, time; "
            f"open({str(tmp_path)!r} + '/{name}', 'w').write(str(len(os.sched_getaffinity(0))) + ' ' + str(min(os.sched_getaffinity(0)))); "
            f"time.sleep(0.3); sys.stderr.write('last line of {name}\\n'); sys.exit({code})"
        )
        return [sys.executable, "-c", script]

    monkeypatch.setattr(runner, "_command_of", command)
    done = runner._run_pinned(["a", "b", "bad"], False, 60.0, cores)
    assert set(done) == {"a", "b", "bad"}
    assert done["bad"][0] == 3 and done["bad"][2] == "last line of bad"
    assert done["a"][0] == 0 and done["b"][0] == 0
    for name in ("a", "b", "bad"):
        count, core = map(int, (tmp_path / name).read_text().split())
        assert count == 1 and core in cores


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_side_lane_runs_unpinned_beside_the_pinned_queue(tmp_path, monkeypatch):
    """SIDE_LANE benchmarks run unpinned, at the same time as the pinned ones, one at a time."""
    import os

    import benchmarks.__main__ as runner

    cores = sorted(os.sched_getaffinity(0))[:1]
    everywhere = len(os.sched_getaffinity(0))

    monkeypatch.setattr(runner, "_command_of", _stand_in(tmp_path, 0.6))
    done = runner._run_pinned(["p"], False, 60.0, cores, side=["s1", "s2"])
    assert {k: v[0] for k, v in done.items()} == {"p": 0, "s1": 0, "s2": 0}
    runs = {n: (tmp_path / n).read_text().split() for n in ("p", "s1", "s2")}
    spans = {n: (float(r[1]), float(r[2])) for n, r in runs.items()}
    assert int(runs["p"][0]) == 1
    assert int(runs["s1"][0]) == everywhere and int(runs["s2"][0]) == everywhere
    side = sorted([spans["s1"], spans["s2"]])
    assert side[0][1] <= side[1][0]  # one side benchmark at a time
    assert spans["p"][0] < side[0][1]  # the pinned one ran beside the first side one


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_cores_run_timing_benchmarks_alone_after_the_parallel_part(bench_dirs, monkeypatch):
    """--cores 2: decode_speed runs alone after the parallel part, batch last; each child is told."""
    import os

    import benchmarks.__main__ as runner

    calls: list[tuple[str, tuple[str, ...]]] = []

    def pinned(names, quick, timeout_s, cores, side=()):
        calls.append(("parallel", tuple(names)))
        calls.append(("side", tuple(side)))
        return {n: (0, 1.0, "") for n in [*names, *side]}

    def one(name, quick, timeout_s, schedule="alone"):
        calls.append(("alone", (name,)))
        return 0, 1.0, ""

    monkeypatch.setattr(runner, "_run_pinned", pinned)
    monkeypatch.setattr(runner, "_run_one", one)
    monkeypatch.setattr(runner, "write_results_md", lambda **kw: bench_dirs / "RESULTS.md")
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs two cores for --cores 2")
    names = ["batch", "decode_speed", "sim_speed", "serial_heldout", "markers"]
    assert runner.main(["--cores", "2", *names]) == 0
    assert calls == [
        ("parallel", ("sim_speed", "markers")),
        ("side", ("serial_heldout",)),
        ("alone", ("decode_speed",)),
        ("alone", ("batch",)),
    ]


def test_finish_records_how_the_run_was_scheduled(bench_dirs, monkeypatch):
    from benchmarks import SCHEDULE_ENV

    monkeypatch.setenv(SCHEDULE_ENV, "alone: no other benchmark of this run at the same time")
    result = finish(str(bench_dirs / "decode_speed.py"), "Decode", [], quick=True, seconds=1.0)
    assert result["schedule"].startswith("alone")
    text = (bench_dirs / "RESULTS.md").read_text()
    assert "· run alone: no other benchmark of this run at the same time" in text


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_process_timing_benchmarks_start_after_the_side_lane(tmp_path, monkeypatch):
    """AFTER_SIDE_LANE benchmarks wait for the side lane; the other pinned ones do not."""
    import os

    import benchmarks.__main__ as runner

    cores = sorted(os.sched_getaffinity(0))[:1]

    monkeypatch.setattr(runner, "_command_of", _stand_in(tmp_path, 0.4))
    monkeypatch.setattr(runner, "_previous_seconds", lambda name: 1.0)
    done = runner._run_pinned(["diagnosis_session", "p"], False, 60.0, cores, side=["s1", "s2"])
    assert {k: v[0] for k, v in done.items()} == {"diagnosis_session": 0, "p": 0, "s1": 0, "s2": 0}
    runs = {n: (tmp_path / n).read_text().split(maxsplit=3) for n in done}
    side_end = max(float(runs[n][2]) for n in ("s1", "s2"))
    assert float(runs["diagnosis_session"][1]) >= side_end
    assert float(runs["p"][1]) < side_end  # the queue's other benchmark did not wait
    assert runs["diagnosis_session"][3].endswith("after the side lane had ended")
