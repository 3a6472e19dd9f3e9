"""The synthetic photo lab: photos with exact ground truth, deterministic by seed.

Every photo is rendered by tracing each pixel back to the scene plane (exact
undistortion through the Brown-Conrady lens of a :class:`cvmeasure.camera_model.CameraModel`,
then an analytic ray/plane intersection) and evaluating anti-aliased shapes
there, so the truth (marker centres, board corners, wire centrelines) is exact
to far below a pixel. Light, white balance, vignetting, blur, shot/read noise
and JPEG follow (:class:`Lighting`).

API
---
``default_camera(image_size_px=(4608, 3072)) -> CameraModel``
    The seed camera: Nikon D3100 + 18-55 mm at ~35 mm, f = 7000 px, barrel distortion.
``Pose(tilt_deg, tilt_direction_deg, yaw_deg, distance_mm, offset_mm)``
    Camera pose relative to the scene plane (see :class:`cvmeasure_datasets.optics.Pose`).
``Lighting(cct_k, wb_error_k, wb_cct_k, exposure, vignetting, noise, blur_px, jpeg_quality,
bayer, ...)``
    ``Lighting.clean()`` (no noise/blur/JPEG/vignetting, perfect WB) and ``Lighting.random(seed)``.
``render_bender_photo(*, pin_angle_deg, bend_angle_deg, kit=None, camera=None, pose=None,
lighting=None, seed=0, scale=1.0, image_size_px=None, occlude=None, geometry=None, linear=False)``
    The bender's top plate with die, pin, bent 3 mm wire and the kit's five markers,
    in the machine frame. Truth: ``pin_angle_deg``, ``bend_angle_deg`` (from the
    rendered marker centres), ``markers[role]`` with ``centre_px`` (projected disc
    centre), ``ellipse_centre_px``, ``r_px``.
``render_part_photo(*, part, board=None, sheet="dark", camera=None, pose=None, lighting=None,
seed=0, scale=1.0, image_size_px=None, placement_deg=None, linear=False)`` with ``arc_part(radius_mm, arc_angle_deg, divisions)``,
``saddle_part(width_mm, height_mm, divisions)``
    A wire part on a matte sheet beside a ChArUco board. Truth in the board frame.
``render_board_view(*, board, camera=None, pose=None, lighting=None, seed=0, scale=1.0,
image_size_px=None, linear=False)``,
``random_board_poses(n, seed)``
    Calibration views; truth ``corners_px`` of every inner corner (OpenCV id order).
``SceneEffects(marker_heights, supports, wire_3d, part_lift_mm, depth_of_field, motion_blur_px,
bayer, textured_background, clutter, wire_across, tool_shadow, ...)``
    Real-scene effects, each switchable (``effects=`` of ``render_bender_photo`` and
    ``render_part_photo``): discs at their kit heights with printed supports, the wire
    as a ray-traced shiny cylinder with a cast shadow, a part rocked so that one end
    lifts, thin-lens depth of field, motion blur, Bayer mosaic, textured backgrounds,
    stray coloured objects, a wire across a ring edge, a tool's shadow.
    ``SceneEffects()`` is the flat scene (renders bit-identical to before);
    ``SceneEffects.all_on()``, ``SceneEffects.only(name)``.
``RenderedPhoto``
    ``bgr`` (uint8), ``camera``, ``truth`` (JSON-able dict), ``linear_rgb16``
    (with ``linear=True``), ``jpeg_bytes``; ``save(stem)`` writes ``<stem>.jpg``
    (``.png`` when uncompressed) and ``<stem>.truth.json``; ``save_linear_tiff(path)``.

``scale`` resizes the camera (and the photo): 0.25 renders 1152 x 768 for tests;
``image_size_px=(w, h)`` does the same by size.
Every function is deterministic for a given ``seed``.

Checks of the truth (``cvmeasure_datasets.checks``): :func:`~cvmeasure_datasets.checks.check_charuco_corners`
and :func:`~cvmeasure_datasets.checks.check_disc_centre` measure a rendered photo with
standard methods and compare with its truth; ``benchmarks/renderer_fidelity.py``
reports them. ``cvmeasure render bender|part|board`` is the command-line front end.
"""

from cvmeasure_datasets.bender import BenderGeometry, render_bender_photo
from cvmeasure_datasets.boards import random_board_poses, render_board_view
from cvmeasure_datasets.effects import SceneEffects
from cvmeasure_datasets.lighting import Lighting
from cvmeasure_datasets.optics import Pose, default_camera
from cvmeasure_datasets.parts import (
    PartSpec,
    arc_part,
    polyline_part,
    render_part_photo,
    saddle_part,
)
from cvmeasure_datasets.photo import RenderedPhoto

__all__ = [
    "BenderGeometry",
    "Lighting",
    "PartSpec",
    "Pose",
    "RenderedPhoto",
    "SceneEffects",
    "arc_part",
    "default_camera",
    "polyline_part",
    "random_board_poses",
    "render_bender_photo",
    "render_board_view",
    "render_part_photo",
    "saddle_part",
]
