#!/usr/bin/env python3
"""Writes a tray of one's own to try camplace on, into a folder: `six_slot.stl` (a six-slot
tray, 260 x 170 mm, 35 mm walls, and a low tab, 12 mm out and 15 mm high, outside its +x
end: the one feature that tells the tray from its half turn, and one its own walls hide
from some views), `hex_item.stl` (a hexagonal item, 44 mm across its flats, 30 mm high)
and `cell.toml`, the default cell with that tray and item.

    python3 scripts/example_tray.py out/own
    cargo run --release -- study --cell out/own/cell.toml --quick --out out/own/study

Meshes are binary STL in mm, origin at the bottom face's centre, z up. Python 3 alone.
"""

import math
import struct
import sys
from pathlib import Path

LENGTH, WIDTH = 260.0, 170.0
FLOOR, WALL, HEIGHT = 6.0, 4.0, 35.0
TAB = (12.0, 40.0, 15.0)  # out past the +x wall, across, high
SLOT_X, SLOT_Y = (-80.0, 0.0, 80.0), (-40.0, 40.0)
ITEM_FLATS, ITEM_HEIGHT = 44.0, 30.0


def box(lo, hi):
    """The twelve triangles of an axis-aligned box, wound outwards."""
    def p(i, j, k):
        return ((lo[0], hi[0])[i], (lo[1], hi[1])[j], (lo[2], hi[2])[k])

    faces = [
        (p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)),
        (p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)),
        (p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)),
        (p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0)),
        (p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)),
        (p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)),
    ]
    for a, b, c, d in faces:
        yield (a, b, c)
        yield (a, c, d)


def tray():
    hx, hy = LENGTH / 2, WIDTH / 2
    parts = [
        ((-hx, -hy, 0.0), (hx, hy, FLOOR)),
        ((-hx, -hy, 0.0), (-hx + WALL, hy, HEIGHT)),
        ((hx - WALL, -hy, 0.0), (hx, hy, HEIGHT)),
        ((-hx, -hy, 0.0), (hx, -hy + WALL, HEIGHT)),
        ((-hx, hy - WALL, 0.0), (hx, hy, HEIGHT)),
        ((hx, -TAB[1] / 2, 0.0), (hx + TAB[0], TAB[1] / 2, TAB[2])),
    ]
    return [t for lo, hi in parts for t in box(lo, hi)]


def hex_item():
    """A hexagonal prism standing on the origin, its flats facing +-y."""
    r = ITEM_FLATS / 2 / math.cos(math.pi / 6)
    ring = [(r * math.cos(math.pi / 3 * k), r * math.sin(math.pi / 3 * k)) for k in range(6)]
    out = []
    for k in range(6):
        (x0, y0), (x1, y1) = ring[k], ring[(k + 1) % 6]
        out.append(((0, 0, 0), (x1, y1, 0), (x0, y0, 0)))
        out.append(((0, 0, ITEM_HEIGHT), (x0, y0, ITEM_HEIGHT), (x1, y1, ITEM_HEIGHT)))
        out.append(((x0, y0, 0), (x1, y1, 0), (x1, y1, ITEM_HEIGHT)))
        out.append(((x0, y0, 0), (x1, y1, ITEM_HEIGHT), (x0, y0, ITEM_HEIGHT)))
    return out


def stl(triangles):
    out = bytearray(80) + struct.pack("<I", len(triangles))
    for t in triangles:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for v in t:
            out += struct.pack("<3f", *v)
        out += b"\0\0"
    return bytes(out)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: example_tray.py OUT_DIR")
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    (out / "six_slot.stl").write_bytes(stl(tray()))
    (out / "hex_item.stl").write_bytes(stl(hex_item()))
    slots = ", ".join(f"[{x:.1f}, {y:.1f}, {FLOOR:.1f}, 0.0]" for y in SLOT_Y for x in SLOT_X)
    (out / "cell.toml").write_text(
        "# A six-slot mesh tray of one's own with a low tab outside its +x end, and hexagonal\n"
        "# items (scripts/example_tray.py); every other key as in the default cell.\n"
        "[tray]\n"
        'kind = "mesh"\n'
        'mesh = "six_slot.stl"\n'
        f"slots = [{slots}]\n\n"
        "[items]\n"
        'kind = "mesh"\n'
        'mesh = "hex_item.stl"\n'
    )
    print(f"wrote {out / 'six_slot.stl'}, {out / 'hex_item.stl'} and {out / 'cell.toml'}")


if __name__ == "__main__":
    main()
