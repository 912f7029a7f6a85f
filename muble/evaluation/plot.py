"""A bar chart of success rates drawn with Pillow (no plotting library needed)."""
from __future__ import annotations

import io

from PIL import Image, ImageDraw, ImageFont

_BAR = (52, 101, 164)
_OVERALL_BAR = (204, 102, 0)
_AXIS = (60, 60, 60)
_GRID = (225, 225, 225)


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has only the fixed bitmap font
        return ImageFont.load_default()


def success_bar_chart(rates: dict[str, float], title: str, highlight: str | None = "overall") -> bytes:
    """PNG bytes of one vertical bar per entry of ``rates`` (fractions in [0, 1]), labelled with percentages.

    Labels are written rotated under the bars so long template names fit; ``highlight`` gets its own colour.
    """
    names = list(rates)
    bar_w, gap, left, top, plot_h = 48, 20, 70, 50, 300
    label_font, small, title_font = _font(14), _font(12), _font(18)
    label_h = max([int(ImageDraw.Draw(Image.new("L", (1, 1))).textlength(n, font=label_font)) for n in names] + [0])
    width = left + len(names) * (bar_w + gap) + gap
    height = top + plot_h + label_h + 30
    width = max(width, 360)
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    draw.text((left, 12), title, fill=_AXIS, font=title_font)
    y0 = top + plot_h
    for pct in range(0, 101, 20):
        y = y0 - plot_h * pct / 100
        draw.line([(left, y), (width - 10, y)], fill=_GRID if pct else _AXIS)
        draw.text((left - 8, y), f"{pct}%", fill=_AXIS, font=small, anchor="rm")
    draw.line([(left, top), (left, y0)], fill=_AXIS)
    for i, name in enumerate(names):
        rate = min(max(float(rates[name]), 0.0), 1.0)
        x = left + gap + i * (bar_w + gap)
        colour = _OVERALL_BAR if name == highlight else _BAR
        if rate > 0:
            draw.rectangle([x, y0 - plot_h * rate, x + bar_w, y0], fill=colour)
        draw.text((x + bar_w / 2, y0 - plot_h * rate - 4), f"{100 * rate:.0f}%", fill=_AXIS, font=small,
                  anchor="mb")
        # Rotated label: drawn on its own transparent strip, then turned 90 degrees.
        strip = Image.new("RGBA", (label_h + 4, 20), (255, 255, 255, 0))
        ImageDraw.Draw(strip).text((label_h + 2, 10), name, fill=_AXIS, font=label_font, anchor="rm")
        turned = strip.rotate(90, expand=True)
        img.paste(turned, (int(x + bar_w / 2 - 10), y0 + 6), turned)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()
