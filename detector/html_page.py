"""Self-contained HTML reports: one style, pictures inlined, plain tables. The demo's and the fine-tune's reports
share them."""
from __future__ import annotations

import base64
import html
from pathlib import Path

import cv2

STYLE = """
body { font-family: sans-serif; max-width: 1150px; margin: 1.5em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 2px solid #ccc; padding-bottom: .2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: .6em 0; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: right; }
th:first-child, td:first-child { text-align: left; } th { background: #f2f2f2; }
img { max-width: 100%; border: 1px solid #ddd; margin: .3em 0; }
.row { display: flex; gap: .6em; flex-wrap: wrap; align-items: flex-start; } .row img { max-width: 49%; height: auto; }
.note { color: #555; font-size: .92em; }
"""


def image(path: str | Path, alt: str, max_width: int = 1400) -> str:
    """An <img> with the picture inlined (downscaled JPEG for photos, PNG for plots)."""
    path = Path(path)
    if not path.is_file():
        return f'<p class="note">({html.escape(alt)}: not produced)</p>'
    picture = cv2.imread(str(path))
    if picture.shape[1] > max_width:
        picture = cv2.resize(picture, (max_width, round(picture.shape[0] * max_width / picture.shape[1])),
                             interpolation=cv2.INTER_AREA)
    kind = "png" if path.suffix == ".png" else "jpeg"
    ok, data = cv2.imencode(f".{'png' if kind == 'png' else 'jpg'}", picture)
    return (f'<img alt="{html.escape(alt)}" title="{html.escape(alt)}" '
            f'src="data:image/{kind};base64,{base64.b64encode(data.tobytes()).decode()}">')


def table(header: list[str], rows: list[list]) -> str:
    """A plain table: one header row, then ``rows``, every cell escaped."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def percent(x: float) -> str:
    """A share 0..1 as ``12.3 %``."""
    return f"{100 * x:.1f} %"


def page(title: str, parts: list[str]) -> str:
    """A whole HTML page: ``title`` and the body ``parts`` in order."""
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{STYLE}</style></head><body>{''.join(parts)}</body></html>")
