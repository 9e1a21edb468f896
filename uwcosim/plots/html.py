"""Building blocks of the self-contained HTML reports (``report.html``), with Plotly.

One file, nothing fetched from the network: :func:`page` inlines Plotly's JavaScript once in
the page head, :func:`png` inlines a PNG figure as a data URI, :func:`plot` gives every plot a
fixed element id (the same run gives the same page). Long runs are thinned to at most
:data:`MAX_POINTS` points per trace (:func:`thin`: every k-th step, the last one kept) for the
interactive plots only. The pages themselves: a run's in :mod:`uwcosim.reports.html`, a
campaign's in :mod:`uwcosim.campaign.html`.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

import numpy as np

#: points per trace of an interactive plot at most
MAX_POINTS = 2500

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
pre { background: #f5f5f5; padding: 0.7em; overflow-x: auto; font-size: 0.85em; }
img { max-width: 100%; }
details { margin: 0.5em 0; }
.plot { margin: 1em 0; }
"""


def esc(x: object) -> str:
    """``x`` as HTML text."""
    return html.escape(str(x))


def table(header: list[str], rows: list[list]) -> str:
    """An HTML table."""
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def num(v: object, fmt: str) -> str:
    """A number formatted with ``fmt``, or a dash for none (or NaN)."""
    return format(v, fmt) if isinstance(v, int | float) and v == v else "–"


def page(title: str, body: list[str]) -> str:
    """The whole page: Plotly's JavaScript inlined in the head, then ``body``."""
    from plotly.offline import get_plotlyjs  # plotly only when a page is written (0.3 s)

    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{esc(title)}</title><style>{_CSS}</style>"
            f"<script type=\"text/javascript\">{get_plotlyjs()}</script></head><body>"
            + "\n".join(body) + "</body></html>\n")


def plot(fig: Any, div_id: str, height: int) -> str:
    """A Plotly figure as a ``<div>`` with a fixed id (no script: :func:`page` has it)."""
    fig.update_layout(height=height, margin={"l": 60, "r": 20, "t": 50, "b": 40},
                      template="plotly_white")
    return ('<div class="plot">' + fig.to_html(full_html=False, include_plotlyjs=False,
                                                div_id=div_id, default_height=f"{height}px",
                                                config={"responsive": True})
            + "</div>")


def png(path: Path) -> str:
    """A PNG file inlined as a figure with its name as caption."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return (f'<figure><img alt="{esc(path.stem)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{esc(path.name)}</figcaption></figure>")


def thin(n: int) -> np.ndarray:
    """Indices of at most :data:`MAX_POINTS` of ``n`` steps: every k-th, the last one kept."""
    stride = max(1, -(-n // MAX_POINTS))
    idx = np.arange(0, n, stride)
    return idx if idx.size == 0 or idx[-1] == n - 1 else np.append(idx, n - 1)


def band(go: Any, t: np.ndarray, s: np.ndarray, name: str, color: str, group: str,
         show: bool) -> Any:
    """A filled ``+-s`` band around zero over ``t`` (``go``: ``plotly.graph_objects``)."""
    ok = np.isfinite(s)
    t, s = t[ok], s[ok]
    return go.Scatter(x=np.concatenate([t, t[::-1]]), y=np.concatenate([s, -s[::-1]]),
                      fill="toself", fillcolor=color, line={"width": 0}, hoverinfo="skip",
                      name=name, legendgroup=group, showlegend=show)
