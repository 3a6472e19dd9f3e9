import subprocess
import sys

import pytest

from cvmeasure.cli import COMMAND_MODULES, build_parser, main


def test_help_lists_demo(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    assert "demo" in capsys.readouterr().out


def test_no_command_is_usage_error(capsys):
    assert main([]) == 2


def test_reader_gone_is_not_a_traceback(tmp_path):
    """``cvmeasure ... | head``: the reader closes the pipe first; no traceback, exit 141."""
    import os
    import subprocess
    import sys

    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before anything is written
    proc = subprocess.run(
        [sys.executable, "-m", "cvmeasure", "targets", "markers", "--format", "json"],
        stdout=write_end,
        stderr=subprocess.PIPE,
        text=True,
        timeout=120,
    )
    os.close(write_end)
    assert proc.returncode == 141
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr


def test_targets_charuco_writes_its_board_json_and_the_default_board(tmp_path, capsys):
    from cvmeasure.board import DEFAULT_BOARD, load_board

    sheet = tmp_path / "board.svg"
    assert main(["targets", "charuco", "-o", str(sheet), "--page", "a3"]) == 0
    assert load_board(tmp_path / "board.board.json") == DEFAULT_BOARD
    out = capsys.readouterr().out
    assert "280 x 200 mm board" in out and "board.board.json" in out
    # the board JSON beside the sheet must not overwrite the --board given
    assert (
        main(
            ["targets", "charuco", "--board", str(tmp_path / "board.board.json"), "-o", str(sheet)]
        )
        == 2
    )
    assert "would overwrite the input --board" in capsys.readouterr().err


def test_targets_help_says_100_percent(capsys):
    with pytest.raises(SystemExit):
        main(["targets", "--help"])
    out = capsys.readouterr().out
    assert "100 %" in out and "%%" not in out


def test_render_saddle_prints_its_numbers(tmp_path, capsys):
    assert (
        main(
            ["render", "part", "--saddle", "200", "20", "13", "--scale", "0.1", "-o", str(tmp_path)]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "chord_width_mm=200" in out and "height_mm=19.69" in out and "radius" not in out


@pytest.mark.parametrize(
    "argv",
    [
        ["fit", "{f}", "-o", "{f}"],
        ["report", "{f}", "-o", "{f}"],
        ["gcode", "{f}", "-o", "{f}"],
        ["simulate", "{f}", "-o", "{f}"],
        ["agreement", "{f}", "{g}", "-o", "{f}"],
        ["measure", "{f}", "--kit", "{g}", "-o", "{g}"],
        ["diagnose", "{f}", "--plot", "{f}"],
        ["part", "{f}", "--board", "{g}", "--camera", "{g}", "--overlay", "{f}"],
    ],
)
def test_an_output_that_is_an_input_is_refused_and_the_input_kept(tmp_path, capsys, argv):
    f, g = tmp_path / "input.csv", tmp_path / "other.json"
    f.write_text("trial,commanded_pin_deg\n1,20\n")
    g.write_text("{}")
    before = (f.read_bytes(), g.read_bytes())
    assert main([a.format(f=f, g=g) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "is also an input: refusing to overwrite it" in err and err.count("\n") == 1
    assert (f.read_bytes(), g.read_bytes()) == before


def test_an_output_file_that_is_a_folder_is_refused(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n1,20\n2,-20\n")
    assert main(["simulate", str(plan), "-o", str(tmp_path)]) == 2
    assert "--out is a folder; give a file name" in capsys.readouterr().err
    assert main(["render", "board", "--scale", "0.1", "-o", str(plan)]) == 2
    assert "--out must be a folder" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["render", "board", "--scale", "0", "-o", "{t}"], "argument --scale: must be > 0"),
        (["render", "board", "--count", "-2", "-o", "{t}"], "argument --count: must be a whole"),
        (
            [
                "render",
                "bender",
                "--pin-deg",
                "1",
                "--bend-deg",
                "2",
                "--jpeg-quality",
                "101",
                "-o",
                "{t}",
            ],
            "argument --jpeg-quality: must be a whole number in 1..100",
        ),
        (
            ["bend", "{t}/j.gcode", "--port", "sim://", "--stall-timeout-s", "-1"],
            "argument --stall-timeout-s: must be > 0",
        ),
        (["targets", "charuco", "-o", "{t}/b.png", "--dpi", "nan"], "argument --dpi: must be"),
        (["agreement", "{t}/a", "{t}/b", "--tol-deg", "0"], "argument --tol-deg: must be > 0"),
        (["plane", "{t}/p", "--board", "b", "--camera", "c", "--tolerance-deg", "0"], "> 0"),
        (["part", "{t}/p", "--divisions", "0"], "argument --divisions: must be a whole number"),
        (["batch", "{t}", "-o", "{t}/r.jsonl", "--workers", "0"], "argument --workers"),
        (["diagnose", "{t}/t.csv", "--folds", "1"], "argument --folds: must be a whole number"),
        (["simulate", "{t}/p.csv", "-o", "{t}/o", "--noise-deg", "-1"], "must be >= 0"),
        (["session", "--simulate", "-o", "{t}/c.json", "--speedup", "0"], "argument --speedup"),
        (["report", "{t}/r", "-o", "{t}/r.html", "--max-thumbnails", "-3"], ">= 0"),
        (["gcode", "{t}/d.svg", "-o", "{t}/j.gcode", "--divisions", "0"], "--divisions: must be"),
    ],
)
def test_bad_option_values_are_one_line_usage_errors(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        main([a.format(t=tmp_path) for a in argv])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_sim_url_speedup_must_be_positive(tmp_path, capsys):
    job = tmp_path / "j.gcode"
    job.write_text("G90\n")
    assert main(["bend", str(job), "--port", "sim://?speedup=0"]) == 2
    assert "speedup must be a finite number > 0" in capsys.readouterr().err


def test_the_parser_loads_no_numerical_library():
    """``cvmeasure --help`` and argument errors start fast: building the parser of every
    command imports neither numpy nor OpenCV (each command imports what it uses when run)."""
    code = (
        "import sys; from cvmeasure.cli import build_parser; build_parser(); "
        "print(sorted(m for m in ('numpy', 'cv2', 'scipy', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_command_loads_only_its_own_module():
    # start-up: `cvmeasure diagnose` must not import the other commands' libraries
    code = (
        "import sys; from cvmeasure.cli import build_parser; "
        "p = build_parser('diagnose'); p.parse_args(['diagnose', 't.csv']); "
        "print(sorted(m for m in ('cvmeasure.batch', 'cv2') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"
    # the full parser (help, unknown command) still knows every command
    names = build_parser()._subparsers._group_actions[0].choices
    assert set(COMMAND_MODULES) <= set(names)
