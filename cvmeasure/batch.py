"""Batch measurement: every photo of a folder or glob, on all cores or a Dask cluster.

A batch measures each photo with the function its *kind* names in
:data:`MEASURERS` (``machine``: the bender's marker photo, ``part``: a finished
part on a ChArUco board, ``disc``: the largest disc's centre and radius, a
simple real measurement used to test and benchmark the machinery), and appends
one JSON object per photo to the results file as soon as it is measured (fsync
after each line). Photos are keyed by resolved path, size and modification
time; a batch run again on the same results file measures only the photos not
yet in it, so an interrupted batch resumes where it stopped and never measures
a photo twice.

Workers are processes started with the **spawn** method (rawpy/OpenMP
deadlock in forked workers), each limited to one thread, or the workers of a
Dask distributed cluster (``scheduler="tcp://host:port"``).

A measurement function has the signature ``measure(photo: Photo, context:
MeasureContext) -> Mapping[str, Any]`` and raises
:class:`~cvmeasure.errors.InputError` when the photo cannot be measured; the
batch records that as ``"ok": false`` with the message and goes on.
"""

from __future__ import annotations

import contextlib
import glob
import importlib
import importlib.util
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cvmeasure import __version__
from cvmeasure.errors import CvmeasureError, InputError
from cvmeasure.extras import require
from cvmeasure.fileio import append_jsonl, atomic_write_text, read_jsonl, repair_jsonl_tail

if TYPE_CHECKING:  # numpy, the photo reader and the process pool load when used, not on import
    from concurrent.futures import Future

    from cvmeasure.board import BoardSpec
    from cvmeasure.camera_model import CameraModel
    from cvmeasure.contracts import PlaneModel
    from cvmeasure.imageio import Photo
    from cvmeasure.kit import MarkerKit

__all__ = [
    "MEASURERS",
    "KINDS",
    "MeasureContext",
    "BatchSummary",
    "register_measurer",
    "resolve_measurer",
    "list_photos",
    "photo_key",
    "done_keys",
    "detect_kind",
    "measure_disc",
    "measure_machine",
    "measure_part",
    "measure_one",
    "run_batch",
    "START_METHODS",
    "FORKSERVER_PRELOAD",
]

#: Photo kind -> "module:function" of its measurement (resolved lazily, also in workers).
MEASURERS: dict[str, str] = {
    "machine": "cvmeasure.batch:measure_machine",
    "part": "cvmeasure.batch:measure_part",
    "disc": "cvmeasure.batch:measure_disc",
}

#: Kinds a user can ask for: the registry's plus ``auto`` (detect per photo).
KINDS: tuple[str, ...] = ("auto", "machine", "part", "disc")

_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


@dataclass(frozen=True)
class MeasureContext:
    """What every measurement of a batch shares: the files it was given, and options.

    Only paths travel to the workers (small, picklable); each worker loads the
    camera, kit and board once (cached). ``measurers`` is the kind registry the
    workers use (:func:`run_batch` fills it from :data:`MEASURERS`, so kinds
    registered in the parent work in spawned and remote workers too).
    """

    camera_path: str | None = None
    kit_path: str | None = None
    board_path: str | None = None
    plane_path: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    measurers: tuple[tuple[str, str], ...] = ()

    def camera(self) -> CameraModel | None:
        """The camera, or None when no camera was given."""
        return None if self.camera_path is None else _load_camera(self.camera_path)

    def kit(self) -> MarkerKit:
        """The kit given, or the built-in kit."""
        return _load_kit(self.kit_path)

    def board(self) -> BoardSpec | None:
        """The board spec, or None when no board was given."""
        return None if self.board_path is None else _load_board(self.board_path)

    def plane(self) -> PlaneModel | None:
        """The measurement plane (with its camera), or None when no plane was given."""
        if self.plane_path is None:
            return None
        return _load_plane(self.plane_path, self.camera_path)

    def option(self, name: str, default: Any = None) -> Any:
        return dict(self.options).get(name, default)

    def validate(self) -> None:
        """Load every file given once, so a wrong file fails before the batch starts."""
        self.camera()
        self.kit()
        self.board()
        self.plane()


