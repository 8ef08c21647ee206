"""Where each panel sits in the window: viewport on the left, live render top right, tools below it.

A layout computed from the window size and the right column's width (the user drags the border between the
columns), so headless screenshots are reproducible and tests know where to look.
"""

from __future__ import annotations

from dataclasses import dataclass

MENU_HEIGHT = 22
STATUS_HEIGHT = 26
RIGHT_WIDTH = 440  # the right column's width until the user drags the border
MIN_RIGHT_WIDTH = 300
MIN_VIEWPORT_WIDTH = 300
RENDER_HEIGHT = 478
RENDER_HEADER = 48  # the render panel's title bar and its status line, above the image
PADDING = 8


@dataclass(frozen=True)
class Rect:
    x: int
    y: int
    width: int
    height: int


@dataclass(frozen=True)
class Layout:
    viewport: Rect  # the 3D view fills it
    render: Rect  # the live render panel
    render_image: Rect  # where the render's image is drawn (square)
    tools: Rect
    status: Rect


def layout_for(width: int, height: int, right_width: int = RIGHT_WIDTH) -> Layout:
    """Panel rectangles (window pixels, y down) for a window of `width` x `height` whose right column is about
    `right_width` wide (at least MIN_RIGHT_WIDTH, leaving the viewport MIN_VIEWPORT_WIDTH; a small window halves). The render panel grows with the column, up to two thirds of the window's height."""
    right = max(min(right_width, width - MIN_VIEWPORT_WIDTH), min(MIN_RIGHT_WIDTH, width // 2))
    body = height - MENU_HEIGHT - STATUS_HEIGHT
    render_height = min(RENDER_HEIGHT + max(right - RIGHT_WIDTH, 0), body * 2 // 3)
    side = max(1, min(right - 2 * PADDING, render_height - RENDER_HEADER - PADDING))
    return Layout(
        viewport=Rect(0, MENU_HEIGHT, width - right, body),
        render=Rect(width - right, MENU_HEIGHT, right, render_height),
        render_image=Rect(width - right + (right - side) // 2, MENU_HEIGHT + RENDER_HEADER, side, side),
        tools=Rect(width - right, MENU_HEIGHT + render_height, right, body - render_height),
        status=Rect(0, height - STATUS_HEIGHT, width, STATUS_HEIGHT),
    )
