"""The JPEG planes path: Y, Cb, Cr decoded once, BGR made only where it is read (issue 19)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import simplejpeg

from cvmeasure import jpegplanes

needs_lib = pytest.mark.skipif(
    not jpegplanes.available(),
    reason="libturbojpeg (Debian libturbojpeg0) not installed: the planes path is not used here",
)


def _jpeg(img: np.ndarray, subsampling: str, quality: int = 90) -> bytes:
    return simplejpeg.encode_jpeg(img, quality, colorspace="BGR", colorsubsampling=subsampling)


def _close(a: np.ndarray, b: np.ndarray) -> None:
    """Equal up to rounding: at most 2 levels apart, 0.25 level on average, unbiased.

    The upsampling's ties round half up here, alternately up and down in libjpeg-turbo, and
    OpenCV's colour conversion rounds its coefficients to 3 decimals;
    on this noisy test image up to ~15 % of the samples differ, on rendered photos ~0.1 %.
    """
    d = a.astype(np.int16) - b.astype(np.int16)
    assert np.abs(d).max() <= 2
    assert np.abs(d).mean() <= 0.25
    assert abs(d.mean()) <= 0.1


@needs_lib
@pytest.mark.parametrize("subsampling", ["444", "422", "420"])
@pytest.mark.parametrize("quality", [75, 98])
def test_planes_give_the_full_decodes_pixels(subsampling, quality, textured_bgr):
    data = _jpeg(textured_bgr(3, (151, 203)), subsampling, quality)
    full = simplejpeg.decode_jpeg(data, colorspace="BGR")
    planes = jpegplanes.read_planes(data)
    assert planes is not None
    # the luma plane is libjpeg-turbo's own, bit for bit
    np.testing.assert_array_equal(planes.y, simplejpeg.decode_jpeg(data, colorspace="GRAY")[..., 0])
    h, w = full.shape[:2]
    _close(planes.region_bgr(0, h, 0, w), full)
    # a region inside, at odd offsets, is the same pixels as the whole image's
    _close(planes.region_bgr(37, 101, 51, 150), full[37:101, 51:150])
    # the sampled copy is the decoded image's every step-th pixel, with the chroma sample
    # it lies in: the same but next to colour edges (where subsampled chroma is interpolated)
    clean = _jpeg(textured_bgr(3, (151, 203), noise=0.0), subsampling, quality)
    planes, full = jpegplanes.read_planes(clean), simplejpeg.decode_jpeg(clean, colorspace="BGR")
    for step in (3, 7, 10):
        got = planes.sampled_bgr(step)
        want = full[::step, ::step]
        assert got.shape == want.shape
        if subsampling == "444":
            _close(got, want)
        else:
            d = np.abs(got.astype(np.int16) - want.astype(np.int16)).max(axis=2)
            assert np.median(d) <= 1  # within rounding but where the chroma changes
            assert np.percentile(d, 80) <= 2  # (steep colour ramps all over this image)


@needs_lib
@pytest.mark.parametrize("subsampling", ["444", "422", "420"])
def test_sampled_copy_takes_each_pixels_own_chroma_sample(subsampling, textured_bgr):
    # odd sizes: the last row/column of chroma samples covers one luma row/column
    planes = jpegplanes.read_planes(_jpeg(textured_bgr(6, (151, 203)), subsampling))
    h, w = planes.y.shape
    for step in (2, 3, 4, 6, 7, 10):  # strided views where step is a multiple of sx, sy
        rows = np.arange(0, h, step) // planes.sy
        cols = np.arange(0, w, step) // planes.sx
        want = planes._to_bgr(
            planes.y[::step, ::step],
            np.ascontiguousarray(planes.cb[rows][:, cols]),
            np.ascontiguousarray(planes.cr[rows][:, cols]),
        )
        np.testing.assert_array_equal(planes.sampled_bgr(step), want)


@needs_lib
def test_lazy_bgr_makes_regions_sampled_copies_and_the_whole_image(textured_bgr):
    data = _jpeg(textured_bgr(4, (151, 203)), "420")
    full = simplejpeg.decode_jpeg(data, colorspace="BGR")
    planes = jpegplanes.read_planes(data)
    lazy = planes.lazy_bgr()
    assert lazy.shape == full.shape and lazy.dtype == np.uint8
    roi = lazy[20:60, 30:90]
    assert type(roi) is np.ndarray and roi.shape == (40, 60, 3)
    np.testing.assert_array_equal(roi, planes.region_bgr(20, 60, 30, 90))
    np.testing.assert_array_equal(lazy[22:50, 35:80], roi[2:30, 5:50])  # from the kept region
    np.testing.assert_array_equal(lazy[::5, ::5], planes.sampled_bgr(5))
    np.testing.assert_array_equal(lazy[10:20, 10:20, 1], planes.region_bgr(10, 20, 10, 20)[..., 1])
    # any other indexing: the whole image is made first, then read as an array
    row = lazy[7]
    h, w = full.shape[:2]
    np.testing.assert_array_equal(row, planes.region_bgr(0, h, 0, w)[7])
    _close(np.asarray(lazy), full)


@needs_lib
def test_lazy_bgr_never_gives_unmade_pixels(textured_bgr):
    # whatever reads the whole image gets its pixels (made on demand), never zeros; OpenCV,
    # which would read memory directly, and Python's operators refuse it
    data = _jpeg(textured_bgr(7, (151, 203)), "420")
    planes = jpegplanes.read_planes(data)
    h, w = planes.y.shape
    whole = planes.region_bgr(0, h, 0, w)
    assert whole.min(axis=(0, 1)).max() > 0  # a test image whose pixels are not all zero
    for read in (np.asarray, np.array, lambda a: np.add(a, 0), lambda a: a[..., 1], lambda a: a[5]):
        want = read(whole)
        got = read(planes.lazy_bgr())
        assert type(got) is np.ndarray
        np.testing.assert_array_equal(got, want)
    assert float(np.mean(planes.lazy_bgr())) == pytest.approx(float(whole.mean()))
    with pytest.raises(cv2.error, match="not a numpy array"):
        cv2.cvtColor(planes.lazy_bgr(), cv2.COLOR_BGR2GRAY)
    with pytest.raises(TypeError):
        planes.lazy_bgr() + 0
    lazy = planes.lazy_bgr()
    assert not isinstance(lazy, np.ndarray) and lazy.shape == (h, w, 3) and lazy.dtype == np.uint8


@needs_lib
def test_what_the_planes_path_does_not_take_is_left_to_the_full_decode(tmp_path, textured_bgr):
    grey = cv2.cvtColor(textured_bgr(5, (151, 203)), cv2.COLOR_BGR2GRAY)
    assert (
        jpegplanes.read_planes(simplejpeg.encode_jpeg(grey[..., None], 90, colorspace="GRAY"))
        is None
    )
    data = _jpeg(textured_bgr(5, (151, 203)), "420")
    assert jpegplanes.read_planes(data[:-300]) is None  # damaged: libjpeg warns, nothing guessed
    assert jpegplanes.read_planes(data, max_pixels=100) is None  # too large: not decoded here
    p = tmp_path / "x.jpg"
    cv2.imwrite(
        str(p),
        textured_bgr(5, (151, 203)),
        [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_PROGRESSIVE, 1],
    )
    planes = jpegplanes.read_planes(p.read_bytes())  # progressive: libjpeg-turbo decodes it too
    assert planes is not None
    full = simplejpeg.decode_jpeg(p.read_bytes(), colorspace="BGR")
    _close(planes.region_bgr(0, full.shape[0], 0, full.shape[1]), full)
