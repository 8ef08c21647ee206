"""The speed-against-error figure of `nvr bench`, drawn with PIL: error against time on log axes, Pareto front marked.

A point is on the Pareto front when no other point is at least as fast and at least as accurate
and strictly better in one of the two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

from models.renderers import RENDERERS
from renderer.io import atomic_path

WIDTH, HEIGHT = 1100, 760
MARGIN_LEFT, MARGIN_RIGHT, MARGIN_TOP, MARGIN_BOTTOM = 90, 30, 50, 70
KEY_ROW = 18  # pixels per row of the key below the plot (labels that found no place beside their points)
LABEL_HEIGHT = 16  # pixels of a label's line
POINT_RADIUS = 6  # pixels
LEADER_FROM = 12  # pixels between a point and its label's box beyond which a line joins them
# Each renderer's color in the plots, by its label in models/renderers.py.
FAMILY_COLORS = {RENDERERS[name].label: color for name, color in (
    ("pathtrace", (200, 80, 40)), ("splat", (60, 140, 60)), ("shaded", (200, 150, 0)), ("nvr", (70, 110, 200)),
    ("nvr+", (130, 60, 170)))}


@dataclass(frozen=True)
class Point:
    label: str
    family: str  # a key of FAMILY_COLORS
    ms: float
    error: float


def pareto_front(points: list[Point]) -> list[Point]:
    """The non-dominated points, fastest first."""
    front = [p for p in points if not any(_dominates(q, p) for q in points)]
    return sorted(front, key=lambda p: (p.ms, p.error))


def _dominates(q: Point, p: Point) -> bool:
    return q.ms <= p.ms and q.error <= p.error and (q.ms < p.ms or q.error < p.error)


def draw_speed_vs_error(points: list[Point], path: str | Path, error_name: str = "MSE (0-255)") -> None:
    """Write the figure as PNG (atomically); points need positive time and error. A label that finds no free place
    next to its point becomes a number there, keyed below the plot."""
    points = [p for p in points if p.ms > 0 and p.error > 0]
    font = ImageFont.load_default(size=14)
    if not points:
        image = Image.new("RGB", (WIDTH, HEIGHT), "white")
        ImageDraw.Draw(image).text((WIDTH // 3, HEIGHT // 2), "no renderer with an error measurement", fill="black",
                                   font=font)
    else:
        x_axis = _LogAxis(min(p.ms for p in points), max(p.ms for p in points), MARGIN_LEFT, WIDTH - MARGIN_RIGHT)
        y_axis = _LogAxis(min(p.error for p in points), max(p.error for p in points), HEIGHT - MARGIN_BOTTOM, MARGIN_TOP)
        centres = [(x_axis(p.ms), y_axis(p.error)) for p in points]
        labels = _place_labels(points, centres, font)
        keyed = [(text, p) for p, (text, _, _) in zip(points, labels) if text != p.label]
        key_rows = math.ceil(len(keyed) / 2)
        image = Image.new("RGB", (WIDTH, HEIGHT + (KEY_ROW * key_rows + 10 if keyed else 0)), "white")
        draw = ImageDraw.Draw(image)
        _draw_axes(draw, font, x_axis, y_axis, error_name)
        front = pareto_front(points)
        xy = [(x_axis(p.ms), y_axis(p.error)) for p in front]
        for (x0, y0), (x1, y1) in zip(xy, xy[1:]):  # staircase: nothing below and left of it
            draw.line([(x0, y0), (x1, y0), (x1, y1)], fill=(120, 120, 120), width=2)
        for p, (x, y), (text, left, top) in zip(points, centres, labels):
            color = FAMILY_COLORS.get(p.family, (0, 0, 0))
            r = POINT_RADIUS
            draw.ellipse([x - r, y - r, x + r, y + r], fill=color if p in front else "white", outline=color, width=2)
            draw.text((left, top), text, fill=color, font=font)
            leader = _leader(x, y, (left, top, left + font.getlength(text), top + LABEL_HEIGHT))
            if leader is not None:
                draw.line(leader, fill=color, width=1)
        for k, (number, p) in enumerate(keyed):
            left = MARGIN_LEFT + (k % 2) * (WIDTH - MARGIN_LEFT - MARGIN_RIGHT) // 2
            draw.text((left, HEIGHT + 5 + KEY_ROW * (k // 2)), f"{number}: {p.label}",
                      fill=FAMILY_COLORS.get(p.family, (0, 0, 0)), font=font)
        _draw_legend(draw, font)
    with atomic_path(path) as tmp:
        image.save(tmp, format="PNG")


def _leader(x: float, y: float, box: tuple[float, float, float, float]) -> tuple[float, float, float, float] | None:
    """A line from the edge of the point's circle at (x, y) to the nearest point of its label's box (left, top, right,
    bottom), where the label does not touch the circle: a label set further out is not read as a nearer point's."""
    left, top, right, bottom = box
    nx, ny = min(max(x, left), right), min(max(y, top), bottom)
    distance = math.hypot(nx - x, ny - y)
    if distance <= LEADER_FROM:
        return None
    return x + (nx - x) * POINT_RADIUS / distance, y + (ny - y) * POINT_RADIUS / distance, nx, ny


