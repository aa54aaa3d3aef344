"""A row's error curves as a small inline SVG plot (no matplotlib: the pages stand alone).
"""

from __future__ import annotations

import html
import math

import numpy as np


def svg_plot(curves: list[tuple[str, np.ndarray, np.ndarray]], width: int = 320,
              height: int = 110) -> str:
    """A small inline SVG of position error [m] against time [s], one line per scenario."""
    colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]
    finite = [e[np.isfinite(e)] for _, _, e in curves]
    top = max([float(np.max(f)) for f in finite if len(f)] + [1e-3])
    tmax = max([float(t[-1]) for _, t, _ in curves if len(t)] + [1.0])
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
             f'viewBox="0 0 {width} {height}"><rect width="100%" height="100%" fill="#fff"/>']
    for k, (label, t, e) in enumerate(curves):
        pts = " ".join(f"{4 + (width - 8) * ti / tmax:.1f},{height - 14 - (height - 24) * ei / top:.1f}"
                       for ti, ei in zip(t[::4], e[::4], strict=True) if math.isfinite(ei))
        parts.append(f'<polyline fill="none" stroke="{colours[k % 4]}" stroke-width="1.2" '
                     f'points="{pts}"><title>{html.escape(label)}</title></polyline>')
    parts.append(f'<text x="4" y="10" font-size="9">{top:.2g} m</text>'
                 f'<text x="{width - 40}" y="{height - 2}" font-size="9">{tmax:.0f} s</text></svg>')
    return "".join(parts)
