"""Cameras for calibration sessions: a real DSLR (gphoto2) and a watched folder.

Every backend implements :class:`CaptureDevice`: ``capture(name) -> CapturedPhoto``
takes one photo and stores it as a file ``<out_dir>/<name><ext>``. Backends:

:class:`GPhoto2Capture`
    a camera on USB through libgphoto2 (python-gphoto2): capture, download,
    read and change settings. Tested with libgphoto2's own virtual camera
    (:func:`virtual_camera_env`), which serves the JPEGs of a folder.
:class:`WatchedFolderCapture`
    tethering software (or a person) writes the photos into a folder; capture
    waits for the next new, completely written file.
:class:`cvmeasure_datasets.simcapture.SimulatedCapture` (the photo lab, not this
package) renders a simulated machine's state and implements the same protocol.

:func:`open_capture` picks one by URL: ``gphoto2://`` (first camera found) or
``gphoto2://usb:001,004`` (a port), ``folder:///path/to/incoming``.
Failures raise :class:`~cvmeasure.errors.DeviceError` (no camera, capture
failed) or :class:`~cvmeasure.errors.DeviceTimeoutError` (no photo in time).
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable
from urllib.parse import unquote, urlparse

from cvmeasure.errors import DeviceError, DeviceTimeoutError
from cvmeasure.extras import require
from cvmeasure.fileio import atomic_write_bytes

__all__ = [
    "CapturedPhoto",
    "CaptureDevice",
    "GPhoto2Capture",
    "WatchedFolderCapture",
    "open_capture",
    "virtual_camera_env",
]

log = logging.getLogger(__name__)

#: File suffixes a watched folder accepts as photos (lower case).
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".nef", ".dng", ".cr2", ".arw")


@dataclass(frozen=True)
class CapturedPhoto:
    """One photo a camera took.

    Attributes
    ----------
    path : Path
        Where the photo file is stored.
    truth : dict or None
        Ground truth of a simulated photo (the renderer's truth dict), else None.
    camera_path : str or None
        Where the photo was on the camera (gphoto2: ``folder/name``).
    camera : CameraModel or None
        The lens model of the photo when the backend knows it (simulation).
    """

    path: Path
    truth: Mapping[str, Any] | None = None
    camera_path: str | None = None
    camera: Any = None

    def to_dict(self) -> dict[str, Any]:
        return {"path": str(self.path), "camera_path": self.camera_path}


@runtime_checkable
class CaptureDevice(Protocol):
    """What a calibration session needs from a camera."""

    def capture(self, name: str) -> CapturedPhoto:
        """Take one photo and store it as ``<out_dir>/<name><ext>``."""
        ...

    def close(self) -> None:
        """Release the device (idempotent)."""
        ...


# ----------------------------------------------------------------------------- gphoto2


@contextlib.contextmanager
def virtual_camera_env(folder: str | os.PathLike[str]) -> Iterator[Path]:
    """Point libgphoto2 at its virtual camera serving the files of ``folder``.

    Sets ``VCAMERADIR`` and switches ``IOLIBS`` to the wheel's ``vusb`` iolib
    (what python-gphoto2's own tests do) for the duration of the block; new
    :class:`GPhoto2Capture` objects then find a "Nikon DSC D750" whose captures
    are copies of the first JPEG in ``folder``. The environment is restored on exit.
    """
    require("gphoto2", "camera", "gphoto2 virtual camera")  # sets IOLIBS/CAMLIBS on import

    folder = Path(folder)
    saved = {k: os.environ.get(k) for k in ("VCAMERADIR", "IOLIBS")}
    iolibs = os.environ.get("IOLIBS", "")
    vusb = Path(iolibs).parent / "vusb" if iolibs else None
    if vusb is None or not vusb.is_dir():
        raise DeviceError("this libgphoto2 build has no virtual camera (vusb iolib missing)")
    os.environ["VCAMERADIR"] = str(folder)
    os.environ["IOLIBS"] = str(vusb)
    try:
        yield folder
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


class GPhoto2Capture:
    """A camera driven through libgphoto2: capture, download, settings.

    Parameters
    ----------
    out_dir : path
        Where downloaded photos are stored.
    port : str, optional
        A libgphoto2 port such as ``usb:001,004``; default: the first camera
        that autodetect finds.
    settings : mapping, optional
        Config values to set after opening, e.g. ``{"shutterspeed": "1/125",
        "f-number": "f/8"}`` (names as ``gphoto2 --list-config`` shows them).
    delete_after_download : bool
        Delete each photo from the camera once downloaded.

    Raises
    ------
    DeviceError
        No camera found, or libgphoto2 refused to open it.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        *,
        port: str | None = None,
        settings: Mapping[str, str] | None = None,
        delete_after_download: bool = False,
    ) -> None:
        gp = require("gphoto2", "camera", f"gphoto2://{port or ''}")

        self._gp = gp
        self.out_dir = Path(out_dir)
        self.delete_after_download = delete_after_download
        self._camera = None
        try:
            cameras = gp.Camera.autodetect()
            found = [(cameras.get_name(i), cameras.get_value(i)) for i in range(cameras.count())]
            if not found:
                raise DeviceError("no camera found by gphoto2 (is it on, in PTP mode, unmounted?)")
            if port is not None and port not in [p for _, p in found]:
                ports = ", ".join(f"{m} on {p}" for m, p in found)
                raise DeviceError(f"no camera on gphoto2 port {port} (found: {ports})")
            model, port = next((m, p) for m, p in found if port in (None, p))
            camera = gp.Camera()
            abilities = gp.CameraAbilitiesList()
            abilities.load()
            camera.set_abilities(abilities[abilities.lookup_model(model)])
            ports = gp.PortInfoList()
            ports.load()
            camera.set_port_info(ports[ports.lookup_path(port)])
            camera.init()
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"gphoto2 could not open the camera: {exc}") from None
        self._camera = camera
        self.model, self.port = model, port
        log.info("opened %s on %s", model, port)
        for name, value in (settings or {}).items():
            self.set_setting(name, value)

    def _require(self) -> Any:
        if self._camera is None:
            raise DeviceError("camera is closed")
        return self._camera

    def capture(self, name: str) -> CapturedPhoto:
        """Take a photo, download it to ``<out_dir>/<name><ext>`` (ext from the camera's name)."""
        gp = self._gp
        camera = self._require()
        try:
            where = camera.capture(gp.GP_CAPTURE_IMAGE)
            camera_file = camera.file_get(where.folder, where.name, gp.GP_FILE_TYPE_NORMAL)
            # keep camera_file alive while its buffer is read (libgphoto2 owns the memory)
            data = bytes(memoryview(camera_file.get_data_and_size()))
            if self.delete_after_download:
                camera.file_delete(where.folder, where.name)
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"gphoto2 capture failed: {exc}") from None
        suffix = Path(where.name).suffix.lower() or ".jpg"
        path = atomic_write_bytes(self.out_dir / f"{name}{suffix}", data)
        return CapturedPhoto(path=path, camera_path=f"{where.folder}/{where.name}")

    def settings(self) -> dict[str, Any]:
        """Every readable config value by name (text, menus, numbers, toggles)."""
        gp = self._gp
        try:
            root = self._require().get_config()
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"gphoto2 could not read the settings: {exc}") from None
        values: dict[str, Any] = {}

        def walk(widget: Any) -> None:
            for i in range(widget.count_children()):
                child = widget.get_child(i)
                if child.get_type() in (gp.GP_WIDGET_SECTION, gp.GP_WIDGET_WINDOW):
                    walk(child)
                elif child.get_type() != gp.GP_WIDGET_BUTTON:
                    with contextlib.suppress(gp.GPhoto2Error):
                        values[child.get_name()] = child.get_value()

        walk(root)
        return values

    def choices(self, name: str) -> list[str]:
        """The allowed values of a menu/radio setting."""
        gp = self._gp
        try:
            widget = self._require().get_single_config(name)
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"camera has no setting {name!r}: {exc}") from None
        return [widget.get_choice(i) for i in range(widget.count_choices())]

    def set_setting(self, name: str, value: Any) -> None:
        """Set one config value; DeviceError names the setting and the allowed values."""
        gp = self._gp
        camera = self._require()
        try:
            widget = camera.get_single_config(name)
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"camera has no setting {name!r}: {exc}") from None
        if widget.get_type() in (gp.GP_WIDGET_MENU, gp.GP_WIDGET_RADIO):
            allowed = [widget.get_choice(i) for i in range(widget.count_choices())]
            if str(value) not in allowed:
                raise DeviceError(
                    f"camera setting {name!r} cannot be {value!r}; allowed: {', '.join(allowed)}"
                )
            value = str(value)
        try:
            widget.set_value(value)
            camera.set_single_config(name, widget)
        except gp.GPhoto2Error as exc:
            raise DeviceError(f"camera refused {name}={value!r}: {exc}") from None

    def close(self) -> None:
        if self._camera is not None:
            with contextlib.suppress(self._gp.GPhoto2Error):
                self._camera.exit()
            self._camera = None

    def __enter__(self) -> GPhoto2Capture:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ----------------------------------------------------------------------------- watched folder


