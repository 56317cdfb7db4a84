"""What a JPEG file's markers say about its data: whether they stop before the image ends."""
from __future__ import annotations

START_OF_IMAGE = b"\xff\xd8\xff"
START_OF_SCAN = b"\xff\xda"
END_OF_IMAGE = b"\xff\xd9"


def truncated_jpeg(data: bytes) -> bool:
    """True for a JPEG whose last scan has no end-of-image marker after it: a copy cut short (a full card, a robot
    powered off while writing), whose missing rows decode grey where a decoder decodes it at all.

    Bytes after the marker do not count: a camera that saves its fixed-size capture buffer (V4L2 MJPEG) pads the
    image with them. Inside a scan a 0xFF byte is always followed by 0x00 or a restart marker, so the end marker
    cannot appear there by chance; an EXIF thumbnail's own markers come before the image's scans."""
    if not data.startswith(START_OF_IMAGE):
        return False
    return data.find(END_OF_IMAGE, max(data.rfind(START_OF_SCAN), 0)) < 0
