"""The app's HTTP API and Grasshopper's Hops protocol, with requests as a browser and Hops send them.

Truth: the simulation of the nominal bender (``cvmeasure.sim.simulate``) bends the pin commands
the app returns; the final angles must be the ones asked for.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cvmeasure.sim import simulate

from .conftest import Server, httpx, wait_for

A = {"X-Client-Id": "operator-a"}
B = {"X-Client-Id": "operator-b"}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("ws")).start()
    yield s
    s.stop()


def _item(value, kind="System.Double"):
    return {"type": kind, "data": json.dumps(value)}


def solve(server, pointer, values, key="0"):
    body = {
        "pointer": pointer,
        "values": [{"ParamName": n, "InnerTree": {key: items}} for n, items in values.items()],
    }
    return httpx.post(server.url + "/hops/solve", json=body, timeout=30)


def outputs(resp) -> dict:
    return {
        v["ParamName"]: [json.loads(i["data"]) for i in v["InnerTree"]["0"]]
        for v in resp.json()["values"]
    }


def test_hops_lists_and_describes_components(server):
    listed = httpx.get(server.url + "/hops").json()
    assert {c["Name"] for c in listed} == {"pin_angles", "springback", "last_part"}
    comp = httpx.get(server.url + "/hops/springback").json()
    assert comp["Inputs"][0]["Name"] == "Angle"
    assert comp["Inputs"][0]["ResultType"] == "System.Double"
    assert [o["Name"] for o in comp["Outputs"]] == ["Pin", "Springback"]
    assert httpx.get(server.url + "/hops/nothing").status_code == 404


@pytest.mark.parametrize("key", ["0", "{0}"])
def test_hops_springback_pin_bends_the_wanted_angle(server, key):
    resp = solve(server, "springback", {"Angle": [_item(45.0)]}, key=key)
    assert resp.status_code == 200, resp.text
    out = outputs(resp)
    pin, spring = out["Pin"][0], out["Springback"][0]
    made = simulate([pin])
    # the nominal machine before any session: its pin makes 45 deg final within 0.05 deg
    assert made.unloaded_bend_deg[0] == pytest.approx(45.0, abs=0.05)
    assert spring == pytest.approx(made.loaded_bend_deg[0] - 45.0, abs=0.05)


def test_hops_pin_angles_for_a_polyline(server):
    bends = np.radians([20.0, -30.0, 25.0])
    heading = np.concatenate([[0.0], np.cumsum(bends)])
    pts = np.vstack([[0.0, 0.0], np.cumsum(20.0 * np.c_[np.cos(heading), np.sin(heading)], axis=0)])
    points = [_item({"X": x, "Y": y, "Z": 0.0}, "Rhino.Geometry.Point3d") for x, y in pts]
    resp = solve(server, "pin_angles", {"Points": points})
    assert resp.status_code == 200, resp.text
    out = outputs(resp)
    made = simulate(out["PinAngles"])
    assert np.abs(np.abs(made.unloaded_bend_deg) - [20.0, 30.0, 25.0]).max() < 0.05
    assert np.allclose(np.abs(out["Bends"]), [20.0, 30.0, 25.0], atol=1e-6)
    assert out["GCode"][0].count("G90 G1 X") == 3


def test_hops_errors_name_the_problem(server):
    resp = solve(server, "last_part", {})
    assert resp.status_code == 400
    assert "no part measured yet" in resp.json()["errors"][0]
    resp = solve(
        server,
        "pin_angles",
        {"Points": [_item({"X": 0, "Y": 0, "Z": 0}, "Rhino.Geometry.Point3d")]},
    )
    assert resp.status_code == 400 and "Points" in resp.json()["errors"][0]
    bad = httpx.post(server.url + "/hops/solve", content=b"not json", timeout=10)
    assert bad.status_code == 400


def test_wrong_file_is_refused_by_name(server, designs, tmp_path):
    with designs["notes"].open("rb") as fh:
        r = httpx.post(server.url + "/api/files", headers=A, files={"file": ("notes.txt", fh)})
    assert r.status_code == 400
    assert r.json()["error"].startswith("notes.txt: ")
    closed = tmp_path / "ring.svg"
    closed.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        'viewBox="0 0 100 100"><circle id="ring" cx="50" cy="50" r="30"/></svg>'
    )
    with closed.open("rb") as fh:
        r = httpx.post(server.url + "/api/files", headers=A, files={"file": ("ring.svg", fh)})
    assert r.status_code == 400 and r.json()["error"].startswith("ring.svg: ")
    assert "closed" in r.json()["error"]
    assert httpx.get(server.url + "/api/files").json()["files"] == []


def test_one_browser_controls_the_others_watch(server, designs):
    with designs["arc"].open("rb") as fh:
        r = httpx.post(server.url + "/api/files", headers=A, files={"file": ("arc.svg", fh)})
    assert r.status_code == 201 and r.json()["bends"] == 4
    cmd = {"command": "add", "design": "arc.svg", "quantity": 3}
    assert httpx.post(server.url + "/api/queue", headers=B, json=cmd).status_code == 409
    assert httpx.get(server.url + "/api/queue").json()["queue"] == []
    assert httpx.post(server.url + "/api/control", headers=B).json() == {"held": True, "you": True}
    assert httpx.post(server.url + "/api/queue", headers=B, json=cmd).status_code == 200
    assert httpx.post(server.url + "/api/queue", headers=A, json=cmd).status_code == 409
    queue = httpx.get(server.url + "/api/queue").json()["queue"]
    assert [(q["design"], q["quantity"], q["done"]) for q in queue] == [("arc.svg", 3, 0)]
    # the design's pin angles compensate its 20 deg bends on the nominal machine
    f = httpx.get(server.url + "/api/files").json()["files"][0]
    made = simulate(f["pin_deg"])
    assert np.abs(np.abs(made.unloaded_bend_deg) - 20.0).max() < 0.05
    # OpenAPI documents the API
    schema = httpx.get(server.url + "/openapi.json").json()
    assert {"/api/connection", "/api/job", "/api/files", "/api/machine", "/api/events"} <= set(
        schema["paths"]
    )
    assert not math.isnan(made.unloaded_bend_deg[0])


def test_events_stream_sends_the_state_then_changes(server):
    with httpx.stream("GET", server.url + "/api/events", timeout=10) as r:
        assert r.headers["content-type"].startswith("text/event-stream")
        kinds = []
        for line in r.iter_lines():
            if line.startswith("event: "):
                kinds.append(line[7:])
            if len(kinds) >= 9:
                break
    assert set(kinds) == {
        "connection",
        "lens",
        "plane",
        "kit",
        "material",
        "files",
        "queue",
        "job",
        "inspect",
    }


def test_serial_loss_mid_part_then_continue_bends_each_bend_once(server):
    """The double's executed bends are the truth: after the loss and the continue, every bend
    stroke of the job ran exactly once and made its 20 deg."""
    hdr = {"X-Client-Id": "operator-b"}  # in control since the control test
    api = server.url + "/api"
    httpx.post(api + "/control", headers=hdr)
    assert (
        httpx.post(api + "/connection", headers=hdr, json={"command": "connect"}).status_code == 204
    )
    before = len(httpx.get(api + "/sim/bends").json()["bends"])
    r = httpx.post(api + "/connection", headers=hdr, json={"command": "lose", "after_lines": 24})
    assert r.status_code == 204
    assert httpx.post(api + "/job", headers=hdr, json={"command": "start"}).status_code == 204
    job = wait_for(lambda: _job_in(api, ("lost", "done", "failed")), 60, "the part to stop")
    assert job["state"] == "lost", job
    assert "continue part 1" in job["message"]
    assert httpx.post(api + "/job", headers=hdr, json={"command": "continue"}).status_code == 204
    job = wait_for(lambda: _job_in(api, ("lost", "done", "failed")), 60, "the part to finish")
    assert job["state"] == "done" and job["progress"]["bends_done"] == 4
    bends = httpx.get(api + "/sim/bends").json()["bends"][before:]
    lines = [b["line_number"] for b in bends]
    assert len(lines) == 4 and len(set(lines)) == 4  # no bend lost, none repeated
    assert np.abs(np.abs([b["unloaded_bend_deg"] for b in bends]) - 20.0).max() < 0.05


def _job_in(api, states):
    job = httpx.get(api + "/job").json()
    return job if job["state"] in states else None


def test_rhino_example_script_calls_the_same_endpoints(server):
    """docs/examples' stdlib-only Rhino 8 script, run as a plain script against the server."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[3] / "docs" / "examples" / "rhino8_cvmeasure_hops.py"
    proc = subprocess.run(
        [sys.executable, "-I", str(script), server.url], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    made = simulate(out["pins"])
    assert np.abs(np.abs(made.unloaded_bend_deg) - 20.0).max() < 0.05  # the script's 20 deg bends
    assert simulate([out["pin_for_angle"]]).unloaded_bend_deg[0] == pytest.approx(45.0, abs=0.05)
    assert out["gcode"].count("G90 G1 X") == 3


def test_ui_command_refuses_bad_options_in_one_line(tmp_path):
    """Bad input: exit 2 and one stderr line naming the option or file."""
    import subprocess
    import sys

    not_a_folder = tmp_path / "file.txt"
    not_a_folder.write_text("x")
    runs = {
        "--dir": ["--dir", str(not_a_folder)],
        "--effect": ["--effect", "backlash=0.5", "--dir", str(tmp_path / "ws")],
    }
    for name, extra in runs.items():
        proc = subprocess.run(
            [sys.executable, "-m", "cvmeasure", "ui", *extra], capture_output=True, text=True,
            timeout=60,
        )  # fmt: skip
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("cvmeasure ui: ")
        assert (str(not_a_folder) if name == "--dir" else name) in lines[0]