@lru_cache(maxsize=8)
def _load_camera(path: str) -> CameraModel:
    from cvmeasure.camera_model import load_camera

    return load_camera(path)


@lru_cache(maxsize=8)
def _load_kit(path: str | None) -> MarkerKit:
    from cvmeasure.kit import default_kit, load_kit

    return default_kit() if path is None else load_kit(path)


@lru_cache(maxsize=8)
def _load_plane(path: str, camera_path: str | None) -> PlaneModel:
    from cvmeasure.contracts import PlaneModel

    camera = None if camera_path is None else _load_camera(camera_path)
    return PlaneModel.load(path, camera=camera)


@lru_cache(maxsize=8)
def _load_board(path: str) -> BoardSpec:
    from cvmeasure.board import load_board

    return load_board(path)


@dataclass(frozen=True)
class BatchSummary:
    """What a batch run did. Rates are photos per second of wall time.

    ``steady_photos_per_s`` leaves out the start-up: it counts the photos after
    each worker's first one, over the time after the last of those first ones.
    """

    output: str
    photos_total: int
    already_done: int
    measured: int
    failed: int
    seconds: float
    workers: int
    backend: str
    failures: tuple[tuple[str, str], ...] = field(default=())
    steady_photos_per_s: float | None = None

    @property
    def photos_per_s(self) -> float:
        """Photos per second of the whole run, worker start-up included."""
        return self.measured / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "output": self.output,
            "photos_total": self.photos_total,
            "already_done": self.already_done,
            "measured": self.measured,
            "failed": self.failed,
            "seconds": round(self.seconds, 3),
            "photos_per_s": round(self.photos_per_s, 4),
            "steady_photos_per_s": None
            if self.steady_photos_per_s is None
            else round(self.steady_photos_per_s, 4),
            "workers": self.workers,
            "backend": self.backend,
            "failures": [{"photo": p, "error": e} for p, e in self.failures],
        }


# --------------------------------------------------------------------------- registry


def register_measurer(kind: str, target: str) -> None:
    """Register (or replace) the measurement of a kind: ``target`` is ``"module:function"``.

    The module must be importable in the workers (a spawned process, or a Dask
    worker), so pass a dotted path rather than a function object.
    """
    if ":" not in target:
        raise ValueError(f"measurer target must be 'module:function', got {target!r}")
    MEASURERS[kind] = target


def resolve_measurer(
    kind: str, registry: Mapping[str, str] | None = None
) -> Callable[[Photo, MeasureContext], Mapping[str, Any]]:
    """The measurement function of ``kind`` (in ``registry``, default :data:`MEASURERS`).

    ValueError lists the valid kinds.
    """
    registry = MEASURERS if registry is None else registry
    try:
        target = registry[kind]
    except KeyError:
        raise ValueError(
            f"unknown photo kind {kind!r}; valid: {', '.join(sorted(registry))}"
        ) from None
    module_name, _, func_name = target.partition(":")
    return getattr(importlib.import_module(module_name), func_name)


# --------------------------------------------------------------------------- photos and keys


