"""The pieces of a self-contained HTML report (inline CSS, plots as inline PNG): used by the sweep's
``report.html`` and the scorecard's."""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Sequence
from typing import Any

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#1d1d1f;max-width:1400px}
h1{font-size:22px}h2{font-size:18px;margin-top:32px;border-bottom:1px solid #ddd;padding-bottom:4px}
table{border-collapse:collapse;font-size:12px;margin:8px 0}
th,td{border:1px solid #d0d0d0;padding:3px 6px;text-align:right;white-space:nowrap}
th{background:#f3f3f3;white-space:normal;max-width:120px;vertical-align:bottom}td.l,th.l{text-align:left}
td.hl{background:#fde8e8;color:#b3261e;font-weight:600}.verdict{padding:8px 12px;border:2px solid}
.verdict.pass{border-color:#137333;background:#e6f4ea}.verdict.fail{border-color:#b3261e;background:#fde8e8}
tr.failed td{background:#fde8e8}.ok{color:#137333}.bad{color:#b3261e;font-weight:600}
.note{color:#555;font-size:13px}img{max-width:100%;height:auto}
.scroll{overflow-x:auto}
"""


def fmt(v: Any) -> str:
    """A cell's text: "–" for None and non-finite numbers, yes/no, 4 significant digits."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "–"
        return f"{v:.4g}"
    return str(v)


def table(header: Sequence[str], rows: Sequence[Sequence[Any]], left: int = 1,
          row_classes: Sequence[str] | None = None, cell_classes: Sequence[Sequence[str]] | None = None,
          cell_titles: Sequence[Sequence[str]] | None = None) -> str:
    """An HTML table (headers wrap; in a horizontally scrolling box if still too wide): the first ``left``
    columns left-aligned; ``cell_classes`` / ``cell_titles`` (per row, per cell; "" for none) mark cells,
    e.g. ``hl`` for a highlighted value with its reason as the title."""
    e = html.escape
    th = "".join(f'<th class="l">{e(h)}</th>' if i < left else f"<th>{e(h)}</th>" for i, h in enumerate(header))
    body = []
    for j, r in enumerate(rows):
        cls = f' class="{row_classes[j]}"' if row_classes and row_classes[j] else ""
        tds = []
        for i, v in enumerate(r):
            c = ["l"] if i < left else []
            if cell_classes and i < len(cell_classes[j]) and cell_classes[j][i]:
                c.append(cell_classes[j][i])
            title = cell_titles[j][i] if cell_titles and i < len(cell_titles[j]) else ""
            attrs = (f' class="{" ".join(c)}"' if c else "") + (f' title="{e(title)}"' if title else "")
            tds.append(f"<td{attrs}>{e(fmt(v))}</td>")
        body.append(f"<tr{cls}>{''.join(tds)}</tr>")
    return f'<div class="scroll"><table><thead><tr>{th}</tr></thead><tbody>{"".join(body)}</tbody></table></div>'


def png(fig) -> str:
    """A matplotlib figure as an inline base64 ``<img>`` (closes the figure; no timestamp in the PNG)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    return f'<img alt="plot" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode("ascii")}">'