class WatchedFolderCapture:
    """Photos written into a folder by tethering software, taken one at a time.

    ``capture(name)`` optionally calls ``trigger()`` (e.g. something that
    presses the shutter), then waits for a photo file that was not in the
    folder before and whose size has stopped changing, and copies it to
    ``<out_dir>/<name><ext>``.

    Parameters
    ----------
    folder : path
        The folder the tethering software writes into (not searched recursively).
    out_dir : path
        Where the session keeps its copies.
    timeout_s : float
        How long to wait for a new photo before :class:`DeviceTimeoutError`.
    settle_s : float
        A file counts as complete once its size has not changed for this long.
    trigger : callable, optional
        Called at the start of every capture.
    """

    def __init__(
        self,
        folder: str | os.PathLike[str],
        out_dir: str | os.PathLike[str],
        *,
        timeout_s: float = 60.0,
        settle_s: float = 0.2,
        poll_s: float = 0.05,
        trigger: Callable[[], None] | None = None,
    ) -> None:
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise DeviceError(f"watched folder {self.folder} does not exist")
        self.out_dir = Path(out_dir)
        self.timeout_s, self.settle_s, self.poll_s = timeout_s, settle_s, poll_s
        self.trigger = trigger
        self._seen = set(self._photos())

    def _photos(self) -> list[str]:
        try:
            names = os.listdir(self.folder)
        except OSError as exc:
            raise DeviceError(f"cannot list watched folder {self.folder}: {exc}") from None
        return sorted(
            n for n in names if Path(n).suffix.lower() in PHOTO_SUFFIXES and not n.startswith(".")
        )

    def capture(self, name: str) -> CapturedPhoto:
        """Wait for the next new photo in the folder and copy it to ``<out_dir>/<name><ext>``."""
        if self.trigger is not None:
            self.trigger()
        deadline = time.monotonic() + self.timeout_s
        sizes: dict[str, tuple[int, float]] = {}
        while True:
            now = time.monotonic()
            for fname in self._photos():
                if fname in self._seen:
                    continue
                try:
                    size = (self.folder / fname).stat().st_size
                except FileNotFoundError:
                    continue
                last = sizes.get(fname)
                if last is None or last[0] != size:
                    sizes[fname] = (size, now)
                elif size > 0 and now - last[1] >= self.settle_s:
                    self._seen.add(fname)
                    src = self.folder / fname
                    dest = atomic_write_bytes(
                        self.out_dir / f"{name}{src.suffix.lower()}", src.read_bytes()
                    )
                    return CapturedPhoto(path=dest, camera_path=str(src))
            if now >= deadline:
                raise DeviceTimeoutError(
                    f"no new photo appeared in {self.folder} within {self.timeout_s:g} s"
                )
            time.sleep(self.poll_s)

    def close(self) -> None:
        pass


# ----------------------------------------------------------------------------- by URL


def open_capture(url: str, out_dir: str | os.PathLike[str], **options: Any) -> CaptureDevice:
    """Open a camera by URL.

    ``gphoto2://`` (first camera), ``gphoto2://usb:001,004`` (that port) or
    ``folder:///path`` (a watched folder). The simulated camera needs a
    machine to render, so sessions build it from the photo lab (``--simulate``).

    Raises
    ------
    ValueError
        Unknown URL scheme.
    DeviceError
        The camera cannot be opened.
    """
    parsed = urlparse(url)
    if parsed.scheme == "gphoto2":
        port = unquote(url[len("gphoto2://") :]) or None
        return GPhoto2Capture(out_dir, port=port, **options)
    if parsed.scheme == "folder":
        return WatchedFolderCapture(unquote(parsed.path), out_dir, **options)
    raise ValueError(f"unknown camera URL {url!r}; use gphoto2://[port] or folder:///path")
