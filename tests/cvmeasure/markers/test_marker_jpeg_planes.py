"""measure_photo_file on JPEGs: through the Y, Cb, Cr planes where libturbojpeg is (issue 19)."""

from __future__ import annotations

import pytest

from cvmeasure import jpegplanes

needs_lib = pytest.mark.skipif(
    not jpegplanes.available(),
    reason="libturbojpeg (Debian libturbojpeg0) not installed: the planes path is not used here",
)


@needs_lib
def test_measure_photo_file_reads_jpegs_through_the_planes(render, flat_kit, tmp_path, monkeypatch):
    from cvmeasure.imageio import read_photo
    from cvmeasure.markers import measure_machine_photo, measure_photo_file

    photo = render(pin=-47.0, bend=-41.0, seed=31)
    path, _ = photo.save(tmp_path / "p")
    assert str(path).endswith(".jpg")
    calls = []
    real = jpegplanes.read_planes
    monkeypatch.setattr(jpegplanes, "read_planes", lambda *a, **k: calls.append(1) or real(*a, **k))
    via_planes = measure_photo_file(path, flat_kit, camera=photo.camera)
    assert calls  # the planes path measured it
    full = measure_machine_photo(read_photo(path).bgr, flat_kit, camera=photo.camera)
    for key in ("pin_angle_deg", "bend_angle_deg"):
        # the same pixels up to rounding: the same angles within a small part of their error
        assert abs(getattr(via_planes, key) - getattr(full, key)) < 0.003
        assert abs(getattr(via_planes, key) - photo.truth[key]) < 0.03
    assert via_planes.photo == str(path)
    assert set(via_planes.markers) == set(full.markers)


@needs_lib
def test_a_marker_missed_on_the_planes_path_is_measured_from_the_full_decode(
    render, flat_kit, tmp_path, monkeypatch
):
    import cvmeasure.markers.measure as measure
    from cvmeasure.markers import MarkerNotFoundError, measure_photo_file

    photo = render(seed=32, occlude=(("pin", 1.0),))
    path, _ = photo.save(tmp_path / "hidden")
    full_reads = []
    real = measure.read_photo
    monkeypatch.setattr(
        measure, "read_photo", lambda *a, **k: full_reads.append(1) or real(*a, **k)
    )
    with pytest.raises(MarkerNotFoundError, match="'pin'"):
        measure_photo_file(path, flat_kit, camera=photo.camera)
    assert full_reads  # the message is the full decode's


def test_without_libturbojpeg_the_full_decode_measures(render, flat_kit, tmp_path, monkeypatch):
    from cvmeasure.imageio import read_photo
    from cvmeasure.markers import measure_machine_photo, measure_photo_file

    photo = render(pin=20.0, bend=18.0, seed=33)
    path, _ = photo.save(tmp_path / "p")
    monkeypatch.setattr(jpegplanes, "available", lambda: False)
    got = measure_photo_file(path, flat_kit, camera=photo.camera)
    want = measure_machine_photo(read_photo(path).bgr, flat_kit, camera=photo.camera)
    assert got.pin_angle_deg == want.pin_angle_deg
    assert got.bend_angle_deg == want.bend_angle_deg