def _place_labels(points: list[Point], centres: list[tuple[float, float]], font) -> list[tuple[str, float, float]]:
    """(text, left, top) per point: its label beside it where that covers no other label or point and stays inside
    the plot, else a number (1, 2, ... in the order of the points) beside it."""
    taken = [(x - 7, y - 7, x + 7, y + 7) for x, y in centres]  # the points' circles
    placed, numbers = [], 0
    for p, (x, y) in zip(points, centres):
        spot = _free_spot(p.label, x, y, font, taken)
        text = p.label
        if spot is None:
            numbers += 1
            text = str(numbers)
            spot = _free_spot(text, x, y, font, taken, anywhere=True)
        left, top = spot
        taken.append((left, top, left + font.getlength(text), top + LABEL_HEIGHT))
        placed.append((text, left, top))
    return placed


def _free_spot(text: str, x: float, y: float, font, taken: list[tuple[float, float, float, float]],
               anywhere: bool = False) -> tuple[float, float] | None:
    """The first of a few places beside (x, y) where `text` fits inside the plot over nothing taken; None if none
    does (with `anywhere`, the first place instead)."""
    width = font.getlength(text)
    candidates = [(left, y + dy) for dy in (-16, 0, -32, 16, -48, 32) for left in (x + 9, x - 9 - width)]
    if anywhere:  # a short number: further out too, nearest first
        candidates += sorted(((x + dx, y + dy) for dx in range(-120, 121, 12) for dy in range(-112, 113, 16)),
                             key=lambda spot: math.hypot(spot[0] - x, spot[1] - y))
    for left, top in candidates:
        inside = MARGIN_LEFT < left and left + width < WIDTH - MARGIN_RIGHT and MARGIN_TOP < top and top + LABEL_HEIGHT < HEIGHT - MARGIN_BOTTOM
        if inside and not any(left < x1 and left + width > x0 and top < y1 and top + LABEL_HEIGHT > y0 for x0, y0, x1, y1 in taken):
            return left, top
    return candidates[0] if anywhere else None


class _LogAxis:
    """Maps values to pixels on a log scale from a little below lo to a little above hi."""

    MARGIN_DECADES = 0.15

    def __init__(self, lo: float, hi: float, start_px: float, end_px: float):
        self.lo = math.log10(lo) - self.MARGIN_DECADES
        self.hi = math.log10(hi) + self.MARGIN_DECADES
        self.start_px, self.end_px = start_px, end_px

    def __call__(self, value: float) -> float:
        t = (math.log10(value) - self.lo) / (self.hi - self.lo)
        return self.start_px + t * (self.end_px - self.start_px)

    def ticks(self) -> list[tuple[float, bool]]:
        """Grid values m * 10^d inside the axis, and whether each gets a label (m = 1, 2, 5)."""
        return [(m * 10.0**d, m in (1, 2, 5)) for d in range(math.floor(self.lo), math.ceil(self.hi) + 1)
                for m in range(1, 10) if self.lo <= math.log10(m * 10.0**d) <= self.hi]


def _draw_axes(draw: ImageDraw.ImageDraw, font, x_axis: _LogAxis, y_axis: _LogAxis, error_name: str) -> None:
    left, right, top, bottom = MARGIN_LEFT, WIDTH - MARGIN_RIGHT, MARGIN_TOP, HEIGHT - MARGIN_BOTTOM
    for value, labelled in x_axis.ticks():
        x = x_axis(value)
        draw.line([(x, top), (x, bottom)], fill=(210, 210, 210) if labelled else (238, 238, 238))
        if labelled:
            draw.text((x - 10, bottom + 8), f"{value:g}", fill="black", font=font)
    for value, labelled in y_axis.ticks():
        y = y_axis(value)
        draw.line([(left, y), (right, y)], fill=(210, 210, 210) if labelled else (238, 238, 238))
        if labelled:
            draw.text((left - 60, y - 8), f"{value:g}", fill="black", font=font)
    draw.rectangle([left, top, right, bottom], outline="black")
    draw.text(((left + right) // 2 - 120, bottom + 34), "time per frame at 256x256 (ms, log scale)", fill="black", font=font)
    draw.text((left, 15), f"{error_name} against a high-spp reference (log scale); filled and joined: Pareto front",
              fill="black", font=font)


def _draw_legend(draw: ImageDraw.ImageDraw, font) -> None:
    x, y = WIDTH - MARGIN_RIGHT - 150, MARGIN_TOP + 10
    for family, color in FAMILY_COLORS.items():
        draw.ellipse([x, y, x + 10, y + 10], fill=color)
        draw.text((x + 16, y - 3), family, fill=color, font=font)
        y += 20
