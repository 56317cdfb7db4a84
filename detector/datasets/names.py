"""Map the class names a dataset uses onto the canonical landmark codes (by name, never by index)."""
from __future__ import annotations

import re

from naoslam.landmarks import CLASSES

_COLOUR_LETTER = {"pink": "p", "magenta": "p", "blue": "b", "skyblue": "b", "cyan": "b", "yellow": "y", "green": "g"}


def canonical_class(name: str) -> str | None:
    """The canonical code for a dataset's class name, or None when it names no landmark.

    Accepts the codes themselves in any case (``"BP"``), with separators (``"b-p"``), and colour words
    top band first (``"blue-pink"``, ``"Blue over Pink"``, ``"sky blue / pink"``).
    """
    text = str(name).strip().lower()
    compact = re.sub(r"[^a-z]", "", text)
    if compact in CLASSES:
        return compact
    words = re.findall(r"[a-z]+", text.replace("sky blue", "skyblue"))
    letters = [_COLOUR_LETTER[w] for w in words if w in _COLOUR_LETTER]
    code = "".join(letters)
    return code if code in CLASSES else None
