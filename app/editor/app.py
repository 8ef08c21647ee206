"""The editor's state and commands, and its frame loop.

`EditorApp` owns the open document, the voxel cache, the live render and the viewport. Its
commands (edit, undo, paint, load a mesh, save, ...) are what the panels, the viewport tools
and the replay file call; every failure becomes a message in the window and the scene stays
as it was.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.editor import edits, side_by_side, state
from app.editor.document import Document
from app.editor.jobs import BackgroundJob, Progress
from app.editor.orbit_view import HOME, viewport_camera
from app.editor.photo_tool import PhotoTool
from app.editor.render_panel import DETAIL_DELAY_S, LiveRender, RenderedFrame, export_render, final_render
from app.editor.viewport import ViewportRenderer
from app.editor.window import Window, upload_image
from renderer.camera import Camera
from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.io import save_png
from renderer.scene import ObjectSpec, PaintOp, Scene, save_scene
from renderer.surface import occupancy
from renderer.voxel_cache import VoxelCache, source_key

AUTOSAVE_SECONDS = 5.0
FRAME_SECONDS = 1.0 / 60.0  # the loop sleeps to this pace so the render thread gets the CPU it needs
MESSAGE_SECONDS = 8.0
REFERENCE_SPP = 64  # with OIDN: the project's reference quality (docs/pathtrace_spp.md)
SHIPPED_ASSETS = Path(__file__).resolve().parents[2] / "assets"  # the demo scene and models: Save writes elsewhere


def shipped(path: str | Path | None) -> bool:
    """Whether `path` is one of the files that ship with NVR Studio (never saved over, nor exported beside)."""
    return path is not None and Path(path).resolve().is_relative_to(SHIPPED_ASSETS)


def new_scene() -> Scene:
    """What File > New starts from: the demo chair (by absolute path) in the default set-up, no file yet."""
    return Scene(object=ObjectSpec(mesh=str(SHIPPED_ASSETS / "demo" / "chair.obj"), rotation_deg=30.0))
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
class Reference:
    """A path-traced image of a scene, shown beside the live render."""

    image: np.ndarray
    scene: Scene
    label: str


@dataclass
class Prompt:
    """A question the window asks before going on (unsaved changes, restoring an autosave)."""

    title: str
    text: str
    choices: tuple[str, ...]
    on_choice: Callable[[str], None]


@dataclass
class FrameStats:
    """UI frame times (wall time per frame, and the part spent working rather than pacing), split by
    whether the live render was working during the frame."""

    wall: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})
    work: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})
    drawn_work: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})  # frames that changed
    renders: list[float] = field(default_factory=list)  # seconds each shown render took
    recent: deque = field(default_factory=lambda: deque(maxlen=240))  # (monotonic time, work seconds) of active frames

    def add(self, wall_seconds: float, work_seconds: float, rendering: bool, drawn: bool) -> None:
        self.recent.append((time.monotonic(), work_seconds))
        self.wall[rendering].append(wall_seconds)
        self.work[rendering].append(work_seconds)
        if drawn:
            self.drawn_work[rendering].append(work_seconds)

    def current_text(self, window_seconds: float = 1.0) -> str:
        """The UI's work per frame over the last second of active frames, or "idle" when nothing was drawing
        (an idle window sleeps until input comes: its frame rate says nothing)."""
        since = time.monotonic() - window_seconds
        work = sorted(w for t, w in self.recent if t >= since)
        if not work:
            return "UI idle"
        return f"UI {1000.0 * work[len(work) // 2]:.1f} ms/frame"

    def summary(self) -> str:
        parts = []
        for rendering, name in ((True, "while rendering"), (False, "idle")):
            wall, work, drawn = self.wall[rendering], self.work[rendering], self.drawn_work[rendering]
            if wall:
                parts.append(f"{name}: {len(wall) / sum(wall):.1f} fps over {len(wall)} frames "
                             f"({1000.0 * sum(work) / len(work):.1f} ms of work per frame; {len(drawn)} drawn"
                             + (f", {1000.0 * sum(drawn) / len(drawn):.1f} ms each" if drawn else "") + ")")
        slowest = max((w for rendering in (True, False) for w in self.work[rendering]), default=None)
        if slowest is not None:
            parts.append(f"slowest frame {1000.0 * slowest:.0f} ms of work")
        if self.renders:
            parts.append(f"render median {1000.0 * sorted(self.renders)[len(self.renders) // 2]:.0f} ms "
                         f"over {len(self.renders)} renders")
        return "UI " + "; ".join(parts)


class EditorApp:
    """The editor: one document, its voxels, the live render, the viewport and the tools' settings."""

    def __init__(self, window: Window, document: Document, model_path: str | None = None, renderer: str = "nvr+",
                 quality: str = "full", recovery_slot: str = state.RECOVERY, detail_delay: float = DETAIL_DELAY_S):
        """`recovery_slot`: where the autosave is kept and looked for (state.HEADLESS_RECOVERY for scripted runs);
        `detail_delay`: how long a settled render stands before it is drawn again at the panel's size (scripted runs:
        0, as they wait for the editor to be idle between actions anyway)."""
        self.window = window
        self.recovery_slot = recovery_slot
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
        self.photo = PhotoTool(self)  # the Photo tab's photo being aligned, and its commands
        self.job: BackgroundJob | None = None
        self._job_done = None  # what to do with the job's result
        self.message: Message | None = None
        self.prompt: Prompt | None = None
        self.stats = FrameStats()
        self.quit_requested = False
        self.keep_recovery = True  # False once the user saved or discarded the changes on closing
        self._synced = -1  # document revision the viewport and render were last updated for
        self.shown_rgba = None  # the painted voxels the viewport shows (for picking)
        self.shown_source = None  # their object's source_key: paint on it keeps the viewport's faces
        self.shown_occupancy = None  # their occupancy (for picking; paint keeps it, and it is slow to find)
        self._autosaved = document.revision
        self._autosave_time = time.monotonic()
        self._screenshots: list[Path] = []
        self.unloadable_source = None  # the object (mesh or voxels file) that failed to load, if any
        self.reference: Reference | None = None  # the last reference render, and its texture
        self.reference_texture = None
        self._reference_error: tuple = (None, None, None)  # (frame, reference, their MSE)
        self._offer_recovery()

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

    def _offer_recovery(self) -> None:
        recovery = state.read_recovery(self.recovery_slot)
        if recovery is None:
            return
        origin = recovery.origin.name if recovery.origin else "an unsaved scene"
        text = f"Unsaved changes to {origin} were autosaved {state.age_text(recovery.saved_at)}."

        def choose(choice: str) -> None:
            if choice == "Restore":
                self._replace_document(Document(recovery.scene, None))
                self.doc.path = recovery.origin
                self.say(f"restored the autosaved changes to {origin}")
            else:
                state.clear_recovery(self.recovery_slot)

        self.ask("Restore unsaved changes?", text, ("Restore", "Discard"), choose)

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

    def undo(self) -> None:
        if not self.doc.undo():
            self.say("nothing to undo")

    def redo(self) -> None:
        if not self.doc.redo():
            self.say("nothing to redo")

    def paint_region(self, seed: tuple[int, int, int]) -> None:
        """Bucket fill: the connected region of similar color around voxel `seed` takes the palette color."""
        op = PaintOp("region", tuple(self.paint_color), tuple(int(s) for s in seed), float(self.tolerance))
        rgba, _ = self.voxels.painted(self.scene)
        if not (all(0 <= s < rgba.shape[0] for s in op.seed) and rgba[op.seed][3] >= 0.5):
            self.say(f"voxel {list(op.seed)} is not part of the object", error=True)
            return
        self.edit(lambda s: edits.paint(s, op))

    def fill_object(self) -> None:
        self.edit(lambda s: edits.paint(s, PaintOp("object", tuple(self.paint_color))))

    def fill_floor(self) -> None:
        self.edit(lambda s: edits.paint(s, PaintOp("floor", tuple(self.paint_color))))

    # --- files ------------------------------------------------------------------------------

    def open_scene(self, path: str | Path) -> None:
        """Open a scene file, asking first when the current one has unsaved changes."""
        def go() -> None:
            try:
                self._replace_document(Document.open(path))
            except InputError as exc:
                self.say(str(exc), error=True)
                return
            state.remember_scene(path)
            self.say(f"opened {path}")

        self._replace_after_asking("Save the current scene before opening another?", go)

    def new_scene(self) -> None:
        """Start a new, unsaved scene with the demo chair (asking first about unsaved changes)."""
        def go() -> None:
            self._replace_document(Document(new_scene(), None))
            self.say("new scene: load a mesh in the Object tab, or import a .vox")

        self._replace_after_asking("Save the current scene before starting a new one?", go)

    def _replace_after_asking(self, question: str, replace_document: Callable[[], None]) -> None:
        """Run `replace_document`, first asking whether to save unsaved changes (Save, Discard or Cancel)."""
        def choose(choice: str) -> None:
            if choice == "Cancel" or (choice == "Save" and not self.save()):
                return
            replace_document()

        if self.doc.dirty:
            choices = ("Save", "Discard", "Cancel") if self.doc.path else ("Discard", "Cancel")
            self.ask("Unsaved changes", question, choices, choose)
        else:
            replace_document()

    def save(self, path: str | Path | None = None, overwrite: bool = False) -> bool:
        """Write the scene (atomically) to `path` or to the file it came from; asks before replacing another file."""
        target = Path(path) if path else self.doc.path
        if target is None:
            self.say("choose a file name to save to (File tab)", error=True)
            self.requested_tab = "File"
            return False
        if path is None and shipped(target):
            self.say(f"{target.name} ships with NVR Studio and is not saved over: choose a file name (File tab, Save as)",
                     error=True)
            self.requested_tab = "File"
            return False
        own_file = (self.doc.path is not None and target.resolve() == self.doc.path.resolve()
                    and not shipped(target))  # a shipped file: ask before replacing

        def write() -> str:
            self.doc.cancel_preview()
            save_scene(state.adopt_capture(self.scene, target), target)
            self.doc.mark_saved(target)
            state.clear_recovery(self.recovery_slot)
            state.remember_scene(target)
            return f"saved {target}"

        return self._write_file(target, overwrite or own_file, write)

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

    def export(self, path: str | Path, overwrite: bool = False, size: int | None = None) -> bool:
        """Write the panel renderer's image of the committed scene at `size` pixels (default the scene's; a network's
        image of another size is resized and the message says so)."""
        def write() -> str:
            used = export_render(self.doc.history.current, path, self.live.model_path, self.live.renderer, self.voxels,
                                 size)
            return f"exported {path} ({used})"

        return self._write_file(path, overwrite, write)

    def export_side_by_side(self, path: str | Path, overwrite: bool = False) -> bool:
        """Write the viewport (as the user sees it, square) and the neural render of the committed scene side by side."""
        def write() -> str:
            if self.job is not None or self._synced != self.doc.revision:
                raise InputError("the viewport is not up to date yet: export again when the work in progress is done")
            scene = self.doc.history.current
            render, used = final_render(scene, self.live.model_path, self.live.renderer, self.voxels)
            height = render.shape[0] * side_by_side.scale_for(render.shape[0])
            viewport = self.viewport.image(height, height, viewport_camera(self.view, height, height), scene,
                                           self.floor_color)
            save_png(path, side_by_side.compose(viewport, to_uint8(render)))
            return f"exported the viewport and the render side by side to {path} ({used})"

        return self._write_file(path, overwrite, write)

    def _may_replace(self, path: str | Path, overwrite: bool, again: Callable[[], object]) -> bool:
        """Whether `path` may be written now; if it exists (and `overwrite` is not set) ask, and on Replace run `again`."""
        if Path(path).exists() and not overwrite:
            self.ask("Replace the file?", f"{path} exists. Replace it?", ("Replace", "Cancel"),
                     lambda choice: choice == "Replace" and again())
            return False
        return True

    def _write_file(self, path: str | Path, overwrite: bool, write: Callable[[], str]) -> bool:
        """Run `write` (it returns the message to show), asking first whether to replace `path` if it exists."""
        if not self._may_replace(path, overwrite, lambda: self._write_file(path, True, write)):
            return False
        try:
            message = write()
        except InputError as exc:
            self.say(str(exc), error=True)
            return False
        self.say(message)
        return True

    def import_vox(self, path: str | Path) -> None:
        """Make a MagicaVoxel model the object (its palette colors; the largest model of the file): one undo step."""
        from renderer.vox import read_vox

        def work(_progress: Progress) -> tuple[Path, int]:
            rgba = read_vox(path)
            return state.save_capture(rgba), rgba.shape[0]  # kept in the state folder; Save copies it beside the scene

        def done(result: tuple[Path, int]) -> None:
            voxels, n = result
            if self.edit(lambda s: edits.replace_object_source(s, voxels=voxels, resolution=n)):
                self.say(f"imported {Path(path).name} ({n}^3 voxels)")

        self.start_job(f"Importing {Path(path).name}", work, done)

    def export_vox(self, path: str | Path, overwrite: bool = False) -> bool:
        """Write the painted object voxels as a MagicaVoxel model (at most 255 colors)."""
        from renderer.vox import write_vox

        def write() -> str:
            rgba, _ = self.voxels.painted(self.doc.history.current)
            colors = write_vox(path, rgba)
            return f"exported {path} ({rgba.shape[0]}^3 voxels, {colors} colors)"

        return self._write_file(path, overwrite, write)

    def export_turntable(self, path: str | Path, frames: int = 36, sweep: str = "rotation", overwrite: bool = False) -> bool:
        """Render the committed scene turning (or the light circling) with the panel's renderer in the background,
        then write an animated GIF (`path` ends in .gif) or a folder of PNG frames; asks before replacing a GIF."""
        from app.turntable import TurntableConfig, render_turntable, write_frames

        target = Path(path)
        overwrite = overwrite or target.suffix.lower() != ".gif"  # a folder of frames is written into, not replaced
        if not self._may_replace(target, overwrite, lambda: self.export_turntable(path, frames, sweep, overwrite=True)):
            return False
        config = TurntableConfig(frames=frames, sweep=sweep, renderer=self.live.renderer, model=self.live.model_path)
        scene = self.doc.history.current

        def work(progress: Progress) -> str:
            images, seconds, name = render_turntable(scene, config, progress=False, on_frame=progress)
            write_frames(target, images)
            return f"exported {path} ({frames} frames, {sweep} sweep, {name}, {1000 * sum(seconds) / len(seconds):.0f} ms a frame)"

        self.start_job(f"Turntable {target.name}", work, self.say)
        return True

    def reference_render(self, spp: int = REFERENCE_SPP) -> None:
        """Path trace the committed scene (edits included) in the background, to show beside the live render."""
        from renderer.pathtrace.path_tracer import PathTracer
        from renderer.reference_object import reference_scene

        scene = self.doc.history.current

        def work(progress: Progress) -> Reference:
            start = time.perf_counter()
            traced_scene, mesh = reference_scene(scene)
            progress(0.15)
            tracer = PathTracer(traced_scene, mesh)
            progress(0.3)
            result = tracer.render(spp, seed=0, denoise=True)
            return Reference(result.image, scene, f"path traced, {result.spp} spp + OIDN, {time.perf_counter() - start:.1f} s")

        def done(reference: Reference) -> None:
            self.reference = reference
            self.reference_texture = upload_image(self.window.ctx, self.reference_texture, reference.image)
            self.say(f"reference render ready ({reference.label})")

        self.start_job("Path tracing the reference", work, done)

    def reference_error(self) -> float | None:
        """MSE (0-255 scale) between the shown render and the reference, when both show the same scene at one size;
        computed once per pair (the panel asks every frame)."""
        frame, reference = self.shown_frame, self.reference
        if self._reference_error[0] is not frame or self._reference_error[1] is not reference:
            same = (frame is not None and reference is not None and not frame.preview and frame.scene == reference.scene
                    and frame.image.shape == reference.image.shape)
            error = float(np.mean((frame.image.astype(np.float64) - reference.image) ** 2) * 255.0**2) if same else None
            self._reference_error = (frame, reference, error)
        return self._reference_error[2]

    def screenshot(self, path: str | Path) -> None:
        """Save the whole window at the end of this frame."""
        self._screenshots.append(Path(path))

    def load_mesh(self, path: str | Path, up: str = "y") -> None:
        """Voxelise a mesh in the background (progress in the window), then put it in place of the object."""
        try:
            candidate = edits.replace_object_source(self.doc.history.current, mesh=Path(path), up=up)
        except InputError as exc:
            self.say(str(exc), error=True)
            return
        def done(_rgba) -> None:
            if self.edit(lambda s: edits.replace_object_source(s, mesh=Path(path), up=up)):
                self.say(f"loaded {Path(path).name}")
                self._warn_missing_materials(Path(path))

        self.start_job(f"Voxelising {Path(path).name}", lambda progress: self.voxels.object_rgba(candidate, progress), done)

    def start_job(self, title: str, work: Callable[[Progress], object], on_result: Callable[[object], None]) -> None:
        """Run `work(progress)` in the background (one job at a time); `on_result` gets its result on the UI thread."""
        if self.job is not None and not self.job.done:
            self.say(f"busy: {self.job.title}", error=True)
            return
        self.job = BackgroundJob(title, work)
        self._job_done = on_result

    def _replace_document(self, document: Document) -> None:
        self.doc = document
        self.photo = PhotoTool(self)  # a photo aligned to the old scene's object does not carry over
        self._synced = -1
        self._autosaved = document.revision

    # --- the frame loop ---------------------------------------------------------------------

    @property
    def busy(self) -> str | None:
        """What is still under way (a job, a render, a scene not yet shown), or None when all is done."""
        if self.job is not None:
            return self.job.title
        if not self.live.idle:
            return "rendering"
        if self._synced != self.doc.revision or self.shown_frame is None or self.shown_frame.scene != self.scene:
            return "showing the latest edit"
        return None

    def request_quit(self) -> None:
        """Close the window, asking first about unsaved changes."""
        if not self.doc.dirty:
            self.quit_requested = True
            return

        def choose(choice: str) -> None:
            if choice == "Save" and not self.save():
                return
            if choice in ("Save", "Discard"):
                self.keep_recovery = False
                self.quit_requested = True

        choices = ("Save", "Discard", "Cancel") if self.doc.path else ("Discard", "Cancel")
        self.ask("Unsaved changes", "Save the scene before closing?", choices, choose)

    def update(self) -> None:
        """Once per frame, before drawing: finish jobs, bring viewport and render up to date, autosave."""
        if self.job is not None and self.job.done:
            job, self.job = self.job, None
            if job.error:
                self.say(job.error, error=True)
            else:
                self._job_done(job.result)
        if self._synced != self.doc.revision:
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
        self._autosave()

    def _sync(self) -> None:
        """Show the document's scene: upload its voxels (voxelising in the background first if needed), render it."""
        scene = self.doc.scene
        if not self.voxels.has_object(scene):
            if self.job is not None:
                return  # voxelising (or another job): the scene is shown when it is done
            if source_key(scene) == self.unloadable_source:  # its error is shown; retried only once the object changes
                self._synced = self.doc.revision
            else:
                self.unloadable_source = source_key(scene)  # until the job succeeds
                self.start_job(f"Loading {Path(scene.object.mesh or scene.object.voxels).name}",
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
        self._warn_missing_materials(self.scene.mesh_path())

    def _warn_missing_materials(self, mesh: Path | None) -> None:
        from renderer.mesh import missing_material_files

        missing = missing_material_files(mesh) if mesh else []
        if missing:
            self.say(f"{mesh.name}: material file {', '.join(missing)} not found: the mesh is grey", error=True)

    def _autosave(self) -> None:
        now = time.monotonic()
        if self.doc.revision == self._autosaved or now - self._autosave_time < AUTOSAVE_SECONDS:
            return
        self.autosave_now()

    def autosave_now(self) -> None:
        """Write the recovery file now if there are unsaved changes (else remove it)."""
        try:
            if self.doc.dirty:
                state.write_recovery(self.doc.history.current, self.doc.path, self.recovery_slot)
            else:
                state.clear_recovery(self.recovery_slot)
        except (InputError, OSError) as exc:
            self.say(f"autosave failed: {exc}", error=True)
        self._autosaved = self.doc.revision
        self._autosave_time = time.monotonic()

    @property
    def screenshot_due(self) -> bool:
        """A screenshot waits for this frame, which must then be drawn even if it looks like the last one."""
        return bool(self._screenshots)

    def take_screenshots(self) -> None:
        """Save the screenshots asked for this frame (the frame is drawn but not yet shown)."""
        for path in self._screenshots:
            try:
                save_png(path, self.window.screenshot())
            except InputError as exc:
                self.say(str(exc), error=True)
        self._screenshots.clear()

    def close(self) -> None:
        """On quitting: keep an autosave of unsaved changes unless the user chose to discard them."""
        if self.keep_recovery:
            self.autosave_now()
        else:
            state.clear_recovery(self.recovery_slot)
        self.live.close()
