"""Small inline-SVG charts for the HTML report (hand-written SVG; no plotting library).

Each function returns an ``<svg>`` string with a ``<title>`` for accessibility. Text is
escaped; numbers that are None or not finite are skipped.
"""

from __future__ import annotations

import math
from html import escape

W, H = 640, 260
PAD_L, PAD_R, PAD_T, PAD_B = 56, 16, 28, 48
GOOD, BAD, GREY, BLUE = "#2b7bba", "#d7301f", "#888888", "#1b9e77"


def _finite(v) -> bool:
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def _nice_max(v: float) -> float:
    if v <= 0:
        return 1.0
    e = 10 ** math.floor(math.log10(v))
    for m in (1, 2, 2.5, 5, 10):
        if m * e >= v:
            return m * e
    return 10 * e


def _frame(title: str, body: str, w: int = W, h: int = H) -> str:
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" height="{h}" role="img">'
            f'<title>{escape(title)}</title><rect width="{w}" height="{h}" fill="#fff"/>'
            f'<text x="{w / 2}" y="18" text-anchor="middle" font-size="14" font-family="sans-serif">{escape(title)}</text>'
            f"{body}</svg>")


def bar_chart(title: str, labels: list[str], values: list, unit: str = "", flags: list[bool] | None = None,
              ref_lines: dict[str, float] | None = None) -> str:
    """Vertical bars (flagged bars red), y axis from 0, optional labelled horizontal lines."""
    vals = [v if _finite(v) else None for v in values]
    top = _nice_max(max([abs(v) for v in vals if v is not None] + list((ref_lines or {}).values()) + [1e-9]))
    n = max(len(vals), 1)
    pw, ph = W - PAD_L - PAD_R, H - PAD_T - PAD_B
    bw = pw / n
    y = lambda v: PAD_T + ph * (1 - v / top)  # noqa: E731
    parts = []
    for k in range(5):
        tv = top * k / 4
        parts.append(f'<line x1="{PAD_L}" x2="{W - PAD_R}" y1="{y(tv):.1f}" y2="{y(tv):.1f}" stroke="#ddd"/>'
                     f'<text x="{PAD_L - 6}" y="{y(tv) + 4:.1f}" text-anchor="end" font-size="11" '
                     f'font-family="sans-serif">{tv:g}</text>')
    for i, (lab, v) in enumerate(zip(labels, vals)):
        x = PAD_L + i * bw
        if v is not None:
            colour = BAD if flags and flags[i] else GOOD
            parts.append(f'<rect x="{x + bw * 0.15:.1f}" y="{y(max(v, 0)):.1f}" width="{bw * 0.7:.1f}" '
                         f'height="{max(ph * abs(v) / top, 0.5):.1f}" fill="{colour}"><title>{escape(str(lab))}: '
                         f'{v:.3g} {escape(unit)}</title></rect>')
        parts.append(f'<text x="{x + bw / 2:.1f}" y="{H - PAD_B + 14}" text-anchor="middle" font-size="10" '
                     f'font-family="sans-serif">{escape(str(lab))}</text>')
    for name, v in (ref_lines or {}).items():
        parts.append(f'<line x1="{PAD_L}" x2="{W - PAD_R}" y1="{y(v):.1f}" y2="{y(v):.1f}" stroke="{GREY}" '
                     f'stroke-dasharray="5,4"/><text x="{W - PAD_R - 2}" y="{y(v) - 3:.1f}" text-anchor="end" '
                     f'font-size="10" fill="#555" font-family="sans-serif">{escape(name)}</text>')
    parts.append(f'<text x="14" y="{PAD_T + ph / 2}" font-size="11" font-family="sans-serif" '
                 f'transform="rotate(-90 14 {PAD_T + ph / 2})" text-anchor="middle">{escape(unit)}</text>')
    parts.append(f'<line x1="{PAD_L}" x2="{PAD_L}" y1="{PAD_T}" y2="{PAD_T + ph}" stroke="#333"/>')
    return _frame(title, "".join(parts))


def scatter_residuals(title: str, points: list[tuple[str, float, float, bool]], sigma_px: float | None = None,
                      sigma_name: str = "sigma") -> str:
    """Residual vectors (du, dv) in px as dots (flagged ones red), with circles at 1 and 3 x ``sigma_px``."""
    size = 300
    pts = [(lab, du, dv, bad) for lab, du, dv, bad in points if _finite(du) and _finite(dv)]
    extent = max([abs(du) for _, du, _, _ in pts] + [abs(dv) for _, _, dv, _ in pts] +
                 [3 * sigma_px if _finite(sigma_px) else 0, 1e-6])
    top = _nice_max(extent * 1.1)
    c, half = size / 2, size / 2 - 30
    s = half / top
    parts = [f'<line x1="{c - half}" x2="{c + half}" y1="{c}" y2="{c}" stroke="#bbb"/>',
             f'<line x1="{c}" x2="{c}" y1="{c - half}" y2="{c + half}" stroke="#bbb"/>',
             f'<text x="{c + half}" y="{c - 4}" text-anchor="end" font-size="10" font-family="sans-serif">'
             f'du +{top:g} px</text>',
             f'<text x="{c + 4}" y="{c + half}" font-size="10" font-family="sans-serif">dv +{top:g} px</text>']
    if _finite(sigma_px):
        for k in (1, 3):
            parts.append(f'<circle cx="{c}" cy="{c}" r="{k * sigma_px * s:.1f}" fill="none" stroke="{GREY}" '
                         f'stroke-dasharray="4,3"><title>{k} x {escape(sigma_name)} ({k * sigma_px:.2f} px)</title></circle>')
    for lab, du, dv, bad in pts:
        parts.append(f'<circle cx="{c + du * s:.1f}" cy="{c + dv * s:.1f}" r="4" fill="{BAD if bad else GOOD}">'
                     f'<title>{escape(str(lab))}: du {du:+.2f}, dv {dv:+.2f} px</title></circle>')
    return _frame(title, "".join(parts), size, size)


def sigma_chart(title: str, names: list[str], sigma1: list, unit: str) -> str:
    """Horizontal bars: 1-sigma (dark) and 3-sigma (light) per axis."""
    vals = [v if _finite(v) else None for v in sigma1]
    top = _nice_max(4.5 * max([v for v in vals if v is not None] + [1e-12]))
    w, h = 420, 40 + 26 * len(names)
    left, right = 90, 20
    sx = (w - left - right) / top
    parts = []
    for i, (n, v) in enumerate(zip(names, vals)):
        yy = 32 + 26 * i
        parts.append(f'<text x="{left - 6}" y="{yy + 13}" text-anchor="end" font-size="11" '
                     f'font-family="sans-serif">{escape(n)}</text>')
        if v is None:
            parts.append(f'<text x="{left}" y="{yy + 13}" font-size="11" font-family="sans-serif">n/a</text>')
            continue
        parts.append(f'<rect x="{left}" y="{yy}" width="{3 * v * sx:.1f}" height="18" fill="#9ecae1">'
                     f'<title>3-sigma {3 * v:.3g} {escape(unit)}</title></rect>'
                     f'<rect x="{left}" y="{yy}" width="{v * sx:.1f}" height="18" fill="{GOOD}">'
                     f'<title>1-sigma {v:.3g} {escape(unit)}</title></rect>'
                     f'<text x="{left + 3 * v * sx + 4:.1f}" y="{yy + 13}" font-size="10" font-family="sans-serif">'
                     f'{v:.3g} / {3 * v:.3g} {escape(unit)}</text>')
    return _frame(title, "".join(parts), w, h)
