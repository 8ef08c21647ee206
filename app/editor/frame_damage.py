"""Which parts of the window a new frame changes, so that only they are drawn again and shown.

With software OpenGL, drawing the whole interface is a large share of a frame (docs/results.md, "Measurements behind the code"). A frame is summed
up by a digest and the bounding box of the vertices of each ImGui draw list, plus the versions of the images
the interface shows (the viewport under it, the render in it). Comparing that summary with
the one of the frame on screen gives the boxes to draw again: none (the frame looks the
same), a few, or the whole window.
"""

from __future__ import annotations

import ctypes
import hashlib
from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import numpy as np
from imgui_bundle import imgui

Box = tuple[int, int, int, int]  # x0, y0, x1, y1: window pixels, y down, x1 and y1 excluded
# sizeof(ImDrawVert): position and uv (4 floats), color (uint32); sizeof(ImDrawIdx): imgui_bundle builds ImGui with 32-bit indices
VERTEX_BYTES, INDEX_BYTES = 20, 4
MAX_BOXES = 4  # more changed boxes than this: draw the whole window


@dataclass(frozen=True)
class FrameSummary:
    size: tuple[int, int]  # the window's framebuffer
    lists: tuple[tuple[bytes, Box | None], ...]  # each draw list: digest, box of what it may draw (None: nothing)
    images: tuple[tuple[Box, Hashable], ...]  # where each image is shown, and its version


def summarize(draw_data: imgui.ImDrawData, size: tuple[int, int], images: Sequence[tuple[Box, Hashable]]) -> FrameSummary:
    """The summary of the frame ImGui is about to draw. Every texture it uses must have been uploaded."""
    return FrameSummary(tuple(size), tuple(_list_summary(draw_list) for draw_list in draw_data.cmd_lists), tuple(images))


def _list_summary(draw_list: imgui.ImDrawList) -> tuple[bytes, Box | None]:
    """A digest of a draw list (vertices, indices, each command's clip rectangle and texture) and the box around its
    vertices: its triangles, and so every pixel it draws, lie inside it."""
    vertices, indices = draw_list.vtx_buffer, draw_list.idx_buffer
    vertex_bytes = ctypes.string_at(vertices.data_address(), vertices.size() * VERTEX_BYTES)
    digest = hashlib.blake2b(vertex_bytes)
    digest.update(ctypes.string_at(indices.data_address(), indices.size() * INDEX_BYTES))
    for command in draw_list.cmd_buffer:
        clip = command.clip_rect
        digest.update(repr((clip.x, clip.y, clip.z, clip.w, command.get_tex_id(), command.elem_count,
                            command.idx_offset, command.vtx_offset)).encode())
    if not vertices.size():
        return digest.digest(), None
    positions = np.frombuffer(vertex_bytes, np.float32).reshape(-1, VERTEX_BYTES // 4)[:, :2]
    (x0, y0), (x1, y1) = positions.min(axis=0), positions.max(axis=0)
    return digest.digest(), (int(np.floor(x0)), int(np.floor(y0)), int(np.ceil(x1)) + 1, int(np.ceil(y1)) + 1)


def changed_boxes(shown: FrameSummary | None, frame: FrameSummary) -> list[Box] | None:
    """Boxes to draw again for the screen to show `frame` instead of `shown`: [] when both look the same, None for all.

    A pixel outside the boxes is drawn by the same draw lists, unchanged, from unchanged images,
    so it keeps its color. A draw list that changed marks both its old and its new box.
    """
    if (shown is None or shown.size != frame.size or len(shown.lists) != len(frame.lists)
            or [box for box, _ in shown.images] != [box for box, _ in frame.images]):
        return None
    boxes = [box for (old_digest, old_box), (new_digest, new_box) in zip(shown.lists, frame.lists)
             if old_digest != new_digest for box in (old_box, new_box) if box is not None]
    boxes += [box for (box, old), (_, new) in zip(shown.images, frame.images) if old != new]
    window = (0, 0, *frame.size)
    merged = merge([inside for box in boxes if (inside := intersection(box, window)) is not None])
    return None if len(merged) > MAX_BOXES else merged


def union(a: Box | None, b: Box) -> Box:
    return b if a is None else (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


def intersection(a: Box, b: Box) -> Box | None:
    box = (max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3]))
    return box if box[0] < box[2] and box[1] < box[3] else None


def merge(boxes: Sequence[Box]) -> list[Box]:
    """Boxes that overlap replaced by the box around them, until none overlap."""
    merged: list[Box] = []
    for box in boxes:
        while True:
            touching = [other for other in merged if intersection(box, other) is not None]
            if not touching:
                break
            for other in touching:
                merged.remove(other)
                box = union(box, other)
        merged.append(box)
    return merged
