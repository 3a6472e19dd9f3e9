from cvmeasure.errors import CvmeasureError, DeviceError, DeviceTimeoutError, InputError


def test_hierarchy():
    assert issubclass(InputError, CvmeasureError)
    assert issubclass(InputError, ValueError)
    assert issubclass(DeviceTimeoutError, DeviceError)
    assert issubclass(DeviceError, CvmeasureError)
    assert not issubclass(DeviceTimeoutError, TimeoutError)


def test_input_error_is_one_line_naming_the_source():
    err = InputError("photos/a.jpg", "unreadable\nphoto   here")
    assert str(err) == "photos/a.jpg: unreadable photo here"
    assert err.source == "photos/a.jpg"
