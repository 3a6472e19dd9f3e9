"""Byte-for-byte tests of the TinyG protocol functions."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvmeasure.driver.protocol import (
    ExceptionReport,
    GcodeError,
    LineSplitter,
    QueueReport,
    Response,
    RxReport,
    StatusReport,
    Unparsed,
    encode_json,
    encode_line,
    format_exception,
    format_queue_report,
    format_response,
    format_rx_report,
    format_status_report,
    parse_block,
    parse_message,
    track_positions,
)


def test_encode_line_appends_lf_only():
    assert encode_line("N12 G91 G1 Y15.5 F3000") == b"N12 G91 G1 Y15.5 F3000\n"


@pytest.mark.parametrize(
    "bad", ["G1 X10!", "G1 ~", "M%", "$ej=1", "?", "G1\tX1", "G1 X1\r", "", "G1 X\u00b0"]
)
def test_encode_line_refuses_realtime_and_control_characters(bad):
    with pytest.raises(ValueError):
        encode_line(bad)


def test_encode_line_refuses_long_lines():
    with pytest.raises(ValueError, match="longer than 80"):
        encode_line("G1 X" + "1" * 80)


def test_encode_json_is_compact_and_null_means_query():
    assert encode_json({"sr": None}) == b'{"sr":null}\n'
    assert encode_json({"ej": 1}) == b'{"ej":1}\n'


def test_encode_json_refuses_silent_mode():
    with pytest.raises(ValueError, match="jv=0"):
        encode_json({"jv": 0})


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=20))
def test_line_splitter_is_independent_of_chunking(cuts):
    stream = b'{"r":{},"f":[1,0,11]}\n\x13{"sr":{"stat":5}}\r\n\x11{"qr":30}\n{"rx":254}\n'
    expected = [b'{"r":{},"f":[1,0,11]}', b'{"sr":{"stat":5}}', b'{"qr":30}', b'{"rx":254}']
    sp, got, pos = LineSplitter(), [], 0
    for n in cuts:
        got += sp.feed(stream[pos : pos + n])
        pos += n
    got += sp.feed(stream[pos:])
    assert got == expected and sp.pending == b""


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        (b'{"r":{},"f":[1,0,11]}', Response(0, 11, {}, (1, 0, 11))),
        (b'{"r":{},"f":[1,0,33,134]}', Response(0, 33, {}, (1, 0, 33, 134))),
        (b'{"r":{},"f":[2,202,9]}', Response(202, 9, {}, (2, 202, 9))),
        # very early builds nest the footer inside r (TinyG #55)
        (b'{"r":{"jv":5,"f":[1,0,9,8847]}}', Response(0, 9, {"jv": 5}, (1, 0, 9, 8847))),
        (b'{"sr":{"line":12,"stat":5}}', StatusReport({"line": 12, "stat": 5})),
        (b'{"qr":28}', QueueReport(28)),
        (b'{"qr":28,"qi":1,"qo":0}', QueueReport(28, 1, 0)),
        (b'{"rx":254}', RxReport(254)),
        (
            b'{"er":{"fb":440.21,"st":204,"msg":"limit switch hit"}}',
            ExceptionReport(
                204, "limit switch hit", {"fb": 440.21, "st": 204, "msg": "limit switch hit"}
            ),
        ),
    ],
)
def test_parse_message(raw, expected):
    assert parse_message(raw) == expected


@pytest.mark.parametrize(
    "raw",
    [
        b'{"r":{},"f"',
        b'{"sr"{"sr":1}}',
        b"tinyg [mm] ok>",
        b'{"r":{},"f":[1,0]}',
        b"[1,2]",
        b'{"x":1}',
    ],
)
def test_parse_message_never_raises_on_garbage(raw):
    msg = parse_message(raw)
    assert isinstance(msg, Unparsed)
    assert msg.text == raw.decode()


def test_banner_is_recognised():
    msg = parse_message(b'{"r":{"fv":0.97,"fb":440.21,"msg":"SYSTEM READY"},"f":[1,0,0]}')
    assert isinstance(msg, Response) and msg.is_banner


def test_line_splitter_strips_xon_xoff_and_handles_cr_lf_and_partials():
    sp = LineSplitter()
    assert sp.feed(b'{"qr":3\x13') == []
    assert sp.pending == b'{"qr":3'
    assert sp.feed(b'2}\r\n\x11{"rx":1}\n\n{"r"') == [b'{"qr":32}', b'{"rx":1}']
    assert sp.pending == b'{"r"'


def test_format_functions_byte_for_byte():
    assert format_response({}, 0, 11) == b'{"r":{},"f":[1,0,11]}\n'
    assert format_response({}, 202, 9, style="446") == b'{"r":{},"f":[2,202,9]}\n'
    four = format_response({}, 0, 9, style="440")
    assert four.startswith(b'{"r":{},"f":[1,0,9,') and four.endswith(b"]}\n")
    assert format_status_report({"posx": 1.23456, "stat": 5, "vel": 1e-9}) == (
        b'{"sr":{"posx":1.235,"stat":5,"vel":0.0}}\n'
    )
    assert format_queue_report(32) == b'{"qr":32}\n'
    assert format_rx_report(254) == b'{"rx":254}\n'
    assert format_exception(204, "limit switch hit") == (
        b'{"er":{"fb":440.21,"st":204,"msg":"limit switch hit"}}\n'
    )


def test_formatted_messages_parse_back():
    for data in (format_response({"qr": 30}, 0, 10), format_queue_report(7), format_rx_report(3)):
        assert not isinstance(parse_message(data.rstrip(b"\n")), Unparsed)


def test_parse_block_words_and_comments():
    b = parse_block("n12 g91 g1 y15.5 f3000 (feed)")
    assert b.line_number == 12
    assert b.g_codes == (91.0, 1.0)
    assert b.axes == {"y": 15.5}
    assert b.feed == 3000.0
    assert b.comment == "feed"
    assert b.motion == 1 and b.distance_mode == "relative"
    marker = parse_block("N62 (end)")
    assert marker.line_number == 62 and marker.axes == {} and marker.motion is None


@pytest.mark.parametrize(
    ("text", "status"), [("G2 X1", 131), ("M3", 132), ("G1 Q5", 137), ("G1 X1#", 130)]
)
def test_parse_block_rejects_with_tinyg_status(text, status):
    with pytest.raises(GcodeError) as info:
        parse_block(text)
    assert info.value.status == status


def test_track_positions_relative_feed_absolute_pin():
    blocks = [
        parse_block(t)
        for t in (
            "G21 G90",
            "G91 G1 Y10 F1",
            "G90 G1 X30 F1",
            "G0 X0",
            "G91 G1 Y2.5 F1",
            "G28.3 Y0",
        )
    ]
    pos = track_positions(blocks, {"y": 100.0})
    assert [p["y"] for p in pos] == [100.0, 110.0, 110.0, 110.0, 112.5, 0.0]
    assert [p["x"] for p in pos] == [0.0, 0.0, 30.0, 0.0, 0.0, 0.0]
