"""cvmeasure from a Rhino 8 Grasshopper script component (CPython 3.9, standard library only).

Calls the same Hops endpoints as a Hops component would, on a running `cvmeasure ui`
(default http://127.0.0.1:8080). Nothing to install in Rhino: no OpenCV, no rhino3dm.

In a Grasshopper "Script" component (Python 3) add the inputs
    points   (list access, Point3d): the polyline's vertices in mm, in bending order
    angle    (item access, float):   a wanted final bend angle, deg (optional)
    server   (item access, str):     the app's address (optional)
and the outputs  pins, bends, gcode, pin_for_angle, springback, part, deviations, verdict, error.

Outside Rhino it runs as a plain script:  python rhino8_cvmeasure_hops.py [server]
"""

import json
import sys
import urllib.error
import urllib.request

DEFAULT_SERVER = "http://127.0.0.1:8080"


def solve(server, component, inputs):
    """POST /hops/solve with Hops's tree form; return {output name: [values]}.

    ``inputs``: {input name: [(type name, JSON-able value), ...]}.
    """
    body = {
        "pointer": component,
        "values": [
            {
                "ParamName": name,
                "InnerTree": {"0": [{"type": t, "data": json.dumps(v)} for t, v in items]},
            }
            for name, items in inputs.items()
        ],
    }
    request = urllib.request.Request(
        server.rstrip("/") + "/hops/solve",
        data=json.dumps(body).encode("utf-8"),
        headers={"Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            answer = json.loads(response.read().decode("utf-8"))
    except urllib.error.HTTPError as exc:
        answer = json.loads(exc.read().decode("utf-8") or "{}")
        raise RuntimeError("; ".join(answer.get("errors", [str(exc)]))) from None
    return {
        v["ParamName"]: [json.loads(item["data"]) for item in v["InnerTree"]["0"]]
        for v in answer["values"]
    }


def point_items(points):
    """Rhino Point3d objects (or (x, y) pairs) as Hops point items."""
    items = []
    for p in points:
        x, y = (p.X, p.Y) if hasattr(p, "X") else (p[0], p[1])
        items.append(("Rhino.Geometry.Point3d", {"X": float(x), "Y": float(y), "Z": 0.0}))
    return items


def run(points, angle=None, server=None):
    """Everything the component outputs, as a dict (errors in "error")."""
    server = server or DEFAULT_SERVER
    out = {"error": ""}
    try:
        if points:
            r = solve(server, "pin_angles", {"Points": point_items(points)})
            out.update(pins=r["PinAngles"], bends=r["Bends"], gcode=r["GCode"][0])
        if angle is not None:
            r = solve(server, "springback", {"Angle": [("System.Double", float(angle))]})
            out.update(pin_for_angle=r["Pin"][0], springback=r["Springback"][0])
        r = solve(server, "last_part", {})
        out.update(part=r["Points"], deviations=r["Deviations"], verdict=r["Verdict"][0])
    except (RuntimeError, urllib.error.URLError, OSError) as exc:
        out["error"] = str(exc)
    return out


def _rhino_points(xy):
    """Point3d in Rhino, tuples elsewhere."""
    try:
        import Rhino.Geometry as rg  # noqa: F401 (only inside Rhino)
    except ImportError:
        return [tuple(p) for p in xy]
    return [rg.Point3d(p["X"], p["Y"], 0.0) for p in xy]


if __name__ == "__main__" and "points" not in globals():
    # a plain script: a polyline of 40 mm chords with three 20 deg bends, 45 deg, the last part
    pts = [(0, 0), (40, 0), (77.588, 13.681), (108.229, 39.392), (128.229, 74.033)]
    result = run(pts, 45.0, *sys.argv[1:2])
    print(json.dumps(result, indent=2))
elif "points" in globals():
    # inside a Grasshopper script component: inputs are globals, outputs are assigned
    _r = run(points, globals().get("angle"), globals().get("server"))  # noqa: F821
    pins, bends, gcode = _r.get("pins"), _r.get("bends"), _r.get("gcode")
    pin_for_angle, springback = _r.get("pin_for_angle"), _r.get("springback")
    part = _rhino_points(_r.get("part") or [])
    deviations, verdict, error = _r.get("deviations"), _r.get("verdict"), _r.get("error")
