"""Camera backends: libgphoto2's own virtual camera, a watched folder, the simulated camera."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest

from cvmeasure.driver.capture import (
    CaptureDevice,
    GPhoto2Capture,
    WatchedFolderCapture,
    open_capture,
    virtual_camera_env,
)
from cvmeasure.errors import DeviceError, DeviceTimeoutError


@pytest.fixture
def vcamera_folder(tmp_path):
    folder = tmp_path / "vcam" / "DCIM"
    folder.mkdir(parents=True)
    image = np.zeros((48, 64, 3), np.uint8)
    cv2.circle(image, (32, 24), 10, (0, 200, 255), -1)
    ok, jpeg = cv2.imencode(".jpg", image)
    assert ok
    (folder / "seed.jpg").write_bytes(jpeg.tobytes())
    return folder.parent, jpeg.tobytes(), image


def test_gphoto2_virtual_camera_capture_and_settings(tmp_path, vcamera_folder):
    root, jpeg, image = vcamera_folder
    with virtual_camera_env(root), GPhoto2Capture(tmp_path / "out") as cam:
        assert isinstance(cam, CaptureDevice)
        assert "D750" in cam.model
        first = cam.capture("loaded_001")
        second = cam.capture("unloaded_001")
        assert first.path == tmp_path / "out" / "loaded_001.jpg"
        assert first.camera_path != second.camera_path  # a new file on the card each time
        # the virtual camera serves a copy of the first JPEG: byte-identical download
        assert first.path.read_bytes() == jpeg
        decoded = cv2.imread(str(second.path))
        assert decoded.shape == image.shape
        settings = cam.settings()
        assert settings["shutterspeed"] == "0.0100s"
        cam.set_setting("shutterspeed", "0.0050s")
        assert cam.settings()["shutterspeed"] == "0.0050s"
        assert "f/5.6" in cam.choices("f-number")
        with pytest.raises(DeviceError, match="cannot be 'fast'"):
            cam.set_setting("shutterspeed", "fast")
        with pytest.raises(DeviceError, match="no setting 'warp'"):
            cam.set_setting("warp", "9")
    with pytest.raises(DeviceError, match="closed"):
        cam.capture("again")


def test_gphoto2_wrong_port_and_no_camera(tmp_path, vcamera_folder):
    root, _, _ = vcamera_folder
    with (
        virtual_camera_env(root),
        pytest.raises(DeviceError, match="no camera on gphoto2 port usb:009,009"),
    ):
        open_capture("gphoto2://usb:009,009", tmp_path)
    # outside the virtual environment this machine has no camera at all
    with pytest.raises(DeviceError, match="no camera found|could not open"):
        GPhoto2Capture(tmp_path)


def test_watched_folder_waits_for_a_complete_new_file(tmp_path):
    incoming = tmp_path / "incoming"
    incoming.mkdir()
    (incoming / "old.jpg").write_bytes(b"old")  # present before: never taken
    cam = open_capture(f"folder://{incoming}", tmp_path / "session", timeout_s=5.0, settle_s=0.1)
    assert isinstance(cam, WatchedFolderCapture)
    payload = bytes(range(256)) * 400

    def tether_writes_slowly():
        time.sleep(0.1)
        with open(incoming / "DSC_0001.JPG", "wb") as fh:
            for i in range(0, len(payload), 20_000):
                fh.write(payload[i : i + 20_000])
                fh.flush()
                time.sleep(0.03)

    writer = threading.Thread(target=tether_writes_slowly)
    writer.start()
    photo = cam.capture("loaded_001")
    writer.join()
    assert photo.path == tmp_path / "session" / "loaded_001.jpg"
    assert photo.path.read_bytes() == payload  # not a half-written copy
    with pytest.raises(DeviceTimeoutError, match="no new photo appeared"):
        WatchedFolderCapture(incoming, tmp_path / "s2", timeout_s=0.2).capture("x")


def test_trigger_and_bad_urls(tmp_path):
    incoming = tmp_path / "in"
    incoming.mkdir()
    calls = []

    def trigger():
        calls.append(1)
        (incoming / f"IMG_{len(calls)}.png").write_bytes(b"png")

    cam = WatchedFolderCapture(incoming, tmp_path / "out", settle_s=0.05, trigger=trigger)
    assert cam.capture("a").path.read_bytes() == b"png"
    assert cam.capture("b").path.name == "b.png" and len(calls) == 2
    with pytest.raises(DeviceError, match="does not exist"):
        WatchedFolderCapture(tmp_path / "missing", tmp_path)
    with pytest.raises(ValueError, match="unknown camera URL"):
        open_capture("ftp://x", tmp_path)


def test_simulated_camera_renders_the_machine_state(tmp_path):
    from cvmeasure.imageio import read_photo
    from cvmeasure.kit import default_kit
    from cvmeasure.markers.measure import measure_machine_photo
    from cvmeasure_datasets.simcapture import PhotoState, SimulatedCapture

    state = PhotoState(pin_angle_deg=-25.0, bend_angle_deg=-37.5)
    cam = SimulatedCapture(tmp_path, lambda: state, scale=0.2, seed=5)
    shot = cam.capture("loaded_001")
    assert shot.path == tmp_path / "loaded_001.jpg" and shot.camera is not None
    assert shot.truth["bend_angle_deg"] == pytest.approx(-37.5, abs=1e-9)
    measured = measure_machine_photo(read_photo(shot.path).bgr, default_kit(), camera=shot.camera)
    assert measured.bend_angle_deg == pytest.approx(-37.5, abs=0.05)
    assert measured.pin_angle_deg == pytest.approx(-25.0, abs=0.2)
