"""The editor's state and its frame loop.

`EditorApp` owns the open document, the view, the tools' settings, the voxel cache, the live render and the
viewport. Its parts own the rest: `files` (open, save, exports), `jobs` (work in the background), `reference` (the
path-traced reference), `autosave` (recovery after a crash) and `photo` (the Photo tab). Panels, viewport tools and
replay files call their commands; every failure becomes a message in the window and the scene stays as it was.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.editor import edits, state
from app.editor.autosave import Autosave
from app.editor.document import Document
from app.editor.files import FileCommands
from app.editor.frame_stats import FrameStats
from app.editor.jobs import JobRunner
from app.editor.orbit_view import HOME, framed, looking_from
from app.editor.photo_tool import PhotoTool
from app.editor.reference import ReferenceRender
from app.editor.render_panel import DETAIL_DELAY_S, LiveRender, RenderedFrame
from app.editor.viewport import ViewportRenderer
from app.editor.window import Screenshots, Window, upload_image
from renderer.camera import Camera
from renderer.errors import InputError
from renderer.scene import PaintOp, Scene
from renderer.surface import occupancy
from renderer.transform import OBJECT_BOX_MAX, OBJECT_BOX_MIN, apply_transform, object_to_world
from renderer.voxel_cache import VoxelCache, source_key

FRAME_SECONDS = 1.0 / 60.0  # the loop sleeps to this pace so the render thread gets the CPU it needs
MESSAGE_SECONDS = 8.0
PALETTE = (
    (0.90, 0.30, 0.25), (0.95, 0.60, 0.20), (0.95, 0.85, 0.30), (0.45, 0.75, 0.35), (0.25, 0.60, 0.55),
    (0.30, 0.50, 0.85), (0.55, 0.40, 0.80), (0.85, 0.45, 0.65), (0.55, 0.38, 0.25), (0.95, 0.95, 0.93),
    (0.60, 0.60, 0.62), (0.15, 0.15, 0.17),
)


@dataclass
class Message:
    text: str
    error: bool
    shown_at: float = field(default_factory=time.monotonic)


@dataclass
class Prompt:
    """A question the window asks before going on (unsaved changes, restoring an autosave)."""

    title: str
    text: str
    choices: tuple[str, ...]
    on_choice: Callable[[str], None]


class EditorApp:
    """The editor: one document, its voxels, the live render, the viewport and the tools' settings."""

    def __init__(self, window: Window, document: Document, model_path: str | None = None, renderer: str = "nvr+",
                 quality: str = "full", recovery_slot: str = state.RECOVERY, detail_delay: float = DETAIL_DELAY_S):
        """`recovery_slot`: where the autosave is kept and looked for (state.HEADLESS_RECOVERY for scripted runs);
        `detail_delay`: how long a settled render stands before it is drawn again at the panel's size (scripted runs:
        0, as they wait for the editor to be idle between actions anyway)."""
        self.window = window
        self.doc = document
        self.voxels = VoxelCache()
        self.live = LiveRender(self.voxels, model_path, renderer, quality, detail_delay)
        self.viewport = ViewportRenderer(window.ctx)
        self.view = HOME
        self.render_texture = None
        self.shown_frame: RenderedFrame | None = None
        self.render_uploads = 0  # counts the images written to render_texture, so the window knows when it changed
        self.floor_color = document.scene.floor.color
        self.tool = "select"  # or "paint"; the bucket works only while the Paint tab shows (bucket_active)
        self.tools_tab = "Object"  # the tools panel's open tab, as drawn last frame
        self.requested_tab: str | None = None  # a tab to open on the next frame (a replay's "tool" action)
        self.paint_color: tuple[float, float, float] = PALETTE[0]
        self.tolerance = 0.1
        self.similarity = "perceptual"  # how the bucket compares colors (renderer.paint; "rgb" as before)
        self.message: Message | None = None
        self.prompt: Prompt | None = None
        self.stats = FrameStats()
        self.quit_requested = False
        self._synced = -1  # document revision the viewport and render were last updated for
        self.shown_rgba = None  # the painted voxels the viewport shows (for picking)
        self.shown_source = None  # their object's source_key: paint on it keeps the viewport's faces
        self.shown_occupancy = None  # their occupancy (for picking; paint keeps it, and it is slow to find)
        self.unloadable_source = None  # the object (mesh or voxels file) that failed to load, if any
        # Its parts, each with its own commands (a selection of objects will join them).
        self.jobs = JobRunner(self.say)
        self.screenshots = Screenshots(window, self.say)
        self.files = FileCommands(self)
        self.reference = ReferenceRender(self)
        self.photo = PhotoTool(self)  # the Photo tab's photo being aligned, and its commands
        self.autosave = Autosave(self, recovery_slot)
        self.autosave.offer_recovery()

    @property
    def bucket_active(self) -> bool:
        """The bucket fills on a click only where the user can see it is chosen: with the Paint tab open."""
        return self.tool == "paint" and self.tools_tab == "Paint"

    # --- messages and prompts ---------------------------------------------------------------

    def say(self, text: str, error: bool = False) -> None:
        """Show a one-line message in the status bar (errors in red, and on stderr)."""
        self.message = Message(text, error)
        if error:
            print(f"nvr-editor: {text}", file=sys.stderr)

    def ask(self, title: str, text: str, choices: tuple[str, ...], on_choice: Callable[[str], None]) -> None:
        """Ask a question in a modal window; `on_choice` gets the chosen answer."""
        self.prompt = Prompt(title, text, choices, on_choice)

    def answer(self, choice: str) -> None:
        """Answer the open prompt (from its buttons or a replay file)."""
        prompt, self.prompt = self.prompt, None
        if prompt is None or choice not in prompt.choices:
            self.say(f"no question to answer with {choice!r}", error=True)
            return
        prompt.on_choice(choice)

    # --- edits ------------------------------------------------------------------------------

    @property
    def scene(self) -> Scene:
        return self.doc.scene

    def edit(self, make_scene: Callable[[Scene], Scene], preview: bool = False) -> bool:
        """Apply `make_scene(current scene)`: shown as a preview, or committed as one undo step."""
        try:
            scene = make_scene(self.doc.scene)
        except InputError as exc:
            self.say(str(exc), error=True)
            return False
        if self.message is not None and self.message.error:
            self.message = None  # the error is over once an edit succeeds
        if preview:
            self.doc.preview(scene)
            return True
        return self.doc.commit(scene)

    def commit_preview(self) -> None:
        if self.doc.previewing:
            self.doc.commit()

    def cancel_preview(self) -> None:
        self.doc.cancel_preview()

    def view_through_render_camera(self) -> None:
        """The viewport looks through the camera that renders the image (its elevation, 40 mm, distance 2.8)."""
        self.view = Camera.from_scene(self.scene)

    def reset_view(self) -> None:
        self.view = HOME

    def look_from(self, side: str) -> None:
        """The viewport looks from the front, back, right, left, top or bottom (orbit_view.VIEWS), as numpad keys do."""
        self.view = looking_from(self.view, side)

    def frame_object(self) -> None:
        """The viewport aims at the object and comes as close as shows all of it (F)."""
        corners = np.array([[x, y, z] for x in (OBJECT_BOX_MIN[0], OBJECT_BOX_MAX[0])
                            for y in (OBJECT_BOX_MIN[1], OBJECT_BOX_MAX[1]) for z in (OBJECT_BOX_MIN[2], OBJECT_BOX_MAX[2])])
        world = apply_transform(object_to_world(self.scene.object), corners)
        centre = world.mean(axis=0)
        self.view = framed(self.view, centre, float(np.linalg.norm(world - centre, axis=1).max()))

    def undo(self) -> None:
        if not self.doc.undo():
            self.say("nothing to undo")

    def redo(self) -> None:
        if not self.doc.redo():
            self.say("nothing to redo")

    def paint_region(self, seed: tuple[int, int, int]) -> None:
        """Bucket fill: the connected region of similar color around voxel `seed` takes the palette color."""
        op = PaintOp("region", tuple(self.paint_color), tuple(int(s) for s in seed), float(self.tolerance),
                     self.similarity)
        rgba, _ = self.voxels.painted(self.scene)
        if not (all(0 <= s < rgba.shape[0] for s in op.seed) and rgba[op.seed][3] >= 0.5):
            self.say(f"voxel {list(op.seed)} is not part of the object", error=True)
            return
        self.edit(lambda s: edits.paint(s, op))

    def pick_color(self, voxel: tuple[int, int, int]) -> None:
        """The eyedropper (Alt+click with the bucket): the palette color becomes the voxel's, as it shows now."""
        rgba, _ = self.voxels.painted(self.scene)
        if not (all(0 <= v < rgba.shape[0] for v in voxel) and rgba[tuple(voxel)][3] >= 0.5):
            self.say(f"voxel {list(voxel)} is not part of the object", error=True)
            return
        self.paint_color = tuple(round(float(c), 4) for c in rgba[tuple(voxel)][:3])
        self.say("picked {:.2f}, {:.2f}, {:.2f} (sRGB)".format(*self.paint_color))

    def fill_object(self) -> None:
        self.edit(lambda s: edits.paint(s, PaintOp("object", tuple(self.paint_color))))

    def fill_floor(self) -> None:
        self.edit(lambda s: edits.paint(s, PaintOp("floor", tuple(self.paint_color))))

    def choose_renderer(self, renderer: str) -> None:
        """Show (and export) `renderer`'s image from now on; the scene is rendered again."""
        try:
            self.live.select(renderer)
        except InputError as exc:
            self.say(str(exc), error=True)
            return
        self.shown_frame = None
        self._synced = -1  # submit the scene again
        self.say(f"rendering with {self.live.label}")

    def replace_document(self, document: Document) -> None:
        """Edit `document` from now on (Open, New, a restored autosave)."""
        self.doc = document
        self.photo = PhotoTool(self)  # a photo aligned to the old scene's object does not carry over
        self.reference.close()  # nor a reference render of the old scene
        self._synced = -1
        self.autosave.reset()

    # --- the frame loop ---------------------------------------------------------------------

    @property
    def synced(self) -> bool:
        """Whether the viewport and the render were last brought up to date for the document as it is."""
        return self._synced == self.doc.revision

    @property
    def busy(self) -> str | None:
        """What is still under way (a job, a render, a scene not yet shown), or None when all is done."""
        if self.jobs.current is not None:
            return self.jobs.current.title
        if not self.live.idle:
            return "rendering"
        if not self.synced or self.shown_frame is None or self.shown_frame.scene != self.scene:
            return "showing the latest edit"
        return None

    def request_quit(self) -> None:
        """Close the window, asking first about unsaved changes."""
        if not self.doc.dirty:
            self.quit_requested = True
            return

        def choose(choice: str) -> None:
            if choice == "Save" and not self.files.save():
                return
            if choice in ("Save", "Discard"):
                self.autosave.keep_on_close = False
                self.quit_requested = True

        choices = ("Save", "Discard", "Cancel") if self.doc.path else ("Discard", "Cancel")
        self.ask("Unsaved changes", "Save the scene before closing?", choices, choose)

    def update(self) -> None:
        """Once per frame, before drawing: finish jobs, bring viewport and render up to date, autosave."""
        self.jobs.finish()
        if not self.synced:
            self._sync()
        self.photo.follow_object()
        self.live.refine()
        frame = self.live.poll()
        if frame is not None:
            if not frame.detail:  # a detail frame redraws the shown one larger: its status and timings stay
                self.shown_frame = frame
                self.stats.renders.append(frame.seconds)
            self.render_texture = upload_image(self.window.ctx, self.render_texture, frame.image)
            self.render_uploads += 1
        if self.live.error:
            self.say(self.live.error, error=True)
            self.live.error = None
        self.autosave.tick()

    def _sync(self) -> None:
        """Show the document's scene: upload its voxels (voxelising in the background first if needed), render it."""
        scene = self.doc.scene
        if not self.voxels.has_object(scene):
            if self.jobs.current is not None:
                return  # voxelising (or another job): the scene is shown when it is done
            if source_key(scene) == self.unloadable_source:  # its error is shown; retried only once the object changes
                self._synced = self.doc.revision
            else:
                self.unloadable_source = source_key(scene)  # until the job succeeds
                self.jobs.start(f"Loading {Path(scene.object.mesh or scene.object.voxels).name}",
                                lambda progress: self.voxels.object_rgba(scene, progress), self._object_loaded)
            return
        try:
            rgba, self.floor_color = self.voxels.painted(scene)
        except InputError as exc:
            self.say(str(exc), error=True)
            self._synced = self.doc.revision
            return
        if rgba is not self.shown_rgba:
            source = source_key(scene)
            if self.shown_source == source and self.shown_rgba is not None:
                self.viewport.recolor(rgba)  # paint: the same object's voxels, other colors
            else:
                self.viewport.set_voxels(rgba)
                self.shown_occupancy = occupancy(rgba)
            self.shown_rgba, self.shown_source = rgba, source
        self.live.submit(scene, preview=self.doc.previewing)
        self._synced = self.doc.revision

    def _object_loaded(self, _rgba) -> None:
        self.unloadable_source = None
        self.warn_missing_materials(self.scene.mesh_path())

    def warn_missing_materials(self, mesh: Path | None) -> None:
        """Say that the mesh's material file is missing, unless the scene colors the object itself (then it does not
        matter)."""
        from renderer.mesh import missing_material_files

        missing = missing_material_files(mesh) if mesh and self.scene.object.color is None else []
        if missing:
            self.say(f"{mesh.name}: material file {', '.join(missing)} not found: the mesh is grey", error=True)

    def close(self) -> None:
        """On quitting: keep an autosave of unsaved changes unless the user chose to discard them."""
        self.autosave.close()
        self.live.close()
