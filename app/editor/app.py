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
from renderer.scene import ObjectSpec, PaintOp, Scene, replaced
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


@dataclass(frozen=True)
class ShownObject:
    """An object as the viewport shows it: its painted voxels, what they were read from (source_key: paint on the
    same object keeps the viewport's faces) and their occupancy (for picking; paint keeps it, and it is slow to find)."""

    rgba: np.ndarray
    source: tuple
    occupancy: np.ndarray


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
        self.shown: list[ShownObject | None] = []  # per object, what the viewport shows (None: not loaded)
        self.unloadable: set[tuple] = set()  # objects (their source_key) whose mesh or voxels file failed to load
        self.submitted: Scene | None = None  # what the render was last asked for: the scene, less unloadable objects
        self.hidden: frozenset[int] = frozenset()  # objects the viewport does not draw (the object list's eye)
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

    @property
    def selected(self) -> int:
        """Index of the selected object: the one the Object, Paint and Photo tabs and G, R, S act on."""
        return self.doc.selected

    @property
    def selected_object(self) -> ObjectSpec:
        return self.scene.objects[self.doc.selected]

    def object_view(self, scene: Scene | None = None) -> Scene:
        """`scene` (default: the shown one) holding the selected object alone: what the object tools read."""
        scene = self.scene if scene is None else scene
        return scene.alone(min(self.doc.selected, len(scene.objects) - 1))

    def edit_object(self, make_scene: Callable[[Scene], Scene], preview: bool = False) -> bool:
        """`edit` the selected object: `make_scene` gets object_view(scene) and its result's object takes the selected
        one's place (the rest of its result, a floor fill's color say, is kept too)."""
        index = self.doc.selected

        def whole(scene: Scene) -> Scene:
            changed = make_scene(self.object_view(scene))
            return changed.with_changes(objects=scene.objects[:index] + (changed.object,) + scene.objects[index + 1:])

        return self.edit(whole, preview)

    def select(self, index: int) -> None:
        """Select object `index` (one undo step): the tools act on it from now on."""
        if not 0 <= index < len(self.scene.objects):
            self.say(f"no object {index}: the scene holds {len(self.scene.objects)}", error=True)
            return
        self.commit_preview()
        self.doc.select(index)

    def duplicate_selected(self) -> None:
        """A copy of the selected object beside it, selected (Shift+D): one undo step."""
        self.commit_preview()
        if self.edit(lambda s: edits.duplicate_object(s, self.selected), select=len(self.scene.objects)):
            self.say(f"duplicated as {edits.object_label(self.scene, self.selected)}")

    def delete_selected(self) -> None:
        """Delete the selected object (X, Delete): one undo step; the one before it is selected."""
        self.commit_preview()
        name, index = edits.object_label(self.scene, self.selected), self.selected
        if self.edit(lambda s: edits.delete_object(s, index), select=max(index - 1, 0)):
            self.say(f"deleted {name} (Ctrl+Z brings it back)")

    def toggle_hidden(self, index: int) -> None:
        """Hide object `index` from the viewport, or show it again (the render still shows it; not an undo step)."""
        self.hidden = self.hidden ^ {index}

    def rename_object(self, index: int, name: str) -> None:
        self.edit(lambda s: edits.rename_object(s, index, name))

    def add_object(self, path: str | Path, up: str = "y") -> None:
        """Voxelise a mesh (or read a MagicaVoxel model) in the background, then add it where the floor has room,
        selected: one undo step."""
        path = Path(path)
        if path.suffix.lower() == ".vox":
            self.files.import_vox(path, add=True)
            return
        try:
            candidate = edits.add_object(self.scene, ObjectSpec(mesh=str(path.resolve()), up=up))
        except InputError as exc:
            self.say(str(exc), error=True)
            return

        def done(_rgba) -> None:
            if self.edit(lambda s: edits.add_object(s, ObjectSpec(mesh=str(path.resolve()), up=up)),
                         select=len(self.scene.objects)):
                self.say(f"added {path.name}")
                self.warn_missing_materials(path, self.selected_object)

        one = candidate.alone(-1)
        self.jobs.start(f"Voxelising {path.name}", lambda progress: self.voxels.object_rgba(one, progress), done)

    def edit(self, make_scene: Callable[[Scene], Scene], preview: bool = False, select: int | None = None) -> bool:
        """Apply `make_scene(current scene)`: shown as a preview, or committed as one undo step (with object `select`
        selected in it, if given)."""
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
        return self.doc.commit(scene, select)

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
        world = apply_transform(object_to_world(self.selected_object), corners)
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
        rgba, _ = self.voxels.painted(self.object_view())
        if not (all(0 <= s < rgba.shape[0] for s in op.seed) and rgba[op.seed][3] >= 0.5):
            self.say(f"voxel {list(op.seed)} is not part of the object", error=True)
            return
        self.edit_object(lambda s: edits.paint(s, op))

    def pick_color(self, voxel: tuple[int, int, int]) -> None:
        """The eyedropper (Alt+click with the bucket): the palette color becomes the voxel's, as it shows now."""
        rgba, _ = self.voxels.painted(self.object_view())
        if not (all(0 <= v < rgba.shape[0] for v in voxel) and rgba[tuple(voxel)][3] >= 0.5):
            self.say(f"voxel {list(voxel)} is not part of the object", error=True)
            return
        self.paint_color = tuple(round(float(c), 4) for c in rgba[tuple(voxel)][:3])
        self.say("picked {:.2f}, {:.2f}, {:.2f} (sRGB)".format(*self.paint_color))

    def fill_object(self) -> None:
        self.edit_object(lambda s: edits.paint(s, PaintOp("object", tuple(self.paint_color))))

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
        if not self.synced or (self.submitted is not None and (self.shown_frame is None
                                                               or self.shown_frame.scene != self.submitted)):
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

    @property
    def shown_rgba(self) -> np.ndarray | None:
        """The selected object's painted voxels as the viewport shows them (the bucket's), None until loaded."""
        shown = self.shown[self.selected] if self.selected < len(self.shown) else None
        return None if shown is None else shown.rgba

    @property
    def shown_occupancy(self) -> np.ndarray | None:
        shown = self.shown[self.selected] if self.selected < len(self.shown) else None
        return None if shown is None else shown.occupancy

    @property
    def loaded_nothing(self) -> bool:
        """Whether no object of the scene could be loaded (and none is loading): there is nothing to show."""
        return (bool(self.unloadable) and self.jobs.current is None  # (checked every frame: no file calls before a failure)
                and all(source_key(one) in self.unloadable for one in self._object_views()))

    def _object_views(self, scene: Scene | None = None) -> list[Scene]:
        scene = self.doc.scene if scene is None else scene
        return [scene.alone(i) for i in range(len(scene.objects))]

    def _sync(self) -> None:
        """Show the document's scene: upload each object's voxels (voxelising in the background first if needed),
        render it. An object that cannot be loaded is named in a message and left out; the others are shown."""
        scene = self.doc.scene
        views = self._object_views(scene)
        for one in views:
            if not self.voxels.has_object(one) and source_key(one) not in self.unloadable:
                if self.jobs.current is None:
                    self.jobs.start(f"Loading {Path(one.object.mesh or one.object.voxels).name}",
                                    lambda progress, one=one: self.voxels.object_rgba(one, progress),
                                    lambda _rgba, one=one: self._object_loaded(one),
                                    on_error=lambda one=one: self.unloadable.add(source_key(one)))
                return  # voxelising (or another job): the scene is shown when it is done
        self.floor_color = scene.floor.color
        self.hidden = frozenset(i for i in self.hidden if i < len(views))
        self.viewport.keep_objects(len(views))
        self.shown = (self.shown + [None] * len(views))[:len(views)]
        drawn = []
        for index, one in enumerate(views):
            if source_key(one) in self.unloadable:
                self.viewport.forget(index)
                self.shown[index] = None
                continue
            try:
                rgba, _ = self.voxels.painted(one)
            except InputError as exc:
                self.say(str(exc), error=True)
                self._synced = self.doc.revision
                return
            self._show_object(index, one, rgba)
            drawn.append(one.object)
        self.submitted = None
        if drawn:
            self.submitted = scene if len(drawn) == len(views) else replaced(scene, objects=tuple(drawn))
            self.live.submit(self.submitted, preview=self.doc.previewing)
        self._synced = self.doc.revision

    def _show_object(self, index: int, one: Scene, rgba: np.ndarray) -> None:
        """Object `index` (`one`: the scene holding it alone) in the viewport with its painted voxels `rgba`."""
        shown, source = self.shown[index], source_key(one)
        if shown is not None and shown.rgba is rgba:
            return
        if shown is not None and shown.source == source:
            self.viewport.recolor(rgba, index=index)  # paint: the same object's voxels, other colors
            self.shown[index] = ShownObject(rgba, source, shown.occupancy)
        else:
            self.viewport.set_voxels(rgba, index)
            self.shown[index] = ShownObject(rgba, source, occupancy(rgba))

    def _object_loaded(self, one: Scene) -> None:
        self.warn_missing_materials(one.mesh_path(), one.object)

    def warn_missing_materials(self, mesh: Path | None, obj: ObjectSpec | None = None) -> None:
        """Say that the mesh's material file is missing, unless the scene colors the object (`obj`, default the
        selected one) itself (then it does not matter)."""
        from renderer.mesh import missing_material_files

        obj = self.selected_object if obj is None else obj
        missing = missing_material_files(mesh) if mesh and obj.color is None else []
        if missing:
            self.say(f"{mesh.name}: material file {', '.join(missing)} not found: the mesh is grey", error=True)

    def close(self) -> None:
        """On quitting: keep an autosave of unsaved changes unless the user chose to discard them."""
        self.autosave.close()
        self.live.close()