def list_photos(spec: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The photo files a folder, a glob pattern, a file, or a list of those names, sorted.

    Folders are searched non-recursively for files with a photo suffix
    (:data:`~cvmeasure.imageio.PHOTO_SUFFIXES`); a glob may use ``**``. Raises
    InputError naming the spec when nothing matches.
    """
    from cvmeasure.imageio import PHOTO_SUFFIXES

    if isinstance(spec, (str, os.PathLike)):
        specs = [spec]
    else:
        specs = list(spec)
    found: dict[str, Path] = {}
    for item in specs:
        text = os.fspath(item)
        path = Path(text)
        if path.is_dir():
            matches = [p for p in path.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES]
        elif path.is_file():
            matches = [path]
        elif glob.has_magic(text):
            matches = [
                Path(p)
                for p in glob.glob(text, recursive=True)
                if Path(p).is_file() and Path(p).suffix.lower() in PHOTO_SUFFIXES
            ]
        else:
            raise InputError(text, "no such photo, folder or pattern")
        if not matches:
            raise InputError(text, "no photos found (JPEG, PNG, TIFF or camera RAW)")
        for p in matches:
            found.setdefault(str(p.resolve()), p)
    return sorted(found.values(), key=lambda p: str(p))


def photo_key(path: str | os.PathLike[str]) -> str:
    """Identity of a photo file for resuming: resolved path, size in bytes, mtime in ns."""
    p = Path(path).resolve()
    st = p.stat()
    return f"{p}|{st.st_size}|{st.st_mtime_ns}"


def done_keys(output: str | os.PathLike[str]) -> set[str]:
    """Keys of the photos measured successfully in a results file (repairs a cut last line).

    A photo whose record says ``"ok": false`` is not done: a re-run retries it.
    """
    path = Path(output)
    if not path.exists():
        return set()
    repair_jsonl_tail(path)
    return {
        r["photo_key"]
        for r in read_jsonl(path)
        if isinstance(r, dict) and "photo_key" in r and r.get("ok", True)
    }


def drop_failed_records(output: str | os.PathLike[str], keys: set[str]) -> int:
    """Rewrite ``output`` (atomically) without the failed records of ``keys``; how many went.

    A key's file is its resolved path (the part before the size and time): a photo
    fixed since (a new size or time) drops its old failed record too. Before a re-run
    retries failed photos, so that the results file keeps one record per photo: its latest.
    """
    files = {k.rsplit("|", 2)[0] for k in keys}
    path = Path(output)
    if not path.exists() or not keys:
        return 0
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    kept, dropped = [], 0
    for line in lines:
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            kept.append(line)
            continue
        key = record.get("photo_key") if isinstance(record, dict) else None
        if isinstance(key, str) and key.rsplit("|", 2)[0] in files and not record.get("ok"):
            dropped += 1
        else:
            kept.append(line)
    if dropped:
        atomic_write_text(path, "".join(kept))
    return dropped


# --------------------------------------------------------------------------- measurements


def detect_kind(photo: Photo, context: MeasureContext | None = None) -> str:
    """``part`` when the photo shows a ChArUco/ArUco board (4+ markers), else ``machine``.

    Detection runs on a copy at most 1600 px wide, with the dictionary of the
    batch's board when one was given (DICT_5X5_100 otherwise).
    """
    import cv2

    gray = photo.gray8()
    scale = min(1.0, 1600.0 / max(gray.shape))
    if scale < 1.0:
        gray = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    board = context.board() if context is not None else None
    name = getattr(board, "dictionary", None) or "DICT_5X5_100"
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    detector = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
    _corners, ids, _rejected = detector.detectMarkers(gray)
    return "part" if ids is not None and len(ids) >= 4 else "machine"


def measure_disc(photo: Photo, context: MeasureContext) -> dict[str, Any]:
    """Centre and radius of the largest disc (dark on light or light on dark), in px.

    Otsu threshold of the blurred grey image; the foreground is the polarity the
    image border does not have; the largest connected component gives the
    centroid (``x_px``, ``y_px``, image frame) and the equal-area radius
    ``r_px``. A real, simple measurement for testing and benchmarking batches.
    """
    import cv2
    import numpy as np

    gray = cv2.GaussianBlur(photo.gray8(), (5, 5), 0)
    _t, mask = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    border = np.concatenate([mask[0], mask[-1], mask[:, 0], mask[:, -1]])
    if np.mean(border > 0) > 0.5:
        mask = cv2.bitwise_not(mask)
    count, _labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count < 2:
        raise InputError(photo.path, "no disc found (uniform image)")
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    area = float(stats[best, cv2.CC_STAT_AREA])
    w, h = photo.size_px
    return {
        "x_px": float(centroids[best, 0]),
        "y_px": float(centroids[best, 1]),
        "r_px": float(np.sqrt(area / np.pi)),
        "image_size_px": [w, h],
    }


def _as_record(result: Any) -> dict[str, Any]:
    from cvmeasure.fileio import to_jsonable

    data = to_jsonable(result)
    if not isinstance(data, dict):
        raise TypeError(f"a measurement must return a mapping, got {type(result).__name__}")
    return data


def measure_machine(photo: Photo, context: MeasureContext) -> dict[str, Any]:
    """A bender photo through :func:`cvmeasure.markers.measure.measure_photo_file`."""
    from cvmeasure.markers.measure import measure_photo_file

    result = measure_photo_file(
        photo, context.kit(), camera=context.camera(), plane=context.plane()
    )
    return result.to_dict()


def measure_part(photo: Photo, context: MeasureContext) -> dict[str, Any]:
    """A part photo through :func:`cvmeasure.part.measure.measure_part` (needs board and camera)."""
    from cvmeasure.part.measure import measure_part as measure_part_photo
    from cvmeasure.part.options import PartOptions

    board, camera = context.board(), context.camera()
    if board is None or camera is None:
        raise InputError(photo.path, "a part photo needs the board (--board) and camera (--camera)")
    options = PartOptions(divisions=context.option("divisions"))
    result = measure_part_photo(photo.bgr, board, camera, options=options, source=photo.path)
    return _as_record(result.to_dict())


def measure_one(path: str, key: str, kind: str, context: MeasureContext) -> dict[str, Any]:
    """Measure one photo; returns its record (``ok`` false with ``error`` on failure).

    Runs in the workers. Bad input (unreadable photo, markers not found) and
    other errors are recorded, not raised, so one photo never stops a batch
    (other exceptions are recorded with their type name).
    """
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    record: dict[str, Any] = {
        "photo": path,
        "file_name": Path(path).name,
        "photo_key": key,
        "kind": kind,
        "ok": False,
        "error": None,
    }
    try:
        from cvmeasure.imageio import read_photo

        photo = read_photo(path)
        if kind == "auto":
            kind = detect_kind(photo, context)
            record["kind"] = kind
        result = resolve_measurer(kind, dict(context.measurers) or None)(photo, context)
        record.update(_as_record(result))
        record["ok"] = True
    except InputError as exc:
        record["error"] = str(exc)
    except CvmeasureError as exc:
        record["error"] = f"{path}: {exc}"
    except Exception as exc:  # noqa: BLE001 - one photo must not stop a batch; recorded
        if type(exc).__module__.startswith("cv2"):  # OpenCV refused the image (too small...)
            text = str(exc).split("error: ", 1)[-1]
            record["error"] = f"{path}: OpenCV cannot process it ({' '.join(text.split())})"
        else:
            text = " ".join(str(exc).split())
            record["error"] = f"{path}: internal error {type(exc).__name__}: {text}"
    record["ok"] = record["error"] is None
    record["seconds"] = round(time.perf_counter() - t0, 4)
    record["cpu_s"] = round(time.process_time() - cpu0, 4)
    record["worker_pid"] = os.getpid()
    record["cvmeasure"] = __version__
    return record


# --------------------------------------------------------------------------- running


def _init_worker() -> None:
    import cv2

    cv2.setNumThreads(1)


#: How often a pool worker checks that the batch that started it is alive (s).
PARENT_POLL_S = 0.2


def _pool_worker_init(batch_pid: int | None = None) -> None:
    """A pool worker: one OpenCV thread, and it exits as soon as its parent is gone.

    The parent is the batch (spawn: ``batch_pid``) or the fork server, which ends
    with the batch. A batch killed with SIGKILL cannot stop its workers; without
    this they finish their photo and idle until the pool's pipes time out (30 s
    seen). A spawned worker still importing when the batch dies is already
    re-parented when this runs: it is compared with ``batch_pid``, not with the
    parent it finds, so it exits too.
    """
    import threading

    _init_worker()
    parent_pid = os.getppid() if batch_pid is None else batch_pid

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


@contextlib.contextmanager
def _single_threaded_env() -> Iterator[None]:
    """Spawned workers inherit the environment: one BLAS/OpenMP thread each."""
    saved = {k: os.environ.get(k) for k in _THREAD_ENV}
    os.environ.update({k: "1" for k in _THREAD_ENV})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_serial(
    jobs: Sequence[tuple[str, str]], kind: str, context: MeasureContext
) -> Iterator[dict[str, Any]]:
    _init_worker()
    for path, key in jobs:
        yield measure_one(path, key, kind, context)


#: Modules a forkserver imports once, before forking the workers from it.
FORKSERVER_PRELOAD: tuple[str, ...] = (
    "cvmeasure.batch",
    "cvmeasure.imageio",
    "cvmeasure.kit",
    "cvmeasure.markers",
    "cv2",
    "rawpy",
    "colour",
)

#: Start methods of the worker processes (never plain ``fork``: rawpy/OpenMP deadlock).
START_METHODS: tuple[str, ...] = ("spawn", "forkserver")


def _pool_context(start_method: str) -> Any:
    """The multiprocessing context; ``forkserver`` preloads :data:`FORKSERVER_PRELOAD`.

    The fork server is a fresh, single-threaded process (started inside the
    one-thread environment) that imports the heavy modules once and forks each
    worker from itself, before any of them has run OpenMP code: the workers skip
    the ~1.3 s CPU of imports each spawned worker pays, without the deadlock of
    forking a process whose OpenMP threads exist.
    """
    import multiprocessing

    if start_method not in START_METHODS:
        raise ValueError(
            f"unknown start method {start_method!r}; valid: {', '.join(START_METHODS)}"
        )
    ctx = multiprocessing.get_context(start_method)
    if start_method == "forkserver":
        preload = []
        for name in FORKSERVER_PRELOAD:
            with contextlib.suppress(ImportError):
                importlib.util.find_spec(name)
                preload.append(name)
        ctx.set_forkserver_preload(preload)
    return ctx


def _run_processes(
    jobs: Sequence[tuple[str, str]],
    kind: str,
    context: MeasureContext,
    workers: int,
    start_method: str = "spawn",
) -> Iterator[dict[str, Any]]:
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = _pool_context(start_method)
    window = 4 * workers
    todo = iter(jobs)
    pending: set[Future[dict[str, Any]]] = set()
    with _single_threaded_env():
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=ctx,
            initializer=_pool_worker_init,
            initargs=(os.getpid() if start_method == "spawn" else None,),
        )
        # the workers start on these first submits, inheriting the one-thread environment
        for path, key in todo:
            pending.add(pool.submit(measure_one, path, key, kind, context))
            if len(pending) >= window:
                break
    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield fut.result()
            for path, key in todo:
                pending.add(pool.submit(measure_one, path, key, kind, context))
                if len(pending) >= window:
                    break
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _dask_client(scheduler: str) -> Any:
    Client = require("distributed", "cluster", "--scheduler").Client
    try:
        return Client(scheduler, timeout="20s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise InputError(scheduler, f"cannot reach the Dask scheduler: {exc}") from None


def _dask_workers(client: Any) -> int:
    workers = client.scheduler_info().get("workers", {})
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))


def _run_dask(
    jobs: Sequence[tuple[str, str]], kind: str, context: MeasureContext, client: Any
) -> Iterator[dict[str, Any]]:
    from distributed import as_completed

    futures = [
        client.submit(measure_one, path, key, kind, context, pure=False) for path, key in jobs
    ]
    try:
        for fut in as_completed(futures, loop=client.loop):
            yield fut.result()
            fut.release()
    finally:
        client.cancel([f for f in futures if not f.done()])


def default_workers() -> int:
    """All the cores this process may use."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _pending_jobs(paths: list[Any], output: Path) -> list[tuple[str, str]]:
    """(path, key) of each photo not yet measured in ``output``, each photo once."""
    done = done_keys(output)
    jobs: list[tuple[str, str]] = []
    seen: set[str] = set()
    for p in paths:
        try:
            key = photo_key(p)
        except OSError as exc:
            raise InputError(p, f"cannot read photo: {exc.strerror or exc}") from None
        if key in done or key in seen:
            continue
        seen.add(key)
        jobs.append((os.fspath(p), key))
    return jobs


