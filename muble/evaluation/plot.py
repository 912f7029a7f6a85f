"""Charts of success rates: a bar chart of one run (Pillow), and the rates of several runs side by side with their
95% intervals (matplotlib)."""
from __future__ import annotations

import io

from PIL import Image, ImageDraw, ImageFont

_BAR = (52, 101, 164)
_OVERALL_BAR = (204, 102, 0)
_AXIS = (60, 60, 60)
_GRID = (225, 225, 225)
# One colour per run of a comparison, in order (a colour-blind-safe qualitative palette), then repeated.
_RUN_COLOURS = [(0, 114, 178), (230, 159, 0), (0, 158, 115), (204, 121, 167), (86, 180, 233), (213, 94, 0),
                (240, 228, 66), (0, 0, 0)]


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has only the fixed bitmap font
        return ImageFont.load_default()


def _label_height(names: list[str], font) -> int:
    draw = ImageDraw.Draw(Image.new("L", (1, 1)))
    return max([int(draw.textlength(n, font=font)) for n in names] + [0])


def _rotated_label(img: Image.Image, name: str, x_centre: float, y_top: int, label_h: int, font) -> None:
    """``name`` written upwards, right-aligned to ``y_top``, centred on ``x_centre``: long template names fit
    under narrow columns. Drawn on its own transparent strip, then turned 90 degrees."""
    strip = Image.new("RGBA", (label_h + 4, 20), (255, 255, 255, 0))
    ImageDraw.Draw(strip).text((label_h + 2, 10), name, fill=_AXIS, font=font, anchor="rm")
    turned = strip.rotate(90, expand=True)
    img.paste(turned, (int(x_centre - 10), y_top), turned)


def _percent_axis(draw: ImageDraw.ImageDraw, left: int, right: int, top: int, plot_h: int, font) -> None:
    y0 = top + plot_h
    for pct in range(0, 101, 20):
        y = y0 - plot_h * pct / 100
        draw.line([(left, y), (right, y)], fill=_GRID if pct else _AXIS)
        draw.text((left - 8, y), f"{pct}%", fill=_AXIS, font=font, anchor="rm")
    draw.line([(left, top), (left, y0)], fill=_AXIS)


def _png(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def success_bar_chart(rates: dict[str, float], title: str, highlight: str | None = "overall") -> bytes:
    """PNG bytes of one vertical bar per entry of ``rates`` (fractions in [0, 1]), labelled with percentages.

    Labels are written rotated under the bars so long template names fit; ``highlight`` gets its own colour.
    """
    names = list(rates)
    bar_w, gap, left, top, plot_h = 48, 20, 70, 50, 300
    label_font, small, title_font = _font(14), _font(12), _font(18)
    label_h = _label_height(names, label_font)
    width = left + len(names) * (bar_w + gap) + gap
    height = top + plot_h + label_h + 30
    width = max(width, 360)
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    draw.text((left, 12), title, fill=_AXIS, font=title_font)
    y0 = top + plot_h
    _percent_axis(draw, left, width - 10, top, plot_h, small)
    for i, name in enumerate(names):
        rate = min(max(float(rates[name]), 0.0), 1.0)
        x = left + gap + i * (bar_w + gap)
        colour = _OVERALL_BAR if name == highlight else _BAR
        if rate > 0:
            draw.rectangle([x, y0 - plot_h * rate, x + bar_w, y0], fill=colour)
        draw.text((x + bar_w / 2, y0 - plot_h * rate - 4), f"{100 * rate:.0f}%", fill=_AXIS, font=small,
                  anchor="mb")
        _rotated_label(img, name, x + bar_w / 2, y0 + 6, label_h, label_font)
    return _png(img)


def interval_chart(groups: dict[str, dict[str, tuple[float, float, float] | None]], title: str) -> bytes:
    """PNG bytes of several runs' success rates per group (task type), drawn with matplotlib:
    ``groups[group][run] = (rate, low, high)``, fractions in [0, 1], or None where the run has no episode of that
    group. Each run is a dot at its rate with an error bar from ``low`` to ``high`` (its 95% interval), in its own
    colour, side by side within the group; a legend names the runs. Overlapping bars are the eye's first test of a
    difference; the paired test is in the text."""
    import matplotlib

    matplotlib.use("Agg")  # files only, never a display
    from matplotlib.figure import Figure

    names = list(groups)
    runs = list(dict.fromkeys(run for per_run in groups.values() for run in per_run))
    fig = Figure(figsize=(max(6.0, 0.9 * len(names) + 2.5), 4.8), dpi=110)
    ax = fig.add_subplot()
    width = 0.8 / max(len(runs), 1)
    for k, run in enumerate(runs):
        xs, ys, lows, highs = [], [], [], []
        for g, group in enumerate(names):
            value = groups[group].get(run)
            if value is None:
                continue
            rate, low, high = value
            xs.append(g - 0.4 + width * (k + 0.5))
            ys.append(100 * rate)
            lows.append(100 * (rate - low))
            highs.append(100 * (high - rate))
        colour = tuple(c / 255 for c in _RUN_COLOURS[k % len(_RUN_COLOURS)])
        ax.errorbar(xs, ys, yerr=[lows, highs], fmt="o", color=colour, capsize=3, label=run)
    ax.set_xticks(range(len(names)), names, rotation=35, ha="right", fontsize=8)
    ax.set_ylim(-2, 102)
    ax.set_ylabel("success rate (%), 95% Wilson interval")
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", color="#e1e1e1")
    ax.set_axisbelow(True)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
