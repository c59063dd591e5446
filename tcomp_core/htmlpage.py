"""Self-contained HTML pages: an inline style sheet, escaped text, figures as embedded PNGs.

Shared by the reports of ``tcomp diagnose`` (:mod:`tcomp_core.report`) and ``tcomp campaign``
(:mod:`tcomp_core.campaign.report`). Figures are :class:`matplotlib.figure.Figure` objects (no
pyplot, no GUI backend) embedded as base64 data URIs, so a page holds no external reference.
"""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Iterable, Sequence
from html import escape

from matplotlib.figure import Figure

__all__ = ["FIGURE_DPI", "bullet_list", "image", "number", "page", "section", "table"]

#: Resolution of the embedded figures, dots per inch.
FIGURE_DPI = 90

STYLE = """
body { font-family: sans-serif; max-width: 70em; margin: 1em auto; padding: 0 1em;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; vertical-align: top; }
th { background: #f2f2f2; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; height: auto; }
.verdict { font-size: 1.2em; font-weight: bold; }
"""


def number(value: float, spec: str = ".4g") -> str:
    """A number for the page; ``n/a`` for NaN and ``inf`` for infinities."""
    value = float(value)
    if math.isnan(value):
        return "n/a"
    return format(value, spec) if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """An HTML table; cells holding numbers are right-aligned. All text is escaped."""
    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = []
    for row in rows:
        cells = "".join(
            f'<td class="num">{escape(number(c))}</td>'
            if isinstance(c, float)
            else f"<td>{escape(str(c))}</td>"
            for c in row
        )
        body.append(f"<tr>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def bullet_list(items: Iterable[str]) -> str:
    """An HTML list of the items (escaped); ``none`` when there are none."""
    entries = "".join(f"<li>{escape(item)}</li>" for item in items)
    return f"<ul>{entries}</ul>" if entries else "<p>none</p>"


def section(title: str, *parts: str) -> str:
    """A titled section of the page (the title escaped, the parts as they are)."""
    return f"<section><h2>{escape(title)}</h2>{''.join(parts)}</section>"


def image(figure: Figure, alt: str) -> str:
    """The figure as an embedded PNG (no metadata naming the software)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=FIGURE_DPI, metadata={"Software": None})
    data = base64.b64encode(buffer.getvalue()).decode("ascii")
    return f'<p><img alt="{escape(alt)}" src="data:image/png;base64,{data}"></p>'


def page(title: str, body: str) -> str:
    """A self-contained HTML page: the title (escaped here) and the body's sections."""
    title = escape(title)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{title}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        f"<h1>{title}</h1>\n{body}\n</body>\n</html>\n"
    )