def _append_records(
    records: Iterable[dict[str, Any]],
    output: Path,
    on_record: Callable[[dict[str, Any]], None] | None,
) -> tuple[list[tuple[str, str]], list[float]]:
    """Append each record as it arrives; return the failures and the arrival times (s)."""
    failures: list[tuple[str, str]] = []
    times: list[float] = []
    for record in records:
        append_jsonl(output, record)
        times.append(time.perf_counter())
        if not record["ok"]:
            failures.append((record["photo"], record["error"]))
        if on_record:
            on_record(record)
    return failures, times


def run_batch(
    photos: Iterable[str | os.PathLike[str]],
    output: str | os.PathLike[str],
    *,
    kind: str = "auto",
    context: MeasureContext | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    start_method: str = "spawn",
    on_record: Callable[[dict[str, Any]], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> BatchSummary:
    """Measure every photo not yet in ``output``, appending one record per photo.

    Parameters
    ----------
    photos : iterable of path-like
        The photo files (see :func:`list_photos`).
    output : path-like
        The JSON Lines results file; created, or resumed when it exists.
    kind : str
        ``auto`` (detect per photo) or a key of :data:`MEASURERS`.
    context : MeasureContext, optional
        Camera, kit, board paths and options shared by every measurement.
    workers : int, optional
        Worker processes (default: every core); 1 runs in this process.
    scheduler : str, optional
        ``tcp://host:port`` of a Dask distributed scheduler; ``workers`` is then ignored.
    start_method : str
        How local worker processes start: ``spawn`` (each imports everything) or
        ``forkserver`` (forked from a server that imported the heavy modules once).
    on_record : callable, optional
        Called with each record after it has been written (progress, logging).
    on_start : callable, optional
        Called once with (photos to measure, photos already done) before measuring.

    Returns
    -------
    BatchSummary
    """
    context = replace(context or MeasureContext(), measurers=tuple(sorted(MEASURERS.items())))
    if start_method not in START_METHODS:
        raise ValueError(
            f"unknown start method {start_method!r}; valid: {', '.join(START_METHODS)}"
        )
    if kind != "auto":
        resolve_measurer(kind)  # ValueError for an unknown kind, before any work
    output = Path(output)
    paths = list(photos)
    jobs = _pending_jobs(paths, output)
    already = len(paths) - len(jobs)
    drop_failed_records(output, {key for _, key in jobs})
    client = None
    if scheduler:
        client = _dask_client(scheduler)
        backend, n_workers = "dask", _dask_workers(client)
    else:
        n_workers = min(workers or default_workers(), max(1, len(jobs)))
        backend = "serial" if n_workers <= 1 else f"{start_method}-pool"
    if on_start:
        on_start(len(jobs), already)
    t0 = time.perf_counter()
    if not jobs:
        records: Iterator[dict[str, Any]] = iter(())
    elif client is not None:
        records = _run_dask(jobs, kind, context, client)
    elif n_workers <= 1:
        records = _run_serial(jobs, kind, context)
    else:
        records = _run_processes(jobs, kind, context, n_workers, start_method)
    try:
        failures, times = _append_records(records, output, on_record)
    finally:
        if client is not None:
            client.close()
    measured = len(times)
    # steady state: after every worker has delivered its first photo (start-up excluded)
    steady = None
    if measured >= n_workers + 2 and times[-1] > times[n_workers - 1]:
        steady = (measured - n_workers) / (times[-1] - times[n_workers - 1])
    return BatchSummary(
        output=os.fspath(output),
        photos_total=len(paths),
        already_done=already,
        measured=measured,
        failed=len(failures),
        seconds=time.perf_counter() - t0,
        workers=n_workers,
        backend=backend,
        failures=tuple(failures),
        steady_photos_per_s=steady,
    )
