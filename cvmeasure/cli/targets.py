"""``cvmeasure targets``: printable calibration boards and marker-kit sheets."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cvmeasure.cli.options import positive_float

__all__ = ["register", "run_charuco", "run_markers", "MAX_DPI"]

#: Finest resolution accepted, and the most pixels a PNG sheet may have (a 280 x 200 mm
#: board at 1200 dpi is about 13000 x 9400 px, 0.5 GB while drawn).
MAX_DPI = 1200.0
MAX_SHEET_PIXELS = 150_000_000


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "targets",
        help="printable ChArUco boards and marker-kit sheets at exact scale",
        description="Write printable targets at exact physical scale. Print at 100 % "
        "(actual size) and check the ruler on the sheet before use.",
    )
    tsub = p.add_subparsers(dest="target", metavar="TARGET")
    tsub.required = True

    c = tsub.add_parser(
        "charuco",
        help="a ChArUco board (or chessboard) from a board JSON",
        description="Render the board of a board JSON at exact scale with the board JSON "
        "text and a 100 mm print-check ruler on the sheet, and write the board JSON beside "
        "the sheet (<sheet>.board.json: what calibrate, plane and part take as --board). "
        "The format follows the file suffix (.pdf, .svg, .png) unless --format is given. "
        "Without --board: the spec's example board, 14 x 10 squares of 20 mm with 15 mm "
        "markers (DICT_5X5_100), 280 x 200 mm, which fits A3 (--page a3).",
    )
    c.add_argument(
        "--board", type=Path, help="board JSON (spec); default: the 14 x 10 example board"
    )
    c.add_argument("-o", "--out", type=Path, required=True, help="sheet to write (.pdf/.svg/.png)")
    c.add_argument("--format", choices=("pdf", "svg", "png"), help="override the file suffix")
    c.add_argument("--dpi", type=positive_float, default=300.0, help="PNG resolution (default 300)")
    c.add_argument(
        "--page",
        help="paper size: a4, a3, letter, tabloid or WxH in mm (default: just fits the board)",
    )
    c.set_defaults(func=run_charuco)

    m = tsub.add_parser(
        "markers",
        help="the colour marker kit: printable sheet, or its JSON",
        description="Write the marker kit (default: the built-in seed-5 kit) as a printable "
        "sheet, or with --format json print (or write) the kit JSON of the spec.",
    )
    m.add_argument(
        "--kit",
        type=Path,
        help="kit JSON (default: the built-in kit, its markers on caps at heights above the plate)",
    )
    m.add_argument(
        "--flat-kit",
        action="store_true",
        help="the kit without heights: flat stickers glued on the plate",
    )
    m.add_argument("-o", "--out", type=Path, help="file to write (required unless --format json)")
    m.add_argument("--format", choices=("pdf", "svg", "png", "json"), help="output format")
    m.add_argument("--dpi", type=positive_float, default=300.0, help="PNG resolution (default 300)")
    m.set_defaults(func=run_markers)


def _page(text: str | None):
    from cvmeasure.errors import InputError

    if text is None:
        return None
    if "x" in text.lower():
        try:
            w, h = (float(v) for v in text.lower().split("x"))
        except ValueError:
            raise InputError("--page", f"{text!r} is not WxH in mm") from None
        return (w, h)
    return text


def run_charuco(args: argparse.Namespace) -> int:
    from cvmeasure.board import DEFAULT_BOARD, load_board
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure_calib_targets.charuco import write_board_sheet

    board = load_board(args.board) if args.board else DEFAULT_BOARD
    board_json = args.out.with_name(args.out.stem + ".board.json")
    if args.board is not None and board_json.resolve() == args.board.resolve():
        raise InputError(board_json, "the sheet's board JSON would overwrite the input --board")
    fmt = args.format or args.out.suffix.lstrip(".").lower()
    if fmt not in ("pdf", "svg", "png"):
        raise InputError(args.out, "unknown sheet format: use .pdf, .svg or .png (or --format)")
    if not 0 < args.dpi <= MAX_DPI:
        raise InputError("--dpi", f"must be in (0, {MAX_DPI:g}]")
    if fmt == "png":
        w_mm, h_mm = board.size_mm
        pixels = ((w_mm + 60.0) * args.dpi / 25.4) * ((h_mm + 80.0) * args.dpi / 25.4)
        if pixels > MAX_SHEET_PIXELS:
            raise InputError(
                "--dpi",
                f"a {w_mm:g} x {h_mm:g} mm board at {args.dpi:g} dpi is {pixels / 1e6:.0f} MP; "
                f"at most {MAX_SHEET_PIXELS / 1e6:.0f} MP (lower --dpi, or write .pdf/.svg)",
            )
    try:
        path = write_board_sheet(board, args.out, fmt, dpi=args.dpi, page=_page(args.page))
    except ValueError as exc:
        raise InputError(args.board or "--page", str(exc)) from None
    atomic_write_json(board_json, board.to_dict())
    w, h = board.size_mm
    print(f"wrote {path} ({w:g} x {h:g} mm board; print at 100 % and check the 100 mm ruler)")
    print(f"wrote {board_json} (the board JSON: give it as --board to calibrate, plane, part)")
    return 0


def run_markers(args: argparse.Namespace) -> int:
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure.kit import default_kit, load_kit

    if not 0 < args.dpi <= MAX_DPI:
        raise InputError("--dpi", f"must be in (0, {MAX_DPI:g}]")
    kit = load_kit(args.kit) if args.kit else default_kit()
    if args.flat_kit:
        kit = kit.flat()
    fmt = args.format or (args.out.suffix.lstrip(".").lower() if args.out else "json")
    if fmt == "json":
        if args.out:
            atomic_write_json(args.out, kit.to_dict())
            print(f"wrote {args.out}")
        else:
            print(json.dumps(kit.to_dict(), indent=2))
        return 0
    if fmt not in ("pdf", "svg", "png"):
        raise InputError(args.out, "unknown sheet format: use .pdf, .svg, .png or --format json")
    if args.out is None:
        raise InputError("--out", "a sheet needs an output file (-o sheet.pdf)")
    from cvmeasure_calib_targets.markers import write_kit_sheet

    path = write_kit_sheet(kit, args.out, fmt, dpi=args.dpi)
    print(f"wrote {path or args.out} (print at 100 % and check the ruler)")
    return 0
