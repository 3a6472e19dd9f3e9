import cv2
import numpy as np
import pytest

from cvmeasure.errors import InputError
from cvmeasure.imageio import read_photo


def test_jpeg_png_tiff_roundtrip(tmp_path):
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:40, 0:60]
    img = np.dstack((xx * 4, yy * 6, 100 + 0 * xx)).astype(np.uint8)
    img[rng.integers(0, 40, 5), rng.integers(0, 60, 5)] += 1
    for ext in (".png", ".tiff"):
        p = tmp_path / f"x{ext}"
        cv2.imwrite(str(p), img)
        np.testing.assert_array_equal(read_photo(p).bgr, img)
    p = tmp_path / "x.jpg"
    cv2.imwrite(str(p), img, [cv2.IMWRITE_JPEG_QUALITY, 100])
    assert np.abs(read_photo(p).bgr.astype(int) - img).mean() < 3


def test_unreadable_photo_named(tmp_path):
    p = tmp_path / "broken.jpg"
    p.write_bytes(b"\xff\xd8 not really a jpeg")
    with pytest.raises(InputError, match="broken.jpg: unreadable photo"):
        read_photo(p)
    with pytest.raises(InputError, match="not found"):
        read_photo(tmp_path / "nope.jpg")


def test_real_dng_decodes_linear_with_camera_white_balance(shared_real):
    photo = read_photo(shared_real / "raw" / "Blackmagic.dng", half_size=True)
    assert photo.linear and photo.bgr.dtype == np.uint16
    assert photo.bgr.shape == (1088, 2064, 3)


def test_real_nef_that_is_a_scan_decodes(shared_real):
    photo = read_photo(shared_real / "raw" / "Nikon_uncompressed.nef")
    assert photo.bgr.shape == (593, 869, 3)


def _png_header_only(path, width, height):
    """A valid PNG signature and IHDR declaring width x height, and no pixel data."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


def test_a_photo_declaring_too_many_pixels_is_refused_before_decoding(tmp_path):
    import resource

    from cvmeasure.errors import InputError
    from cvmeasure.imageio import read_photo

    bomb = tmp_path / "bomb.png"
    _png_header_only(bomb, 30000, 30000)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(InputError, match=r"declares 30000 x 30000 pixels \(900 MP\)"):
        read_photo(bomb)
    grown_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kb < 200_000  # nothing near the 2.7 GB a decode would take


@pytest.mark.parametrize(
    "params",
    [
        [cv2.IMWRITE_JPEG_QUALITY, 80],
        [cv2.IMWRITE_JPEG_QUALITY, 98],
        [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_SAMPLING_FACTOR, 0x111111],
        [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_PROGRESSIVE, 1],
        [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_RST_INTERVAL, 4],
    ],
)
def test_jpeg_decode_gives_opencvs_pixels_bit_for_bit(tmp_path, params, textured_bgr):
    from cvmeasure.imageio import decode_jpeg

    p = tmp_path / "x.jpg"
    cv2.imwrite(str(p), textured_bgr(5), params)
    data = np.fromfile(p, dtype=np.uint8)
    fast = decode_jpeg(data, p)
    assert fast is not None  # simplejpeg decoded it (not the fallback)
    np.testing.assert_array_equal(fast, cv2.imdecode(data, cv2.IMREAD_UNCHANGED))
    np.testing.assert_array_equal(read_photo(p).bgr, fast)


def test_grey_jpeg_reads_as_three_equal_channels(tmp_path, textured_bgr):
    p = tmp_path / "grey.jpg"
    grey = cv2.cvtColor(textured_bgr(6), cv2.COLOR_BGR2GRAY)
    cv2.imwrite(str(p), grey, [cv2.IMWRITE_JPEG_QUALITY, 95])
    bgr = read_photo(p).bgr
    assert bgr.shape == grey.shape + (3,)
    np.testing.assert_array_equal(bgr[..., 0], cv2.imread(str(p), cv2.IMREAD_GRAYSCALE))
    np.testing.assert_array_equal(bgr[..., 0], bgr[..., 2])


def test_truncated_jpeg_goes_to_opencv_as_before(tmp_path, textured_bgr):
    from cvmeasure.imageio import decode_jpeg

    p = tmp_path / "cut.jpg"
    cv2.imwrite(str(p), textured_bgr(7), [cv2.IMWRITE_JPEG_QUALITY, 90])
    data = np.fromfile(p, dtype=np.uint8)[:-400]
    data.tofile(p)
    assert decode_jpeg(data, p) is None  # strict: damaged data is not guessed at here
    assert cv2.imdecode(data, cv2.IMREAD_UNCHANGED) is None  # nor by OpenCV: refused as before
    with pytest.raises(InputError, match="cut.jpg: unreadable photo"):
        read_photo(p)


def test_a_jpeg_declaring_too_many_pixels_is_refused_before_decoding(tmp_path, textured_bgr):
    import struct

    p = tmp_path / "bomb.jpg"
    cv2.imwrite(str(p), textured_bgr(8, (16, 16)), [cv2.IMWRITE_JPEG_QUALITY, 90])
    data = bytearray(p.read_bytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = struct.pack(">HH", 30000, 30000)  # height, width
    p.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"bomb.jpg: photo declares 30000 x 30000 pixels"):
        read_photo(p)
