"""What a JPEG file's markers say about its data: whether they stop before the image ends."""
from __future__ import annotations

START_OF_IMAGE = b"\xff\xd8\xff"
#: Marker codes (the byte after 0xFF) that the walk treats specially.
END_OF_IMAGE, START_OF_SCAN, FILL, STUFFED = 0xD9, 0xDA, 0xFF, 0x00
#: Markers without a length field: TEM, the restart markers RST0-RST7 and a stray start of image.
STANDALONE = frozenset({0x01, *range(0xD0, 0xD9)})


def truncated_jpeg(data: bytes) -> bool:
    """True for a JPEG whose data stop before its end-of-image marker: a copy cut short (a full card, a robot
    powered off while writing), whose missing rows decode grey where a decoder decodes it at all.

    The file's segments are walked from its start as a decoder reads them, so bytes after the end marker do not count
    (a camera that saves its fixed-size capture buffer, V4L2 MJPEG, pads the image with them, whatever they hold), and
    neither do the markers of an EXIF thumbnail, which sit inside a segment that is skipped by its length. Not a JPEG:
    False (other checks name it)."""
    if not data.startswith(START_OF_IMAGE):
        return False
    position = 2
    while True:
        position = data.find(b"\xff", position)
        while 0 <= position < len(data) - 1 and data[position + 1] == FILL:
            position += 1
        if position < 0 or position >= len(data) - 1:
            return True
        marker, position = data[position + 1], position + 2
        if marker == END_OF_IMAGE:
            return False
        if marker in STANDALONE:
            continue
        if position + 2 > len(data):
            return True
        position += int.from_bytes(data[position:position + 2], "big")
        if marker == START_OF_SCAN:
            position = _end_of_entropy_coded_data(data, position)


def _end_of_entropy_coded_data(data: bytes, position: int) -> int:
    """Where the scan data starting at ``position`` end: the 0xFF of the next marker, or the end of ``data``. Inside a
    scan 0xFF is followed by a stuffed 0x00, a restart marker or a fill byte; anything else is a marker."""
    while True:
        position = data.find(b"\xff", position)
        if position < 0 or position >= len(data) - 1:
            return len(data)
        following = data[position + 1]
        if following == STUFFED or 0xD0 <= following <= 0xD7:
            position += 2
        elif following == FILL:
            position += 1
        else:
            return position
